"""A least-squares B-spline calf (``mode="lsq"``): beyond the paper's 7 x m interpolation.

The paper's surface interpolates 7 x m feature points, so it is only as good as the
points picked.  Here every resampled section point and then every scan point of the
calf takes part:

1. **Anatomical parameters.**  u runs around the leg, u = 0 anterior (the calf frame's
   +y), increasing counter-clockwise seen from above (+z); v runs along it with the
   seven feature layers (B, ., B1, ., C, ., D; paper section 2.2) at v = k/6 - a
   monotone cubic (PCHIP) through (layer height, k/6), so v is smooth in z and B, B1,
   C, D sit at v = 0, 1/3, 2/3, 1 for every leg.  With the knot vectors below fixed
   too, two lsq records on the same grid correspond control point to control point
   (what comparisons and population averages need).
2. **Tensor-product cubic B-spline**, periodic in u (``around`` distinct control
   columns, uniform knots: the leg has no preferred direction of detail that holds
   for every leg) and clamped in v (``along`` control rows, uniform interior knots in
   the anatomical v: the anatomy already spaces the data, a layer per sixth of v).
   Measured alternatives on the 5 real legs (knots warped t -> t^1.3 towards B, towards
   D, or towards both ends): 10% lower E at 12 x 24 towards B, but 9-33% higher at
   7 x 15; the knots must be shared by all records of a grid (correspondence), so a
   per-grid choice would have to be fitted on a population - not done.
   Weights are all 1: free weights would make the fit nonlinear (and the average of two
   rational nets is not the average surface); the calf holds no conic section that
   would need them.  Not measured.
3. **First fit** to the 200 x 72 polar resampling of :mod:`app.geometry.sections` (the
   gaps already bridged in the polar domain, paper 2.1), parameters (u of the ray, v
   of the section): data on a tensor grid, so two small 1-D least-squares problems
   (:func:`solve_grid`).
4. **Refinement against the scan points** (:data:`CORRECTIONS` rounds): the scan
   points between B and D are projected on the surface (exact foot points by Newton,
   :mod:`app.geometry.spline.distance`), and the net is refitted with those foot
   parameters by squared-distance minimization (SDM; Wang, Pottmann & Liu, ACM TOG
   25(2), 2006): the normal part of each point's offset is minimized, the tangential
   part only weakly (:data:`TANGENTIAL`).  Plain parameter correction (Hoschek 1988:
   project, refit all three offsets, repeat) converges linearly and slowly, because
   the refit drags the surface along its own tangents; SDM follows the local
   quadratic model of the squared distance.  Measured on the bodyparts3d leg at 7 x 15
   after two rounds: exact E 0.72% with plain correction, 0.62% with SDM and a
   tangential weight of 0.1, 0.47% with 0.01 (the paper mode: 0.99%).
   A small second-difference (thin-plate-like) penalty on the net, with a weight fixed
   relative to the data term's mean diagonal (:data:`SMOOTHING`), holds the surface
   where a hole leaves no points; where the points are dense it is negligible.

Solving: every point's row of the collocation matrix has 4 x 4 non-zeros (the product
of the u and v cubic bases, :class:`~app.geometry.spline.basis.BSplineBasis`), so the normal
equations ``(A^T W A + lambda D^T D) x = A^T W q`` (W: the weights 1/r_k^2 that make
the squares those of the error index E, paper eq. 4; SDM couples x, y and z through
3 x 3 blocks) are assembled sparse (a few thousand unknowns at most) and factorized
once per round - never a dense solve over the points.

Units: mm; control points (around + 3, along, 3) in the stored (unwrapped) form of
:mod:`app.geometry.spline.nurbs`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.sparse import block_diag, bmat, csr_matrix, diags, vstack
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.sections import PolarSections
from app.geometry.spline.basis import BSplineBasis
from app.geometry.spline.distance import foot_points
from app.geometry.spline.nurbs import NurbsSurface, evaluate_derivatives, evaluate_grid

DEGREE = 3
#: rounds of parameter correction against the scan points
CORRECTIONS = 2
#: scan points per correction round: every floor(n / this)-th (so 20k-40k of a large
#: scan; a cloud's calf points arrive already thinned to 20k): the net has at most a few
#: thousand unknowns, so 20k points over-determine it tenfold
MAX_CORRECTION_POINTS = 20_000
#: weight of the tangential part of the squared distance in SDM (see
#: :func:`solve_net_squared_distance`)
TANGENTIAL = 0.01
#: weight of the second-difference penalty, relative to the mean diagonal of A^T A
SMOOTHING = 1e-4
#: the grid's bounds (control rows along x distinct control columns around)
ALONG_RANGE = (4, 40)
AROUND_RANGE = (6, 72)
_GRID = re.compile(r"^\s*(\d+)\s*[xX*]\s*(\d+)\s*$")


@dataclass(frozen=True)
class LsqGrid:
    """Control net size: ``along`` rows from B to D, ``around`` distinct columns."""

    along: int = 7
    around: int = 15

    @classmethod
    def parse(cls, text: str) -> LsqGrid:
        """``"ALONGxAROUND"`` (e.g. ``"7x15"``) -> LsqGrid; FitFailure INVALID_OPTION."""
        match = _GRID.match(str(text))
        if not match:
            raise FitFailure(FailureReason.INVALID_OPTION,
                             f"grid must be ALONGxAROUND, e.g. 7x15 or 12x24, not {text!r}")
        grid = cls(int(match.group(1)), int(match.group(2)))
        grid.validate()
        return grid

    def validate(self) -> None:
        if not ALONG_RANGE[0] <= self.along <= ALONG_RANGE[1] or not AROUND_RANGE[0] <= self.around <= AROUND_RANGE[1]:
            raise FitFailure(
                FailureReason.INVALID_OPTION,
                f"grid must have {ALONG_RANGE[0]}-{ALONG_RANGE[1]} control rows along the leg and "
                f"{AROUND_RANGE[0]}-{AROUND_RANGE[1]} around it, not {self.along}x{self.around}",
            )

    def __str__(self) -> str:
        return f"{self.along}x{self.around}"


def periodic_knots(n: int) -> np.ndarray:
    """Uniform periodic cubic knots (n + 7,) over [0, 1] for n distinct control columns,
    written out in full (the stored, unwrapped form)."""
    return np.arange(-DEGREE, n + DEGREE + 1, dtype=np.float64) / n


def clamped_knots(n: int) -> np.ndarray:
    """Clamped cubic knots (n + 4,) over [0, 1] with uniform interior knots."""
    interior = np.linspace(0.0, 1.0, n - DEGREE + 1)[1:-1]
    return np.concatenate([np.zeros(DEGREE + 1), interior, np.ones(DEGREE + 1)])


def _periodic_basis(u: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Column indices (N, 4) in [0, n) and values (N, 4) of the periodic cubic basis."""
    columns, values = BSplineBasis(periodic_knots(n), DEGREE, periodic=True).local(np.mod(u, 1.0))
    return np.mod(columns, n), values


def _clamped_basis(v: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Column indices (N, 4) and values (N, 4) of the clamped cubic basis, v in [0, 1]."""
    return BSplineBasis(clamped_knots(n), DEGREE).local(np.clip(v, 0.0, 1.0))


def collocation(u: np.ndarray, v: np.ndarray, grid: LsqGrid) -> csr_matrix:
    """Sparse (N, around * along) matrix: row k holds the 16 tensor-product basis values
    at (u_k, v_k); unknown ``i * along + j`` is control point (column i around, row j)."""
    iu, bu = _periodic_basis(u, grid.around)
    iv, bv = _clamped_basis(v, grid.along)
    cols = (iu[:, :, None] * grid.along + iv[:, None, :]).reshape(len(u), -1)
    vals = (bu[:, :, None] * bv[:, None, :]).reshape(len(u), -1)
    rows = np.repeat(np.arange(len(u)), cols.shape[1])
    return csr_matrix((vals.ravel(), (rows, cols.ravel())), shape=(len(u), grid.around * grid.along))


def second_differences(grid: LsqGrid) -> csr_matrix:
    """Sparse penalty rows: second differences of the net around (periodic) and along."""
    n_u, n_v = grid.around, grid.along
    index = np.arange(n_u * n_v).reshape(n_u, n_v)
    rows = []
    # around: C[i-1, j] - 2 C[i, j] + C[i+1, j], i cyclic
    centre = index.ravel()
    rows.append((np.roll(index, 1, axis=0).ravel(), centre, np.roll(index, -1, axis=0).ravel()))
    # along: C[i, j-1] - 2 C[i, j] + C[i, j+1], 1 <= j <= n_v - 2
    rows.append((index[:, :-2].ravel(), index[:, 1:-1].ravel(), index[:, 2:].ravel()))
    blocks = []
    for lo, mid, hi in rows:
        m = len(mid)
        r = np.repeat(np.arange(m), 3)
        c = np.column_stack([lo, mid, hi]).ravel()
        d = np.tile([1.0, -2.0, 1.0], m)
        blocks.append(csr_matrix((d, (r, c)), shape=(m, n_u * n_v)))
    return vstack(blocks).tocsr()


def _solve_normal_equations(normal, rhs: np.ndarray) -> np.ndarray:
    """Solve sparse normal equations with a tiny ridge (a control point with no data and
    no penalty stays finite) by one LU; FitFailure DEGENERATE_SURFACE when the points do
    not determine the net."""
    normal = normal + diags(np.full(normal.shape[0], 1e-12 * float(normal.diagonal().max())))
    try:
        solution = splu(normal.tocsc()).solve(rhs)
    except RuntimeError as exc:
        raise FitFailure(FailureReason.DEGENERATE_SURFACE,
                         "the least-squares surface is not determined by the scan points") from exc
    if not np.isfinite(solution).all():
        raise FitFailure(FailureReason.DEGENERATE_SURFACE, "the least-squares surface is not determined by the scan points")
    return solution


def _dense_basis(indices: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros((len(indices), n))
    np.add.at(out, (np.repeat(np.arange(len(indices)), indices.shape[1]), indices.ravel()), values.ravel())
    return out


def solve_grid(data: np.ndarray, u: np.ndarray, v: np.ndarray, grid: LsqGrid,
               row_weights: np.ndarray | None = None) -> np.ndarray:
    """Least-squares net (around, along, 3) of gridded points data (k, a, 3) at ray
    parameters u (a,) and section parameters v (k,), each row weighted (k,): with data
    on a tensor grid the problem separates into two small 1-D ones (de Boor, *A
    Practical Guide to Splines*, ch. XVII):  C = (Bv' W Bv)^-1 Bv' W P Bu (Bu' Bu)^-1."""
    bu = _dense_basis(*_periodic_basis(u, grid.around), grid.around)  # (a, around)
    bv = _dense_basis(*_clamped_basis(v, grid.along), grid.along)  # (k, along)
    w = np.ones(len(v)) if row_weights is None else row_weights
    left = bv.T @ (w[:, None] * bv)
    right = bu.T @ bu
    for m in (left, right):  # a tiny ridge: a basis function without data stays finite
        m[np.diag_indices_from(m)] += 1e-12 * m.diagonal().max()
    try:
        along_solved = np.linalg.solve(left, np.einsum("ka,kc->ac", bv * w[:, None], data.reshape(len(v), -1)))
        along_solved = along_solved.reshape(grid.along, len(u), 3)
        net = np.linalg.solve(right, np.einsum("ai,jac->ijc", bu, along_solved).reshape(grid.around, -1))
    except np.linalg.LinAlgError as exc:
        raise FitFailure(FailureReason.DEGENERATE_SURFACE, "the least-squares surface is not determined by the sections") from exc
    return net.reshape(grid.around, grid.along, 3)


def solve_net_squared_distance(points: np.ndarray, u: np.ndarray, v: np.ndarray, normals: np.ndarray,
                               grid: LsqGrid, smoothing: float = SMOOTHING, weights: np.ndarray | None = None,
                               tangential: float | None = None,
                               end_heights: tuple[float, float] | None = None) -> np.ndarray:
    """One step of squared-distance minimization (SDM; Wang, Pottmann & Liu, ACM TOG
    2006): the net (around, along, 3) minimizing, with the foot parameters (u, v) fixed,

        sum_k w_k [ (n_k . e_k)^2 + tangential * |e_k - (n_k . e_k) n_k|^2 ],
        e_k = S(u_k, v_k) - q_k,

    n_k (N, 3) the unit surface normals at the foot points.  The normal term is the
    local second-order model of the squared distance, so the iteration converges fast
    (tangent-distance minimization is quadratic for small residuals); the small
    tangential term keeps the system well posed along the surface, where distance
    does not change.  x, y, z are coupled: 3 x unknowns, sparse, one LU.
    ``tangential=1`` is plain least squares on the points (the metric is the identity,
    the normals do not matter); ``smoothing`` weights the second-difference penalty
    relative to the mean diagonal of the data term (0: none).
    """
    tangential = TANGENTIAL if tangential is None else tangential
    a = collocation(u, v, grid)
    n = a.shape[1]
    w = np.ones(len(points)) if weights is None else weights
    metric = tangential * np.eye(3)[None] + (1.0 - tangential) * normals[:, :, None] * normals[:, None, :]
    # a point whose foot lies on the border (v = 0 or 1) is off the end of the surface:
    # its distance is not along the normal, so it pulls by its whole offset (PDM)
    border = (v <= 0.0) | (v >= 1.0)
    metric[border] = np.eye(3)
    normal = bmat([[(diags(w * metric[:, i, j]) @ a).T @ a for j in range(3)] for i in range(3)]).tocsc()
    rhs = np.concatenate([(a.T @ (w * np.einsum("kij,kj->ki", metric, points)[:, i])) for i in range(3)])
    if smoothing > 0:
        penalty = second_differences(grid)
        scale = smoothing * float(normal.diagonal().mean())
        pp = penalty.T @ penalty
        normal = normal + scale * block_diag([pp, pp, pp])
    if end_heights is not None:
        # flat ends: the z of the first and last control rows (the border curves of a
        # clamped surface) held at the heights of B and D by a stiff penalty
        index = np.arange(n).reshape(grid.around, grid.along)
        ends = np.concatenate([index[:, 0], index[:, -1]]) + 2 * n
        target = np.repeat(np.asarray(end_heights, dtype=np.float64), grid.around)
        stiff = END_STIFFNESS * float(normal.diagonal().mean())
        normal = normal + diags(np.bincount(ends, minlength=3 * n).astype(float) * stiff)
        rhs = rhs + np.bincount(ends, weights=target * stiff, minlength=3 * n)
    solution = _solve_normal_equations(normal, rhs)
    return solution.reshape(3, n).T.reshape(grid.around, grid.along, 3)


def surface_from_net(net: np.ndarray) -> NurbsSurface:
    """The stored (unwrapped, non-rational) surface of a net (around, along, 3)."""
    n_u, n_v, _ = net.shape
    control = np.concatenate([net, net[:DEGREE]], axis=0)
    return NurbsSurface(DEGREE, DEGREE, periodic_knots(n_u), clamped_knots(n_v), np.ascontiguousarray(control),
                        np.ones(control.shape[:2]), True)


def anatomical_v(z: np.ndarray, layer_heights: np.ndarray) -> np.ndarray:
    """v (N,) of calf-frame heights z (N,) mm: layer k of the 7 at v = k/6 (PCHIP)."""
    layers = np.asarray(layer_heights, dtype=np.float64)
    return np.clip(PchipInterpolator(layers, np.linspace(0.0, 1.0, len(layers)), extrapolate=True)(z), 0.0, 1.0)


def ray_u(angles_rad: np.ndarray) -> np.ndarray:
    """u (a,) of polar ray angles (a,) in the calf frame: 0 anterior (+y), counter-clockwise."""
    return np.mod((angles_rad - np.pi / 2.0) / (2.0 * np.pi), 1.0)


def section_points(sections: PolarSections) -> np.ndarray:
    """(k, a, 3) calf-frame points of resampled sections (NaN rows for missing ones)."""
    a = sections.angles_rad
    c = sections.centroids_mm
    return np.stack([c[:, 0, None] + sections.radii_mm * np.cos(a), c[:, 1, None] + sections.radii_mm * np.sin(a),
                     np.broadcast_to(sections.heights_mm[:, None], sections.radii_mm.shape)], axis=-1)


#: weight of the flat-ends penalty, relative to the mean diagonal of the normal equations
END_STIFFNESS = 1e4
#: the end rings hold the border as firmly as the scan points of this much leg would
END_RING_BAND_MM = 5.0


def end_rings(sections: PolarSections, layer_heights: np.ndarray, n_points: int,
              length_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The resampled sections at B and D as data of the SDM rounds held on the border:
    points (2a, 3), v (2a,) (their sections' v: 0 at B, 1 at D) and weights (2a,); each
    round pairs them with the nearest point of their ring (:func:`ring_feet`).

    A clamped surface's border curve is its first (last) control row, and in the SDM
    rounds no scan point pulls it: the points project inside, so the border drifts off
    the planes of B and D and away from the skin (a plane z = D then cuts the surface
    only partly: a D girth 15-62 mm short on the real legs).  The polar resampling's
    rings at B and D (gaps bridged in the polar domain, paper 2.1) hold it: each ring
    weighs as much as the scan points within :data:`END_RING_BAND_MM` of it, with the
    1 / r^2 weight of the error index; being on the border, its points pull by their
    whole offset (point distance); with the flat ends of
    :func:`solve_net_squared_distance` the border lies in the planes z = B and z = D."""
    valid = np.flatnonzero(sections.valid)
    ends = valid[[0, -1]]
    points = section_points(sections)[ends].reshape(-1, 3)
    a = len(sections.angles_rad)
    v = np.repeat(anatomical_v(sections.heights_mm[ends], layer_heights), a)
    radius = np.repeat(sections.mean_radii()[ends], a)
    per_point = n_points / max(length_mm, 1e-9) * END_RING_BAND_MM / a
    return points, v, per_point / radius ** 2


#: samples of a ring searched for the nearest point (0.14 mm apart round a 400 mm girth)
RING_SAMPLES = 2880


def ring_feet(surface: NurbsSurface, points: np.ndarray, v: np.ndarray) -> np.ndarray:
    """u (N,) of the nearest point to each of points (N, 3) on the surface's ring at its
    v (N,) (a few distinct v: the end rings), from :data:`RING_SAMPLES` samples: the
    ring's own parameter, so that an end ring holds the border without dragging it
    round the leg (the ray angle is not the surface's u)."""
    u_grid = np.arange(RING_SAMPLES) / RING_SAMPLES
    out = np.empty(len(points))
    for ring_v in np.unique(v):  # two rings
        pick = v == ring_v
        ring = evaluate_grid(surface, u_grid, np.array([ring_v]))[:, 0]
        out[pick] = u_grid[cKDTree(ring).query(points[pick])[1]]
    return out


@dataclass(frozen=True)
class LsqFit:
    """The lsq surface and how its refinement went: ``rms_mm`` (rounds + 1,), the RMS
    distance of the correction points after the first fit and after each round."""

    surface: NurbsSurface
    grid: LsqGrid
    rms_mm: tuple


def fit_lsq_surface(sections: PolarSections, layer_heights: np.ndarray, scan_points: np.ndarray,
                    grid: LsqGrid, corrections: int = CORRECTIONS, smoothing: float = SMOOTHING) -> LsqFit:
    """The lsq calf (module docstring) from the resampled sections (k, a) between B and
    D, the 7 layer heights (7,) mm, and the scan points (N, 3) mm of the calf (calf
    frame, B <= z <= D)."""
    grid.validate()
    valid = sections.valid
    data = section_points(sections)[valid]  # (k', a, 3)
    u = np.broadcast_to(ray_u(sections.angles_rad)[None, :], data.shape[:2])
    v = np.broadcast_to(anatomical_v(sections.heights_mm[valid], layer_heights)[:, None], data.shape[:2])
    # weights 1 / r_k^2: the squares summed are then those of the error index E
    # (paper eq. 4: distances relative to the section's mean radius r_k)
    radius = sections.mean_radii()[valid]
    net = solve_grid(data, u[0], v[:, 0], grid, 1.0 / radius**2)
    surface = surface_from_net(net)
    length = float(layer_heights[-1] - layer_heights[0])
    sample = scan_points[:: max(len(scan_points) // MAX_CORRECTION_POINTS, 1)]
    heights = sections.heights_mm[valid]
    nearest = np.clip(np.searchsorted(heights, sample[:, 2]), 0, len(heights) - 1)
    sample_weight = 1.0 / radius[nearest] ** 2
    rms = []
    anchors, anchor_v, anchor_weight = end_rings(sections, layer_heights, len(sample), length)
    for _ in range(corrections if len(sample) else 0):
        distance, pu, pv = foot_points(surface, sample, length)
        rms.append(float(np.sqrt(np.mean(distance**2))))
        _, su, sv, _, _, _ = evaluate_derivatives(surface, pu, pv)
        normals = np.cross(su, sv)
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        anchor_u = ring_feet(surface, anchors, anchor_v)
        net = solve_net_squared_distance(np.concatenate([sample, anchors]), np.concatenate([pu, anchor_u]),
                                         np.concatenate([pv, anchor_v]),
                                         np.concatenate([normals, np.zeros_like(anchors)]), grid, smoothing,
                                         np.concatenate([sample_weight, anchor_weight]),
                                         end_heights=(float(layer_heights[0]), float(layer_heights[-1])))
        # the stiff penalty leaves the end rows within ~1e-4 mm of B and D: exactly flat
        net[:, 0, 2], net[:, -1, 2] = layer_heights[0], layer_heights[-1]
        surface = surface_from_net(net)
    if corrections and len(sample):
        rms.append(float(np.sqrt(np.mean(foot_points(surface, sample, length)[0] ** 2))))
    return LsqFit(surface, grid, tuple(rms))

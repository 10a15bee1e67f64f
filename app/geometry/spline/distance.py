"""Distance of scan points to the NURBS surface and the error index E (paper section 2.6).

Two distances per scan point q:

(a) the paper's Algorithm 1: the surface is resampled on a dense (u, v) grid (denser
    than the scan: 1 degree x ~1 mm, chordal error < 0.002 mm at r = 50 mm), each quad split into two triangles; the
    nearest grid vertex g(x, y) is found (k-d tree) and l is the smallest distance from
    q to the 8 triangles of the 2 x 2 quads around it (exact point-triangle distance,
    Ericson, *Real-Time Collision Detection* 5.1.5, instead of the paper's unbounded
    point-to-plane distance, which can undershoot);
(b) the exact orthogonal distance: Newton iteration on ``(S(u,v) - q) . S_u = 0``,
    ``(S(u,v) - q) . S_v = 0`` (The NURBS Book section 6.1, eqs. 6.5-6.7), seeded at the
    grid vertex of (a), u wrapped periodically, v clamped to the domain.

Error index (paper eq. 4):  E = sqrt(mean((l / r_k)^2)), r_k the mean radius of the
cross-section the point lies in.  The paper's text says it normalizes by the mean
*diameter*; that form is exactly E / 2 and is stored beside it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from app.geometry.spline.nurbs import NurbsSurface, evaluate_derivatives, evaluate_grid

#: Algorithm 1 grid: rays around the leg and rows per millimetre of leg
DENSE_U = 360
DENSE_V_PER_MM = 1.0
NEWTON_ITERATIONS = 8
#: a point whose next Newton step is shorter than this on the surface has converged, mm
STEP_TOLERANCE_MM = 1e-3


@dataclass(frozen=True)
class SurfaceError:
    """Error statistics of a fitted surface against the scan points between B and D.

    All indices are fractions (0.0037 means 0.37%); distances in mm.
    ``per_layer`` rows: one per feature layer band, keys ``layer``, ``height_mm``,
    ``n_points``, ``error_index_exact``, ``max_error_mm``.
    """

    error_index: float  # Algorithm 1 distances, normalized by the mean radius (eq. 4)
    error_index_exact: float  # Newton distances, normalized by the mean radius
    error_index_diameter: float  # Algorithm 1, normalized by the mean diameter (paper's text)
    error_index_exact_diameter: float
    max_error_mm: float  # exact
    mean_error_mm: float  # exact
    n_points: int
    per_layer: tuple


def dense_grid(surface: NurbsSurface, length_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dense parameter grid for Algorithm 1.

    Returns u (a,) (periodic: end excluded), v (b,) (both ends), points (a, b, 3) mm.
    """
    u0, u1 = surface.domain_u
    v0, v1 = surface.domain_v
    u = u0 + (u1 - u0) * np.arange(DENSE_U) / DENSE_U
    v = np.linspace(v0, v1, max(int(np.ceil(length_mm * DENSE_V_PER_MM)) + 1, 8))
    return u, v, evaluate_grid(surface, u, v)


def _dot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Dot products over the last axis of (..., 3) arrays (broadcasting) -> (...)."""
    return x[..., 0] * y[..., 0] + x[..., 1] * y[..., 1] + x[..., 2] * y[..., 2]


def point_triangle_distances(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance from p to triangle (a, b, c), (..., 3) arrays that broadcast -> (...)
    (Ericson 5.1.5, vectorized): the length of :func:`point_triangle_offsets`."""
    diff = point_triangle_offsets(p, a, b, c)
    return np.sqrt(_dot(diff, diff))


def point_triangle_offsets(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """p minus its closest point on triangle (a, b, c), (..., 3) arrays that broadcast ->
    (..., 3) mm (Ericson 5.1.5, vectorized).

    The Voronoi region of the closest feature (vertex, edge or face) is chosen on arrays
    of barycentric weights (v, w) with closest point ``a + v*ab + w*ac``.  A degenerate
    triangle (a mesh whose vertices were rounded to a grid collapses some: two corners
    on one point, or three on a line) has no face region and an edge of zero length,
    whose parameter is 0/0; Ericson's regions assume a face, so such a triangle (its
    squared doubled area |ab x ac|^2 = |ab|^2 |ac|^2 - (ab.ac)^2 under 1e-12 of
    |ab|^2 |ac|^2) is measured as the nearest of its three segments.
    """
    ab, ac, ap = b - a, c - a, p - a
    d1 = _dot(ab, ap)
    d2 = _dot(ac, ap)
    ab_ab = _dot(ab, ab)
    ab_ac = _dot(ab, ac)
    ac_ac = _dot(ac, ac)
    d3, d4 = d1 - ab_ab, d2 - ab_ac  # ab.bp, ac.bp with bp = ap - ab
    d5, d6 = d1 - ab_ac, d2 - ac_ac  # ab.cp, ac.cp with cp = ap - ac
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = 1.0 / (va + vb + vc)
        v = vb * denom
        w = vc * denom
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    regions = [  # in Ericson's order of tests; the first that holds wins
        ((d1 <= 0) & (d2 <= 0), 0.0, 0.0),
        ((d3 >= 0) & (d4 <= d3), 1.0, 0.0),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), t_ab, 0.0),
        ((d6 >= 0) & (d5 <= d6), 0.0, 1.0),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), 0.0, t_ac),
        ((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), 1.0 - t_bc, t_bc),
    ]
    for condition, rv, rw in reversed(regions):
        v = np.where(condition, rv, v)
        w = np.where(condition, rw, w)
    offsets = ap - v[..., None] * ab - w[..., None] * ac
    flat = np.broadcast_to(ab_ab * ac_ac - ab_ac**2 <= 1e-12 * ab_ab * ac_ac, offsets.shape[:-1])
    if flat.any():  # a degenerate triangle: the nearest of its segments
        offsets = np.array(offsets)
        p_, a_, b_, c_ = (np.broadcast_to(x, offsets.shape)[flat] for x in (p, a, b, c))
        edges = np.stack([_segment_offsets(p_, a_, b_), _segment_offsets(p_, b_, c_), _segment_offsets(p_, c_, a_)])
        offsets[flat] = np.take_along_axis(edges, np.argmin(_dot(edges, edges), axis=0)[None, :, None], axis=0)[0]
    return offsets


def _segment_offsets(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k, 3): p minus its closest point on the segment a-b, (k, 3) arrays, mm (a segment of
    zero length is its point a)."""
    ab = b - a
    t = np.clip(_dot(p - a, ab) / np.maximum(_dot(ab, ab), np.finfo(float).tiny), 0.0, 1.0)
    return p - a - t[:, None] * ab


#: the 2 x 2 quads around a grid vertex, as (row, column) origins in its 3 x 4 neighbourhood
_QUAD_ROW = np.array([0, 0, 1, 1])
_QUAD_COL = np.array([0, 2, 0, 2])


def algorithm1_distances(
    points: np.ndarray, grid: np.ndarray, tree: cKDTree
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Paper Algorithm 1 on a periodic-in-u grid.

    points (N, 3); grid (a, b, 3) surface samples; tree over ``grid.reshape(-1, 3)``.
    Returns distances (N,), and the nearest vertex indices iu (N,), iv (N,).

    The 8 triangles of the 2 x 2 quads around the nearest vertex (iu, iv) are built from
    its neighbourhood gathered once, relative to the point: rows iu-1, iu, iu+1 (u
    periodic) and the two quads' columns (origins iv-1 and iv, clamped to the grid, so
    at the ends of v a quad is taken twice).
    """
    a, b, _ = grid.shape
    _, nearest = tree.query(points)
    iu, iv = np.divmod(nearest, b)
    rows = np.mod(iu[:, None] + np.array([-1, 0, 1]), a)
    low, high = np.clip(iv - 1, 0, b - 2), np.clip(iv, 0, b - 2)
    cols = np.stack([low, low + 1, high, high + 1], axis=1)
    around = grid[rows[:, :, None], cols[:, None, :]] - points[:, None, None, :]  # (N, 3, 4, 3)
    i, j = _QUAD_ROW, _QUAD_COL
    p00, p10 = around[:, i, j], around[:, i + 1, j]
    p11, p01 = around[:, i + 1, j + 1], around[:, i, j + 1]
    tri_a = np.concatenate([p00, p00], axis=1)  # (N, 8, 3)
    tri_b = np.concatenate([p10, p01], axis=1)
    tri_c = np.concatenate([p11, p11], axis=1)
    dist = point_triangle_distances(np.zeros(3), tri_a, tri_b, tri_c).min(axis=1)
    return dist, iu, iv


def refine_seeds(points: np.ndarray, u: np.ndarray, v: np.ndarray, grid: np.ndarray, iu: np.ndarray,
                 iv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One Gauss-Newton step on the sampling grid itself: the tangents are central
    differences of neighbouring grid vertices, so no surface evaluation is needed.  Takes
    the nearest-vertex seeds (about half a grid cell off) to within hundredths of a mm.

    points (N, 3); u (a,), v (b,) grid parameters; grid (a, b, 3); iu, iv (N,) seed
    vertices.  Returns refined (u, v) seeds, (N,) each.
    """
    a, b, _ = grid.shape
    up, um = np.mod(iu + 1, a), np.mod(iu - 1, a)
    vp, vm = np.minimum(iv + 1, b - 1), np.maximum(iv - 1, 0)
    du_param = (u[1] - u[0]) * 2.0
    dv_param = v[vp] - v[vm]
    su = (grid[up, iv] - grid[um, iv]) / du_param
    sv = (grid[iu, vp] - grid[iu, vm]) / dv_param[:, None]
    r = points - grid[iu, iv]
    g11 = np.einsum("ij,ij->i", su, su)
    g12 = np.einsum("ij,ij->i", su, sv)
    g22 = np.einsum("ij,ij->i", sv, sv)
    b1 = np.einsum("ij,ij->i", su, r)
    b2 = np.einsum("ij,ij->i", sv, r)
    det = g11 * g22 - g12 * g12
    det = np.where(np.abs(det) > 1e-12, det, 1.0)
    step_u = np.clip((g22 * b1 - g12 * b2) / det, -du_param, du_param)
    step_v = np.clip((g11 * b2 - g12 * b1) / det, -np.abs(dv_param), np.abs(dv_param))
    return u[iu] + step_u, np.clip(v[iv] + step_v, v[0], v[-1])


def newton_distances(
    surface: NurbsSurface, points: np.ndarray, u: np.ndarray, v: np.ndarray, iterations: int = NEWTON_ITERATIONS,
    tolerance_mm: float = STEP_TOLERANCE_MM,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact point-to-surface distance by Newton point inversion (NURBS Book 6.1).

    points (N, 3) mm; u, v (N,) seeds.  Returns distance (N,), u (N,), v (N,) at the
    foot points.  A point whose next Newton step would move its foot point by less
    than ``tolerance_mm`` (:data:`STEP_TOLERANCE_MM`) on the surface is done: its
    distance is then exact to that tolerance, and later iterations only touch the
    points still moving.
    """
    u0, u1 = surface.domain_u
    v0, v1 = surface.domain_v
    period, height = u1 - u0, v1 - v0
    u = u0 + np.mod(np.asarray(u, dtype=np.float64) - u0, period)
    v = np.clip(np.asarray(v, dtype=np.float64), v0, v1)
    best = np.full(len(points), np.inf)
    active = np.arange(len(points))
    for iteration in range(iterations + 1):
        ua, va, pa = u[active], v[active], points[active]
        s, su, sv, suu, suv, svv = evaluate_derivatives(surface, ua, va)
        r = s - pa
        best[active] = np.minimum(best[active], np.linalg.norm(r, axis=1))
        if iteration == iterations:
            break
        f = np.einsum("ij,ij->i", r, su)
        g = np.einsum("ij,ij->i", r, sv)
        j11 = np.einsum("ij,ij->i", su, su) + np.einsum("ij,ij->i", r, suu)
        j12 = np.einsum("ij,ij->i", su, sv) + np.einsum("ij,ij->i", r, suv)
        j22 = np.einsum("ij,ij->i", sv, sv) + np.einsum("ij,ij->i", r, svv)
        det = j11 * j22 - j12 * j12
        safe = np.abs(det) > 1e-12
        det = np.where(safe, det, 1.0)
        step_u = np.clip(np.where(safe, -(j22 * f - j12 * g) / det, 0.0), -0.05 * period, 0.05 * period)
        step_v = np.clip(np.where(safe, -(j11 * g - j12 * f) / det, 0.0), -0.1 * height, 0.1 * height)
        new_u = u0 + np.mod(ua + step_u - u0, period)
        new_v = np.clip(va + step_v, v0, v1)
        moved_mm = np.linalg.norm(su * step_u[:, None] + sv * (new_v - va)[:, None], axis=1)
        moving = moved_mm > tolerance_mm
        u[active], v[active] = np.where(moving, new_u, ua), np.where(moving, new_v, va)
        active = active[moving]
        if active.size == 0:
            break
    return best, u, v


#: foot points for fitting and comparing are found to this tolerance (mm; Newton
#: converges quadratically, so this costs one or two iterations more than 1e-3)
FOOT_TOLERANCE_MM = 1e-7
FOOT_ITERATIONS = 12


def foot_points(surface: NurbsSurface, points: np.ndarray, length_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact foot points of points (N, 3) on the surface (Algorithm 1's nearest grid
    vertex, one grid Gauss-Newton step, then Newton to :data:`FOOT_TOLERANCE_MM`).
    ``length_mm``: the surface's extent along z (sets the grid's density).  Returns
    distance (N,), u (N,), v (N,)."""
    u_grid, v_grid, grid = dense_grid(surface, length_mm)
    tree = cKDTree(grid.reshape(-1, 3), balanced_tree=False, compact_nodes=False)
    _, nearest = tree.query(points)
    iu, iv = np.divmod(nearest, grid.shape[1])
    return newton_distances(surface, points, *refine_seeds(points, u_grid, v_grid, grid, iu, iv),
                            iterations=FOOT_ITERATIONS, tolerance_mm=FOOT_TOLERANCE_MM)


def error_statistics(
    surface: NurbsSurface,
    points: np.ndarray,
    section_heights: np.ndarray,
    section_mean_radii: np.ndarray,
    layer_heights: np.ndarray,
) -> tuple[SurfaceError, np.ndarray, np.ndarray]:
    """E both ways for scan points (N, 3) in the calf frame between B and D.

    section_heights (k,), section_mean_radii (k,): the resampled sections giving r_k.
    layer_heights (7,): feature layers, for the per-layer breakdown.
    Returns the statistics, the Algorithm 1 distances (N,) and the exact ones (N,).
    """
    if len(points) == 0:
        raise ValueError("no scan points between B and D")
    length = float(section_heights[-1] - section_heights[0])
    u, v, grid = dense_grid(surface, length)
    tree = cKDTree(grid.reshape(-1, 3), balanced_tree=False, compact_nodes=False)
    approx, iu, iv = algorithm1_distances(points, grid, tree)
    exact, _, _ = newton_distances(surface, points, *refine_seeds(points, u, v, grid, iu, iv))
    index = np.clip(np.searchsorted(section_heights, points[:, 2]), 1, len(section_heights) - 1)
    nearer_low = points[:, 2] - section_heights[index - 1] < section_heights[index] - points[:, 2]
    index = np.where(nearer_low, index - 1, index)
    r_k = section_mean_radii[index]
    e_approx = float(np.sqrt(np.mean((approx / r_k) ** 2)))
    e_exact = float(np.sqrt(np.mean((exact / r_k) ** 2)))
    # per feature layer band: each point to its nearest layer height
    band = np.abs(points[:, 2, None] - layer_heights[None, :]).argmin(axis=1)
    per_layer = []
    for i, h in enumerate(layer_heights):
        sel = band == i
        per_layer.append(
            {
                "layer": i,
                "height_mm": float(h),
                "n_points": int(sel.sum()),
                "error_index_exact": float(np.sqrt(np.mean((exact[sel] / r_k[sel]) ** 2))) if sel.any() else None,
                "max_error_mm": float(exact[sel].max()) if sel.any() else None,
            }
        )
    stats = SurfaceError(
        error_index=e_approx,
        error_index_exact=e_exact,
        error_index_diameter=e_approx / 2.0,
        error_index_exact_diameter=e_exact / 2.0,
        max_error_mm=float(exact.max()),
        mean_error_mm=float(exact.mean()),
        n_points=int(len(points)),
        per_layer=tuple(per_layer),
    )
    return stats, approx, exact

"""B-spline/NURBS machinery (paper sections 2.4-2.5; Piegl & Tiller, *The NURBS Book*).

The basis functions are scipy's (:mod:`app.geometry.spline.basis` checks their
contract): evaluation on grids through ``scipy.interpolate.BSpline``, one direction at
a time, derivatives at scattered points through
``scipy.interpolate.NdBSpline``, interpolation through ``make_interp_spline``.

Representation (the standard open one every NURBS library reads)
-----------------------------------------------------------------
A :class:`NurbsSurface` has ``control_points`` (nu, nv, 3), ``weights`` (nu, nv) and full
knot vectors ``knots_u`` (nu + degree_u + 1,) and ``knots_v`` (nv + degree_v + 1,).
The valid domain is ``[knots_u[degree_u], knots_u[nu]] x [knots_v[degree_v], knots_v[nv]]``.
A surface closed around the leg (``periodic_u``) is stored *unwrapped*: its first
``degree_u`` control columns are repeated at the end and ``knots_u`` is the periodic knot
sequence written out in full, so it evaluates correctly in any non-periodic NURBS code.
Coordinates are millimetres in the calf frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline, NdBSpline, make_interp_spline

from app.geometry.spline.basis import BSplineBasis


@dataclass(frozen=True)
class NurbsSurface:
    """A tensor-product NURBS surface (see module docstring for the layout).

    Attributes
    ----------
    degree_u, degree_v : int
    knots_u : (nu + degree_u + 1,) float64
    knots_v : (nv + degree_v + 1,) float64
    control_points : (nu, nv, 3) float64, mm
    weights : (nu, nv) float64, all > 0
    periodic_u : bool
        True when the surface is closed in u (the first ``degree_u`` columns repeat).

    The contract (:class:`~app.geometry.spline.basis.BSplineBasis`: u periodic or
    clamped, v clamped; the net's shape matching the knots; positive weights) is checked
    on construction: ValueError names the rule broken.
    """

    degree_u: int
    degree_v: int
    knots_u: np.ndarray
    knots_v: np.ndarray
    control_points: np.ndarray
    weights: np.ndarray
    periodic_u: bool = True

    def __post_init__(self) -> None:
        try:
            basis_u = BSplineBasis(self.knots_u, self.degree_u, self.periodic_u)
        except ValueError as broken:
            raise ValueError(f"knots_u: {broken}") from None
        try:
            basis_v = BSplineBasis(self.knots_v, self.degree_v, False)
        except ValueError as broken:
            raise ValueError(f"knots_v: {broken}") from None
        shape = (basis_u.n_functions, basis_v.n_functions)
        if np.shape(self.control_points) != shape + (3,):
            raise ValueError(f"the knots ask for a {shape[0]} x {shape[1]} x 3 control net, got {np.shape(self.control_points)}")
        if np.shape(self.weights) != shape:
            raise ValueError(f"the weights must be {shape[0]} x {shape[1]} like the control net, got {np.shape(self.weights)}")
        if not np.all(np.asarray(self.weights) > 0):
            raise ValueError("the weights must be positive")
        object.__setattr__(self, "_bases", (basis_u, basis_v))

    @property
    def basis_u(self) -> BSplineBasis:
        """Around the leg (periodic for a closed calf)."""
        return self._bases[0]  # type: ignore[attr-defined]

    @property
    def basis_v(self) -> BSplineBasis:
        """Along the leg (clamped: the ends are the first and last control rows)."""
        return self._bases[1]  # type: ignore[attr-defined]

    @property
    def shape(self) -> tuple[int, int]:
        return self.control_points.shape[0], self.control_points.shape[1]

    @property
    def domain_u(self) -> tuple[float, float]:
        return self.basis_u.domain

    @property
    def domain_v(self) -> tuple[float, float]:
        return self.basis_v.domain

    def homogeneous(self) -> np.ndarray:
        """(nu, nv, 4) weighted control points ``[w*x, w*y, w*z, w]``."""
        w = self.weights[..., None]
        return np.concatenate([self.control_points * w, w], axis=-1)

    def is_polynomial(self) -> bool:
        """All weights 1 (the paper's and the lsq surfaces): a plain B-spline."""
        return bool(np.all(self.weights == 1.0))


# --------------------------------------------------------------------- evaluation


def evaluate_grid(surface: NurbsSurface, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Surface points on the tensor grid ``u x v`` (eq. 1 of the paper).

    u (a,), v (b,) inside the domain; returns (a, b, 3) mm.  scipy's ``BSpline``
    contracts the homogeneous net one direction at a time (u, then v), on the bases the
    surface checked on construction.
    """
    nu, nv = surface.shape
    polynomial = surface.is_polynomial()  # all weights 1: the net itself, no division
    net = surface.control_points if polynomial else surface.homogeneous()
    channels = net.shape[-1]
    rows = BSpline(surface.knots_u, net.reshape(nu, nv * channels), surface.degree_u)(np.asarray(u, dtype=np.float64))
    grid = BSpline(surface.knots_v, np.transpose(rows.reshape(len(u), nv, channels), (1, 0, 2)), surface.degree_v)(
        np.asarray(v, dtype=np.float64))  # (b, a, channels)
    grid = np.transpose(grid, (1, 0, 2))
    return grid if polynomial else grid[..., :3] / grid[..., 3:]


#: working memory of one chunk of :func:`evaluate_derivatives` (bytes)
EVALUATION_CHUNK_BYTES = 32 * 1024 * 1024

#: the (u, v) derivative orders :func:`evaluate_derivatives` returns, in its order
DERIVATIVE_ORDERS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))


def evaluate_derivatives(
    surface: NurbsSurface, u: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, ...]:
    """Point and derivatives up to second order at scattered (u, v) pairs.

    The polynomial (homogeneous) parts from ``scipy.interpolate.NdBSpline``; rational
    derivatives by the quotient rule of The NURBS Book eq. (4.20) / A4.4; a surface
    whose weights are all 1 (the paper's) takes the polynomial shortcut.
    u, v (N,); returns ``S, Su, Sv, Suu, Suv, Svv``, each (N, 3) mm.
    """
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    # scipy gathers (p+1)(q+1) x 4 channels per point and order: evaluated in chunks of
    # EVALUATION_CHUNK_BYTES, so memory does not grow with N
    chunk = max(1024, EVALUATION_CHUNK_BYTES // (8 * (surface.degree_u + 1) * (surface.degree_v + 1) * 4 * 6))
    if len(u) > chunk:
        parts = [evaluate_derivatives(surface, u[i:i + chunk], v[i:i + chunk]) for i in range(0, len(u), chunk)]
        return tuple(np.concatenate([part[k] for part in parts]) for k in range(6))
    polynomial = surface.is_polynomial()
    net = surface.control_points if polynomial else surface.homogeneous()
    spline = NdBSpline((surface.knots_u, surface.knots_v), net, (surface.degree_u, surface.degree_v))
    xi = np.column_stack([u, v])
    a00, a10, a01, a20, a11, a02 = (spline(xi, nu=order) for order in DERIVATIVE_ORDERS)
    if polynomial:
        return a00, a10, a01, a20, a11, a02
    w, wu, wv = a00[:, 3:], a10[:, 3:], a01[:, 3:]
    wuu, wuv, wvv = a20[:, 3:], a11[:, 3:], a02[:, 3:]
    s = a00[:, :3] / w
    s_u = (a10[:, :3] - wu * s) / w
    s_v = (a01[:, :3] - wv * s) / w
    s_uu = (a20[:, :3] - 2.0 * wu * s_u - wuu * s) / w
    s_vv = (a02[:, :3] - 2.0 * wv * s_v - wvv * s) / w
    s_uv = (a11[:, :3] - wu * s_v - wv * s_u - wuv * s) / w
    return s, s_u, s_v, s_uu, s_uv, s_vv


# ------------------------------------------------------------------ construction


def chord_length_parameters(points: np.ndarray, closed: bool) -> np.ndarray:
    """Normalized accumulated chord lengths (Hartley-Judd / chord-length parameters).

    points (..., m, d).  Closed: returns (..., m + 1) from 0 to 1 with the closing chord
    last.  Open: returns (..., m) from 0 to 1.  Coincident points raise ``ValueError``.
    """
    if closed:
        nxt = np.concatenate([points[..., 1:, :], points[..., :1, :]], axis=-2)
        chords = np.linalg.norm(nxt - points, axis=-1)
    else:
        chords = np.linalg.norm(np.diff(points, axis=-2), axis=-1)
    if np.any(chords <= 1e-9 * max(float(np.abs(points).max()), 1.0)):
        raise ValueError("coincident data points: chord length zero")
    cumulative = np.concatenate([np.zeros(chords.shape[:-1] + (1,)), np.cumsum(chords, axis=-1)], axis=-1)
    return cumulative / cumulative[..., -1:]


def periodic_knot_vector(params: np.ndarray, degree: int) -> np.ndarray:
    """Unwrapped knot vector of a closed B-spline interpolating at ``params``.

    params (m + 1,) with params[0] = 0 and params[m] = 1 (the closing parameter).
    Returns (m + 2*degree + 1,): ``knots[degree + k] = params[k]``, extended periodically.
    The curve then has m + degree control points, the last ``degree`` repeating the first.
    """
    m = len(params) - 1
    period = params[m] - params[0]
    j = np.arange(-degree, m + degree + 1)
    return params[:-1][j % m] + np.floor_divide(j, m) * period


def interpolate_closed_cubic(points: np.ndarray, params: np.ndarray) -> np.ndarray:
    """Control points of closed cubic B-splines through ``points`` at ``params``.

    Paper section 2.4 (eq. 3) / The NURBS Book section 9.2.4 for a periodic curve: the
    curve ``sum_i N_{i,3}(u) P_{i mod m}`` on :func:`periodic_knot_vector` must pass
    through Q_k at u = t_k, a cyclic tridiagonal system in the control points, which
    ``scipy.interpolate.make_interp_spline(..., bc_type="periodic")`` solves (its knots
    are :func:`periodic_knot_vector`'s).

    points (L, m, d): L closed curves sharing the parameters params (m + 1,).
    Returns (L, m + 3, d) unwrapped control points (first 3 repeated at the end).
    """
    layers, m, dim = points.shape
    closed = np.concatenate([points, points[:, :1]], axis=1)  # the first point again at t = 1
    values = np.transpose(closed, (1, 0, 2)).reshape(m + 1, layers * dim)
    spline = make_interp_spline(params, values, k=3, bc_type="periodic")
    return np.transpose(spline.c.reshape(m + 3, layers, dim), (1, 0, 2))


def hartley_judd_knots(polygon: np.ndarray, degree: int = 3) -> np.ndarray:
    """Clamped knot vector from a control polygon by the Hartley-Judd rule.

    polygon (..., n + 1, d).  Interior knots
    ``u_i = sum_{j=k+1..i} L_j / sum_{j=k+1..n+1} L_j`` with ``L_j`` the sum of the k
    polygon sides ending at side j (k = degree).  Returns (..., n + degree + 2).
    """
    n = polygon.shape[-2] - 1
    sides = np.linalg.norm(np.diff(polygon, axis=-2), axis=-1)  # l_1..l_n at index 0..n-1
    windows = np.stack([sides[..., j - degree - 1 : j - 1].sum(axis=-1) for j in range(degree + 1, n + 2)], axis=-1)
    cumulative = np.cumsum(windows, axis=-1)
    interior = cumulative[..., :-1] / cumulative[..., -1:]
    shape = polygon.shape[:-2]
    zeros = np.zeros(shape + (degree + 1,))
    ones = np.ones(shape + (degree + 1,))
    return np.concatenate([zeros, interior, ones], axis=-1)


def averaged_knots(params: np.ndarray, degree: int) -> np.ndarray:
    """Clamped knot vector by averaging (The NURBS Book eq. 9.8). params (n + 1,)."""
    n = len(params) - 1
    interior = np.array([params[j : j + degree].mean() for j in range(1, n - degree + 1)])
    return np.concatenate([np.zeros(degree + 1), interior, np.ones(degree + 1)])


def interpolate_open(points: np.ndarray, params: np.ndarray, knots: np.ndarray, degree: int = 3) -> np.ndarray:
    """Control points of open (clamped) B-splines through points at params (NURBS Book
    A9.1, solved by ``scipy.interpolate.make_interp_spline`` on the given knots).

    points (n + 1, r) - r independent coordinate columns; returns (n + 1, r).
    """
    return make_interp_spline(params, points, k=degree, t=knots).c


def surface_from_layers(
    layer_points: np.ndarray, weights: np.ndarray | None = None, mode: str = "paper"
) -> NurbsSurface:
    """The paper's NURBS calf surface from a layers x m grid of feature points.

    Paper sections 2.4-2.5: each layer (a closed contour of m data points) is
    interpolated by a closed cubic B-spline with chord-length parameters averaged over
    the layers (the "averaged knot vector" in u, cf. The NURBS Book eq. 9.18), solving
    the cyclic tridiagonal system of eq. 3.  Along the leg (v, cubic, clamped):

    ``mode="paper"`` (default): the layers' control polygons are interpolated through
        the 7 layers with averaged chord-length parameters and averaged knots (The
        NURBS Book section 9.2.5, global surface interpolation: "averaged knot vectors
        in both u, v directions were utilized to fit the feature points").  The surface
        passes through every feature point.  This is the reading that reproduces the
        paper's accuracy (see benchmarks/results/fit.md).
    ``mode="paper_stacked"``: the literal reading of section 2.4 - the layers' control
        polygons are used directly as the rows of the control net, with Hartley-Judd v
        knots averaged over the columns; the surface then passes through the first and
        last layers only and E is 2-3x larger on real legs.

    layer_points (L, m, 3) mm, L >= 4, ordered along the leg; returns a NurbsSurface with
    control_points (m + 3, L, 3) and all weights 1 unless ``weights`` (m + 3, L) is given.
    """
    layers, m, _ = layer_points.shape
    if layers < 4 or m < 4:
        raise ValueError("need at least 4 layers and 4 points per layer")
    params_u = chord_length_parameters(layer_points, closed=True).mean(axis=0)
    control = interpolate_closed_cubic(layer_points, params_u)  # (L, m+3, 3)
    knots_u = periodic_knot_vector(params_u, 3)
    columns = np.transpose(layer_points, (1, 0, 2))  # (m, L, 3)
    if mode == "paper_stacked":
        knots_v = hartley_judd_knots(columns, 3).mean(axis=0)
    elif mode == "paper":
        params_v = chord_length_parameters(columns, closed=False).mean(axis=0)
        knots_v = averaged_knots(params_v, 3)
        flat = interpolate_open(control.reshape(layers, -1), params_v, knots_v)
        control = flat.reshape(control.shape)
    else:
        raise ValueError(f"unknown surface mode {mode!r}")
    net = np.transpose(control, (1, 0, 2))
    if weights is None:
        weights = np.ones(net.shape[:2])
    return NurbsSurface(3, 3, knots_u, knots_v, np.ascontiguousarray(net), weights, True)

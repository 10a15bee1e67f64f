"""B-spline/NURBS machinery (paper sections 2.4-2.5; Piegl & Tiller, *The NURBS Book*).

All evaluation is vectorized over parameter values: the only Python loops run over the
degree (3) and the derivative order (<= 2).

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
from scipy.linalg import solve_banded


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
    """

    degree_u: int
    degree_v: int
    knots_u: np.ndarray
    knots_v: np.ndarray
    control_points: np.ndarray
    weights: np.ndarray
    periodic_u: bool = True

    @property
    def shape(self) -> tuple[int, int]:
        return self.control_points.shape[0], self.control_points.shape[1]

    @property
    def domain_u(self) -> tuple[float, float]:
        nu = self.control_points.shape[0]
        return float(self.knots_u[self.degree_u]), float(self.knots_u[nu])

    @property
    def domain_v(self) -> tuple[float, float]:
        nv = self.control_points.shape[1]
        return float(self.knots_v[self.degree_v]), float(self.knots_v[nv])

    def homogeneous(self) -> np.ndarray:
        """(nu, nv, 4) weighted control points ``[w*x, w*y, w*z, w]``."""
        w = self.weights[..., None]
        return np.concatenate([self.control_points * w, w], axis=-1)


# --------------------------------------------------------------------------- basis


def find_spans(knots: np.ndarray, degree: int, n_ctrl: int, u: np.ndarray) -> np.ndarray:
    """Knot span index of each parameter (The NURBS Book A2.1, vectorized).

    Returns (N,) int with ``knots[s] <= u < knots[s+1]``, clamped to ``[degree, n_ctrl-1]``
    so that the right end of the domain belongs to the last span.
    """
    spans = np.searchsorted(knots, u, side="right") - 1
    return np.clip(spans, degree, n_ctrl - 1)


def _ratio(numerator: np.ndarray, denominator: np.ndarray) -> np.ndarray:
    """numerator / denominator, 0 where the denominator is 0: the knot differences of
    A2.3 vanish only at a parameter outside its span's support (a repeated knot), where
    the term they divide is itself 0 (The NURBS Book's 0/0 := 0 convention, eq. 2.5)."""
    return np.divide(numerator, denominator, out=np.zeros(np.broadcast(numerator, denominator).shape),
                     where=denominator != 0)


def basis_function_derivatives(
    knots: np.ndarray, degree: int, spans: np.ndarray, u: np.ndarray, order: int
) -> np.ndarray:
    """Non-zero basis functions and their derivatives (The NURBS Book A2.3, vectorized).

    Returns (order + 1, N, degree + 1): ``out[k, n, j]`` is the k-th derivative of
    ``N_{spans[n] - degree + j, degree}`` at ``u[n]``.  ``order`` may exceed ``degree``
    (higher derivatives are zero).
    """
    p = degree
    u = np.asarray(u, dtype=np.float64)
    n_pts = u.shape[0]
    ndu = np.zeros((p + 1, p + 1, n_pts))
    ndu[0, 0] = 1.0
    left = np.zeros((p + 1, n_pts))
    right = np.zeros((p + 1, n_pts))
    for j in range(1, p + 1):
        left[j] = u - knots[spans + 1 - j]
        right[j] = knots[spans + j] - u
        saved = np.zeros(n_pts)
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]
            temp = _ratio(ndu[r, j - 1], ndu[j, r])
            ndu[r, j] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        ndu[j, j] = saved
    ders = np.zeros((order + 1, p + 1, n_pts))
    ders[0] = ndu[:, p]
    for r in range(p + 1):
        a = np.zeros((2, p + 1, n_pts))
        a[0, 0] = 1.0
        s1, s2 = 0, 1
        for k in range(1, min(order, p) + 1):
            d = np.zeros(n_pts)
            rk, pk = r - k, p - k
            if r >= k:
                a[s2, 0] = _ratio(a[s1, 0], ndu[pk + 1, rk])
                d = a[s2, 0] * ndu[rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2, j] = _ratio(a[s1, j] - a[s1, j - 1], ndu[pk + 1, rk + j])
                d = d + a[s2, j] * ndu[rk + j, pk]
            if r <= pk:
                a[s2, k] = _ratio(-a[s1, k - 1], ndu[pk + 1, r])
                d = d + a[s2, k] * ndu[r, pk]
            ders[k, r] = d
            s1, s2 = s2, s1
    factor = p
    for k in range(1, min(order, p) + 1):
        ders[k] *= factor
        factor *= p - k
    return np.transpose(ders, (0, 2, 1))


def basis_matrix(
    knots: np.ndarray, degree: int, n_ctrl: int, u: np.ndarray, order: int = 0
) -> np.ndarray:
    """Dense basis matrices: (order + 1, N, n_ctrl), entry [k, n, i] = N_i^(k)(u_n)."""
    u = np.asarray(u, dtype=np.float64)
    spans = find_spans(knots, degree, n_ctrl, u)
    ders = basis_function_derivatives(knots, degree, spans, u, order)
    out = np.zeros((order + 1, u.shape[0], n_ctrl))
    cols = spans[:, None] - degree + np.arange(degree + 1)[None, :]
    rows = np.broadcast_to(np.arange(u.shape[0])[:, None], cols.shape)
    out[:, rows, cols] = ders
    return out


# --------------------------------------------------------------------- evaluation


def evaluate_grid(surface: NurbsSurface, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Surface points on the tensor grid ``u x v`` (eq. 1 of the paper).

    u (a,), v (b,) inside the domain; returns (a, b, 3) mm.
    """
    nu, nv = surface.shape
    bu = basis_matrix(surface.knots_u, surface.degree_u, nu, u)[0]
    bv = basis_matrix(surface.knots_v, surface.degree_v, nv, v)[0]
    pw = surface.homogeneous()
    rows = (bu @ pw.reshape(nu, nv * 4)).reshape(len(u), nv, 4)
    grid = np.einsum("avc,bv->abc", rows, bv, optimize=True)
    return grid[..., :3] / grid[..., 3:]


_SPAN_POLYNOMIALS: dict = {}


def span_polynomials(knots: np.ndarray, degree: int, n_ctrl: int) -> np.ndarray:
    """Power-basis coefficients of the non-zero basis functions on every knot span.

    Returns (n_ctrl - degree, degree + 1, degree + 1): for span s (index s - degree),
    ``N_{s-degree+j}(u) = sum_k C[s-degree, j, k] t^k`` with t = (u - knots[s]) /
    (knots[s+1] - knots[s]).  Built once per knot vector from A2.2 values at degree + 1
    points per span (a Vandermonde solve) and cached; empty spans get zeros.
    """
    key = (knots.tobytes(), degree, n_ctrl)
    cached = _SPAN_POLYNOMIALS.get(key)
    if cached is not None:
        return cached
    spans = np.arange(degree, n_ctrl)
    width = knots[spans + 1] - knots[spans]
    nodes = (np.arange(degree + 1) + 0.5) / (degree + 1)  # inside the span, away from its ends
    u = (knots[spans][:, None] + nodes[None, :] * width[:, None]).ravel()
    values = basis_function_derivatives(knots, degree, np.repeat(spans, degree + 1), u, 0)[0]
    values = values.reshape(len(spans), degree + 1, degree + 1)  # [span, node, j]
    vandermonde = nodes[:, None] ** np.arange(degree + 1)[None, :]  # [node, k]
    coefficients = np.linalg.solve(vandermonde, values)  # [span, k, j]
    coefficients = np.transpose(coefficients, (0, 2, 1)).copy()  # [span, j, k]
    coefficients[width <= 0] = 0.0
    if len(_SPAN_POLYNOMIALS) > 256:
        _SPAN_POLYNOMIALS.clear()
    _SPAN_POLYNOMIALS[key] = coefficients
    return coefficients


def basis_derivatives_fast(knots: np.ndarray, degree: int, n_ctrl: int, u: np.ndarray, spans: np.ndarray) -> np.ndarray:
    """Same as :func:`basis_function_derivatives` up to order 2, from the span polynomials.

    Returns (3, N, degree + 1).
    """
    coefficients = span_polynomials(knots, degree, n_ctrl)[spans - degree]  # (N, p+1, p+1)
    width = knots[spans + 1] - knots[spans]
    safe = np.where(width > 0, width, 1.0)
    t = (u - knots[spans]) / safe
    inv = 1.0 / safe
    monomials = np.zeros((len(u), degree + 1, 3))  # [n, power k, derivative order]
    power = np.ones_like(t)
    for k in range(degree + 1):  # t^k, k t^(k-1) / h, k (k-1) t^(k-2) / h^2
        monomials[:, k, 0] = power if k else 1.0
        if k >= 1:
            monomials[:, k, 1] = k * monomials[:, k - 1, 0] * inv
        if k >= 2:
            monomials[:, k, 2] = k * (k - 1) * monomials[:, k - 2, 0] * inv * inv
        power = power * t
    return np.transpose(np.matmul(coefficients, monomials), (2, 0, 1))


#: working memory of one chunk of :func:`evaluate_derivatives` (bytes)
EVALUATION_CHUNK_BYTES = 32 * 1024 * 1024


def evaluate_derivatives(
    surface: NurbsSurface, u: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, ...]:
    """Point and derivatives up to second order at scattered (u, v) pairs.

    Rational derivatives by the quotient rule of The NURBS Book eq. (4.20) / A4.4; a
    surface whose weights are all 1 (the paper's) takes the polynomial shortcut.
    u, v (N,); returns ``S, Su, Sv, Suu, Suv, Svv``, each (N, 3) mm.
    """
    nu, nv = surface.shape
    p, q = surface.degree_u, surface.degree_v
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    # the gathered patches take (p+1)(q+1) x 4 channels x ~5 arrays of float64 per point:
    # evaluated in chunks of EVALUATION_CHUNK_BYTES, so memory does not grow with N
    chunk = max(1024, EVALUATION_CHUNK_BYTES // (8 * (p + 1) * (q + 1) * 4 * 5))
    if len(u) > chunk:
        parts = [evaluate_derivatives(surface, u[i:i + chunk], v[i:i + chunk]) for i in range(0, len(u), chunk)]
        return tuple(np.concatenate([part[k] for part in parts]) for k in range(6))
    su = find_spans(surface.knots_u, p, nu, u)
    sv = find_spans(surface.knots_v, q, nv, v)
    du = basis_derivatives_fast(surface.knots_u, p, nu, u, su)  # (3, N, p+1)
    dv = basis_derivatives_fast(surface.knots_v, q, nv, v, sv)  # (3, N, q+1)
    iu = su[:, None] - p + np.arange(p + 1)
    iv = sv[:, None] - q + np.arange(q + 1)
    flat_index = iu[:, :, None] * nv + iv[:, None, :]  # (N, p+1, q+1)
    polynomial = bool(np.all(surface.weights == 1.0))
    channels = 3 if polynomial else 4
    net = surface.control_points if polynomial else surface.homogeneous()
    patch = net.reshape(nu * nv, channels)[flat_index]  # (N, p+1, q+1, c)
    # contract v first: (N, p+1, c, q+1) @ (N, 1, q+1, 3) -> (N, p+1, c, 3 v-orders)
    along_v = np.matmul(patch.transpose(0, 1, 3, 2), dv.transpose(1, 2, 0)[:, None])
    # then u: (N, 3 u-orders, p+1) @ (N, p+1, c*3) -> (N, 3, c, 3): [n, k, coord, v-order]
    both = np.matmul(du.transpose(1, 0, 2), along_v.reshape(len(u), p + 1, channels * 3)).reshape(len(u), 3, channels, 3)

    def a(k: int, order_v: int) -> np.ndarray:  # the k-th u and order_v-th v derivative
        return both[:, k, :, order_v]

    if polynomial:
        return a(0, 0), a(1, 0), a(0, 1), a(2, 0), a(1, 1), a(0, 2)
    a00, a10, a01, a20, a11, a02 = a(0, 0), a(1, 0), a(0, 1), a(2, 0), a(1, 1), a(0, 2)
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


def solve_cyclic_tridiagonal(
    lower: np.ndarray, diag: np.ndarray, upper: np.ndarray, rhs: np.ndarray
) -> np.ndarray:
    """Solve a cyclic tridiagonal system (paper eq. 3) by Sherman-Morrison + banded LU.

    Row i reads ``lower[i] x[i-1] + diag[i] x[i] + upper[i] x[i+1] = rhs[i]`` with the
    indices taken cyclically.  lower, diag, upper (m,); rhs (m, r).  Returns (m, r).
    """
    m = len(diag)
    gamma = -diag[0]
    top_right, bottom_left = lower[0], upper[m - 1]
    band = np.zeros((3, m))
    band[0, 1:] = upper[:-1]
    band[1] = diag
    band[1, 0] -= gamma
    band[1, m - 1] -= top_right * bottom_left / gamma
    band[2, :-1] = lower[1:]
    correction = np.zeros((m, 1))
    correction[0, 0] = gamma
    correction[m - 1, 0] = bottom_left
    solved = solve_banded((1, 1), band, np.concatenate([rhs, correction], axis=1))
    y, z = solved[:, :-1], solved[:, -1]
    factor = (y[0] + top_right * y[m - 1] / gamma) / (1.0 + z[0] + top_right * z[m - 1] / gamma)
    return y - z[:, None] * factor[None, :]


def interpolate_closed_cubic(points: np.ndarray, params: np.ndarray) -> np.ndarray:
    """Control points of closed cubic B-splines through ``points`` at ``params``.

    Paper section 2.4 (eq. 3) / The NURBS Book section 9.2.4 for a periodic curve: the
    curve ``sum_i N_{i,3}(u) P_{i mod m}`` on :func:`periodic_knot_vector` must pass
    through Q_k at u = t_k, which is a cyclic tridiagonal system in the control points.

    points (L, m, d): L closed curves sharing the parameters params (m + 1,).
    Returns (L, m + 3, d) unwrapped control points (first 3 repeated at the end).
    """
    layers, m, dim = points.shape
    degree = 3
    knots = periodic_knot_vector(params, degree)
    t = params[:-1]
    spans = np.arange(m) + degree
    basis = basis_function_derivatives(knots, degree, spans, t, 0)[0]  # (m, 4); [:, 3] == 0
    # row k: basis[k,0] P_k + basis[k,1] P_{k+1} + basis[k,2] P_{k+2}; unknown x_k = P_{k+1}
    rhs = np.transpose(points, (1, 0, 2)).reshape(m, layers * dim)
    x = solve_cyclic_tridiagonal(basis[:, 0], basis[:, 1], basis[:, 2], rhs)
    control = np.roll(x.reshape(m, layers, dim), 1, axis=0)  # P_k = x_{k-1}
    control = np.transpose(control, (1, 0, 2))
    return np.concatenate([control, control[:, :degree]], axis=1)


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
    """Control points of open (clamped) B-splines through points at params (NURBS Book A9.1).

    points (n + 1, r) - r independent coordinate columns; returns (n + 1, r).
    """
    n_ctrl = len(params)
    matrix = basis_matrix(knots, degree, n_ctrl, params)[0]
    return np.linalg.solve(matrix, points)


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

"""Volume enclosed by the calf surface between two heights, from the surface itself.

Divergence theorem with the field F = (x, y, 0) / 2 (div F = 1): the volume of the
solid bounded by the surface and the planes z = h0, z = h1 is the flux of F through its
boundary; the flat caps have normals +-z, along which F has no component, so only the
lateral surface counts:

    V = 1/2 | integral over {(u, v): h0 <= z(u, v) <= h1} of  x N_x + y N_y  du dv |,
    N = S_u x S_v  (not normalized: dA is folded in).

For every u the band [v0(u), v1(u)] with z(u, v0) = h0 and z(u, v1) = h1 is found
(bracketing on a v grid, then safeguarded Newton; z increases along v on a calf
surface), and the integrand is integrated by Gauss-Legendre quadrature on each knot
span - in u over the u domain, in v over the part of each span inside the band.  On
a span the integrand of a polynomial surface is a polynomial of degree <= 8 in u and
in v (x: 3, N: 2 + 3), which :data:`GAUSS_POINTS` = 8 nodes integrate exactly; only the
curved band ends (planes that cut the surface obliquely) and rational weights make the
quadrature approximate (tests: an exact rational cylinder and cone frustum to 1e-4, and
a real calf's volume additive over a split to 1e-9).

Units: mm in, mm^3 out (1 ml = 1000 mm^3).
"""

from __future__ import annotations

import numpy as np

from app.geometry.spline.nurbs import NurbsSurface, evaluate_derivatives, evaluate_grid

#: Gauss-Legendre nodes per knot span, in u and in v
GAUSS_POINTS = 8
#: subdivisions of every u knot span (the band ends are curves in (u, v))
U_SUBDIVISIONS = 4
_BRACKET_SAMPLES = 400
#: quadrature points evaluated at a time (their derivatives take ~150 bytes each)
QUADRATURE_CHUNK_POINTS = 65536
_NEWTON_STEPS = 40


def _spans(knots: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Distinct knot values inside [lo, hi], with lo and hi: the span breaks (s,)."""
    inner = np.unique(knots[(knots > lo) & (knots < hi)])
    return np.concatenate([[lo], inner, [hi]])


def heights_v(surface: NurbsSurface, u: np.ndarray, heights_mm) -> np.ndarray:
    """v (h, n) at which z(u, v) = each of heights_mm (h,), for each u (n,); NaN where
    z never reaches it.  One bracketing grid for all the heights."""
    heights = np.atleast_1d(np.asarray(heights_mm, dtype=np.float64))[:, None, None]  # (h, 1, 1)
    v0, v1 = surface.domain_v
    grid_v = np.linspace(v0, v1, _BRACKET_SAMPLES)
    z = evaluate_grid(surface, u, grid_v)[..., 2][None]  # (1, n, samples)
    tolerance = 1e-9 * np.maximum(1.0, np.abs(heights))  # a height at the surface's very end
    above = z >= heights - tolerance
    # first sample at or above the height (z rises along v)
    first = np.argmax(above, axis=2)  # (h, n)
    reached = above.any(axis=2) & (z[..., 0] <= heights[..., 0] + tolerance[..., 0])
    lo = grid_v[np.maximum(first - 1, 0)]
    hi = grid_v[first]
    v = np.where(first == 0, v0, 0.5 * (lo + hi))
    target = np.broadcast_to(heights[..., 0], v.shape)
    uu = np.broadcast_to(u, v.shape)
    for _ in range(_NEWTON_STEPS):  # safeguarded Newton: stays in [lo, hi], bisects otherwise
        s, _, sv, _, _, _ = evaluate_derivatives(surface, uu.ravel(), v.ravel())
        f = s[:, 2].reshape(v.shape) - target
        lo = np.where(f < 0, v, lo)
        hi = np.where(f >= 0, v, hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = v - f / sv[:, 2].reshape(v.shape)
        v = np.where((step > lo) & (step < hi) & np.isfinite(step), step, 0.5 * (lo + hi))
    return np.where(reached, v, np.nan)


def cut_height_range(surface: NurbsSurface, samples: int = 4096) -> tuple[float, float]:
    """(low, high) mm: the heights between which every plane z = h cuts the whole
    surface around - above the highest point of its first ring, below the lowest of
    its last (an lsq surface's end rings are not planar)."""
    u = np.linspace(*surface.domain_u, samples, endpoint=False)
    rings = evaluate_grid(surface, u, np.array(surface.domain_v))[..., 2]  # (samples, 2)
    return float(rings[:, 0].max()), float(rings[:, 1].min())


def volume_between(surface: NurbsSurface, low_mm: float, high_mm: float) -> float:
    """Volume (mm^3) inside the surface between the planes z = low_mm and z = high_mm
    (calf frame); raises ValueError when a plane does not cut the whole surface."""
    if not high_mm > low_mm:
        raise ValueError("the upper height must be above the lower one")
    nodes, weights = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    u_breaks = _spans(surface.knots_u, *surface.domain_u)
    u_breaks = np.concatenate([np.linspace(a, b, U_SUBDIVISIONS + 1)[:-1] for a, b in zip(u_breaks[:-1], u_breaks[1:])]
                              + [u_breaks[-1:]])
    a, b = u_breaks[:-1, None], u_breaks[1:, None]
    u = (0.5 * (b - a) * nodes + 0.5 * (a + b)).ravel()  # (nu,)
    wu = (0.5 * (b - a) * weights).ravel()
    v_low, v_high = heights_v(surface, u, [low_mm, high_mm])
    if not (np.isfinite(v_low).all() and np.isfinite(v_high).all()):
        raise ValueError("the heights must lie within the surface's height range")
    v_breaks = _spans(surface.knots_v, *surface.domain_v)
    # per u node and v span: the part of the span inside [v_low, v_high]
    start = np.clip(v_breaks[None, :-1], v_low[:, None], v_high[:, None])  # (nu, spans)
    end = np.clip(v_breaks[None, 1:], v_low[:, None], v_high[:, None])
    half = 0.5 * (end - start)
    v = (half[..., None] * nodes + (0.5 * (start + end))[..., None])  # (nu, spans, g)
    w = wu[:, None, None] * half[..., None] * weights  # (nu, spans, g)
    uu = np.broadcast_to(u[:, None, None], v.shape)
    # summed over chunks of u nodes: the quadrature's memory does not grow with the net
    per_chunk = max(1, QUADRATURE_CHUNK_POINTS // (v.shape[1] * v.shape[2]))
    total = 0.0
    for i in range(0, len(u), per_chunk):
        s, su, sv, _, _, _ = evaluate_derivatives(surface, uu[i:i + per_chunk].ravel(), v[i:i + per_chunk].ravel())
        normal = np.cross(su, sv)
        integrand = 0.5 * (s[:, 0] * normal[:, 0] + s[:, 1] * normal[:, 1])
        total += float((integrand * w[i:i + per_chunk].ravel()).sum())
    return abs(total)

"""Feature points of the 7 layers and their k-means arrangement (paper section 2.3).

Per layer contour r(theta) (72 rays):
  S1  peaks and valleys of the radius,
  S2  middles of arcs where the radius hardly changes (flat arcs),
  S3  peaks and valleys of the curvature, the curvature taken from a 5-point circle
      fit (algebraic least-squares circle through rays i-2..i+2),
  plus points that fill the spans between them: the paper keeps "middle points ...
  within larger spans"; here m points per layer spaced by the integral of
  sqrt(curvature) ds (see :func:`curvature_spaced_angles`), which on a 55 x 40 mm
  ellipse lowers E from 0.085% to about 0.02% at m = 15.
All candidate angles of all layers are pooled and clustered by scikit-learn's KMeans
into m angles shared by every layer (angles embedded on the unit circle so that 359
and 1 degree are neighbours).  The data grid is then each layer's contour at those m
angles: a layers x m "quasi-rectangular mesh".
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.interpolate import CubicSpline
from sklearn.cluster import KMeans

#: a flat arc changes radius by less than this fraction of the mean radius per ray step
FLAT_TOLERANCE = 0.002
#: an S1 radius extremum must differ from a neighbour ray by this fraction of the mean
#: radius (0.05 mm at r = 50 mm); an S3 curvature extremum by this fraction of the mean
#: curvature
S1_TOLERANCE = 1e-3
S3_TOLERANCE = 0.02
#: spans between curvature extrema wider than this get their middle as a candidate
WIDE_SPAN_RAD = np.deg2rad(30.0)


def _circular_extrema(values: np.ndarray, tolerance: np.ndarray | float = 0.0) -> np.ndarray:
    """(L, a) -> (L, a) bool: local maxima or minima along the circular axis that stand
    out from at least one neighbour by more than ``tolerance`` ((L, 1) or scalar), so
    that tessellation ripple and round-off do not count as shape features."""
    prev = np.roll(values, 1, axis=1)
    nxt = np.roll(values, -1, axis=1)
    extremum = ((values > prev) & (values >= nxt)) | ((values < prev) & (values <= nxt))
    step = np.maximum(np.abs(values - prev), np.abs(values - nxt))
    return extremum & (step > tolerance)


def five_point_curvature(contour_xy: np.ndarray) -> np.ndarray:
    """Signed curvature at every contour point from a 5-point circle fit.

    contour_xy (L, a, 2) closed contours, counter-clockwise, mm.  For each point the
    algebraic (Kasa) circle ``x^2 + y^2 + D x + E y + F = 0`` is fitted by least squares
    to points i-2..i+2; curvature = 1/R, negative where the contour turns clockwise
    (concave).  Returns (L, a) in 1/mm.
    """
    neighbours = np.stack([np.roll(contour_xy, -s, axis=1) for s in (-2, -1, 0, 1, 2)], axis=2)  # (L,a,5,2)
    local = neighbours - neighbours[:, :, 2:3, :]  # centre on the point itself for conditioning
    x, y = local[..., 0], local[..., 1]
    design = np.stack([x, y, np.ones_like(x)], axis=-1)  # (L,a,5,3)
    target = -(x**2 + y**2)
    normal = np.einsum("lapi,lapj->laij", design, design)
    rhs = np.einsum("lapi,lap->lai", design, target)
    coef = np.linalg.solve(normal + 1e-12 * np.eye(3), rhs[..., None])[..., 0]
    d, e, f = coef[..., 0], coef[..., 1], coef[..., 2]
    radius = np.sqrt(np.maximum(d**2 / 4 + e**2 / 4 - f, 1e-12))
    before, after = local[:, :, 1], local[:, :, 3]
    turn = np.sign(before[..., 0] * after[..., 1] - before[..., 1] * after[..., 0])
    # before -> point -> after turning left (ccw) means cross(-before, after) > 0
    return -turn / radius


def curvature_spaced_angles(radii: np.ndarray, angles: np.ndarray, curvature: np.ndarray, m: int) -> np.ndarray:
    """Per layer, m angles at equal steps of the integral of sqrt(|kappa|) ds.

    The generalised form of the paper's "middle points within larger spans": spans are
    filled in proportion to how sharply the contour bends (the point density that
    minimises the error of interpolating a curve, de Boor's sqrt-curvature rule), the
    first angle at the layer's sharpest point.  radii, curvature (L, a); returns (L*m,).
    """
    x, y = radii * np.cos(angles), radii * np.sin(angles)
    ds = np.hypot(np.roll(x, -1, axis=1) - x, np.roll(y, -1, axis=1) - y)
    weight = ds * np.sqrt(np.abs(curvature) + np.roll(np.abs(curvature), -1, axis=1)) + 1e-12
    start = np.argmax(np.abs(curvature), axis=1)
    order = (start[:, None] + np.arange(radii.shape[1])[None, :]) % radii.shape[1]
    w = np.take_along_axis(weight, order, axis=1)
    cumulative = np.concatenate([np.zeros((len(w), 1)), np.cumsum(w, axis=1)], axis=1)
    cumulative /= cumulative[:, -1:]
    step = angles[1] - angles[0]
    targets = np.arange(m) / m
    out = [angles[start[i]] + np.interp(targets, cumulative[i], np.arange(len(angles) + 1) * step) for i in range(len(w))]
    return np.mod(np.concatenate(out), 2 * np.pi)


def candidate_angles(radii: np.ndarray, angles: np.ndarray, m: int | None = None) -> np.ndarray:
    """Pooled S1, S2, S3 (+ span fillers) candidate angles of all layers.

    radii (L, a) mm at angles (a,); with ``m``, the span fillers are
    :func:`curvature_spaced_angles`, otherwise the middles of spans wider than
    :data:`WIDE_SPAN_RAD` between S3 points.  Returns (n,) angles in [0, 2*pi).
    """
    layers, a = radii.shape
    step = angles[1] - angles[0]
    mean_r = radii.mean(axis=1, keepdims=True)
    found = [np.broadcast_to(angles, radii.shape)[_circular_extrema(radii, S1_TOLERANCE * mean_r)]]  # S1

    # S2: middles of flat arcs (runs of >= 3 small radius steps)
    tolerance = FLAT_TOLERANCE * radii.mean(axis=1, keepdims=True)
    flat = np.abs(np.roll(radii, -1, axis=1) - radii) < tolerance  # step i -> i+1 is flat
    for flat_layer in np.flatnonzero(flat.any(axis=1) & ~flat.all(axis=1)):
        row = flat[flat_layer]
        start = int(np.argmin(row))  # a non-flat step: runs cannot wrap past it
        rolled = np.roll(row, -start)
        edges = np.diff(np.concatenate([[0], rolled.astype(np.int8), [0]]))
        run_starts, run_ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        long_runs = run_ends - run_starts >= 3
        middle = (run_starts[long_runs] + run_ends[long_runs]) / 2.0 + start
        found.append(np.mod(middle * step, 2 * np.pi))

    # S3: curvature extrema and the middles of wide spans between them
    contour = np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=-1)
    curvature = five_point_curvature(contour)
    s3_mask = _circular_extrema(curvature, S3_TOLERANCE * np.abs(curvature).mean(axis=1, keepdims=True))
    found.append(np.broadcast_to(angles, radii.shape)[s3_mask])
    if m is not None:
        found.append(curvature_spaced_angles(radii, angles, curvature, m))
        return np.mod(np.concatenate(found), 2 * np.pi)
    for layer in range(layers):
        s3 = angles[s3_mask[layer]]
        if s3.size == 0:
            continue
        gaps = np.diff(np.concatenate([s3, [s3[0] + 2 * np.pi]]))
        wide = gaps > WIDE_SPAN_RAD
        found.append(np.mod(s3[wide] + gaps[wide] / 2.0, 2 * np.pi))
    return np.mod(np.concatenate(found), 2 * np.pi)


def shared_angles(candidates: np.ndarray, m: int) -> np.ndarray:
    """k-means of candidate angles into m shared angles, ascending in [0, 2*pi).

    Initialised at m evenly spaced angles (deterministic, one run).  When fewer than m
    distinct candidates exist the evenly spaced angles are pooled in.
    """
    even = np.arange(m) * (2 * np.pi / m)
    pool = np.unique(np.round(candidates, 6))
    if pool.size < 2 * m:
        pool = np.concatenate([pool, even])
    embedded = np.stack([np.cos(pool), np.sin(pool)], axis=1)
    init = np.stack([np.cos(even), np.sin(even)], axis=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        km = KMeans(n_clusters=m, init=init, n_init=1, max_iter=100, random_state=0).fit(embedded)
    centres = km.cluster_centers_
    result = np.sort(np.mod(np.arctan2(centres[:, 1], centres[:, 0]), 2 * np.pi))
    # an emptied cluster or two centres on top of each other would make coincident data
    # points; replace such a centre by the middle of the widest gap
    min_sep = np.deg2rad(2.0)
    for _ in range(m):
        gaps = np.diff(np.concatenate([result, [result[0] + 2 * np.pi]]))
        if gaps.min() >= min_sep:
            break
        widest = int(np.argmax(gaps))
        result[int(np.argmin(gaps))] = np.mod(result[widest] + gaps[widest] / 2, 2 * np.pi)
        result = np.sort(result)
    return result


def radii_at(radii: np.ndarray, angles: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Periodic cubic interpolation of each layer's r(theta) at ``targets``.

    radii (L, a) at angles (a,); targets (m,) -> (L, m) mm.
    """
    theta = np.append(angles, angles[0] + 2 * np.pi)
    values = np.concatenate([radii, radii[:, :1]], axis=1).T
    return CubicSpline(theta, values, axis=0, bc_type="periodic")(np.mod(targets, 2 * np.pi)).T

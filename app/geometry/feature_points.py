"""Feature points of the 7 layers and their k-means arrangement (paper section 2.3).

Per layer contour r(theta) (72 rays):
  S1  peaks and valleys of the radius,
  S2  middles of arcs where the radius hardly changes (flat arcs),
  S3  peaks and valleys of the curvature, the curvature taken from a 5-point circle
      fit (algebraic least-squares circle through rays i-2..i+2), plus the middles of
      spans between S3 points wider than :data:`WIDE_SPAN_RAD`.
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
#: spans between curvature extrema wider than this get their middle as a candidate
WIDE_SPAN_RAD = np.deg2rad(30.0)


def _circular_extrema(values: np.ndarray) -> np.ndarray:
    """(L, a) -> (L, a) bool: strict local maxima or minima along the circular axis."""
    prev = np.roll(values, 1, axis=1)
    nxt = np.roll(values, -1, axis=1)
    return ((values > prev) & (values >= nxt)) | ((values < prev) & (values <= nxt))


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


def candidate_angles(radii: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Pooled S1, S2, S3 (+ wide-span middles) candidate angles of all layers.

    radii (L, a) mm at angles (a,); returns (n,) angles in [0, 2*pi).
    """
    layers, a = radii.shape
    step = angles[1] - angles[0]
    found = [np.broadcast_to(angles, radii.shape)[_circular_extrema(radii)]]  # S1

    # S2: middles of flat arcs (runs of >= 3 small radius steps)
    tolerance = FLAT_TOLERANCE * radii.mean(axis=1, keepdims=True)
    flat = np.abs(np.roll(radii, -1, axis=1) - radii) < tolerance  # step i -> i+1 is flat
    for layer in np.flatnonzero(flat.any(axis=1) & ~flat.all(axis=1)):
        row = flat[layer]
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
    s3_mask = _circular_extrema(curvature)
    found.append(np.broadcast_to(angles, radii.shape)[s3_mask])
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

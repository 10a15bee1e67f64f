"""A section's points moved onto the smooth curve they sample: moving least squares.

A tape girth is the convex hull of a section.  Read on the raw points, a scanner's noise
widens the hull by its outermost excursions (0.6 mm of noise across an ellipse shaped as
a heel-instep loop: more than 3 mm, tests/geometry/sections/test_loop_smoothing.py).
The foot's loops were read before as median radii in bins of angle round the centroid,
averaged over +-5 degrees: single planes of a clean generated forefoot read up to 7 mm
short of their exact hull (a bin mixes points of both sides where the loop is not
star-shaped from its centroid; the averaging cuts corners).  The band medians and the
minimum over tilts kept the clean meshes' cA and cY within -0.4..+0.8 mm of the exact
hull, but a cloud of the same skin read them 0.5-1.0 mm longer than its mesh and a body
scanner's vertices 0.6-0.7 mm shorter: one leg's re-scans read cY 2.01 mm apart (p95,
benchmarks/chart_accuracy.py 8 5; 1.27 read as below, cA 1.83 -> 1.32).

Each point is moved by Lee's curve reconstruction (I.-K. Lee, "Curve reconstruction from
unorganized points", CAGD 17 (2000) 161-177), the moving least squares of Levin (2003) for
curves: its neighbours, weighted by a Gaussian of their distance, give a local frame
(their weighted principal direction is the tangent) and a quadratic y = a + b x + c x^2
fitted in it; the point moves to the quadratic at its own x.  A quadratic is exact for a
curve to second order, so a clean section's points stay on it and its hull keeps its
length; the noise across the curve is averaged over the neighbourhood.

How wide a neighbourhood is the trade: wide, it averages more noise (a mesh's noise is its
vertices', and its section holds two points of each crossed edge, so near points share
it); too wide, it spans a tight bend and cuts it. The reach is chosen per point by
Lepski's rule (O. V. Lepski, "Asymptotically minimax adaptive estimation", Theory Probab.
Appl. 36 (1991); for local polynomials, Lepski, Mammen and Spokoiny, Ann. Statist. 25
(1997)): of the reaches that span the 4th, 8th, 12th and 16th nearest points
(:data:`LOOP_REACH_MM` to :data:`MAX_REACH_MM`), the widest whose fitted point lies within
:data:`LEPSKI_BAND` standard errors of every narrower fit's - a wider fit that moves the
point further than the noise can is bending round a corner. On an ellipse the shape of a
heel-instep loop (tests/geometry/sections/test_loop_smoothing.py), points 9 mm apart read
2.1 mm short on average (their chords' hull 2.2; the 16th neighbour's reach alone 36), 0.6
mm of noise 2 mm apart 0.4 mm long (the 4th's alone 0.45, the raw points' hull more than
3). In the pipeline (benchmarks/chart_accuracy.py, one leg's re-scans, pairwise p95): a
fixed 5 mm reach read a noisy mesh's cY 1.3 mm long and seed 11's cY 2.16 mm apart; the
rule, read on the band the raw hulls rank first (app.geometry.anatomy.foot), 1.54 (seed 5:
1.27, seed 3: 1.11; cA 1.08, 1.32, 1.21). Units: mm. Arrays: (n, 2) in the section's
plane.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: the narrowest reach (weight e^-1 at this distance, 2% at twice it), mm: small against
#: the foot loop's radii of curvature (10-30 mm)
LOOP_REACH_MM = 5.0
#: at most this many neighbours a point: a dense cloud's crossings (~4 a mm of loop) hold
#: 80 within +-10 mm, twice the narrowest reach
LOOP_NEIGHBOURS = 80
#: the widest reach, mm: its window (+-2 reaches) stays inside the foot loops' bends
#: (heel and ankle 25-35 mm radius); the rule alone let a sparse ellipse's 14 mm ends be
#: spanned (points 9 mm apart: 21 mm short on one draw of ten)
MAX_REACH_MM = 10.0
#: a dense section's points moved onto the curve are thinned to about this many (a point
#: every 1 mm of a foot's 200-350 mm loops: the hull's chords between them lie within
#: 0.01 mm of a 10 mm bend); every point still counts in the fits
LOOP_POINTS_MOVED = 360
#: the reaches tried: out to each point's 4th, 8th, 12th, 16th nearest other point (4: a
#: quadratic's 3 coefficients and one to spare)
REACH_NEIGHBOURS = (4, 8, 12, 16)
#: a wider fit is kept while it lies within this many standard errors of every narrower
#: fit (a two-sided 95% band)
LEPSKI_BAND = 2.0


def _local_quadratic_fit(distinct: np.ndarray, distance: np.ndarray, neighbour: np.ndarray,
                         reach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each point (m, 2) moved onto the quadratic fitted to its ``neighbour`` (m, k)
    points at ``distance`` (m, k) mm with Gaussian weights of ``reach`` (m,) mm: the moved
    points (m, 2), the sum of squares of each fitted value's weights on the points (m,)
    (its variance over the noise's), its weight on its own point (m,) and its residual
    across the curve (m,) mm."""
    weight = np.exp(-((distance / reach[:, None]) ** 2))  # (m, k)
    total = weight.sum(axis=1)
    near_x, near_y = distinct[neighbour, 0], distinct[neighbour, 1]  # (m, k) each
    centre = np.column_stack([(weight * near_x).sum(axis=1), (weight * near_y).sum(axis=1)]) / total[:, None]
    dx, dy = near_x - centre[:, :1], near_y - centre[:, 1:]
    # the weighted scatter's principal direction in closed form (a 2 x 2 eigenproblem)
    sxx, syy, sxy = (weight * dx * dx).sum(axis=1), (weight * dy * dy).sum(axis=1), (weight * dx * dy).sum(axis=1)
    angle = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    tangent = np.column_stack([np.cos(angle), np.sin(angle)])  # (m, 2)
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    x = dx * tangent[:, :1] + dy * tangent[:, 1:]  # (m, k) along the tangent
    y = dx * normal[:, :1] + dy * normal[:, 1:]  # (m, k) across it
    # the normal equations of y = a + b x + c x^2: moments of x up to the 4th
    wx = weight * x
    wxx = wx * x
    moment = [total, wx.sum(axis=1), wxx.sum(axis=1), (wxx * x).sum(axis=1), (wxx * x * x).sum(axis=1)]
    normal_matrix = np.stack([np.stack(moment[row : row + 3], axis=-1) for row in range(3)], axis=1)  # (m, 3, 3)
    inverse = np.linalg.inv(normal_matrix + 1e-9 * np.eye(3))
    x0 = x[:, 0]  # the point itself is its own nearest (distance 0)
    own = np.column_stack([np.ones_like(x0), x0, x0 * x0])  # (m, 3)
    row = np.einsum("mi,mij->mj", own, inverse)  # (m, 3)
    # the fitted value at the point is a weighted sum of the neighbours' y: its weights
    hat = weight * (row[:, :1] + row[:, 1:2] * x + row[:, 2:] * x * x)  # (m, k)
    fitted = (hat * y).sum(axis=1)
    moved = centre + x0[:, None] * tangent + fitted[:, None] * normal
    return moved, (hat * hat).sum(axis=1), hat[:, 0], y[:, 0] - fitted


def project_on_local_quadratics(points: np.ndarray) -> np.ndarray:
    """The section's distinct points (m, 2) mm - at most about LOOP_POINTS_MOVED of them,
    evenly taken, each fitted over all its neighbours - each moved onto the quadratic
    fitted to its neighbours over the reach Lepski's rule chooses (module docstring).
    points (n, 2) mm, n >= 5; a point repeated (the two segment ends a mesh's section holds
    at each edge crossing) counts once."""
    distinct = np.unique(points, axis=0)
    k = min(LOOP_NEIGHBOURS, len(distinct))
    moved = distinct[:: -(-len(distinct) // LOOP_POINTS_MOVED)]
    distance, neighbour = cKDTree(distinct).query(moved, k=k)  # (m, k); each point its own nearest
    fits = [_local_quadratic_fit(distinct, distance, neighbour,
                                 np.clip(distance[:, min(count, k - 1)], LOOP_REACH_MM, MAX_REACH_MM))
            for count in REACH_NEIGHBOURS]
    # the noise across the curve, from the narrowest fit's residuals (RSS / (n - trace))
    _, _, own_weight, residual = fits[0]
    sigma = float(np.sqrt(np.mean(residual**2) / max(1.0 - float(np.mean(own_weight)), 1e-3)))
    chosen = fits[0][0].copy()
    consistent = np.ones(len(moved), dtype=bool)
    for wider in range(1, len(fits)):
        for narrower in range(wider):
            consistent &= (np.linalg.norm(fits[wider][0] - fits[narrower][0], axis=1)
                           <= LEPSKI_BAND * sigma * np.sqrt(fits[narrower][1]))
        chosen[consistent] = fits[wider][0][consistent]
    return chosen

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
benchmarks/chart_accuracy.py 8 5; 1.47 read as below, cA 1.83 -> 1.41).

:func:`project_on_local_quadratics` is Lee's curve reconstruction (I.-K. Lee, "Curve
reconstruction from unorganized points", CAGD 17 (2000) 161-177), the moving least
squares of Levin (2003) for curves: each point's neighbours, weighted by a Gaussian of
their distance, give a local frame (their weighted principal direction is the tangent)
and a quadratic y = a + b x + c x^2 fitted in it; the point moves to the quadratic at its
own x.  A quadratic is exact for a curve to second order, so a clean section's points
stay on it (the foot's smallest radii of curvature, 10-30 mm, are 2-6 times the reach)
and its hull keeps its length; the noise across the curve is averaged over the
neighbourhood.  Units: mm.  Arrays: (n, 2) in the section's plane.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: the Gaussian's reach (weight e^-1 at this distance, 2% at twice it), mm: larger than a
#: scanner's noise correlation, small against the foot loop's radii of curvature
LOOP_REACH_MM = 5.0
#: at most this many neighbours a point: a dense cloud's crossings (~4 a mm of loop) hold
#: 80 within +-10 mm, twice the reach
LOOP_NEIGHBOURS = 80
#: a sparse section's reach grows to the distance of each point's 4th-nearest other point,
#: so every quadratic (3 coefficients) has at least 4 neighbours of weight e^-1 or more.
#: Wider (1.5 times the 7th's) the quadratic spans a tight bend and cuts it: an ellipse's
#: 14 mm-radius ends sampled every 6 mm read 3.6 mm short, every 9 mm 21 mm; at the 4th
#: the same samples read 0.2 and 1.4 mm short, closer than their chords' hull (0.9, 2.0)
SPARSE_NEIGHBOUR = 4


def project_on_local_quadratics(points: np.ndarray, reach_mm: float = LOOP_REACH_MM) -> np.ndarray:
    """The section's distinct points (m, 2) mm, each moved onto the quadratic fitted to its
    neighbours (module docstring).  points (n, 2) mm, n >= 3; a point repeated (the two
    segment ends a mesh's section holds at each edge crossing) counts once."""
    distinct = np.unique(points, axis=0)
    k = min(LOOP_NEIGHBOURS, len(distinct))
    distance, neighbour = cKDTree(distinct).query(distinct, k=k)  # (m, k)
    reach = np.maximum(reach_mm, distance[:, min(SPARSE_NEIGHBOUR, k - 1)])
    weight = np.exp(-((distance / reach[:, None]) ** 2))  # (m, k)
    near = distinct[neighbour]  # (m, k, 2)
    centre = np.einsum("mk,mkd->md", weight, near) / weight.sum(axis=1)[:, None]
    offset = near - centre[:, None, :]
    scatter = np.einsum("mk,mki,mkj->mij", weight, offset, offset)
    _, frame = np.linalg.eigh(scatter)  # columns by rising eigenvalue: normal, tangent
    normal, tangent = frame[..., 0], frame[..., 1]
    x = np.einsum("mkd,md->mk", offset, tangent)
    y = np.einsum("mkd,md->mk", offset, normal)
    basis = np.stack([np.ones_like(x), x, x * x], axis=-1)  # (m, k, 3)
    normal_matrix = np.einsum("mk,mki,mkj->mij", weight, basis, basis) + 1e-9 * np.eye(3)
    right = np.einsum("mk,mki,mk->mi", weight, basis, y)
    a, b, c = np.linalg.solve(normal_matrix, right[..., None])[..., 0].T
    x0 = np.einsum("md,md->m", distinct - centre, tangent)
    return centre + x0[:, None] * tangent + (a + b * x0 + c * x0 * x0)[:, None] * normal

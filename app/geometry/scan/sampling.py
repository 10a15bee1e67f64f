"""How a scan sampled the skin: each point's share of the skin it stands for.

A scanner samples the skin unevenly - a side it saw at a slant 4 times sparser (the
corpus's cloud_uneven), a tessellation's vertices crowded along a crease - so a mean,
median or percentile over the points is one over the scanner's sampling, not over the
skin.  Weighted by :func:`area_weights` it is one over the skin's area: each point by the
area round it that holds no nearer point, read from its distance to its
:data:`AREA_NEIGHBOURS`-th nearest (the k-nearest-neighbour density estimate,
Loftsgaarden & Quesenberry 1965: k points lie within pi r_k^2 of skin, so a point stands
for about pi r_k^2 / k).  (The posterior profile's sector weights,
app.geometry.anatomy.gluteal_fold, do the same for the angle round a section.)  Units: mm.
Arrays: points (n, 3).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

#: the neighbour whose distance reads a point's share of the skin: 8 averages the
#: spacing round a point over both directions of the surface and stays local (within 2-3
#: spacings).  Measured on BodyParts3D's leg as an 80,000-point cloud 4 times sparser on
#: one half, split 8 ways through the leg (tests/geometry/anatomy/test_side.py): the side
#: read from the foot was right and sure (0.85-0.96) all 8 ways; with each point weighted
#: by 1 / the points in its cube of 6 mm (or 10 mm), 2 (4) ways said the wrong side or
#: none - a cube on the sparse side holds ~2 points, or none
AREA_NEIGHBOURS = 8
#: a point stands for at most this many times the median point's area: a stray far off
#: the skin (a scanner's ghosts lie 20-40 mm apart) would stand for hundreds of times a
#: skin point's; 9 still weighs a side sampled 9 times sparser whole
MAX_SHARE_RATIO = 9.0


def area_weights(points: np.ndarray) -> np.ndarray:
    """(n,) each point's share of the skin (module docstring), relative: its
    AREA_NEIGHBOURS-th neighbour's distance squared, at most MAX_SHARE_RATIO times the
    median.  points (n, 3) mm; all ones for AREA_NEIGHBOURS points or fewer."""
    if len(points) <= AREA_NEIGHBOURS:
        return np.ones(len(points))
    reach = cKDTree(points).query(points, k=AREA_NEIGHBOURS + 1)[0][:, -1]
    share = reach**2
    typical = float(np.median(share))
    if typical <= 0.0:  # most points repeated: the sampling says nothing of the area
        return np.ones(len(points))
    return np.minimum(share, MAX_SHARE_RATIO * typical) / typical


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The ``q`` (0..1) quantile of ``values`` (m,) under ``weights`` (m,, positive): the
    least value whose weights up to it reach q of the total (no interpolation)."""
    order = np.argsort(values, kind="stable")
    running = np.cumsum(weights[order])
    return float(values[order][min(int(np.searchsorted(running, q * running[-1])), len(values) - 1)])

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


def grouped_weighted_quantiles(group: np.ndarray, values: np.ndarray, weights: np.ndarray, n_groups: int,
                                quantiles) -> np.ndarray:
    """(n_groups, q) the weighted ``quantiles`` (q,) in 0..1 of ``values`` (m,) within each
    ``group`` (m,) label in 0..n_groups-1: the least value whose group's ``weights`` (m,,
    positive) up to it reach the quantile of the group's total (no interpolation); NaN
    rows for empty groups.  One sort for every group and quantile."""
    q = np.atleast_1d(np.asarray(quantiles, dtype=np.float64))
    out = np.full((n_groups, len(q)), np.nan)
    if not len(group):
        return out
    # by group, then value: one float key (a group's span of values past every value of
    # the one below), sorted 3-4 times faster than np.lexsort's two keys
    low = float(values.min())
    order = np.argsort(group * (float(values.max()) - low + 1.0) + (values - low))
    group, values, weights = group[order], values[order], weights[order]
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    ends = np.r_[starts[1:], len(group)]
    running = np.cumsum(weights)
    before = np.r_[0.0, running][starts]
    reach = before[:, None] + q[None, :] * (running[ends - 1] - before)[:, None]
    pick = np.clip(np.searchsorted(running, reach, side="left"), starts[:, None], ends[:, None] - 1)
    out[group[starts]] = values[pick]
    return out


def weighted_quantiles(values: np.ndarray, weights: np.ndarray, quantiles) -> np.ndarray:
    """(q,) the weighted ``quantiles`` (q,) in 0..1 of ``values`` (m,) under ``weights``
    (m,, positive): :func:`grouped_weighted_quantiles` over one group."""
    return grouped_weighted_quantiles(np.zeros(len(values), dtype=np.int64), values, weights, 1, quantiles)[0]


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The weighted ``q`` (0..1) quantile of ``values`` (m,): :func:`weighted_quantiles`."""
    return float(weighted_quantiles(values, weights, [q])[0])

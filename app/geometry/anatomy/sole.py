"""The sole: the floor a standing person's lengths are measured from (RAL-GZ 387's lB ...
lG and the foot's points; ISO 8559-1 takes heights above the standing surface), found on
the scan's heel - or why the scan has none.

Frame: the calf frame (mm; z up the leg from B = 0, y anterior, x the subject's right),
found from the foot (its anterior cue).  Arrays: points (n, 3), faces (f, 3) or None.

- **The heel's lowest skin.**  The sole is the lowest point of the heel, the part of the
  foot behind and below B's centroid (not the whole foot: a lying body's pointed toes
  reach lower).
- **A cloud's stray points are not skin.**  A scanner's ghosts 5-40 mm off the skin and
  a floor's stray points under the heel were taken for its lowest point: the corpus's
  cloud_outliers read every length 5-12 mm long.  Skin is a surface sampled about evenly:
  sampled at random with median nearest-neighbour spacing m, a disc of radius r round a
  point of it holds about ln 2 (r / m)^2 other points (Poisson sampling: a point's
  nearest neighbour lies beyond m with probability 1/2), 11 at r = STRAY_RADIUS_SPACINGS
  m, more on a scanner's regular grid; a ghost off the skin holds none, a floor's stray
  points under the heel one or two.  A cloud's point with fewer than STRAY_NEIGHBOURS
  (a third of the skin's) is no skin.  m is the heel's own, the median over the points
  where its lowest skin can lie: a scanner's spacing changes over a foot (a
  tessellation's vertices: 0.4 mm apart on the heel's back, 1.2 mm on the sole), and a
  spacing taken over the whole foot took the sole's points for strays (lB 1.9 mm short).
  Only the points that decide - the heel's back and the lowest points - are tested.  A
  mesh's vertices are joined skin (the clean-up removed its stray pieces:
  app.geometry.scan.cleanup).
- **The heel turns under the sole.**  On a standing foot the back of the heel (the
  calcaneal tuberosity under its pad) is furthest back 20-42 mm above the floor (measured
  on 6 generated legs and the 5 real ones of tests/data), and below that the heel rounds
  forward into the sole by 14-32 mm.  A scan cut through the foot above the heel's
  underside (a crop at the midfoot) has its lowest point on the cut: there the heel's
  back still runs down, its rearmost point within a few mm of the scan's lowest (at
  most 8 mm on the corpus's midfoot crops), and a round heel (radius 25-30 mm) turns
  forward by only 2-3 mm within 12 mm of its rearmost point.  So the sole is in the scan
  only where the heel's rearmost point lies at least HEEL_REARMOST_ABOVE_MM above the
  lowest and the heel's back at the lowest is at least HEEL_TURN_MM forward of it.
- **A foot standing flat has its forefoot on the heel's floor.**  The forefoot's lowest
  point lies within 12 mm of the heel's (above or below: the heel pad and the toes' pads
  differ) on the same legs standing; a foot pointed by an angle t lowers the ball of the
  foot by about 0.74 x foot length x sin t (ANSUR II's ball-of-foot length; 30 mm at 7
  degrees, 60 mm at 15 on a 250 mm foot).  A forefoot more than FLAT_FOOT_MM below the
  heel is a pointed foot: the person is not standing on it, its "floor" is no floor, and
  the foot's girths (cA, cY: RAL-GZ 387 takes them with the foot at a right angle) are
  not read on it either.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

#: a cloud's stray point: fewer than STRAY_NEIGHBOURS within STRAY_RADIUS_SPACINGS median
#: spacings (module docstring)
STRAY_RADIUS_SPACINGS = 4.0
STRAY_NEIGHBOURS = 4
#: the lowest points are tested this many at a time, lowest first
STRAY_BATCH = 256
#: stray points lie up to this far off the skin (a scanner's ghosts: 5-40 mm), mm
STRAY_REACH_MM = 40.0
#: the heel's back is read in a band this far either side of its middle (x), mm, from the
#: lowest point up HEEL_SPAN_MM, in slabs HEEL_SLAB_MM high
HEEL_HALF_BAND_MM = 10.0
HEEL_SPAN_MM = 60.0
HEEL_SLAB_MM = 2.0
#: the sole is in the scan only where the heel's rearmost point lies this far above the
#: scan's lowest point (standing feet: 20-42 mm) ...
HEEL_REARMOST_ABOVE_MM = 12.0
#: ... and the heel's back at the lowest slab lies this far forward of it (standing: 14-32)
HEEL_TURN_MM = 5.0
#: a forefoot this far below the heel is pointed (standing feet: within 12 mm), mm
FLAT_FOOT_MM = 25.0


@dataclass(frozen=True)
class Sole:
    """The sole's height (calf-frame z, mm), or None with the ``reason`` the scan has no
    floor to measure from."""

    height_mm: float | None
    reason: str | None = None


class _Skin:
    """Which points of a cloud are skin, asked of a few at a time (module docstring);
    every point of a mesh is.  ``points`` (n, 3) mm, ``spacing_from`` (k,) the indices of
    the points whose median spacing is the skin's."""

    def __init__(self, points: np.ndarray, is_mesh: bool, spacing_from: np.ndarray):
        self.points = points
        self.tree = None if is_mesh or len(spacing_from) <= STRAY_NEIGHBOURS else cKDTree(points)
        if self.tree is not None:
            sample = points[spacing_from[:: max(len(spacing_from) // 2000, 1)]]
            self.radius = STRAY_RADIUS_SPACINGS * float(np.median(self.tree.query(sample, k=2)[0][:, 1]))

    def of(self, index: np.ndarray) -> np.ndarray:
        """(k,) bool for the points ``index`` (k,)."""
        if self.tree is None or not len(index):
            return np.ones(len(index), dtype=bool)
        return self.tree.query_ball_point(self.points[index], self.radius, return_length=True) - 1 >= STRAY_NEIGHBOURS

    def lowest(self, index: np.ndarray) -> int | None:
        """The lowest skin point among ``index`` (its index), None when none is skin."""
        order = index[np.argsort(self.points[index, 2], kind="stable")]
        for start in range(0, len(order), STRAY_BATCH):  # one batch unless hundreds of strays lie lower
            batch = order[start:start + STRAY_BATCH]
            skin = self.of(batch)
            if skin.any():
                return int(batch[np.argmax(skin)])
        return None


def _heel_back(band: np.ndarray, lowest_mm: float) -> tuple[float, float] | None:
    """How far above ``lowest_mm`` the heel's back (the least y of each slab of the band
    ``band`` (k, 3): skin points of the heel in a sagittal band round its middle, within
    HEEL_SPAN_MM above the lowest) is furthest back, and how far forward of that it lies
    at the lowest slab holding a point (mm); None where fewer than 3 slabs hold one."""
    n_slabs = int(np.ceil(HEEL_SPAN_MM / HEEL_SLAB_MM))
    slab = np.clip(np.floor((band[:, 2] - lowest_mm) / HEEL_SLAB_MM).astype(np.int64), 0, n_slabs - 1)
    rear = np.full(n_slabs, np.inf)
    np.minimum.at(rear, slab, band[:, 1])
    filled = np.flatnonzero(np.isfinite(rear))
    if len(filled) < 3:
        return None
    rearmost = int(filled[np.argmin(rear[filled])])
    return (rearmost + 0.5) * HEEL_SLAB_MM, float(rear[filled[0]] - rear[rearmost])


def find_sole(points: np.ndarray, faces: np.ndarray | None) -> Sole:
    """The sole of a scan whose foot is in it (module docstring): ``points`` (n, 3) calf
    frame mm, ``faces`` (f, 3) or None."""
    foot = points[points[:, 2] < 0.0]
    if len(foot):  # where the heel's and the forefoot's lowest skin can lie, strays included
        foot = foot[foot[:, 2] < float(foot[:, 2].min()) + HEEL_SPAN_MM + STRAY_REACH_MM]
    behind = np.flatnonzero(foot[:, 1] <= 0.0)
    heel_bottom = behind[foot[behind, 2] < float(foot[:, 2].min()) + STRAY_REACH_MM + HEEL_SPAN_MM / 3]
    skin = _Skin(foot, faces is not None and len(faces) > 0, heel_bottom)
    heel_index = skin.lowest(behind) if len(behind) >= 10 else None
    if heel_index is None:
        return Sole(None, "the scan has no heel behind and below the ankle to stand on")
    lowest = float(foot[heel_index, 2])
    near = behind[(foot[behind, 2] >= lowest) & (foot[behind, 2] < lowest + HEEL_SPAN_MM)]
    middle_x = float(np.median(foot[near[foot[near, 2] < lowest + HEEL_SPAN_MM / 3], 0]))
    band = near[np.abs(foot[near, 0] - middle_x) <= HEEL_HALF_BAND_MM]
    back = _heel_back(foot[band[skin.of(band)]], lowest)
    if back is None:
        return Sole(None, "the back of the heel is not in the scan (a hole or a crop), so where the sole lies is unknown")
    rearmost_above, turn = back
    if rearmost_above < HEEL_REARMOST_ABOVE_MM or turn < HEEL_TURN_MM:
        return Sole(None, f"the scan is cut through the foot above the heel's underside: the heel's back runs down to "
                          f"the scan's lowest point (furthest back {rearmost_above:.0f} mm above it, {turn:.0f} mm "
                          f"forward at it; a standing heel rounds forward under it by 14-32 mm), so the sole and the "
                          f"floor are not in the scan")
    toe_index = skin.lowest(np.flatnonzero(foot[:, 1] > 0.0))
    below = 0.0 if toe_index is None else lowest - float(foot[toe_index, 2])
    if below > FLAT_FOOT_MM:
        return Sole(None, f"the foot is pointed: its forefoot reaches {below:.0f} mm below the heel (standing flat, "
                          f"within {FLAT_FOOT_MM:.0f} mm), so the scan has no floor, and the foot's girths are taken "
                          f"with the foot at a right angle: scan the leg standing")
    return Sole(lowest)

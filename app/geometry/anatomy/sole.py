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
  cloud_outliers read every length 5-12 mm long.  Only skin points decide the sole
  (:class:`app.geometry.anatomy.skin_points.Skin`).
- **The heel turns under the sole.**  On a standing foot the back of the heel (the
  calcaneal tuberosity under its pad) is furthest back 21-53 mm above the floor, and
  below that the heel rounds forward into the sole by 12-34 mm (117 scans of 12
  generated legs, every kind of benchmarks/sole.py, and the 5 real legs of tests/data,
  21-43 and 19-27 mm; the back read as the median of each 2 mm slab's rearmost point and
  its neighbours', so that a streak or a clump of strays in one slab does not read as
  the heel).  A scan cut through the foot above the heel's underside (a crop at the
  midfoot) has its lowest point on the cut: there the heel's back still runs down,
  furthest back 3-11 mm above the scan's lowest point and 0-6 mm forward at it on the
  corpus's 12 midfoot crops (cut 30-50 mm above the sole; a round heel of radius 25-30
  mm turns forward by only 2-3 mm within 12 mm of its rearmost point).  So the sole is
  in the scan only where the heel's rearmost point lies at least HEEL_REARMOST_ABOVE_MM
  above the lowest and the heel's back just above the lowest lies at least HEEL_TURN_MM
  forward of it, each halfway between the crops' largest and the standing feet's
  least.  A crop within about 15 mm of the sole is not told from a foot standing on a
  platform that hid its sole: it reads the lengths short by the crop's height.
- **The heel's underside, not its lowest sample.**  A scanner's noise moves each point
  off the skin both ways, and the lowest of the many points under a heel is the one
  the noise moved furthest down: on meshes with 0.3-1 mm of noise on the vertices the
  lowest vertex lay 1.2-1.3 mm below the clean heel's on average, and every length from
  the floor read that much long (benchmarks/chart_accuracy.py, seeds 3-13, kind noise;
  cloud_noise, cloud_outliers alike).  The sole is therefore the least of the quadratic
  surface z = q(x, y) fitted by least squares to the heel's skin within SOLE_PATCH_MM of
  the lowest point across and above it (the underside of a heel, a cap of curvature
  radius 30-60 mm, rises 1-2 mm over 10 mm: a quadratic within 0.05 mm; the six
  coefficients average the noise of the 20-100 points under it).
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

from app.geometry.anatomy.level_runs import running_median
from app.geometry.anatomy.skin_points import Skin
from app.geometry.sections import mesh_section_segments

#: stray points lie up to this far off the skin (a scanner's ghosts: 5-40 mm), mm
STRAY_REACH_MM = 40.0
#: the heel's back is read in a band this far either side of its middle (x), mm, from the
#: lowest point up HEEL_SPAN_MM, in slabs HEEL_SLAB_MM high
HEEL_HALF_BAND_MM = 10.0
HEEL_SPAN_MM = 60.0
HEEL_SLAB_MM = 2.0
#: the sole is in the scan only where the heel's rearmost point lies this far above the
#: scan's lowest point (standing feet: 21-53 mm; crops 30-50 mm above the sole: 3-11) ...
HEEL_REARMOST_ABOVE_MM = 16.0
#: ... and the heel's back just above the lowest lies this far forward of it (standing:
#: 12-34 mm; the crops: 0-6)
HEEL_TURN_MM = 8.5
#: a forefoot this far below the heel is pointed (standing feet: within 12 mm), mm
FLAT_FOOT_MM = 25.0
#: the heel's underside is fitted within this far of its lowest point, across and up, mm
SOLE_PATCH_MM = 10.0
#: ... when at least this many skin points lie there (else its lowest point is the sole)
SOLE_PATCH_POINTS = 12


@dataclass(frozen=True)
class Sole:
    """The sole's height (calf-frame z, mm), or None with the ``reason`` the scan has no
    floor to measure from."""

    height_mm: float | None
    reason: str | None = None


def _heel_back(heel: np.ndarray, faces: np.ndarray | None, middle_x: float, lowest_mm: float) -> tuple[float, float] | None:
    """How far above ``lowest_mm`` the heel's back is furthest back, and how far forward
    of that it lies just above the lowest (mm); None where fewer than 3 of its heights
    hold skin.  The back at a height is the least y, behind B (y <= 0) and within
    HEEL_HALF_BAND_MM of ``middle_x``, of a mesh's exact plane section there (``heel``
    (k, 3) its vertices, ``faces`` (f, 3): a mesh's vertices alone are 3-4 mm apart and
    a crop's ragged edge moved its lowest ones forward, reading a cut heel as one that
    turns under) or of a cloud's points (``faces`` None) in the HEEL_SLAB_MM slab above."""
    n_slabs = int(np.ceil(HEEL_SPAN_MM / HEEL_SLAB_MM))
    if faces is not None:
        plane, segments = mesh_section_segments(heel, faces, lowest_mm + HEEL_SLAB_MM * (np.arange(n_slabs) + 0.5))
        slab, xy = np.repeat(plane, 2), segments.reshape(-1, 2)
    else:
        slab = np.floor((heel[:, 2] - lowest_mm) / HEEL_SLAB_MM).astype(np.int64)
        xy = heel[:, :2]
    keep = (np.abs(xy[:, 0] - middle_x) <= HEEL_HALF_BAND_MM) & (xy[:, 1] <= 0.0) & (slab >= 0) & (slab < n_slabs)
    rear = np.full(n_slabs, np.inf)
    np.minimum.at(rear, slab[keep], xy[keep, 1])
    rear[~np.isfinite(rear)] = np.nan
    filled = np.flatnonzero(np.isfinite(rear))
    if len(filled) < 3:
        return None
    # the median of each slab and its neighbours: a streak or a clump of strays the skin
    # test let through reaches back in one or two slabs (a cloud's, 28 mm behind the heel
    # 6 mm above its lowest point, read the heel as cut), the heel's back in all of them
    rear = np.where(np.isfinite(rear), running_median(rear, 3), np.nan)
    rearmost = int(filled[np.nanargmin(rear[filled])])
    return (rearmost + 0.5) * HEEL_SLAB_MM, float(rear[filled[0]] - rear[rearmost])


def _quadratic_terms(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(k, 6) the terms 1, x, y, x^2, xy, y^2 of a quadratic surface at (x, y) (k,) mm."""
    return np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])


def heel_underside(patch: np.ndarray, lowest: np.ndarray) -> float:
    """The sole's height (mm): the least of the quadratic z = q(x, y) fitted by least
    squares to the heel's skin points ``patch`` (k, 3) mm within SOLE_PATCH_MM of its
    ``lowest`` (3,) point (module docstring), over the patch's own (x, y) and the
    surface's vertex when it lies inside the patch; the lowest point's height with
    fewer than SOLE_PATCH_POINTS points, or where the fit is not a cap (not lower
    than the patch's highest)."""
    if len(patch) < SOLE_PATCH_POINTS:
        return float(lowest[2])
    x, y = patch[:, 0] - lowest[0], patch[:, 1] - lowest[1]
    design = _quadratic_terms(x, y)
    coef = np.linalg.lstsq(design, patch[:, 2], rcond=None)[0]
    heights = design @ coef
    least = float(heights.min())
    hessian = np.array([[2 * coef[3], coef[4]], [coef[4], 2 * coef[5]]])
    if np.all(np.linalg.eigvalsh(hessian) > 0):  # a cap: its vertex, where it lies over the patch
        vertex = np.linalg.solve(hessian, -coef[1:3])
        if np.hypot(*vertex) <= SOLE_PATCH_MM:
            least = min(least, float(_quadratic_terms(vertex[:1], vertex[1:])[0] @ coef))
    return least if least < float(patch[:, 2].max()) else float(lowest[2])


def find_sole(points: np.ndarray, faces: np.ndarray | None) -> Sole:
    """The sole of a scan whose foot is in it (module docstring): ``points`` (n, 3) calf
    frame mm, ``faces`` (f, 3) or None."""
    foot = points[points[:, 2] < 0.0]
    if len(foot):  # where the heel's and the forefoot's lowest skin can lie, strays included
        foot = foot[foot[:, 2] < float(foot[:, 2].min()) + HEEL_SPAN_MM + STRAY_REACH_MM]
    behind = np.flatnonzero(foot[:, 1] <= 0.0)
    is_mesh = faces is not None and len(faces) > 0
    skin = Skin(foot, is_mesh)
    heel_index = skin.first(behind, foot[behind, 2]) if len(behind) >= 10 else None
    if heel_index is None:
        return Sole(None, "the scan has no heel behind and below the ankle to stand on")
    lowest = float(foot[heel_index, 2])
    near = behind[(foot[behind, 2] >= lowest) & (foot[behind, 2] < lowest + HEEL_SPAN_MM)]
    middle_x = float(np.median(foot[near[foot[near, 2] < lowest + HEEL_SPAN_MM / 3], 0]))
    if faces is not None and is_mesh:
        low_faces = faces[points[faces, 2].min(axis=1) < lowest + HEEL_SPAN_MM]  # the planes cut nothing higher
        back = _heel_back(points, low_faces, middle_x, lowest)
    else:
        band = near[np.abs(foot[near, 0] - middle_x) <= HEEL_HALF_BAND_MM]
        back = _heel_back(foot[band[skin.of(band)]], None, middle_x, lowest)
    if back is None:
        return Sole(None, "the back of the heel is not in the scan (a hole or a crop), so where the sole lies is unknown")
    rearmost_above, turn = back
    if rearmost_above < HEEL_REARMOST_ABOVE_MM or turn < HEEL_TURN_MM:
        return Sole(None, f"the scan is cut through the foot above the heel's underside: the heel's back runs down to "
                          f"the scan's lowest point (furthest back {rearmost_above:.0f} mm above it, {turn:.0f} mm "
                          f"forward at it; a standing heel rounds forward under it by 12 mm or more), so the sole and the "
                          f"floor are not in the scan")
    front = np.flatnonzero(foot[:, 1] > 0.0)
    toe_index = skin.first(front, foot[front, 2])
    below = 0.0 if toe_index is None else lowest - float(foot[toe_index, 2])
    if below > FLAT_FOOT_MM:
        return Sole(None, f"the foot is pointed: its forefoot reaches {below:.0f} mm below the heel (standing flat, "
                          f"within {FLAT_FOOT_MM:.0f} mm), so the scan has no floor, and the foot's girths are taken "
                          f"with the foot at a right angle: scan the leg standing")
    under = behind[(np.hypot(foot[behind, 0] - foot[heel_index, 0], foot[behind, 1] - foot[heel_index, 1]) <= SOLE_PATCH_MM)
                   & (foot[behind, 2] <= lowest + SOLE_PATCH_MM)]
    return Sole(heel_underside(foot[under[skin.of(under)]], foot[heel_index]))

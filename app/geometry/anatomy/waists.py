"""A girth profile's waists and crown read to a tape measure's resolution, for the
landmarks of :mod:`app.geometry.anatomy.landmarks` (paper section 2.2, with the
robustness rules stated there): an interior waist's vertex (B, D), whether a waist at
the scan's edge is reached there, and the middle of the calf's crown (C).

Units: mm.  Heights (k,) ascending and evenly spaced along the slicing axis; girths
(k,) mm, NaN where missing.
"""

from __future__ import annotations

import numpy as np

from app.geometry.anatomy.level_runs import run_around

#: the calf's crown: the heights around the maximum whose girth is within this fraction
#: of it (0.5%: 2 mm on a 400 mm calf, the reading resolution of a tape measure, +-1 mm
#: at each end).  A tape cannot tell these heights apart, so where the maximum lies
#: among them is noise; C is the middle of the crown, which a re-scan reproduces
CROWN_FRACTION = 0.005
#: landmarks at the scan's edge: the girth over the last EDGE_FIT_MM of the scan is fitted
#: by a parabola; B (or D) is taken at the edge when the parabola's minimum lies inside
#: the scan or at most EDGE_REACH_MM beyond its edge (the ankle and knee waists are
#: smooth minima: within 15 mm of one the girth differs from it by ~1 mm), and refused
#: when the girth is still falling towards a minimum further out
EDGE_FIT_MM = 40.0
EDGE_REACH_MM = 15.0
#: ... or when the parabola's minimum lies at most this far below the girth at the edge
#: (or CROWN_FRACTION of it, whichever is more): a tape reads to 1 mm, +-1 mm at each
#: end, so a minimum 2 mm below the edge's girth cannot be told from it (it is also the
#: B and C girth tolerance).  The parabola over 40 mm of an ankle, which rises faster
#: than a parabola above its minimum, puts the vertex 10-20 mm too far out, so the
#: depth is the surer test at the ankle.
TAPE_RESOLUTION_MM = 2.0
#: an interior waist (B, D) is the vertex of the least-squares parabola fitted to the
#: unsmoothed girth within WAIST_FIT_MM of the profile's lowest section (statistics:
#: the lowest single section of a flat waist moves with the noise of the sections
#: around it - D moved up to 9 mm between re-scans of one leg - while the vertex of a
#: fit to the ~40 sections of +-20 mm averages that noise; anatomy: the ankle and knee
#: waists are smooth minima, within 20 mm of which the girth rises 1-5 mm, enough to
#: measure the curvature and still parabolic).  The vertex is used only when it falls
#: within WAIST_FIT_MM / 2 of the lowest section; otherwise the lowest section stays
WAIST_FIT_MM = 20.0
#: ... a window cut short by the scan's end or the landmark's search window is fitted as
#: far as it goes, when it still reaches this far to each side of the lowest section
#: (half the window: both flanks of the waist are measured, so the curvature is).  A
#: knee-high scan stops 15-45 mm above D: the lowest single section, which it used to
#: fall back to, moved D by up to 3 mm between re-scans of one leg
WAIST_MIN_FLANK_MM = 10.0


def waist_vertex(heights: np.ndarray, raw: np.ndarray, index: int, low_mm: float, high_mm: float) -> float:
    """Height of a waist (B or D) from the girth around its lowest section, mm.

    The vertex of the least-squares parabola fitted to the unsmoothed girth ``raw``
    (k,) within :data:`WAIST_FIT_MM` of ``heights[index]`` (see there why), the window
    clipped to [low_mm, high_mm] (the scan and the landmark's search window) when it
    still reaches :data:`WAIST_MIN_FLANK_MM` to each side; it must hold at least 10
    measured sections, curve upwards and put its vertex within half the window of the
    lowest section; otherwise ``heights[index]``.  heights (k,) ascending, mm.
    """
    z0 = float(heights[index])
    low, high = max(z0 - WAIST_FIT_MM, low_mm), min(z0 + WAIST_FIT_MM, high_mm)
    if min(z0 - low, high - z0) < WAIST_MIN_FLANK_MM:
        return z0
    near = (heights >= low) & (heights <= high) & np.isfinite(raw)
    if near.sum() < 10:
        return z0
    c, b, _ = np.polyfit(heights[near] - z0, raw[near], 2)
    if c <= 0:
        return z0
    offset = -b / (2.0 * c)
    return z0 + float(offset) if abs(offset) <= WAIST_FIT_MM / 2 else z0


def minimum_reached_at_edge(heights: np.ndarray, raw: np.ndarray, edge: float, inward: int) -> bool:
    """Does the girth reach its waist minimum at the scan's edge (within EDGE_REACH_MM)?

    A parabola g(x) = a + b x + c x^2 is fitted by least squares to the (unsmoothed)
    girth over the last :data:`EDGE_FIT_MM` of the scan, x the distance from the edge
    into the scan (``inward`` +1 for the bottom edge, -1 for the top).  True when the
    girth does not fall into the scan's edge (b <= 0: the minimum is inside) or the
    parabola's vertex lies at most :data:`EDGE_REACH_MM` beyond the edge, or at most
    :data:`TAPE_RESOLUTION_MM` (or :data:`CROWN_FRACTION`) below the edge's girth.
    """
    x = (heights - edge) * inward
    near = (x >= 0) & (x <= EDGE_FIT_MM) & np.isfinite(raw)
    if near.sum() < 5:
        return False
    c, b, a = np.polyfit(x[near], raw[near], 2)
    if b <= 0:
        return True
    if c <= 0:
        return False
    # the vertex is near enough, or so shallow below the edge girth that a tape could
    # not tell the two apart (CROWN_FRACTION, the rule that defines C's crown)
    return bool(-b / (2 * c) >= -EDGE_REACH_MM or b * b / (4 * c) <= max(CROWN_FRACTION * a, TAPE_RESOLUTION_MM))


def crown_centre(heights: np.ndarray, g: np.ndarray, ic: int, low_mm: float, high_mm: float) -> int:
    """Index of the middle of the calf's crown around the maximum at index ``ic``.

    The crown is the connected run of heights around ``ic``, strictly between
    ``low_mm`` and ``high_mm``, whose smoothed girth ``g`` (k,) differs from ``g[ic]``
    by at most :data:`CROWN_FRACTION` of it; heights (k,) ascending, mm.  On a peaked
    calf the crown is a few millimetres long and C barely moves; on a flat one C no
    longer depends on which point of the plateau the noise made highest.
    """
    level = np.abs(g - g[ic]) <= CROWN_FRACTION * g[ic]
    level &= (heights > low_mm) & (heights < high_mm)
    if not level[ic]:
        return ic
    start, stop = run_around(level, ic)
    middle = 0.5 * (heights[start] + heights[stop])
    return int(start + np.argmin(np.abs(heights[start : stop + 1] - middle)))

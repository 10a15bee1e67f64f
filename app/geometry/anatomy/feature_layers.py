"""The calf's landmarks as a record holds them (paper section 2.2): B, B1, C, D with their
heights and girths, how sharply the profile places each (their height tolerances and
confidences), B1 found between B and C, and the 7 feature layers the paper's NURBS net
is built on.  :mod:`app.geometry.anatomy.landmarks` finds B, C and D on a circumference
profile; this module holds what is made of them.

Units: mm.  Heights are positions along the calf frame's z (B's section at 0 once placed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.anatomy.landmarks import smooth_profile
from app.geometry.anatomy.level_runs import run_around
from app.geometry.anatomy.waists import CROWN_FRACTION

LANDMARK_NAMES = ("B", "B1", "C", "D")

#: a landmark's confidence from its height tolerance (:func:`height_tolerances`):
#: "high" up to 10 mm (the reproducibility of a measuring point placed by hand on the
#: skin, ~1 cm in anthropometric practice), "medium" up to 25 mm (still inside the
#: 50 mm bands over which a compression garment's pressure is graded), "low" beyond, or
#: when the landmark was taken at the scan's or its search window's edge
HIGH_CONFIDENCE_MM = 10.0
MEDIUM_CONFIDENCE_MM = 25.0


@dataclass(frozen=True)
class Landmark:
    """One feature height: ``height_mm`` along the calf axis, ``circumference_mm``."""

    height_mm: float
    circumference_mm: float


@dataclass(frozen=True)
class Landmarks:
    """The paper's feature heights and the 7 feature layers (calf-frame z, mm)."""

    B: Landmark
    B1: Landmark
    C: Landmark
    D: Landmark
    layer_heights_mm: np.ndarray  # (7,)
    d_at_window_edge: bool = False  # D is the bottom of its search window (no distinct minimum)
    b_at_scan_edge: bool = False  # the scan starts at (or just above) the ankle minimum
    d_at_scan_edge: bool = False  # the scan ends at (or just below) the knee waist
    tape_girths_mm: dict | None = None  # name -> convex-hull (tape) girth of the section, mm
    tolerances_mm: dict | None = None  # name -> height tolerance (:func:`height_tolerances`), mm
    #: name -> how far the tape girth may be off where the scan misses an arc of the skin
    #: there, mm (app.geometry.placement.coverage.bridged_arcs; only those beyond an
    #: order's 3 mm)
    girth_uncertainties_mm: dict | None = None

    def at_edge(self, name: str) -> bool:
        """Was the landmark taken at the scan's edge (B, D) or its window's edge (D)?"""
        return bool((name == "B" and self.b_at_scan_edge)
                    or (name == "D" and (self.d_at_scan_edge or self.d_at_window_edge)))

    def confidence(self, name: str) -> str | None:
        """high | medium | low (see :data:`HIGH_CONFIDENCE_MM`), None without tolerances."""
        if not self.tolerances_mm:
            return None
        if self.at_edge(name):
            return "low"
        tolerance = self.tolerances_mm[name]
        return "high" if tolerance <= HIGH_CONFIDENCE_MM else "medium" if tolerance <= MEDIUM_CONFIDENCE_MM else "low"

    def as_dict(self) -> dict:
        out = {}
        for name in LANDMARK_NAMES:
            mark = getattr(self, name)
            entry = {"height_mm": mark.height_mm, "circumference_mm": mark.circumference_mm}
            if self.tape_girths_mm:
                entry["tape_girth_mm"] = self.tape_girths_mm[name]
            entry["at_scan_edge"] = bool((name == "B" and self.b_at_scan_edge) or (name == "D" and self.d_at_scan_edge))
            if self.tolerances_mm:
                entry["height_tolerance_mm"] = self.tolerances_mm[name]
                entry["confidence"] = self.confidence(name)
            if self.girth_uncertainties_mm and name in self.girth_uncertainties_mm:
                entry["girth_uncertainty_mm"] = self.girth_uncertainties_mm[name]
            out[name] = entry
        return out


def b1_height(heights: np.ndarray, girth: np.ndarray, b_mm: float, c_mm: float, level: float | None = None) -> float:
    """B1: where the girth has risen half of the way from B to C (to ``level`` when given:
    halfway between B's and C's girths read some surer way, mm).

    The paper (section 2.2, Fig. 3b) puts B1 where the girth rises fastest, the largest
    dC/dh between B and C: the transition of the Achilles tendon into the calf muscles
    (RAL-GZ 387's measuring point B1).  Between the ankle and the calf the profile is a
    sigmoid-shaped rise, and a sigmoid rises fastest at half its rise; but the maximum
    of a derivative is flat-topped on a real calf and moves with the noise of the
    profile - the same leg scanned again put it up to 39 mm elsewhere
    (benchmarks/results/repeatability.md).  The half-rise level crossing is the same
    point of a symmetric rise, found from two girths each known to ~1 mm: a 1 mm change
    of either moves it by about 1 mm / (2 dC/dh), under a millimetre on a calf.

    heights (k,) evenly spaced, girth (k,) mm; the first height above B where the
    smoothed profile reaches (C(B) + C(C)) / 2, linearly interpolated; mm.
    """
    g = smooth_profile(heights, girth)
    inside = np.flatnonzero((heights > b_mm) & (heights < c_mm))
    if not inside.size:
        return 0.5 * (b_mm + c_mm)
    if level is None:
        level = 0.5 * (np.interp(b_mm, heights, g) + np.interp(c_mm, heights, g))
    above = inside[g[inside] >= level]
    if not above.size or above[0] == 0:
        return 0.5 * (b_mm + c_mm)
    i = above[0]
    h0, h1, g0, g1 = heights[i - 1], heights[i], g[i - 1], g[i]
    return float(h0 + (level - g0) / (g1 - g0) * (h1 - h0)) if g1 > g0 else float(h1)


#: B1 read again on the tape's own girths: planes every B1_TAPE_STEP_MM within
#: B1_TAPE_REACH_MM of the first reading, mm
B1_TAPE_REACH_MM = 8.0
B1_TAPE_STEP_MM = 2.0


def level_crossing(heights: np.ndarray, girth: np.ndarray, level: float, near_mm: float) -> float:
    """Where the least-squares line through the girths (k,) at ``heights`` (k,) mm reaches
    ``level`` (mm): B1 on the tape's girths over a few planes round ``near_mm``, each known
    to ~0.5 mm, the line averaging them.  ``near_mm`` where fewer than 3 are measured, the
    line does not rise or reaches the level outside the measured planes (no
    extrapolation)."""
    measured = np.isfinite(girth)
    if measured.sum() < 3:
        return near_mm
    slope, intercept = np.polyfit(heights[measured] - near_mm, girth[measured], 1)
    if slope <= 0:
        return near_mm
    crossing = near_mm + float((level - intercept) / slope)
    inside = heights[measured].min() <= crossing <= heights[measured].max()
    return crossing if inside else near_mm


def height_tolerances(heights: np.ndarray, girth: np.ndarray, marks_mm: dict) -> dict:
    """How sharply the profile places each landmark: its height tolerance, mm.

    The heights around a landmark whose smoothed girth a tape cannot tell from the
    landmark's own (within :data:`CROWN_FRACTION` of it, at least 1 mm: the tolerance
    that defines C's crown) could hold the landmark as well; the tolerance is half the
    length of that connected run for C and B1, and its length on the inner side for B
    and D (the profile is measured from B to D only; the ankle and knee waists are
    nearly symmetric).  A steep B1 is placed to ~1 mm, a flat calf's C or a long knee
    waist's D to tens of millimetres: their girths are sure, their heights are not.

    heights (k,) ascending from B to D, girth (k,) mm (NaN where missing); ``marks_mm``
    name -> height, mm.  Returns name -> tolerance, mm.
    """
    g = smooth_profile(heights, girth)
    out = {}
    for name, z in marks_mm.items():
        i = int(np.clip(np.searchsorted(heights, z), 0, len(heights) - 1))
        level = np.interp(z, heights, g)
        first, last = run_around(np.abs(g - level) <= max(CROWN_FRACTION * level, 1.0), i)
        start, stop = heights[first], heights[last]
        if name == "B":
            out[name] = float(stop - z)
        elif name == "D":
            out[name] = float(z - start)
        else:
            out[name] = float(0.5 * (stop - start))
    return out


def layer_heights(b: float, b1: float, c: float, d: float) -> np.ndarray:
    """The 7 feature layers: B, B1, C, D and the midway layers between them, (7,) mm."""
    return np.array([b, 0.5 * (b + b1), b1, 0.5 * (b1 + c), c, 0.5 * (c + d), d])

"""Circumference profile and the feature heights B, B1, C, D (paper section 2.2).

The paper's "speed-up strategy": find the calf maximum C first, then the nearest
minima below (ankle, B) and above (below the knee, D); B1 is the maximum of the first
derivative C'(h) between B and C.  Three midway layers make the 7 feature layers.

Robustness additions (documented, not in the paper): the profile is Gaussian-smoothed
(sigma 4 mm) before extrema are taken; B and D must be *interior* minima (the girth
must rise again beyond them inside the scan, otherwise the ankle or the knee is not in
the scanned range); the calf must bulge (C >= 1.2 B) and the knee end must be thicker
than the ankle (D >= 1.05 B).  The last rule also tells the ankle end from the knee end
when the scan's up direction is unknown.

Units: mm.  Heights are positions along the slicing axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks

from app.geometry.errors import FailureReason, FitFailure

#: Gaussian smoothing of the circumference profile, mm
PROFILE_SMOOTHING_MM = 4.0
#: B lies 100-350 mm below C (reference legs 190-265, MakeHuman range 219-246); D lies
#: 30-250 mm above C (adult lower legs)
ANKLE_BELOW_CALF_MM = (100.0, 350.0)
KNEE_ABOVE_CALF_MM = (30.0, 250.0)
#: an extremum needs this much scan beyond it to count as interior, mm
INTERIOR_MARGIN_MM = 6.0
#: minimum calf bulge C/B: ANSUR II's 6,068 subjects range 1.40-2.3 (median 1.72); 1.2
#: leaves room for oedematous ankles and still rejects a knee bulge over the knee waist
#: (about 1.1).  And the knee-end ratio D/B.
MIN_CALF_RATIO = 1.20
MIN_KNEE_RATIO = 1.05
#: a plateau shoulder: the girth slope falls below this fraction of the steepest slope
#: of the calf flank in the FLANK_MM below it
SHOULDER_FRACTION = 0.35
FLANK_MM = 150.0
#: re-detection keeps C within this distance of its previous height, mm
C_HINT_MM = 40.0

LANDMARK_NAMES = ("B", "B1", "C", "D")


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

    def as_dict(self) -> dict:
        return {
            name: {"height_mm": getattr(self, name).height_mm, "circumference_mm": getattr(self, name).circumference_mm}
            for name in LANDMARK_NAMES
        }


@dataclass(frozen=True)
class FeatureHeights:
    """Indices/heights of B, C, D found on a circumference profile."""

    b_mm: float
    c_mm: float
    d_mm: float
    girth_b_mm: float
    girth_c_mm: float
    girth_d_mm: float
    d_at_window_edge: bool


def smooth_profile(heights: np.ndarray, girth: np.ndarray, sigma_mm: float = PROFILE_SMOOTHING_MM) -> np.ndarray:
    """Gaussian-smoothed girth profile; NaN sections are bridged linearly first.

    heights (k,) ascending and evenly spaced, girth (k,) mm; returns (k,).
    """
    ok = np.isfinite(girth)
    if ok.sum() < 3:
        raise FitFailure(FailureReason.NOT_A_LEG, "too few cross-sections could be measured")
    filled = np.interp(heights, heights[ok], girth[ok])
    spacing = float(np.median(np.diff(heights)))
    return gaussian_filter1d(filled, sigma_mm / spacing, mode="nearest")


def _calf_candidates(heights: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Candidate calf maxima: true maxima, then plateau shoulders.

    True maxima: local maxima of the smoothed girth with >= 1 mm prominence, bottom up.
    Shoulders (for calves whose girth only levels off before rising to the knee): local
    minima of the slope below :data:`SHOULDER_FRACTION` of the steepest slope
    in the :data:`FLANK_MM` below, bottom up.  Returns the two
    index arrays.
    """
    peaks, _ = find_peaks(g, prominence=1.0)
    slope = np.gradient(g, heights)
    dips, _ = find_peaks(-slope)
    spacing = float(np.median(np.diff(heights)))
    reach = max(int(round(FLANK_MM / spacing)), 1)
    flank = np.array([slope[max(i - reach, 0) : i + 1].max() for i in dips]) if dips.size else np.zeros(0)
    shoulders = dips[slope[dips] < SHOULDER_FRACTION * flank]
    return peaks, shoulders


def _check_candidate(heights, g, ok, local_min, ic, bottom, top, spacing) -> FeatureHeights | FitFailure:
    """B and D around a calf candidate at index ``ic``, or the reason there are none.

    B is the lowest local minimum of the girth 100-350 mm below C, D the lowest local
    minimum 30-250 mm above C (or, when the girth only levels off, the bottom of that
    window); ``local_min`` (k,) bool marks the local minima of ``g``.
    """
    zc = heights[ic]
    below = (heights >= zc - ANKLE_BELOW_CALF_MM[1]) & (heights <= zc - ANKLE_BELOW_CALF_MM[0]) & ok
    if not below.any():
        return _no_ankle(zc - bottom)
    minima = np.flatnonzero(below & local_min)
    if minima.size == 0:
        return _no_ankle(zc - bottom)
    ib = minima[np.argmin(g[minima])]
    under = (heights < heights[ib]) & (heights >= heights[ib] - 150.0)
    if heights[ib] - bottom < INTERIOR_MARGIN_MM or not under.any() or g[under].max() < g[ib] + 0.5:
        return _no_ankle(zc - bottom)
    if g[ic] < MIN_CALF_RATIO * g[ib]:
        return FitFailure(
            FailureReason.NOT_A_LEG,
            f"no calf bulge: the largest girth above the ankle ({g[ic]:.0f} mm) is less than "
            f"{MIN_CALF_RATIO:.2f} x the ankle girth ({g[ib]:.0f} mm)",
        )
    lo, hi = zc + KNEE_ABOVE_CALF_MM[0], zc + KNEE_ABOVE_CALF_MM[1]
    above = (heights >= lo) & (heights <= hi) & ok
    if not above.any():
        return _no_knee(top - zc)
    minima = np.flatnonzero(above & local_min)
    if minima.size:
        id_ = minima[np.argmin(g[minima])]
    else:  # no distinct minimum: the girth levels off and rises; D is the window's bottom
        id_ = np.flatnonzero(above)[0]
    over = (heights > heights[id_]) & (heights <= heights[id_] + 150.0)
    if top - heights[id_] < INTERIOR_MARGIN_MM or not over.any() or g[over].max() < g[id_] + 0.5:
        return _no_knee(top - zc)
    if g[id_] < MIN_KNEE_RATIO * g[ib]:
        return FitFailure(
            FailureReason.NO_KNEE,
            "the minimum above the calf is not thicker than the ankle: no knee in the scanned range",
        )
    return FeatureHeights(
        float(heights[ib]), float(zc), float(heights[id_]),
        float(g[ib]), float(g[ic]), float(g[id_]),
        bool(heights[id_] - lo < 2 * spacing),
    )


def find_feature_heights(heights: np.ndarray, girth: np.ndarray, near_c_mm: float | None = None) -> FeatureHeights:
    """B, C, D on a profile sampled bottom (ankle end) to top (knee end).

    C is the first calf candidate above the ankle (see :func:`_calf_candidates`) that
    has an interior ankle minimum below it and an interior minimum above it; peaks of a
    plateau separated by a dip shallower than 2% are merged (the higher wins).
    heights (k,) ascending, evenly spaced, mm; girth (k,) mm (NaN where missing).
    ``near_c_mm``: when re-detecting after a small change of axis, only candidates
    within :data:`C_HINT_MM` of the previous C are considered (if there are any), so the
    choice cannot jump between two similar plateau points.
    Raises FitFailure NOT_A_LEG (no calf bulge), NO_ANKLE or NO_KNEE.
    """
    g = smooth_profile(heights, girth)
    ok = np.isfinite(girth)
    bottom, top = heights[ok][0], heights[ok][-1]
    spacing = float(np.median(np.diff(heights)))
    inner = g[(heights >= bottom + 20.0) & (heights <= top - 20.0)]
    if inner.size and inner.max() < MIN_CALF_RATIO * inner.min():
        raise FitFailure(
            FailureReason.NOT_A_LEG,
            f"the girth varies only from {inner.min():.0f} to {inner.max():.0f} mm along the scan: "
            "no ankle, calf and knee",
        )
    peaks, shoulders = _calf_candidates(heights, g)
    if near_c_mm is not None:
        near_peaks = peaks[np.abs(heights[peaks] - near_c_mm) <= C_HINT_MM]
        near_shoulders = shoulders[np.abs(heights[shoulders] - near_c_mm) <= C_HINT_MM]
        if near_peaks.size or near_shoulders.size:
            peaks, shoulders = near_peaks, near_shoulders
        else:  # the flattest point near the previous C
            window = np.flatnonzero(np.abs(heights - near_c_mm) <= C_HINT_MM)
            slope = np.abs(np.gradient(g, heights))[window]
            peaks, shoulders = np.array([], dtype=np.int64), window[[np.argmin(slope)]]
    local_min = np.zeros(len(g), dtype=bool)
    local_min[find_peaks(-g)[0]] = True
    if peaks.size == 0 and shoulders.size == 0:
        raise FitFailure(
            FailureReason.NOT_A_LEG,
            "the circumference profile has no calf maximum: the scan does not bulge like a calf",
        )
    failures: list[tuple[int, float, FitFailure]] = []
    for group in (peaks, shoulders):
        valid: list[tuple[int, FeatureHeights]] = []
        for ic in group:
            outcome = _check_candidate(heights, g, ok, local_min, ic, bottom, top, spacing)
            if isinstance(outcome, FitFailure):
                failures.append((_FAILURE_STAGE[outcome.reason], float(g[ic]), outcome))
            else:
                valid.append((int(ic), outcome))
        if valid:
            index, best = valid[0]
            for other_index, other in valid[1:] if group is peaks else ():
                if heights[other_index] - heights[index] > 100.0:
                    break
                dip = g[index : other_index + 1].min()
                if other.girth_c_mm > best.girth_c_mm and dip >= 0.98 * best.girth_c_mm:
                    index, best = other_index, other
            return best
    # report how far the most complete candidate got: an ankle without a knee says more
    # than no ankle; a bump too weak to be a calf is reported only if nothing else is
    raise max(failures, key=lambda item: (item[0], item[1]))[2]


#: how far a candidate got before it failed (higher is more informative)
_FAILURE_STAGE = {FailureReason.NOT_A_LEG: 0, FailureReason.NO_ANKLE: 1, FailureReason.NO_KNEE: 2}


def _no_ankle(span_mm: float) -> FitFailure:
    return FitFailure(
        FailureReason.NO_ANKLE,
        "no ankle minimum below the calf maximum in the scanned range "
        f"(the scan reaches {span_mm:.0f} mm below the calf maximum and its girth keeps falling)",
    )


def _no_knee(span_mm: float) -> FitFailure:
    return FitFailure(
        FailureReason.NO_KNEE,
        "no minimum below the knee above the calf maximum in the scanned range "
        f"(the scan reaches {span_mm:.0f} mm above the calf maximum)",
    )


def b1_height(heights: np.ndarray, girth: np.ndarray, b_mm: float, c_mm: float) -> float:
    """B1: height of the largest dC/dh strictly between B and C (paper section 2.2, Fig. 3b).

    heights (k,) evenly spaced, girth (k,) mm; returns mm.
    """
    g = smooth_profile(heights, girth)
    slope = np.gradient(g, heights)
    inside = (heights > b_mm) & (heights < c_mm)
    if not inside.any():
        return 0.5 * (b_mm + c_mm)
    return float(heights[inside][np.argmax(slope[inside])])


def layer_heights(b: float, b1: float, c: float, d: float) -> np.ndarray:
    """The 7 feature layers: B, B1, C, D and the midway layers between them, (7,) mm."""
    return np.array([b, 0.5 * (b + b1), b1, 0.5 * (b1 + c), c, 0.5 * (c + d), d])

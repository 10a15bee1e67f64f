"""Circumference profile and the feature heights B, B1, C, D (paper section 2.2).

The paper's "speed-up strategy": find the calf maximum C first, then the nearest
minima below (ankle, B) and above (below the knee, D); B1 is the maximum of the first
derivative C'(h) between B and C.  Three midway layers make the 7 feature layers.

Robustness additions (documented, not in the paper): the profile is Gaussian-smoothed
(sigma 4 mm) before extrema are taken; B and D must be *interior* minima (the girth
must rise again beyond them inside the scan, otherwise the ankle or the knee is not in
the scanned range); the calf must bulge (C >= 1.2 B; 1.05 B over an ankle standing on
its foot) and the knee end must be thicker than the ankle (D >= 1.05 B, unless the foot
under the ankle tells the ends apart).  The last rule also tells the ankle end from the
knee end when the scan's up direction is unknown.

Where a calf candidate's B and D lie, or why it has none, is
:mod:`app.geometry.anatomy.calf_candidates`; how a waist's vertex, a waist at the scan's
edge and the calf's crown are read (to a tape's resolution) is
:mod:`app.geometry.anatomy.waists`; what a record makes of the
landmarks found (their tolerances, B1, the 7 layers) is
:mod:`app.geometry.anatomy.feature_layers`; how a candidate's refusal reads is
:mod:`app.geometry.anatomy.landmark_refusals`.

Units: mm.  Heights are positions along the slicing axis.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks

from app.geometry.anatomy.calf_candidates import (
    ANKLE_BELOW_CALF_MM,
    CROWN_SPREAD,
    INTERIOR_MARGIN_MM,
    KNEE_ABOVE_CALF_MM,
    MIN_CALF_RATIO,
    MIN_CALF_RATIO_ON_FOOT,
    FeatureHeights,
    GirthProfile,
    calf_candidates,
    check_candidate,
    on_a_larger_calfs_flank,
)
from app.geometry.anatomy.landmark_refusals import ends_inside_calf, failure_stage, no_calf
from app.geometry.anatomy.waists import crown_centre
from app.geometry.errors import BulgeOnFlank, CalfWithoutBulge, FailureReason, FitFailure, FootFound

#: Gaussian smoothing of the circumference profile, mm; and the profile noise beyond
#: which it grows, up to the slab thickness of the sparsest clouds (smooth_profile)
PROFILE_SMOOTHING_MM = 4.0
PROFILE_NOISE_MM = 1.0
MAX_PROFILE_SMOOTHING_MM = 20.0
#: re-detection keeps C within this distance of its previous height, mm
C_HINT_MM = 40.0
#: two calf candidates whose B and D lie within this of each other bracket one calf
#: (B and D are each found to a few mm; two calves of one scan lie 300+ mm apart)
SAME_WAIST_MM = 10.0


def smooth_profile(heights: np.ndarray, girth: np.ndarray, sigma_mm: float = PROFILE_SMOOTHING_MM) -> np.ndarray:
    """Gaussian-smoothed girth profile; NaN sections are bridged linearly first.

    The smoothing grows with the profile's own noise (:func:`profile_noise`): beyond
    :data:`PROFILE_NOISE_MM` the sigma is scaled by noise / PROFILE_NOISE_MM, up to
    :data:`MAX_PROFILE_SMOOTHING_MM`.  A scan's profile has 0.2-0.5 mm of noise and
    keeps the 4 mm sigma; a sparse cloud's (slabs 20 mm thick catching a few points of
    each ring) has 3-8 mm, whose bumps would otherwise pass for calves and waists.
    heights (k,) ascending and evenly spaced, girth (k,) mm; returns (k,).
    """
    ok = np.isfinite(girth)
    if ok.sum() < 3:
        raise FitFailure(FailureReason.NOT_A_LEG, "too few cross-sections could be measured")
    filled = np.interp(heights, heights[ok], girth[ok])
    spacing = float(np.median(np.diff(heights)))
    noise = profile_noise(filled, sigma_mm / spacing)
    if noise > PROFILE_NOISE_MM:
        sigma_mm = min(sigma_mm * noise / PROFILE_NOISE_MM, MAX_PROFILE_SMOOTHING_MM)
    return gaussian_filter1d(filled, sigma_mm / spacing, mode="nearest")


def profile_noise(girth: np.ndarray, sigma_samples: float) -> float:
    """Robust standard deviation (1.4826 x MAD, mm) of a gap-free girth profile (k,)
    about its Gaussian smoothing of ``sigma_samples``."""
    residual = girth - gaussian_filter1d(girth, sigma_samples, mode="nearest")
    return float(1.4826 * np.median(np.abs(residual - np.median(residual))))


def find_feature_heights(heights: np.ndarray, girth: np.ndarray, near_c_mm: float | None = None,
                         elongation: np.ndarray | None = None, on_foot: bool = False) -> FeatureHeights:
    """B, C, D on a profile sampled bottom (ankle end) to top (knee end).

    C is the first calf candidate above the ankle (see :func:`_calf_candidates`) that
    has an interior ankle minimum below it and an interior minimum above it; peaks of a
    plateau whose girths between them stay within 2% are merged (the higher wins), and C
    is then the middle of the crown (:func:`crown_centre`).
    heights (k,) ascending, evenly spaced, mm; girth (k,) mm (NaN where missing).
    ``near_c_mm``: when re-detecting after a small change of axis, only candidates
    within :data:`C_HINT_MM` of the previous C are considered (if there are any), so the
    choice cannot jump between two similar plateau points.
    ``elongation`` (k,), when given: a candidate whose section is more elongated than
    :data:`MAX_CALF_ELONGATION` is not a calf (it is a foot).  ``on_foot``: an earlier
    profile of the same leg found its ankle on its foot (:attr:`FeatureHeights.on_foot`),
    which this one, cut to the calf, no longer holds.
    Raises FitFailure NOT_A_LEG (no calf bulge), NO_ANKLE or NO_KNEE.
    """
    g = smooth_profile(heights, girth)
    ok = np.isfinite(girth)
    bottom, top = heights[ok][0], heights[ok][-1]
    spacing = float(np.median(np.diff(heights)))
    inner = g[(heights >= bottom + 20.0) & (heights <= top - 20.0)]
    # (a profile of a leg whose ankle stood on its foot, cut to its calf, may bulge less)
    if inner.size and inner.max() < (MIN_CALF_RATIO_ON_FOOT if on_foot else MIN_CALF_RATIO) * inner.min():
        raise FitFailure(
            FailureReason.NOT_A_LEG,
            f"the girth varies only from {inner.min():.0f} to {inner.max():.0f} mm along the scan: "
            "no ankle, calf and knee",
        )
    peaks, shoulders = calf_candidates(heights, g)
    if near_c_mm is not None:
        near_peaks = peaks[np.abs(heights[peaks] - near_c_mm) <= C_HINT_MM]
        near_shoulders = shoulders[np.abs(heights[shoulders] - near_c_mm) <= C_HINT_MM]
        if near_peaks.size or near_shoulders.size:
            # the crown search starts at the first candidate near the previous C and may
            # still grow up its crown; none near: all candidates compete again
            peaks = peaks[heights[peaks] >= heights[near_peaks].min()] if near_peaks.size else near_peaks
            shoulders = shoulders[heights[shoulders] >= heights[near_shoulders].min()] if near_shoulders.size else near_shoulders
    local_min = np.zeros(len(g), dtype=bool)
    local_min[find_peaks(-g)[0]] = True
    stretch = np.zeros(len(g)) if elongation is None else np.nan_to_num(elongation)
    profile = GirthProfile(heights, girth, g, ok, local_min, float(bottom), float(top), spacing, stretch, on_foot)
    footlike = profile.footlike
    if peaks.size == 0 and shoulders.size == 0:
        # no bulge inside the scan: when the girth is largest at one end, the scan stops
        # inside the calf (the up end: the knee waist is missing; the down end: the ankle)
        widest = heights[ok][np.argmax(g[ok])]
        narrowest_h = heights[ok][np.argmin(g[ok])]
        if top - widest <= INTERIOR_MARGIN_MM * 5:
            raise ends_inside_calf(top - narrowest_h, float(g[ok].min()), float(g[ok].max()), at_top=True)
        if widest - bottom <= INTERIOR_MARGIN_MM * 5:
            raise ends_inside_calf(narrowest_h - bottom, float(g[ok].min()), float(g[ok].max()), at_top=False)
        raise no_calf("the circumference profile has no calf maximum: the scan does not bulge like a calf")
    # (stage, rank, failure, the candidate's height mm)
    failures: list[tuple[float, float, FitFailure, float]] = []
    for group in (peaks, shoulders):
        valid: list[tuple[int, FeatureHeights]] = []
        for ic in group:
            outcome: FeatureHeights | FitFailure
            if footlike[ic]:
                outcome = FootFound(no_calf(f"the bulge at {g[ic]:.0f} mm girth is {stretch[ic]:.2f} times as "
                                             "long as it is wide: a foot, not a calf").detail, float(g[ic]))
            else:
                outcome = check_candidate(profile, int(ic))
            if isinstance(outcome, FitFailure):
                # among ankles missing, the lowest bulge (the calf is the first bulge above
                # the ankle); otherwise the largest
                # (and among legs without a calf bulge on their foot, the lowest: the one
                # read from the ankle, not a thigh's over a knee waist)
                lowest = outcome.reason is FailureReason.NO_ANKLE or isinstance(outcome, CalfWithoutBulge)
                rank = -float(heights[ic]) if lowest else float(g[ic])
                failures.append((failure_stage(outcome), rank, outcome, float(heights[ic])))
            else:
                valid.append((int(ic), outcome))
        valid = [(i, o) for i, o in valid if not on_a_larger_calfs_flank(profile, o)]
        if valid:
            index, best = valid[0]
            # C is the calf maximum: of the candidates that bracket the same calf (the
            # same ankle B and knee waist D, to SAME_WAIST_MM), the largest girth - a
            # bump of a sparse cloud's noisy profile below the real maximum is not C
            # (the same ankle alone is not enough: a thigh above the knee stands on it
            # too, measured on BodyParts3D's leg)
            same_calf = [(i, o) for i, o in valid if abs(o.b_mm - best.b_mm) <= SAME_WAIST_MM
                         and abs(o.d_mm - best.d_mm) <= SAME_WAIST_MM]
            index, best = max(same_calf, key=lambda item: item[1].girth_c_mm)
            # candidates less than 100 mm apart whose girths between them stay within 2%
            # (a dip between peaks, a rise between shoulders) are one crown: the higher wins
            for other_index, other in valid[1:]:
                if other_index <= index:  # below the largest of the same calf (it was taken over them)
                    continue
                if heights[other_index] - heights[index] > 100.0:
                    break
                span = g[index : other_index + 1]
                same_crown = (span.min() >= (1.0 - CROWN_SPREAD) * best.girth_c_mm
                              and span.max() <= (1.0 + CROWN_SPREAD) * best.girth_c_mm)
                if other.girth_c_mm > best.girth_c_mm and same_crown:
                    index, best = other_index, other
            crown = crown_centre(heights, g, index, best.b_mm, best.d_mm - KNEE_ABOVE_CALF_MM[0])
            return replace(best, c_mm=float(heights[crown]), girth_c_mm=float(g[crown]))
    # the scan stops inside the calf: above its narrowest point the girth is largest at
    # the top edge (the knee waist is missing); below it, at the bottom edge (the ankle)
    # (only when no candidate found even an ankle: otherwise that candidate says more)
    finite = np.flatnonzero(ok)
    feet = finite[footlike[finite]]  # the narrowest section of the leg, above its foot (not the toes)
    if feet.size and (finite > feet.max()).sum() >= 3:
        finite = finite[finite > feet.max()]
    narrowest = finite[np.argmin(g[finite])]
    up = finite[finite > narrowest]
    # (a candidate at or below the foot's highest elongated section is a bump of the heel
    # or instep, no calf: its missing ankle or knee tells nothing of the leg above; it held
    # back robustness cut_below_knee-04's "the scan ends inside the calf", which was refused
    # as "a foot, not a calf")
    above_foot = heights[feet.max()] if feet.size else -np.inf
    # (a leg measured on its foot without a calf bulge, CalfWithoutBulge, found its ankle or foot too)
    got_ankle = any((failure.reason in (FailureReason.NO_ANKLE, FailureReason.NO_KNEE) and at_mm > above_foot)
                    or isinstance(failure, CalfWithoutBulge) for _, _, failure, at_mm in failures)
    # (only when the girth rises without a bulge from the narrowest point to the top: a
    # scan holding a calf, a knee and a thigh above its narrowest point does not stop
    # inside the calf)
    dips = find_peaks(-g, prominence=1.0)[0]
    rising = up.size and not np.isin(up, dips).any()
    # (and rises over at least the shortest ankle-to-calf distance: a foot with a few
    # centimetres of shin above its ankle is a foot, not a calf cut short)
    long_rise = top - heights[narrowest] >= ANKLE_BELOW_CALF_MM[0]
    if (near_c_mm is None and not got_ankle and rising and long_rise
            and top - heights[up[np.argmax(g[up])]] <= 5 * INTERIOR_MARGIN_MM):
        raise ends_inside_calf(top - heights[narrowest], float(g[narrowest]), float(g[up].max()), at_top=True)
    if not failures:
        # every candidate was a bulge on the flank of a larger one (on_a_larger_calfs_flank),
        # and that one was no candidate: no ankle or knee waist of its own in the scan
        raise no_calf("the profile's bulges lie on the rising flank of a larger bulge above them, which has no "
                      "ankle and knee waist of its own in the scan: the scan must hold the whole lower leg, from "
                      "below the ankle bones to above the knee joint")
    # report how far the most complete candidate got: an ankle without a knee says more
    # than no ankle; a bump too weak to be a calf is reported only if nothing else is
    reported = max(failures, key=lambda item: (item[0], item[1]))[2]
    # with the bulges set aside as on a flank: their girths may tell a wrong unit
    reported.flank_bulges_mm = tuple(f.girth_mm for _, _, f, _ in failures if isinstance(f, BulgeOnFlank))
    raise reported

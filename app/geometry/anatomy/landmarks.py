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

How a waist's vertex, a waist at the scan's edge and the calf's crown are read (to a
tape's resolution) is :mod:`app.geometry.anatomy.waists`; what a record makes of the
landmarks found (their tolerances, B1, the 7 layers) is
:mod:`app.geometry.anatomy.feature_layers`; how a candidate's refusal reads is
:mod:`app.geometry.anatomy.landmark_refusals`.

Units: mm.  Heights are positions along the slicing axis.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks

from app.geometry.anatomy.landmark_refusals import ends_inside_calf, failure_stage, no_ankle, no_calf, no_knee
from app.geometry.anatomy.waists import (
    CROWN_FRACTION,
    crown_centre,
    minimum_reached_at_edge,
    waist_vertex,
)
from app.geometry.errors import BulgeOnFlank, FailureReason, FitFailure, FootFound

#: Gaussian smoothing of the circumference profile, mm; and the profile noise beyond
#: which it grows, up to the slab thickness of the sparsest clouds (smooth_profile)
PROFILE_SMOOTHING_MM = 4.0
PROFILE_NOISE_MM = 1.0
MAX_PROFILE_SMOOTHING_MM = 20.0
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
#: D, the narrowest part of the leg below the knee, may be read wider than C, the calf's
#: widest, only where the girth levels off above C and D is the bottom of its window: on
#: the real legs and the 218 generated cases of benchmarks/robustness.py the accepted
#: candidates' D/C stays at most 1.016 (the Visible Human female's flat calf), but for
#: a sparse cloud's noise bumps on the calf's rising flank (1.107-1.121: their "D" is
#: the flank above them, and one such record read C 102 mm small) and two bent knees'
#: candidates (2.08, 2.32: their "D" lies in the thigh folded onto the shank, and one such
#: record read D 167 mm wide).  A candidate whose D is wider than this times C is not a
#: calf's maximum with its knee waist
MAX_KNEE_OVER_CALF = 1.05
#: a plateau shoulder: the girth slope falls below this fraction of the steepest slope
#: of the calf flank in the FLANK_MM below it
SHOULDER_FRACTION = 0.35
FLANK_MM = 150.0
#: re-detection keeps C within this distance of its previous height, mm
C_HINT_MM = 40.0
#: the ankle B is the narrowest section of the leg above the foot (anthropometry: the
#: minimum leg girth, ISO 8559-1 5.3.23); a candidate B with a leg section more than
#: this fraction narrower below it is a knee waist (the scan starts above the ankle,
#: and the bulge above the candidate is the thigh).  3% is three times the girth noise
#: of a section (~1%), so a flat ankle region never trips it.
NARROWER_BELOW = 0.03
#: ... looking down from B until the girth reaches FOOT_RATIO x B: below a real ankle the
#: heel and instep come first (heel-ankle girth ~1.4-1.6 x the ankle minimum), and the
#: small sections of a sole or toes under them are not leg; below a knee waist lies
#: only the calf, at most ~1.25 x the knee waist
FOOT_RATIO = 1.3

#: two calf candidates whose B and D lie within this of each other bracket one calf
#: (B and D are each found to a few mm; two calves of one scan lie 300+ mm apart)
SAME_WAIST_MM = 10.0
#: peaks whose girths between them stay within this share of each other are one crown
#: (a dip between peaks, a rise between shoulders); a bulge that falls by more has a waist
CROWN_SPREAD = 0.02

#: the calf maximum's section is nearly round: calf sections have an elongation
#: (:meth:`app.geometry.sections.PolarSections.elongations`, sqrt(a/b) for an a x b
#: ellipse) of 1.01-1.10 on the real and generated legs (width to depth 1.0-1.2, as
#: anthropometry has it); a section through the heel and the instep, which a scan read
#: upside down offers as a "calf", is 1.5 or more (about 2.5:1).  1.35 (a 1.8:1
#: section) lies between, well clear of both.
MAX_CALF_ELONGATION = 1.35

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
    b_at_scan_edge: bool = False
    d_at_scan_edge: bool = False


@dataclass(frozen=True)
class GirthProfile:
    """A circumference profile as the landmark search reads it: ``heights`` (k,)
    ascending, evenly ``spacing`` mm apart; ``raw`` (k,) girths (NaN where missing) and
    ``smooth`` (k,) the smoothed ones, mm; ``measured`` (k,) bool; ``local_min`` (k,) bool
    the local minima of ``smooth``; ``bottom`` and ``top`` the first and last measured
    heights, mm; ``elongation`` (k,) the sections' elongations (0 where not known)."""

    heights: np.ndarray
    raw: np.ndarray
    smooth: np.ndarray
    measured: np.ndarray
    local_min: np.ndarray
    bottom: float
    top: float
    spacing: float
    elongation: np.ndarray

    @property
    def footlike(self) -> np.ndarray:
        """(k,) bool: the sections more elongated than a calf's (MAX_CALF_ELONGATION: the
        foot's)."""
        return self.elongation > MAX_CALF_ELONGATION


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


def _calf_candidates(heights: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Candidate calf maxima: true maxima, then plateau shoulders.

    True maxima: local maxima of the smoothed girth with >= 1 mm prominence, bottom up.
    Shoulders (for calves whose girth only levels off before rising to the knee): local
    minima of the slope below :data:`SHOULDER_FRACTION` of the steepest slope
    in the :data:`FLANK_MM` below, where the girth is the highest of that flank, bottom up.  Returns the two
    index arrays.
    """
    peaks, _ = find_peaks(g, prominence=1.0)
    slope = np.gradient(g, heights)
    dips, _ = find_peaks(-slope)
    spacing = float(np.median(np.diff(heights)))
    reach = max(int(round(FLANK_MM / spacing)), 1)
    flank = np.array([slope[max(i - reach, 0) : i + 1].max() for i in dips]) if dips.size else np.zeros(0)
    # a shoulder levels off a rising flank: its girth is the highest of the flank below
    # it (to the crown's tolerance); a pause in a falling girth above the calf is not one
    highest = np.array([g[max(i - reach, 0) : i + 1].max() for i in dips]) if dips.size else np.zeros(0)
    shoulders = dips[(slope[dips] < SHOULDER_FRACTION * flank) & (g[dips] >= (1.0 - CROWN_FRACTION) * highest)]
    return peaks, shoulders


def _check_candidate(profile: GirthProfile, ic: int) -> FeatureHeights | FitFailure:
    """B and D around a calf candidate at index ``ic`` of the profile, or the reason
    there are none.

    B is the lowest local minimum of the girth 100-350 mm below C, D the lowest local
    minimum 30-250 mm above C (or, when the girth only levels off, the bottom of that
    window).
    """
    heights, g, raw, ok, local_min = profile.heights, profile.smooth, profile.raw, profile.measured, profile.local_min
    bottom, top, spacing = profile.bottom, profile.top, profile.spacing
    zc = heights[ic]
    below = (heights >= zc - ANKLE_BELOW_CALF_MM[1]) & (heights <= zc - ANKLE_BELOW_CALF_MM[0]) & ok
    if not below.any():
        return no_ankle(zc - bottom)
    ib, b_edge = None, False
    # the ankle is a leg's section: a minimum among the foot's elongated sections (a
    # pointed foot's toes, in line with the shank, narrow below the heel) is not B
    minima = np.flatnonzero(below & local_min & ~profile.footlike)
    if minima.size:
        ib = minima[np.argmin(g[minima])]
        under = (heights < heights[ib]) & (heights >= heights[ib] - 150.0)
        if heights[ib] - bottom < INTERIOR_MARGIN_MM or not under.any() or g[under].max() < g[ib] + 0.5:
            ib = None
    if ib is None:
        if heights[below][0] - bottom > 2 * spacing or not minimum_reached_at_edge(heights, raw, bottom, +1):
            return no_ankle(zc - bottom)
        ib, b_edge = np.flatnonzero(below)[np.argmin(g[below])], True
    # walk down from B until the girth passes the foot's or the sections turn as
    # elongated as a foot's (a knee waist has only the calf below it, a real ankle the
    # heel and instep)
    # (not the lowest INTERIOR_MARGIN_MM of the scan: its edge sections are often partial)
    down = np.flatnonzero(ok & (heights < heights[ib] - INTERIOR_MARGIN_MM) & (heights >= bottom + INTERIOR_MARGIN_MM))[::-1]
    foot = np.flatnonzero((g[down] >= FOOT_RATIO * g[ib]) | profile.footlike[down])
    lower = down[: foot[0]] if foot.size else down
    if lower.size and g[lower].min() < (1.0 - NARROWER_BELOW) * g[ib]:
        # the ankle is the narrowest part of the leg above the foot: with a narrower leg
        # below this "ankle", it is a knee waist and the bulge above it a thigh
        return no_calf(
            f"the minimum below the bulge at {g[ic]:.0f} mm girth ({g[ib]:.0f} mm) is not the ankle: "
            f"the leg below it is narrower ({g[lower].min():.0f} mm)"
        )
    if g[ic] < MIN_CALF_RATIO * g[ib]:
        return no_calf(
            f"no calf bulge: the largest girth above the ankle ({g[ic]:.0f} mm) is less than "
            f"{MIN_CALF_RATIO:.2f} x the ankle girth ({g[ib]:.0f} mm)"
        )
    lo, hi = zc + KNEE_ABOVE_CALF_MM[0], zc + KNEE_ABOVE_CALF_MM[1]
    above = (heights >= lo) & (heights <= hi) & ok
    if not above.any():
        return no_knee(top - zc)
    minima = np.flatnonzero(above & local_min)
    if minima.size:
        id_ = minima[np.argmin(g[minima])]
    else:  # no distinct minimum: the girth levels off and rises; D is the window's bottom
        id_ = np.flatnonzero(above)[0]
    over = (heights > heights[id_]) & (heights <= heights[id_] + 150.0)
    d_edge = False
    if top - heights[id_] < INTERIOR_MARGIN_MM or not over.any() or g[over].max() < g[id_] + 0.5:
        if top - heights[above][-1] > 2 * spacing or not minimum_reached_at_edge(heights, raw, top, -1):
            return no_knee(top - zc)
        id_, d_edge = np.flatnonzero(above)[np.argmin(g[above])], True
    if g[id_] > MAX_KNEE_OVER_CALF * g[ic]:
        flank = no_calf(
            f"the bulge at {g[ic]:.0f} mm girth is not the calf's maximum: {heights[id_] - zc:.0f} mm above it the "
            f"leg is {g[id_]:.0f} mm round and still widening, with no knee waist between"
        )
        return BulgeOnFlank(flank.detail, float(g[ic]))
    if g[id_] < MIN_KNEE_RATIO * g[ib]:
        return FitFailure(
            FailureReason.NO_KNEE,
            "the minimum above the calf is not thicker than the ankle: no knee in the scanned range",
        )
    z_b = float(heights[ib]) if b_edge else waist_vertex(heights, raw, ib, max(bottom, zc - ANKLE_BELOW_CALF_MM[1]), zc)
    z_d = float(heights[id_]) if d_edge else waist_vertex(heights, raw, id_, lo, min(top, hi))
    return FeatureHeights(
        z_b, float(zc), z_d,
        float(np.interp(z_b, heights, g)), float(g[ic]), float(np.interp(z_d, heights, g)),
        bool(heights[id_] - lo < 2 * spacing) and not d_edge,
        b_edge, d_edge,
    )


def _on_a_larger_calfs_flank(profile: GirthProfile, candidate: FeatureHeights) -> bool:
    """Whether ``candidate``'s D is no waist but a point on the rising flank of a larger
    calf above it: D is wider than C (the girth rose from C to it), and above D, within
    KNEE_ABOVE_CALF_MM[1] of C, the girth rises further to a maximum and falls from it by
    more than a crown's spread (CROWN_SPREAD) - a bulge with its own waist, the calf.  (On sparse vertex
    clouds of knee-high scans, shoulders and noise dips of the flank 25-60 mm below the
    calf's maximum were taken for C and D, D 120-140 mm below the knee waist, with no word
    but D's low confidence; their D was 1.03-1.05 times C.  A calf that levels off into
    the knee - the Visible Human female's left, D 1.016 times C - has no bulge above D
    that falls again below the thigh.)  The bulge above need not be a candidate of its own:
    its waist may lie past the scan's end, and the scan is then refused for it."""
    if candidate.girth_d_mm <= candidate.girth_c_mm:
        return False
    heights, g, measured = profile.heights, profile.smooth, profile.measured
    above = np.flatnonzero((heights > candidate.d_mm) & (heights <= candidate.c_mm + KNEE_ABOVE_CALF_MM[1]) & measured)
    if len(above) < 2:
        return False
    top = above[int(np.argmax(g[above]))]
    after = above[above > top]
    return bool(g[top] > candidate.girth_d_mm and after.size and g[after].min() < (1.0 - CROWN_SPREAD) * g[top])


def find_feature_heights(heights: np.ndarray, girth: np.ndarray, near_c_mm: float | None = None,
                         elongation: np.ndarray | None = None) -> FeatureHeights:
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
    :data:`MAX_CALF_ELONGATION` is not a calf (it is a foot).
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
            # the crown search starts at the first candidate near the previous C and may
            # still grow up its crown; none near: all candidates compete again
            peaks = peaks[heights[peaks] >= heights[near_peaks].min()] if near_peaks.size else near_peaks
            shoulders = shoulders[heights[shoulders] >= heights[near_shoulders].min()] if near_shoulders.size else near_shoulders
    local_min = np.zeros(len(g), dtype=bool)
    local_min[find_peaks(-g)[0]] = True
    stretch = np.zeros(len(g)) if elongation is None else np.nan_to_num(elongation)
    profile = GirthProfile(heights, girth, g, ok, local_min, float(bottom), float(top), spacing, stretch)
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
                outcome = _check_candidate(profile, int(ic))
            if isinstance(outcome, FitFailure):
                # among ankles missing, the lowest bulge (the calf is the first bulge above
                # the ankle); otherwise the largest
                rank = -float(heights[ic]) if outcome.reason is FailureReason.NO_ANKLE else float(g[ic])
                failures.append((failure_stage(outcome), rank, outcome, float(heights[ic])))
            else:
                valid.append((int(ic), outcome))
        valid = [(i, o) for i, o in valid if not _on_a_larger_calfs_flank(profile, o)]
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
    got_ankle = any(failure.reason in (FailureReason.NO_ANKLE, FailureReason.NO_KNEE) and at_mm > above_foot
                    for _, _, failure, at_mm in failures)
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
    # report how far the most complete candidate got: an ankle without a knee says more
    # than no ankle; a bump too weak to be a calf is reported only if nothing else is
    reported = max(failures, key=lambda item: (item[0], item[1]))[2]
    # with the bulges set aside as on a flank: their girths may tell a wrong unit
    reported.flank_bulges_mm = tuple(f.girth_mm for _, _, f, _ in failures if isinstance(f, BulgeOnFlank))
    raise reported

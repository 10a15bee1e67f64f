"""A calf candidate on a girth profile (app.geometry.anatomy.landmarks): the bulges that
may be the calf's maximum C, and for one of them where its ankle B and knee waist D lie,
or why it has none (paper section 2.2's "speed-up strategy" with the robustness rules
stated below: B and D interior minima or waists reached at the scan's edge; the calf
bulging over the ankle; the ankle the narrowest leg above its foot, and on it; the knee
end thicker than the ankle where no foot tells the ends apart; D no wider than C).

Units: mm.  Heights are positions along the slicing axis; profiles (k,) ascending.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import find_peaks

from app.geometry.anatomy.landmark_refusals import calf_without_bulge, knee_unreadable, no_ankle, no_calf, no_knee
from app.geometry.anatomy.waists import CROWN_FRACTION, minimum_reached_at_edge, waist_vertex
from app.geometry.errors import BulgeOnFlank, FailureReason, FitFailure

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
#: ... where the ankle stands on its foot (MAX_ANKLE_ABOVE_FOOT_MM), the knee bulge
#: cannot pass for the calf - its knee waist lies a shank above the foot - and the calf
#: need only bulge as much as its crown can be read: 5% over the ankle (15 mm on a 300
#: mm ankle, 7 times a tape's resolution).  A swollen leg (oedema, lymphoedema) keeps
#: its landmarks down to C/B 1.05, the calf's crown flat and its height warned about
MIN_CALF_RATIO_ON_FOOT = 1.05
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
#: ... and the foot begins at most this far below the ankle B: B, the narrowest girth
#: above the malleoli, lies 46-66 mm above the first of the foot's sections (FOOT_RATIO
#: or elongated) on the five real legs of tests/data and 75 generated scans of
#: benchmarks/corpus (robustness' kinds, seed 7); a knee waist lies a shank above its
#: ankle (ANSUR II's tibiale to lateral malleolus: at least 284 mm over 6,068
#: subjects).  150 mm, more than twice the one and about half the other: a "B" further
#: above the foot, with no narrower leg between (NARROWER_BELOW), is a knee waist over a
#: lower leg as wide as it - a swollen leg (benchmarks/swollen.py)
MAX_ANKLE_ABOVE_FOOT_MM = 150.0
#: ... and a foot is told by its shape: a section more elongated than a calf's
#: (MAX_CALF_ELONGATION, the heel and instep) lies at most this far below the foot's
#: first section (FOOT_RATIO or elongated), mm.  Measured 0-15 mm on the five real legs,
#: 120 corpus scans of seed 7 and 60 swollen legs of benchmarks/swollen.py 60 23 whose
#: ankle stands on a foot; below a knee waist read upside down the thigh is as wide as a
#: foot (FOOT_RATIO) but round (elongation 1.02-1.06), and the nearest elongated section
#: (the hip's cut) lay 204 mm below its first such section on the body's leg where this
#: was found: read so, it was measured cB 333 mm at the knee waist and cD 242 at the
#: ankle (benchmarks/chart_accuracy.py 8 7, leg 7's body vertices)
FOOT_SHAPE_REACH_MM = 50.0

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
    #: B is an ankle on its foot (the foot begins at most MAX_ANKLE_ABOVE_FOOT_MM below
    #: it): the foot told the ankle's end, not the knee waist's being thicker
    on_foot: bool = False


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
    #: the ankle's end was told by its foot on an earlier profile (FeatureHeights.on_foot)
    on_foot: bool = False

    @property
    def footlike(self) -> np.ndarray:
        """(k,) bool: the sections more elongated than a calf's (MAX_CALF_ELONGATION: the
        foot's)."""
        return self.elongation > MAX_CALF_ELONGATION


def calf_candidates(heights: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def _rises_below(heights: np.ndarray, g: np.ndarray, i: int) -> bool:
    """Does the girth ``g`` (k,) rise by at least 0.5 mm somewhere in the 150 mm below index
    ``i`` (heights (k,) ascending, mm) - a minimum with the heel and foot or the calf below it?"""
    under = (heights < heights[i]) & (heights >= heights[i] - 150.0)
    return bool(under.any() and g[under].max() >= g[i] + 0.5)


#: a leg's girth rises at most ~1%/mm anywhere above the ankle (about 0.5%/mm at the
#: knee): a rise of 10% within 5 mm means the plane has reached another body part (a
#: bent knee's thigh, the other leg touching this one); the corpus truth ends the
#: shank's sections by the same rule
MERGE_RISE = 0.10
MERGE_RUN_MM = 5.0
#: ... but a profile read from a scan, not from a shank cut free at its knee, is noisy: a
#: sparse cloud's section reads 5% low, and across unread sections its girth rose 10.5% in
#: 9 mm (robustness 220 7, sparse_leg_vertices-02, 1.2%/mm on the calf's lower flank).
#: Another body part joining the sections adds its own girth: the other leg's knee or the
#: thigh of a bent knee 80-100% (other_leg.py 24 3 case 13, robustness 220 23 seated-04),
#: a forearm beside a 350 mm calf at least 40% (ANSUR II: forearm girth >= 200 mm, against
#: the calf's 300-420).  A join rises by at least this within MERGE_RUN_MM
JOIN_RISE = 0.25


def merged_above(heights: np.ndarray, raw: np.ndarray, index: int, reach_mm: float) -> tuple[int, float] | None:
    """The first index within ``reach_mm`` above ``index``, and the rise there (a
    fraction), where the measured girth
    ``raw`` (k,) rises by JOIN_RISE within MERGE_RUN_MM - over the higher of the two
    sections MERGE_RUN_MM and one spacing more below it - and stays so MERGE_RUN_MM
    further up (another body part joins the sections), or None; None too where those
    sections are not measured (a rise over a gap is no rise within MERGE_RUN_MM).  The
    higher of two, not one: a sparse cloud's single section reading 5% low is no level
    to rise from.  heights (k,) ascending, evenly spaced, mm."""
    spacing = float(np.median(np.diff(heights)))
    run = max(int(round(MERGE_RUN_MM / spacing)), 1)
    j = np.arange(index + run + 1, len(heights))
    j = j[heights[j] <= heights[index] + reach_mm]
    if not j.size:
        return None
    below = np.fmax(raw[j - run], raw[j - run - 1])  # NaN only where both are
    later = raw[np.minimum(j + run, len(raw) - 1)]
    with np.errstate(invalid="ignore"):
        jumps = (raw[j] > (1.0 + JOIN_RISE) * below) & ~(later < (1.0 + JOIN_RISE) * below)
    if not jumps.any():
        return None
    first = int(np.argmax(jumps))
    return int(j[first]), float(raw[j[first]] / below[first] - 1.0)


def check_candidate(profile: GirthProfile, ic: int) -> FeatureHeights | FitFailure:
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
    # ... and one the girth rises from below, inside the scan: the narrowest of those (a
    # partial section at the scan's edge - a toe tip a stray point or two made finite -
    # is a minimum too, and taken first it hid the ankle above it: a cloud with stray
    # points, benchmarks/chart_accuracy.py 8 17 leg 7, was refused no_ankle)
    ankles = [int(i) for i in np.flatnonzero(below & local_min & ~profile.footlike)
              if heights[i] - bottom >= INTERIOR_MARGIN_MM and _rises_below(heights, g, int(i))]
    if ankles:
        ib = ankles[int(np.argmin(g[ankles]))]
    if ib is None:
        if heights[below][0] - bottom > 2 * spacing or not minimum_reached_at_edge(heights, raw, bottom, +1):
            return no_ankle(zc - bottom)
        ib, b_edge = np.flatnonzero(below)[np.argmin(g[below])], True
    # the calf is the leg's own: no other body part joins the sections between the ankle
    # and it (a step of another limb's girth onto the leg's levels off into a shoulder,
    # which passed for a calf twice the leg's girth)
    # (a seated leg read along its shank: its thigh joins the sections under the knee,
    # and the bulge above the join is the thigh's - robustness 220 23, seated-04, whose
    # 880 mm "calf" was placed and refused only by the record's knee check)
    joined = merged_above(heights, raw, int(ib), float(zc - heights[ib]))
    if joined is not None:
        return knee_unreadable(float(heights[joined[0]] - heights[ib]), joined[1], "the ankle")
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
    # how far above the foot's first section this "ankle" lies (None: no foot below it).
    # A foot is told by its shape, not its girth alone: the foot's elongated sections (the
    # heel and instep) begin within FOOT_SHAPE_REACH_MM below its first wide section.  A
    # knee waist read upside down has the thigh below it, as wide but round
    foot_mm = float(heights[down[foot[0]]]) if foot.size else None
    if foot_mm is not None and not (ok & profile.footlike & (heights <= foot_mm)
                                    & (heights >= foot_mm - FOOT_SHAPE_REACH_MM)).any():
        foot_mm = None
    above_foot = None if foot_mm is None else float(heights[ib]) - foot_mm
    if above_foot is not None and above_foot > MAX_ANKLE_ABOVE_FOOT_MM:
        # no narrower leg between it and a foot far below: the knee waist over a swollen
        # lower leg, the thigh above it taken for a calf
        return calf_without_bulge(
            f"no ankle waist above the foot: from the foot up to the narrowest girth below the bulge at {g[ic]:.0f} "
            f"mm ({g[ib]:.0f} mm, {above_foot:.0f} mm above the foot, where an ankle lies at most "
            f"{MAX_ANKLE_ABOVE_FOOT_MM:.0f} mm above it) the leg is nowhere narrower, so that girth is a knee waist "
            "and the bulge above it the thigh"
        )
    # the ankle stands on its foot (here, or on an earlier profile of the leg): the foot,
    # not the knee waist's width, tells the ends apart, and the calf need bulge less
    on_foot = above_foot is not None or profile.on_foot
    least = MIN_CALF_RATIO_ON_FOOT if on_foot else MIN_CALF_RATIO
    if g[ic] < least * g[ib]:
        bulge = (f"no calf bulge: the largest girth above the ankle ({g[ic]:.0f} mm) is less than "
                 f"{least:.2f} x the ankle girth ({g[ib]:.0f} mm)")
        if above_foot is not None:  # an ankle on its foot: the leg itself does not bulge
            return calf_without_bulge(f"{bulge}, {above_foot:.0f} mm above the foot")
        return no_calf(bulge)
    lo, hi = zc + KNEE_ABOVE_CALF_MM[0], zc + KNEE_ABOVE_CALF_MM[1]
    above = (heights >= lo) & (heights <= hi) & ok
    if not above.any():
        return no_knee(top - zc)
    minima = np.flatnonzero(above & local_min)
    if minima.size:
        id_ = minima[np.argmin(g[minima])]
    else:  # no distinct minimum: the girth levels off and rises; D is the window's bottom
        id_ = np.flatnonzero(above)[0]
    merge = merged_above(heights, raw, int(id_), 150.0)
    if merge is not None:
        # the rise above D must be the leg's own: where another limb joins the sections
        # above it, the leg's own sections end at the join as at a scan's edge, and the
        # waist must be reached there (waists.minimum_reached_at_edge: levelled off, or
        # within a tape's resolution).  The smoothed profile rises into the join over a
        # few sigma, and that rise made a minimum of a leg still narrowing 0.7 mm per mm
        # into the other leg's knee: cD 26 mm over the knee waist's (benchmarks/other_leg.py
        # 24 3, case 13: the other leg cut at its calf, touching this one at the knee)
        own = np.where(heights < heights[merge[0]], raw, np.nan)
        edge = float(heights[np.isfinite(own)][-1])
        if not minimum_reached_at_edge(heights, own, edge, -1):
            return knee_unreadable(float(heights[merge[0]] - zc), merge[1])
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
    # the knee waist is thicker than the ankle (D >= MIN_KNEE_RATIO x B), which tells the
    # knee's end from the ankle's where nothing else does; an ankle on its foot is told by
    # the foot, and a swollen ankle may be wider than its knee waist
    if not on_foot and g[id_] < MIN_KNEE_RATIO * g[ib]:
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
        b_edge, d_edge, on_foot,
    )


def on_a_larger_calfs_flank(profile: GirthProfile, candidate: FeatureHeights) -> bool:
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

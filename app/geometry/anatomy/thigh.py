"""The order form's points above the calf, measured from the scan as a tape would: E, the
middle of the knee; G, the top of the thigh below the gluteal fold; F, the middle of the
thigh between them (RAL-GZ 387's cE, cF, cG, a thigh-high AG stocking's points).

Frame: the calf frame (mm; z up the leg from B = 0, y anterior, x the subject's right).
Arrays: points (n, 3), faces (f, 3) or None.  Girths are tape girths (the convex hull of
the section, :func:`app.geometry.sections.tape_girths`) in planes perpendicular to the
leg's axis, every STEP_MM from D across the knee, every PROFILE_STEP_MM on up to G, and
at E, F and G themselves.  Heights are along the calf frame's z: on a standing
leg the thigh continues the shank's axis within a few degrees (the femur's 5-9 degree
valgus tilts the plane by as much; a tape reads cos 7 deg = 0.7% more); a bent knee (its
thigh cut free of the shank by the placement) has no thigh here, and says so.

- **E, the middle of the knee**: the middle of the knee's level stretch
  (:mod:`app.geometry.anatomy.knee_middle` finds it and says how uncertain it is).
- **G, the top of the thigh.**  Behind the thigh the skin runs down from the buttock into
  the thigh's back at the gluteal fold, a corner in the posterior profile (the rearmost
  point of each STEP_MM of height) where the profile's slope turns from the thigh's
  gentle one to the buttock's steep one.  G is that corner: where the slope drops
  between the thigh's back (100 mm above E) and the buttock's rearmost point, the
  centroid of the drop beyond what a thigh's back without a fold has - where the
  tangents to the profile either side of the fold meet, the crease itself on a crease;
  :mod:`app.geometry.anatomy.gluteal_fold` finds it.  A scan without a buttock (its
  rearmost point at the scan's top, as a body's leg cut by the placement below the hips
  has) has no G; a back whose largest bend is under FOLD_MIN_BEND has none found, and
  says so with the bend it has.  A fold smoother than a crease (its peak wider than a
  corner's) is measured with a warning that gives how uncertain cG is.
- **F** is halfway between E and G (RAL-GZ 387: the middle of the thigh).

Something lying against the thigh below G (a hand hanging at the side) leaves the thigh
beneath it out of the scan: G, and F halfway to it, are then not measured
(:mod:`app.geometry.anatomy.thigh_contact`); where it hides the fold itself, F and G
give it as their reason.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from app.geometry.anatomy.gluteal_fold import gluteal_fold, posterior_profile
from app.geometry.anatomy.knee_middle import KNEE_WINDOW_MM, girth_slope, middle_of_the_knee
from app.geometry.anatomy.landmark_refusals import SCAN_STRAIGHT
from app.geometry.anatomy.level_points import GIRTH_TOLERANCE_MM, LevelPoint, girth_spread, level_on_section, read_across_tape
from app.geometry.anatomy.level_runs import SLOPE_HALF_MM, STEP_MM, gaps_filled
from app.geometry.anatomy.side import outer_side_angle
from app.geometry.anatomy.thigh_contact import ABOVE_G_MM, CONTACT_FROM_E_MM, ThighContact, thigh_contact
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.sections import LimbGraph, PolarSections, tape_sections

#: the stored thigh profile's spacing, mm (a knitting specification's usual step)
PROFILE_STEP_MM = 5.0
#: the thigh's back, where the fold's chord starts: this far above E, mm
THIGH_BACK_ABOVE_E_MM = 100.0
#: a knee bent but read straight (the placement cuts a thigh free only where the bend
#: splits the leg's centre line into two long runs): the line through the centroids of
#: the sections from THIGH_AXIS_FROM_D_MM above D (above the knee joint) to the top of
#: E's window leaves the shank's axis (the frame's z) by more than MAX_THIGH_TILT_DEG.
#: Measured (benchmarks/results/robustness.md's corpus, the real legs in tests/data):
#: the three real standing legs 3.0-6.1 degrees (the femur's valgus, 5-9 degrees in
#: anatomy texts, tilts the thigh); the corpus's seated legs read straight 30.6-51
#: degrees, their "cE" 464-760 mm where a knee is 350-450 round.  15 degrees leaves
#: room for a standing knee held slightly flexed, where a tape across the shank's axis
#: reads a thigh 1/cos 15 = 3.5% long
THIGH_AXIS_FROM_D_MM = 80.0
MAX_THIGH_TILT_DEG = 15.0
#: the farthest a gluteal fold lies above E, mm: ANSUR II's crotch height less its
#: mid-patella knee height is 257-456 mm over 6,068 adults (the fold lies about at crotch
#: height).  Where no fold is found, a hand at the leg's outer side, or a garment's hem,
#: is looked for up to ABOVE_G_MM over that (app.geometry.anatomy.thigh_contact)
FOLD_ABOVE_E_MAX_MM = 460.0


@dataclass(frozen=True)
class ThighMeasures:
    knee: LevelPoint  # E
    mid_thigh: LevelPoint  # F
    top_of_thigh: LevelPoint  # G
    #: the tape girth profile from D to G every PROFILE_STEP_MM, (k,) heights and (k,)
    #: girths mm, when G is measured (a thigh-high design knits from it); else empty
    profile_heights_mm: tuple[float, ...] = ()
    profile_girths_mm: tuple[float, ...] = ()
    #: what the service cannot stand behind in these points (the record's warnings)
    warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        out = {"cE": self.knee.as_dict(), "cF": self.mid_thigh.as_dict(), "cG": self.top_of_thigh.as_dict()}
        if self.profile_heights_mm:
            out["thigh_profile"] = {"heights_mm": list(self.profile_heights_mm), "tape_girth_mm": list(self.profile_girths_mm)}
        return out


def _none(reason: str, warnings: tuple[str, ...] = ()) -> ThighMeasures:
    return ThighMeasures(LevelPoint("E", None, None, reason), LevelPoint("F", None, None, reason),
                         LevelPoint("G", None, None, reason), warnings=warnings)


def bent_knee_warning(tilt_deg: float) -> str:
    """The record's warning for a knee bent but read straight (:data:`MAX_THIGH_TILT_DEG`):
    its knee waist and the calf's axis are read on a bent knee.

    Why: the planes across the shank near the knee meet the back of the thigh, whose
    underside closes on the knee's hollow, and a seated knee's waist is not a standing
    one's.  Measured on the generated seated legs the placement reads straight (knees
    bent 34-82 degrees; benchmarks/robustness.py 220 with seeds 7, 11 and 13: 22 fits,
    the thigh leaving the shank's axis by 31-55 degrees): cD off by up to 4.6 mm (median
    1.35, p95 4.2), lD by up to 6.8 and lC by up to 5.4, where the 57 standing legs that
    reach the thigh (ankle_to_thigh, two_legs) stayed within 2.5 mm of cD (median 0.3),
    3.7 of lD and 1.9 of lC.  An order's tolerance on cD is 4 mm
    (benchmarks/results/robustness.md), so the record says so rather than stand behind
    them."""
    return (f"the knee is bent (above the knee waist D the leg leaves the shank's axis by {tilt_deg:.0f} degrees; a "
            f"standing leg's by less than {MAX_THIGH_TILT_DEG:.0f}): cD and lD are read at the waist of a bent knee, "
            "whose hollow the back of the thigh closes on, and lC along the shank below it, so they may be off by more "
            "than an order's tolerance (4 mm of cD); take cD, lC and lD with the leg straight, or scan standing")


def _thigh_tilt_deg(heights: np.ndarray, sections: PolarSections, d_mm: float) -> float | None:
    """Angle (degrees) between the calf frame's z and the least-squares line through the
    centroids of ``sections`` at ``heights`` (k,) mm from THIGH_AXIS_FROM_D_MM above D
    up; None with fewer than 4 closed sections there."""
    rows = (heights >= d_mm + THIGH_AXIS_FROM_D_MM) & sections.valid
    if rows.sum() < 4:
        return None
    drift = np.polyfit(heights[rows], sections.centroids_mm[rows], 1)[0]  # (2,) mm of x, y per mm of z
    return float(np.degrees(np.arctan(np.hypot(drift[0], drift[1]))))


def _knee_span(d_mm: float, top_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The heights (k,) every STEP_MM from D to below the scan's top ``top_mm``, and which
    of them (k,) bool lie in E's window and its slope's reach (the knee's sections)."""
    heights = np.arange(d_mm, top_mm - STEP_MM, STEP_MM)
    return heights, heights <= d_mm + KNEE_WINDOW_MM[1] + SLOPE_HALF_MM + STEP_MM


#: the refusals of a calf read straight that a bent knee explains: its sections open or
#: not closed where the planes across the shank cut the thigh or the buttock too
KNEE_BENT_CAUSES = (FailureReason.PARTIAL_VIEW, FailureReason.NOT_A_LEG)


def bent_knee_refusal(failure: FitFailure, points: np.ndarray, faces: np.ndarray | None, d_mm: float,
                      edges: LimbGraph | None = None) -> FitFailure:
    """``failure`` of a calf the placement read straight (knee waist D at ``d_mm``), said
    as what it is when the knee is bent: ``knee_bent`` when the failure is one of
    :data:`KNEE_BENT_CAUSES` and the leg above D leaves the shank's axis by more than
    MAX_THIGH_TILT_DEG (:func:`_thigh_tilt_deg`, the test that warns of a bent knee on a
    fit); else ``failure`` itself.

    Why: a knee bent 82-98 degrees (a leg scanned seated) puts the back of the thigh and
    the buttock in the planes across the shank at the calf and the knee waist; the
    sections then hold two pieces, their rays are cast from between them, and the calf
    is refused as seen from one side ("scan all round the leg": benchmarks/robustness.py
    220 11 seated-02, -07, -09 and 220 13 seated-04), which sends the clinic the wrong way.
    Their thighs leave the shank's axis by 51-61 degrees (the seated legs fitted with the
    bent-knee warning by 31-55), a standing leg's by less than 8.  points (n, 3)
    calf-frame mm, faces (f, 3) or None."""
    if failure.reason not in KNEE_BENT_CAUSES or not len(points):
        return failure
    heights, knee = _knee_span(d_mm, float(points[:, 2].max()))
    heights = heights[knee & (heights >= d_mm + THIGH_AXIS_FROM_D_MM)]
    if len(heights) < 4:
        return failure
    tilt = _thigh_tilt_deg(heights, tape_sections(points, faces, heights, edges), d_mm)
    if tilt is None or tilt <= MAX_THIGH_TILT_DEG:
        return failure
    return FitFailure(
        FailureReason.KNEE_BENT,
        f"the knee is bent: above the knee the leg leaves the shank's axis by {tilt:.0f} degrees (a standing leg's "
        f"by less than {MAX_THIGH_TILT_DEG:.0f}), and the planes a tape lies in across the calf and below the knee cut "
        "the thigh or the buttock too, so the calf's girths cannot be read from this scan (read as "
        f"{failure.reason.value}). {SCAN_STRAIGHT}")


def _covered(knee: LevelPoint, contact: ThighContact, warnings: tuple[str, ...]) -> ThighMeasures:
    """E as read, and F and G not measured for what lies against the thigh (said in the warnings too)."""
    reason = contact.reason()
    return ThighMeasures(knee, LevelPoint("F", None, None, reason), LevelPoint("G", None, None, reason),
                         warnings=warnings + (f"cF and cG not measured: {reason}",))


def _contact_without_fold(points: np.ndarray, faces: np.ndarray | None, edges: LimbGraph | None, d_mm: float,
                          e_mm: float, top_mm: float, side: str | None) -> ThighContact | None:
    """Something against a thigh whose gluteal fold was not found: every arc judged up to
    where the fold is first looked for (THIGH_BACK_ABOVE_E_MM over E, below any fold),
    then the arcs at the leg's outer side, and a garment's hem all round, up to
    ABOVE_G_MM over the highest a fold lies (FOLD_ABOVE_E_MAX_MM over E) or the scan's
    top (app.geometry.anatomy.thigh_contact; a loose garment hides the fold as a hand
    does, and bare thighs' median moves stayed under 5 mm there: the three real legs to
    their tops, 4.9).  It changes only the reason F and G give: they are not measured
    either way."""
    reach = min(e_mm + FOLD_ABOVE_E_MAX_MM + ABOVE_G_MM, top_mm - STEP_MM)
    planes = np.arange(d_mm, reach, PROFILE_STEP_MM)
    sections = tape_sections(points, faces, planes, edges)
    return thigh_contact(sections, np.arange(len(planes)), e_mm + CONTACT_FROM_E_MM, e_mm + THIGH_BACK_ABOVE_E_MM,
                         outer_side_angle(side), outer_to_mm=reach, hem_to_mm=reach)


def thigh_measures(points: np.ndarray, faces: np.ndarray | None, d_mm: float, knee_bent: bool,
                   edges: LimbGraph | None = None, side: str | None = None) -> ThighMeasures:
    """E, F, G of the module docstring (mm), or why not; ``edges``: a sparse cloud's
    neighbour graph, its girths read where the edges cross the tape's planes
    (app.geometry.sections.tape_sections); ``side`` ("left", "right" or None): the leg's,
    where a hand against it hangs (app.geometry.anatomy.thigh_contact)."""
    if knee_bent:
        return _none("the knee is bent: the thigh is cut free of the shank (a thigh-high stocking is measured standing)")
    top = float(points[:, 2].max())
    if top < d_mm + KNEE_WINDOW_MM[1] + SLOPE_HALF_MM:
        return _none(f"the scan ends {top - d_mm:.0f} mm above D, below the top of the knee")
    heights, knee_span = _knee_span(d_mm, top)
    # girths every STEP_MM only where E is searched (its window and the slope's reach):
    # above it only F, G and the profile's PROFILE_STEP_MM planes are read, each plane a
    # section of its own (tape_sections), so the thigh's sections cost a third of reading
    # every STEP_MM up to the scan's top (benchmarks/bench_fit.py)
    knee_sections = tape_sections(points, faces, heights[knee_span], edges)
    girth = np.full(len(heights), np.nan)
    girth[knee_span] = knee_sections.tape_perimeters()
    tilt = _thigh_tilt_deg(heights[knee_span], knee_sections, d_mm)
    if tilt is not None and tilt > MAX_THIGH_TILT_DEG:
        return _none(f"the knee is bent: above it the leg leaves the shank's axis by {tilt:.0f} degrees (a standing "
                     f"leg's thigh by less than {MAX_THIGH_TILT_DEG:.0f}), so a tape across the shank's axis would cut "
                     "the knee and thigh obliquely (a thigh-high stocking is measured standing)",
                     (bent_knee_warning(tilt),))
    slope = girth_slope(heights, girth)
    window = (heights >= d_mm + KNEE_WINDOW_MM[0]) & (heights <= d_mm + KNEE_WINDOW_MM[1]) & np.isfinite(slope)
    if not window.any():
        return _none("the knee has no closed sections in the scan (a hole or a crop)")
    middle = middle_of_the_knee(points, faces, heights, knee_sections, girth, slope, window, edges)
    knee, e_mm, warnings = middle.point, middle.height_mm, middle.warnings
    # G: the gluteal fold, the corner of the posterior profile below the buttock
    rear = posterior_profile(points, faces, heights, edges)
    fold = gluteal_fold(heights, rear, e_mm + THIGH_BACK_ABOVE_E_MM, top)
    if fold.height_mm is None:
        # a hand or a loose garment on the thigh can hide the fold from the back's
        # profile (a hand did in 11 of 57 hands covering G, benchmarks/hand_on_thigh.py
        # 8 21 and 12 22): say so, and what to do, rather than that no fold was found
        contact = _contact_without_fold(points, faces, edges, d_mm, e_mm, top, side)
        if contact is not None:
            return _covered(knee, contact, warnings)
        return ThighMeasures(knee, LevelPoint("F", None, None, fold.reason), LevelPoint("G", None, None, fold.reason),
                             warnings=warnings)
    g_mm = fold.height_mm
    f_mm = (e_mm + g_mm) / 2
    profile_z = np.unique(np.r_[np.arange(d_mm, g_mm, PROFILE_STEP_MM), g_mm])  # D ... G, G included
    # and above G as far as it may lie (its uncertainty, within the scan): cG's uncertainty
    # is read on the girths either side of it
    g_height = fold.height_uncertainty_mm
    over_g = np.r_[np.arange(g_mm + PROFILE_STEP_MM, g_mm + g_height, PROFILE_STEP_MM), g_mm + g_height]
    # and every PROFILE_STEP_MM from D to ABOVE_G_MM over G, where a hand is looked for
    contact_z = np.arange(d_mm, min(g_mm + ABOVE_G_MM, top - STEP_MM), PROFILE_STEP_MM)
    planes = np.unique(np.r_[profile_z, f_mm, over_g[(over_g > g_mm) & (over_g < top - STEP_MM)], contact_z])
    sections = tape_sections(points, faces, planes, edges)
    planes_girth = sections.tape_perimeters()
    top_of_thigh = level_on_section("G", sections, planes_girth, int(np.searchsorted(planes, g_mm)))
    if top_of_thigh.girth_mm is None:
        reason = "the section at the gluteal fold is not closed (a hole, or the scan's edge)"
        return ThighMeasures(knee, LevelPoint("F", None, None, reason), LevelPoint("G", None, None, reason),
                             warnings=warnings)
    # a hand or anything else against the thigh below G, or at its outer side just over
    # G: the thigh beneath it is not in the scan, and the back's profile G was read on
    # passes it (a hand held towards the back moved G down to its fingertips), so neither
    # G nor F, halfway to it, is measured (app.geometry.anatomy.thigh_contact)
    contact = thigh_contact(sections, np.searchsorted(planes, contact_z), e_mm + CONTACT_FROM_E_MM, g_mm,
                            outer_side_angle(side))
    if contact is not None:
        return _covered(knee, contact, warnings)
    mid_thigh, top_of_thigh = read_across_tape(
        (level_on_section("F", sections, planes_girth, int(np.searchsorted(planes, f_mm))), top_of_thigh), points, faces, edges)
    # a plane without a closed section: read between its neighbours
    profile_g = gaps_filled(profile_z, planes_girth[np.searchsorted(planes, profile_z)])
    # a fold smoother than a crease: G is uncertain by the fold's own half extent (or by
    # how far its middle moves with the level its extent is read at), and cG by the most
    # the girth changes within that of G (girth_spread: the girth's slope below G alone
    # understated it where it steepens into the buttock above G - a held-out re-scan's cG
    # read 3.5 mm off and said nothing, benchmarks/chart_accuracy.py 8 5); said when that
    # is more than an order's tolerance.  F lies halfway: its height is uncertain by half
    # of E's and G's (said or not: F's girth rises faster than the knee's), its girth by
    # the most it changes within that of F
    g_girth = girth_spread(planes, planes_girth, g_mm, g_height)
    g_uncertain = g_girth > GIRTH_TOLERANCE_MM
    f_height = (middle.height_uncertainty_mm + g_height) / 2
    f_girth = girth_spread(planes, planes_girth, f_mm, f_height)
    if f_girth > GIRTH_TOLERANCE_MM:
        mid_thigh = dataclasses.replace(mid_thigh, uncertainty_mm=f_girth)
    if g_uncertain:
        top_of_thigh = dataclasses.replace(top_of_thigh, uncertainty_mm=g_girth)
        warnings = warnings + (
            f"{fold.uncertainty_text}, over which the thigh's girth changes by up "
            f"to {g_girth:.0f} mm, so cG and lG (and F, halfway to it) are uncertain by about {g_girth:.0f} mm of "
            f"cG; a tape just below the fold decides",)
    # where E, F and G may lie, for their lengths from the floor (F halfway: half of E's and G's)
    mid_thigh = dataclasses.replace(mid_thigh, height_uncertainty_mm=float(f_height))
    top_of_thigh = dataclasses.replace(top_of_thigh, height_uncertainty_mm=float(g_height))
    return ThighMeasures(knee, mid_thigh, top_of_thigh, tuple(float(z) for z in profile_z), tuple(float(v) for v in profile_g),
                         warnings)

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

- **E, the middle of the knee.**  Going up from the knee waist D the girth rises over the
  knee's bulge (the femoral condyles and the patella), stays nearly level across it, and
  rises again along the thigh.  E is the middle of that level stretch: of the run of
  heights round the smallest girth slope (the slope of a least-squares spline through
  the knee's sections, :func:`_girth_slope`, searched between D + 20 mm and D + 150 mm)
  whose slope stays within KNEE_LEVEL_SLOPE of it, its ends read between the STEP_MM
  samples where the slope crosses that bound (:func:`run_between_crossings`).
  ANSUR II puts the mid-patella 17 +- 9 mm above the tibial plateau (6,068 subjects); on
  the Visible Human male, whose D is 456 mm above the floor, E lands 50 mm above D, where
  the ANSUR proportions of a 1.8 m man put the mid-patella.
- **G, the top of the thigh.**  Behind the thigh the skin runs down from the buttock into
  the thigh's back at the gluteal fold, a corner in the posterior profile (the rearmost
  point of each STEP_MM of height) where the profile's slope turns from the thigh's
  gentle one to the buttock's steep one.  G is that corner: the largest drop of the
  slope between the thigh's back (100 mm above E) and the buttock's rearmost point, read
  as the middle of the drop's peak (its full width at half maximum, read between the
  samples: the largest drop alone wanders along a smooth fold's flat peak);
  :mod:`app.geometry.anatomy.gluteal_fold` finds it.  A scan without a buttock (its
  rearmost point at the scan's top, as a body's leg cut by the placement below the hips
  has) has no G; a back whose largest bend is under FOLD_MIN_BEND has none found, and
  says so with the bend it has.  A fold smoother than a crease (its peak wider than a
  corner's) is measured with a warning that gives how uncertain cG is.
- **F** is halfway between E and G (RAL-GZ 387: the middle of the thigh).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_lsq_spline

from app.geometry.anatomy.gluteal_fold import gluteal_fold, posterior_profile
from app.geometry.anatomy.level_runs import SLOPE_HALF_MM, STEP_MM, run_between_crossings
from app.geometry.sections import PolarSections, tape_band_girths, tape_sections

#: the stored thigh profile's spacing, mm (a knitting specification's usual step)
PROFILE_STEP_MM = 5.0
#: the knee's level stretch is searched this far above D, mm
KNEE_WINDOW_MM = (20.0, 150.0)
#: the knee's level stretch: slopes within this of the least one, mm of girth per mm of height
#: (the knee's crown rises 0.1-0.3, the thigh ~1)
KNEE_LEVEL_SLOPE = 0.15
#: the knot spacing of the spline whose slope E is read on (:func:`_girth_slope`), mm:
#: coarse enough to average the sections' noise, fine enough for a knee's level
#: stretch (14-39 mm long on the five real legs of tests/data, read on the local
#: slope).  Measured on chart_accuracy 8 11's scans (E found again on each scan's
#: captured knee sections; |a - b| over two scans of one leg, p95): lE 6.15 mm with
#: the local slope, 4.08 / 3.55 / 3.70 with knots every 30 / 40 / 50 mm, cE (the plane
#: at E) 3.02 against 2.03 / 1.48 / 1.65; 20 mm was as noisy as the local slope.  On
#: the real legs E moves at most 5 mm (BodyParts3D's, whose crown is the shortest)
KNEE_SLOPE_KNOT_MM = 40.0
#: E's uncertainty: E read again with the level band this many times as wide.  On the 8
#: generated legs' 88 scans (benchmarks/chart_accuracy.py 8 11) every re-scan whose cE
#: lies more than 3 mm off its leg's clean scan then states an uncertainty that holds (3
#: of 3, 30 of 30 stated), and a leg's re-scans agree on whether cE is uncertain; from the
#: crownless run's length alone, 2 of the 3 stated one, 1 that held, and the same leg's
#: scans disagreed
KNEE_LEVEL_SLOPE_JUDGED = (0.5, 1.5)
#: a made-to-measure order's girths are held to this (mm): an E whose height is uncertain
#: by more than this much of cE is said to be
GIRTH_TOLERANCE_MM = 3.0
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


@dataclass(frozen=True)
class LevelPoint:
    """A point of the leg at a height: ``girth_mm`` (tape) and ``height_mm`` (calf
    frame), or None with the ``reason``; ``at_mm``: the centre of the tape's section
    (x, y, height), where its plane crosses the limb (the workbench draws the tape there)."""

    name: str
    girth_mm: float | None
    height_mm: float | None
    reason: str | None = None
    at_mm: tuple[float, float, float] | None = None
    #: how far the girth may be off (mm) where the scan leaves the point's place uncertain
    #: by more than GIRTH_TOLERANCE_MM of girth (a knee without a level crown, a smooth
    #: gluteal fold); the record's warnings say why.  None: within the tolerance
    uncertainty_mm: float | None = None

    def as_dict(self) -> dict:
        out: dict = {"value_mm": self.girth_mm, "height_mm": self.height_mm, "reason": self.reason}
        if self.at_mm is not None:
            out["at_mm"] = list(self.at_mm)
        if self.uncertainty_mm is not None:
            out["uncertainty_mm"] = self.uncertainty_mm
        return out


def _girth_slope(heights: np.ndarray, girth: np.ndarray) -> np.ndarray:
    """d girth / d height (k,) of the girths (k,) at ``heights`` (k,) every STEP_MM, mm
    per mm: the derivative of the least-squares cubic B-spline through the measured
    girths with interior knots every KNEE_SLOPE_KNOT_MM (scipy's ``make_lsq_spline``; The
    NURBS Book section 9.4.1's least-squares curve), where :func:`_local_girth_slope`
    has a slope (not where a missing section or the profile's end lies within
    +-SLOPE_HALF_MM).  E is where the slope crosses a bound a little above its least
    value, and a knee's slope changes slowly (0.5 to 1 mm/mm over 130 mm, 0.004 per mm):
    the local slope's noise (0.05 mm/mm for 1 mm of girth noise) moves that crossing by
    about 13 mm, the spline's, fitted to every section of the knee, by a few.  Where the
    sections leave a knot's span empty (a hole) so that the spline cannot be fitted, the
    local slope."""
    local = _local_girth_slope(girth)
    measured = np.isfinite(girth)
    x, y = heights[measured], girth[measured]
    if len(x) < 8:
        return local
    inner = np.arange(x[0] + KNEE_SLOPE_KNOT_MM, x[-1] - KNEE_SLOPE_KNOT_MM / 2, KNEE_SLOPE_KNOT_MM)
    knots = np.r_[[x[0]] * 4, inner, [x[-1]] * 4]
    try:
        spline = make_lsq_spline(x, y, knots, k=3)
    except (ValueError, np.linalg.LinAlgError):
        return local
    slope = np.full(len(girth), np.nan)
    has = np.isfinite(local)
    slope[has] = spline.derivative()(heights[has])
    return slope


def _local_girth_slope(girth: np.ndarray) -> np.ndarray:
    """d girth / d height (k,) of girths (k,) every STEP_MM: the slope of the
    least-squares line through the girths within +-SLOPE_HALF_MM (a Savitzky-Golay first
    derivative of order 1) - every section of the window votes, where a difference of
    the window's two end sections carries their noise whole (11 sections 2 mm apart: the
    slope's standard error sqrt(440 / 200) = 1.5 times smaller for independent noise,
    more where one section is spoiled); NaN where the window holds a missing section or
    runs off the profile.  (The gluteal fold's bend read from such slopes was tried and
    measured worse: chart_accuracy 8 11 gave cG p95 3.78 mm and lG 4.57 against 3.71 and
    3.85 with the three-sample bend, though it found G in 2 more re-scans.)"""
    lag = int(round(SLOPE_HALF_MM / STEP_MM))
    offsets = np.arange(-lag, lag + 1, dtype=np.float64)
    kernel = offsets / (STEP_MM * float((offsets**2).sum()))
    slope = np.full(len(girth), np.nan)
    if len(girth) > 2 * lag:
        windows = np.lib.stride_tricks.sliding_window_view(girth, 2 * lag + 1)
        slope[lag:-lag] = windows @ kernel
    return slope


def girth_spread(heights: np.ndarray, girths: np.ndarray, at_mm: float, half_mm: float) -> float:
    """How much a tape's girth may change when its point lies anywhere within +-``half_mm``
    of ``at_mm`` (mm): the largest |girth(z) - girth(at)| over the measured ``girths`` (k,)
    at ``heights`` (k,, rising) within that reach and at its ends, read linearly between
    them (held beyond the measured ones; NaN girths are left out).  The girth's slope at
    the point alone understates it where the girth turns within the reach: above a
    smooth gluteal fold (the buttock) or across a knee's crown."""
    measured = np.isfinite(girths)
    z, g = heights[measured], girths[measured]
    if not len(z):
        return 0.0
    inside = z[(z > at_mm - half_mm) & (z < at_mm + half_mm)]
    reach = np.interp(np.r_[at_mm - half_mm, inside, at_mm + half_mm], z, g)
    return float(np.max(np.abs(reach - np.interp(at_mm, z, g))))


def _read_across_tape(levels: tuple[LevelPoint, ...], points: np.ndarray, faces: np.ndarray | None
                      ) -> tuple[LevelPoint, ...]:
    """Each point's girth read across a tape's width (the median over the planes
    app.geometry.sections.TAPE_BAND_OFFSETS_MM about its height, as B, B1, C, D are:
    one plane spoiled by a scanner's noise or a hole's edge is outvoted), its height and
    centre kept; the single plane's girth where the band has no reading.  The points are
    read in one call: each plane's section depends on its own plane (a mesh's) or slab (a
    cloud's) only, so reading them together gives what reading each alone does."""
    readable = [i for i, level in enumerate(levels) if level.girth_mm is not None and level.height_mm is not None]
    if not readable:
        return levels
    band = tape_band_girths(points, faces, np.array([levels[i].height_mm for i in readable]))
    read = list(levels)
    for i, girth in zip(readable, band):
        if np.isfinite(girth):
            read[i] = dataclasses.replace(levels[i], girth_mm=float(girth))
    return tuple(read)


def _level(name: str, sections: PolarSections, girths: np.ndarray, index: int) -> LevelPoint:
    """The point ``name`` read on section ``index`` of ``sections`` (its tape girth, of
    ``girths`` (k,) the sections' tape perimeters, and its centre), or not closed there."""
    girth = float(girths[index])
    height = float(sections.heights_mm[index])
    if not np.isfinite(girth):
        return LevelPoint(name, None, None, "the section there is not closed (a hole, or the scan's edge)")
    centre = sections.centroids_mm[index]
    return LevelPoint(name, girth, height, at_mm=(float(centre[0]), float(centre[1]), height))


def _level_between(name: str, sections: PolarSections, girths: np.ndarray, height_mm: float) -> LevelPoint:
    """The point ``name`` at ``height_mm``, between two of ``sections`` (evenly spaced):
    its girth and centre read linearly between theirs (a tape's reading across its width,
    :func:`_read_across_tape`, then replaces the girth), or not closed there when either
    of the two sections is not."""
    z = sections.heights_mm
    below = int(np.clip(np.searchsorted(z, height_mm, side="right") - 1, 0, len(z) - 2)) if len(z) > 1 else 0
    above = min(below + 1, len(z) - 1)
    t = float(np.clip((height_mm - z[below]) / (z[above] - z[below]), 0.0, 1.0)) if above != below else 0.0
    weights = np.array([1 - t, t])
    pair = girths[[below, above]]
    if not np.isfinite(pair[weights > 0]).all():
        return LevelPoint(name, None, None, "the section there is not closed (a hole, or the scan's edge)")
    centre = weights[weights > 0] @ sections.centroids_mm[[below, above]][weights > 0]
    girth = float(weights[weights > 0] @ pair[weights > 0])
    return LevelPoint(name, girth, float(height_mm), at_mm=(float(centre[0]), float(centre[1]), float(height_mm)))


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


def _none(reason: str) -> ThighMeasures:
    return ThighMeasures(LevelPoint("E", None, None, reason), LevelPoint("F", None, None, reason),
                         LevelPoint("G", None, None, reason))


@dataclass(frozen=True)
class KneeMiddle:
    """E found: the point, its height (mm; read even where its section is not closed),
    how uncertain that height is (mm, said in the warnings or not: F inherits half of it)
    and the warning when cE is uncertain by more than GIRTH_TOLERANCE_MM."""

    point: LevelPoint
    height_mm: float
    height_uncertainty_mm: float
    warnings: tuple[str, ...]


def _middle_of_the_knee(points: np.ndarray, faces: np.ndarray | None, heights: np.ndarray, knee_sections: PolarSections,
                        girth: np.ndarray, slope: np.ndarray, window: np.ndarray) -> KneeMiddle:
    """E (module docstring) on ``heights`` (k,) every STEP_MM from D, whose prefix
    ``knee_sections`` are, with their tape ``girth`` (k,; NaN above them), its ``slope``
    (k,) and the ``window`` (k,) E is searched in."""
    # the level stretch: the run of heights round the least slope whose slope stays within
    # KNEE_LEVEL_SLOPE of it; E is its middle (the least slope alone wanders along a flat
    # stretch with a scanner's noise), as C is the middle of the calf's crown
    inside = np.flatnonzero(window)
    least = int(inside[np.argmin(slope[inside])])
    level = run_between_crossings(heights, slope, window, least, slope[least] + KNEE_LEVEL_SLOPE)
    e_mm = level.middle_mm
    # knee_span is a prefix of heights: its sections are indexed as heights are
    (knee,) = _read_across_tape((_level_between("E", knee_sections, girth, e_mm),), points, faces)
    warnings: tuple[str, ...] = ()
    crownless = bool(least in (inside[0], inside[-1]))
    # how far E moves with the level band's width, a judgement (KNEE_LEVEL_SLOPE): E read
    # with the band half and one and a half times as wide; a crown's sharp ends keep it
    # in place, a knee whose slope rises slowly through the band's bound lets it wander
    moved_mm = 0.0
    for factor in KNEE_LEVEL_SLOPE_JUDGED:
        z = run_between_crossings(heights, slope, window, least, slope[least] + factor * KNEE_LEVEL_SLOPE).middle_mm
        moved_mm = max(moved_mm, abs(z - e_mm))
    if crownless:
        # the least slope at the window's end: no level crown to find (the girth rises
        # all the way through the knee, as on every generated MakeHuman leg): E may lie
        # anywhere along the least-rising stretch, half its length either way
        moved_mm = max(moved_mm, (level.top_mm - level.bottom_mm) / 2.0)
    # cE is uncertain by the most its girth changes within that reach of E (the least
    # slope times the reach understated it where the girth's rise steepens: a re-scan's
    # cE read 4.3 mm off where 3.5 were said, benchmarks/chart_accuracy.py 8 3)
    moved_girth = girth_spread(heights, girth, e_mm, moved_mm)
    e_uncertain = bool(knee.height_mm is not None and moved_girth > GIRTH_TOLERANCE_MM)
    if e_uncertain:
        knee = dataclasses.replace(knee, uncertainty_mm=moved_girth)
        # said when that moves cE by more than an order's girths are held to
        why = (f"the knee shows no level crown: its girth rises at least {slope[least]:.1f} mm per mm of height "
               f"from {KNEE_WINDOW_MM[0]:.0f} to {KNEE_WINDOW_MM[1]:.0f} mm above D, so E (cE, lE) is the middle "
               f"of its least-rising stretch" if crownless else
               "the knee's level stretch has no sharp ends (its girth's slope leaves the level slowly), so E (cE, lE), "
               "its middle, moves with where the stretch is taken to end")
        warnings = (f"{why}, uncertain by about {moved_mm:.0f} mm of height and {moved_girth:.0f} mm of cE; "
                    f"a tape at the middle of the patella decides",)
    return KneeMiddle(knee, e_mm, moved_mm, warnings)


def _thigh_tilt_deg(heights: np.ndarray, sections: PolarSections, d_mm: float) -> float | None:
    """Angle (degrees) between the calf frame's z and the least-squares line through the
    centroids of ``sections`` at ``heights`` (k,) mm from THIGH_AXIS_FROM_D_MM above D
    up; None with fewer than 4 closed sections there."""
    rows = (heights >= d_mm + THIGH_AXIS_FROM_D_MM) & sections.valid
    if rows.sum() < 4:
        return None
    drift = np.polyfit(heights[rows], sections.centroids_mm[rows], 1)[0]  # (2,) mm of x, y per mm of z
    return float(np.degrees(np.arctan(np.hypot(drift[0], drift[1]))))


def thigh_measures(points: np.ndarray, faces: np.ndarray | None, d_mm: float, knee_bent: bool) -> ThighMeasures:
    """E, F, G of the module docstring (mm), or why not."""
    if knee_bent:
        return _none("the knee is bent: the thigh is cut free of the shank (a thigh-high stocking is measured standing)")
    top = float(points[:, 2].max())
    if top < d_mm + KNEE_WINDOW_MM[1] + SLOPE_HALF_MM:
        return _none(f"the scan ends {top - d_mm:.0f} mm above D, below the top of the knee")
    heights = np.arange(d_mm, top - STEP_MM, STEP_MM)
    # girths every STEP_MM only where E is searched (its window and the slope's reach):
    # above it only F, G and the profile's PROFILE_STEP_MM planes are read, each plane a
    # section of its own (tape_sections), so the thigh's sections cost a third of reading
    # every STEP_MM up to the scan's top (benchmarks/bench_fit.py)
    knee_span = heights <= d_mm + KNEE_WINDOW_MM[1] + SLOPE_HALF_MM + STEP_MM
    knee_sections = tape_sections(points, faces, heights[knee_span])
    girth = np.full(len(heights), np.nan)
    girth[knee_span] = knee_sections.tape_perimeters()
    tilt = _thigh_tilt_deg(heights[knee_span], knee_sections, d_mm)
    if tilt is not None and tilt > MAX_THIGH_TILT_DEG:
        return _none(f"the knee is bent: above it the leg leaves the shank's axis by {tilt:.0f} degrees (a standing "
                     f"leg's thigh by less than {MAX_THIGH_TILT_DEG:.0f}), so a tape across the shank's axis would cut "
                     "the knee and thigh obliquely (a thigh-high stocking is measured standing)")
    slope = _girth_slope(heights, girth)
    window = (heights >= d_mm + KNEE_WINDOW_MM[0]) & (heights <= d_mm + KNEE_WINDOW_MM[1]) & np.isfinite(slope)
    if not window.any():
        return _none("the knee has no closed sections in the scan (a hole or a crop)")
    middle = _middle_of_the_knee(points, faces, heights, knee_sections, girth, slope, window)
    knee, e_mm, warnings = middle.point, middle.height_mm, middle.warnings
    # G: the gluteal fold, the corner of the posterior profile below the buttock
    rear = posterior_profile(points, faces, heights)
    fold = gluteal_fold(heights, rear, e_mm + THIGH_BACK_ABOVE_E_MM, top)
    if fold.height_mm is None:
        return ThighMeasures(knee, LevelPoint("F", None, None, fold.reason), LevelPoint("G", None, None, fold.reason),
                             warnings=warnings)
    g_mm = fold.height_mm
    f_mm = (e_mm + g_mm) / 2
    profile_z = np.unique(np.r_[np.arange(d_mm, g_mm, PROFILE_STEP_MM), g_mm])  # D ... G, G included
    # and above G as far as it may lie (its uncertainty, within the scan): cG's uncertainty
    # is read on the girths either side of it
    g_height = fold.height_uncertainty_mm
    over_g = np.r_[np.arange(g_mm + PROFILE_STEP_MM, g_mm + g_height, PROFILE_STEP_MM), g_mm + g_height]
    planes = np.unique(np.r_[profile_z, f_mm, over_g[(over_g > g_mm) & (over_g < top - STEP_MM)]])
    sections = tape_sections(points, faces, planes)
    planes_girth = sections.tape_perimeters()
    top_of_thigh = _level("G", sections, planes_girth, int(np.searchsorted(planes, g_mm)))
    if top_of_thigh.girth_mm is None:
        reason = "the section at the gluteal fold is not closed (a hole, or the scan's edge)"
        return ThighMeasures(knee, LevelPoint("F", None, None, reason), LevelPoint("G", None, None, reason),
                             warnings=warnings)
    mid_thigh, top_of_thigh = _read_across_tape(
        (_level("F", sections, planes_girth, int(np.searchsorted(planes, f_mm))), top_of_thigh), points, faces)
    profile_g = planes_girth[np.searchsorted(planes, profile_z)]
    finite = np.isfinite(profile_g)  # a plane without a closed section: read between its neighbours
    profile_g = np.interp(profile_z, profile_z[finite], profile_g[finite])
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
    if f_height > 0:
        f_girth = girth_spread(planes, planes_girth, f_mm, f_height)
        if f_girth > GIRTH_TOLERANCE_MM:
            mid_thigh = dataclasses.replace(mid_thigh, uncertainty_mm=f_girth)
    if g_uncertain:
        top_of_thigh = dataclasses.replace(top_of_thigh, uncertainty_mm=g_girth)
        extent = (f"it spans about {fold.excess_half_width_mm:.0f} mm of height either side of G beyond a crease's width"
                  if fold.excess_half_width_mm >= fold.level_shift_mm else
                  f"its bend rises along about {fold.level_shift_mm:.0f} mm of height below or above G, so where G lies "
                  f"depends on where the fold is taken to begin")
        warnings = warnings + (
            f"the gluteal fold is smooth, not a crease: {extent}, over which the thigh's girth changes by up "
            f"to {g_girth:.0f} mm, so cG and lG (and F, halfway to it) are uncertain by about {g_girth:.0f} mm of "
            f"cG; a tape just below the fold decides",)
    return ThighMeasures(knee, mid_thigh, top_of_thigh, tuple(float(z) for z in profile_z), tuple(float(v) for v in profile_g),
                         warnings)

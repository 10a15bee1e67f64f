"""E, the middle of the knee (RAL-GZ 387's cE, a thigh-high AG stocking's point), found
on the girths of the knee's sections every STEP_MM from the knee waist D.

Going up from the knee waist D the girth rises over the knee's bulge (the femoral
condyles and the patella), stays nearly level across it, and rises again along the
thigh. E is the middle of that level stretch: of the run of heights round the smallest
girth slope (the slope of a least-squares spline through the knee's sections,
:func:`girth_slope`, searched between D + 20 mm and D + 150 mm) whose slope stays within
KNEE_LEVEL_SLOPE of it, its ends read between the STEP_MM samples where the slope
crosses that bound (:func:`run_between_crossings`). ANSUR II puts the mid-patella 17 +-
9 mm above the tibial plateau (6,068 subjects); on the Visible Human male, whose D is
456 mm above the floor, E lands 50 mm above D, where the ANSUR proportions of a 1.8 m
man put the mid-patella.

The window's top is the thigh's, not the knee's, where the girth's rise slows there to
as little as anywhere in the window after peaking in between (the slope at the window's
top within KNEE_LEVEL_SLOPE of the least, and the thigh's rise more than that above it):
the thigh's rise (the last stretch of the window rising more than that over the top) is
where the knee ends and the thigh's muscles widen the leg, and above it the thigh levels
off - a stretch a tape there would read as a thigh's girth, not the knee's.  The window
is then cut at the steepest point of that rise (:func:`knee_window`).  On a real knee
the thigh rises again above its crown (the five real legs of tests/data: the slope at
the window's top 0.98-1.38 mm/mm over a crown of -0.02-0.51), so its window stays whole;
on generated MakeHuman knees, which have no crown, the two ends of the window rose
nearly alike (0.82 and 0.83 mm/mm) and a re-scan put E at the other end, 110 mm away
(benchmarks/chart_accuracy.py 8 13, legs 1 and 3).

E's uncertainty: E read again with the level stretch's bound half and one and a half
times as wide (KNEE_LEVEL_SLOPE_JUDGED), or half the least-rising stretch where the knee
has no crown, or as far as another stretch of the window whose slope is as near the
least (the least could as well lie there); cE's is the most its girth changes within that reach
(:func:`app.geometry.anatomy.level_points.girth_spread`).

Frame: the calf frame (mm; z up the leg from B = 0).  Arrays: heights (k,) every STEP_MM
from D, girths and slopes (k,).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_lsq_spline

from app.geometry.anatomy.level_points import GIRTH_TOLERANCE_MM, LevelPoint, girth_spread, level_between, read_across_tape
from app.geometry.anatomy.level_runs import SLOPE_HALF_MM, STEP_MM, run_around, run_between_crossings
from app.geometry.sections import LimbGraph, PolarSections

#: the knee's level stretch is searched this far above D, mm
KNEE_WINDOW_MM = (20.0, 150.0)
#: the knee's level stretch: slopes within this of the least one, mm of girth per mm of height
#: (the knee's crown rises 0.1-0.3, the thigh ~1)
KNEE_LEVEL_SLOPE = 0.15
#: the knot spacing of the spline whose slope E is read on (:func:`girth_slope`), mm:
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


def girth_slope(heights: np.ndarray, girth: np.ndarray) -> np.ndarray:
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


def knee_window(slope: np.ndarray, window: np.ndarray) -> np.ndarray:
    """The heights (k,) of ``window`` (k,) that can hold the knee's level stretch, given
    the girth's ``slope`` (k,, mm per mm): ``window`` cut below the thigh's steepest rise
    where the thigh levels off above it as little as anywhere below (module docstring);
    else ``window`` itself.  The thigh's rise is the last run of heights whose slope
    exceeds the top's by KNEE_LEVEL_SLOPE: a knee whose condyles rise steeply below its
    crown keeps the crown."""
    inside = np.flatnonzero(window)
    top = int(inside[-1])
    if slope[top] > slope[inside].min() + KNEE_LEVEL_SLOPE:  # the thigh still rises at the top
        return window
    # the thigh's rise: the last run of the window rising more than the band over its top
    # (not the steepest of all: a knee's condyles may rise more steeply below its crown)
    rising = window & (slope > slope[top] + KNEE_LEVEL_SLOPE)
    if not rising.any():
        return window
    last = int(np.flatnonzero(rising)[-1])
    first, _ = run_around(rising, last)
    peak = first + int(np.argmax(slope[first:last + 1]))
    if peak <= int(inside[0]):
        return window
    return window & (np.arange(len(window)) < peak)


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


@dataclass(frozen=True)
class KneeMiddle:
    """E found: the point (with how uncertain its height is, mm, said in the warnings or
    not: F inherits half of it), its height (mm; read even where its section is not
    closed) and the warning when cE is uncertain by more than GIRTH_TOLERANCE_MM."""

    point: LevelPoint
    height_mm: float
    warnings: tuple[str, ...]

    @property
    def height_uncertainty_mm(self) -> float:
        """How far E may lie from ``height_mm`` along the leg (mm): the point's own."""
        return float(self.point.height_uncertainty_mm or 0.0)


def middle_of_the_knee(points: np.ndarray, faces: np.ndarray | None, heights: np.ndarray, knee_sections: PolarSections,
                       girth: np.ndarray, slope: np.ndarray, window: np.ndarray,
                       edges: LimbGraph | None = None) -> KneeMiddle:
    """E (module docstring) on ``heights`` (k,) every STEP_MM from D, whose prefix
    ``knee_sections`` are, with their tape ``girth`` (k,; NaN above them), its ``slope``
    (k,) and the ``window`` (k,) E is searched in; ``edges`` a sparse cloud's neighbour
    graph (app.geometry.sections.tape_sections)."""
    # the level stretch: the run of heights round the least slope whose slope stays within
    # KNEE_LEVEL_SLOPE of it; E is its middle (the least slope alone wanders along a flat
    # stretch with a scanner's noise), as C is the middle of the calf's crown
    cut = knee_window(slope, window)
    cut_below = (" (where the thigh's steeper rise begins)," if cut.sum() < window.sum() else ",")
    window = cut
    inside = np.flatnonzero(window)
    least = int(inside[np.argmin(slope[inside])])
    level = run_between_crossings(heights, slope, window, least, slope[least] + KNEE_LEVEL_SLOPE)
    e_mm = level.middle_mm
    # knee_span is a prefix of heights: its sections are indexed as heights are
    (knee,) = read_across_tape((level_between("E", knee_sections, girth, e_mm),), points, faces, edges)
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
    # another stretch of the window rises as little (its slope within KNEE_LEVEL_SLOPE of
    # the least, apart from E's own run): the least slope could as well lie there, and E
    # with it.  A crownless knee's slope can be least at both ends of the window (0.669 and
    # 0.68 mm/mm on a generated leg, benchmarks/motion.py 20 17 leg 8): its clean mesh put
    # E 146 mm above D saying 4 mm of height, a cloud of it 23 mm above D - cE 134 mm apart
    rivals = inside[(slope[inside] <= slope[least] + KNEE_LEVEL_SLOPE)
                    & ((heights[inside] < level.bottom_mm) | (heights[inside] > level.top_mm))]
    rival_mm, rival_at = 0.0, 0.0  # how far from E the farthest rival lies, and its height above D
    if rivals.size:
        farthest = rivals[np.argmax(np.abs(heights[rivals] - e_mm))]
        rival_mm, rival_at = abs(float(heights[farthest]) - e_mm), float(heights[farthest] - heights[0])
    moved_mm = max(moved_mm, rival_mm)
    # cE is uncertain by the most its girth changes within that reach of E (the least
    # slope times the reach understated it where the girth's rise steepens: a re-scan's
    # cE read 4.3 mm off where 3.5 were said, benchmarks/chart_accuracy.py 8 3)
    moved_girth = girth_spread(heights, girth, e_mm, moved_mm)
    e_uncertain = bool(knee.height_mm is not None and moved_girth > GIRTH_TOLERANCE_MM)
    if e_uncertain:
        knee = dataclasses.replace(knee, uncertainty_mm=moved_girth)
        # said when that moves cE by more than an order's girths are held to
        why = (f"the knee's girth rises as little {rival_at:.0f} mm above D as at E, {e_mm - heights[0]:.0f} mm above "
               "D, so E (cE, lE) may lie at either or between" if rival_mm >= moved_mm > 0 else
               f"the knee shows no level crown: its girth rises at least {slope[least]:.1f} mm per mm of height "
               f"from {heights[inside[0]] - heights[0]:.0f} to {heights[inside[-1]] - heights[0]:.0f} mm above D"
               f"{cut_below} so E (cE, lE) is the middle of its least-rising stretch" if crownless else
               "the knee's level stretch has no sharp ends (its girth's slope leaves the level slowly), so E (cE, lE), "
               "its middle, moves with where the stretch is taken to end")
        warnings = (f"{why}, uncertain by about {moved_mm:.0f} mm of height and {moved_girth:.0f} mm of cE; "
                    f"a tape at the middle of the patella decides",)
    return KneeMiddle(dataclasses.replace(knee, height_uncertainty_mm=float(moved_mm)), e_mm, warnings)

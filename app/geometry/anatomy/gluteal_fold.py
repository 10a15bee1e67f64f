"""The gluteal fold, where the back of the thigh turns into the buttock: the top of the
thigh, RAL-GZ 387's G (a thigh-high AG stocking's top), read from the leg's posterior
profile (app.geometry.anatomy.thigh puts cG, and F halfway to it, on the order form).

Frame: the calf frame (mm; z up the leg from B = 0, y anterior).  Arrays: points (n, 3),
faces (f, 3) or None; heights (k,) evenly spaced by STEP_MM.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.anatomy.level_runs import SLOPE_HALF_MM, STEP_MM, gaps_filled, run_around, run_between_crossings
from app.geometry.anatomy.skin_points import Skin
from app.geometry.scan.sampling import grouped_weighted_quantiles
from app.geometry.sections import LimbGraph, mesh_section_segments, round_edge_crossings

#: the gluteal fold: the smallest bend of the posterior profile that counts (a drop of its
#: slope dy/dz), the buttock's rearmost point at least this far under the scan's top, and
#: the skin above it back forward by at least this much, mm.  The bend separates two kinds
#: of back: a thigh's back without a fold bends 0.01-0.06 (the Visible Human legs, cut
#: below the hips, as meshes and as clouds), a fold 0.18-0.36 (the smooth folds of 8
#: generated MakeHuman legs, 11 scans each) and 0.51-0.56 (BodyParts3D's crease); the
#: bound lies halfway between the fold-less backs' largest and the folds' smallest.  (At
#: 0.3, inside the smooth folds' range, the same leg's fold was found on some re-scans
#: and not on others: 25 of 96 scans of those 8 legs had G, 87 of the 88 that reach the
#: thigh have it now; a smooth fold's G carries its uncertainty.)
FOLD_MIN_BEND = 0.12
BUTTOCK_BELOW_TOP_MM = 10.0
BUTTOCK_RETURN_MM = 5.0
#: a cloud's posterior profile at a height: the points within two STEP_MM bins of it (+-5
#: mm of height), each brought to the height along the profile's slope, each weighted by
#: the share of the section's angle it stands for (see posterior_profile).  Read as they
#: are, the 8 generated legs' clouds put lG 1.6-3.3 mm below their meshes' on 4 smooth
#: folds, and one leg's scans read cG apart by 2.34 mm p95 - a band's rearmost points lie
#: at its top edge where the back goes back into the buttock - and a cloud sparser on one
#: side (cloud_uneven) moved G by up to 6 mm (10 mm once brought to the height): a
#: percentile of its points reaches round the back by a depth that changes with the
#: section's shape where they are sparse (benchmarks/chart_accuracy.py 8 11).  Both
#: corrected, one leg's scans read cG apart by 1.51 mm p95, cG 1.46 mm p95 from the clean
#: mesh's (2.01 before), BodyParts3D's vertices G 0.1 mm from its mesh's.  Narrower
#: bands were measured and not taken: at +-3 mm a body scan's 6,549 vertices and a cloud
#: with stray points (benchmarks/record_diff.py's body_vertices-00, cloud_outliers-01)
#: lost their folds to noise in the thin bands.  Wider ones were not taken either: at +-7
#: mm BodyParts3D's crease, where the buttock overhangs the thigh, read as a cloud put G
#: 7 mm below its mesh's (no straight line brings an overhang's points to the height).
#: The section's robust polar fit (app.geometry.sections.cloud) has no band, but near the
#: scan's cut it has no section, where the buttock's top is read: as the profile (its mix
#: with the band's) it put lG p95 at 5.7-7.0 mm against 4.5
CLOUD_PROFILE_HALF_MM = 4.0
#: a cloud's band counts its points per angle round the band's centre in this many sectors
#: (the paper's 72 polar rays, 5 degrees each): each sector weighs the same
CLOUD_SECTORS = 72
#: the bend a thigh's back has without a fold: the largest of the fold-less backs'
#: (FOLD_MIN_BEND's docstring: 0.01-0.06).  G is the centroid of the bend beyond it - the
#: fold's own turning, the back's own left out - over the peak's run above it.  The
#: centroid of a profile's bend between two heights is where the tangents at those heights
#: meet (integrate z (-y'') by parts): G is the corner the thigh's back and the buttock's
#: underside make, the crease itself on a crease.  Every height of the run weighs by its
#: bend, so a scanner's noise that lifts or dents the bend somewhere moves G by its share
#: of the fold's turning, where the middle of the run at half the maximum moved with the
#: maximum itself: a noisy mesh of a smooth fold whose bend is a long ramp with a peak on
#: top read G 16 mm above its clean mesh's, cG 9.3 mm off (benchmarks/chart_accuracy.py 8 5,
#: leg 2); the centroid reads it 1.0 mm above, cG 0.6 mm off.  One leg's re-scans
#: apart, p95, middle -> centroid (chart_accuracy.py 8 SEED): seed 5 cG 3.02 -> 2.15, cF
#: 2.42 -> 1.86; 11: 1.51 -> 1.33, 1.59 -> 1.56; 9: 2.99 -> 2.35, 2.04 -> 1.74; first run
#: after the rule was set, 13: 1.97 -> 1.85, 2.04 -> 1.80; 7: 1.77 -> 1.52, 2.44 -> 2.11;
#: all six seeds: 2.14 -> 1.93, 1.98 -> 1.85, the largest |re-scan - clean| cG 9.3 -> 3.5.
#: Seed 3 reads worse, cG 1.75 -> 2.13, cF 1.70 -> 2.31: a weak fold (bend 0.15-0.2) with
#: a shoulder below it that rises beyond THIGH_BACK_BEND on some scans and not on others
#: pulls G down the shoulder by up to 7 mm.  What is left is mostly in the profile, not in
#: the rule: a noisy mesh's cG, p90 2.4 mm off its clean mesh's (no bias: -0.1 mm in the
#: mean), and a cloud's, 1.2-1.8 mm p90 and 0.3-0.4 mm high in the mean, more the nearer the
#: scan's top is to G (correlation -0.3 to -0.6 with the room above G), which neither
#: following the profile's shape in the band nor weighting a mesh's section by angle
#: removed.  The tails below THIGH_BACK_BEND, the back's own bend and its noise, are left
#: out: with them, G moved down the thigh's back by up to 11 mm on a cloud.  BodyParts3D's
#: crease reads G where the middle of its peak was (0.3 mm apart)
THIGH_BACK_BEND = 0.06
#: the fold's bend must be at least FOLD_MIN_SIGNAL times the scatter of the back's bend
#: (1.4826 x its median absolute deviation: a standard deviation robust to the fold's own)
#: further than FOLD_NOISE_GAP_MM from the fold's peak (its slopes reach +-SLOPE_HALF_MM,
#: a smooth fold as far again), read where FOLD_NOISE_MIN_SAMPLES such heights are.  The
#: bend's noise is correlated over its slopes' +-SLOPE_HALF_MM: a back 150 mm long holds
#: about 8 independent readings, and the largest of 8 Gaussian ones passes 4 standard
#: deviations with probability 2.5e-4 (3: 1%).  Measured on 8 generated legs, 13 kinds of
#: scan each (mesh and cloud kinds of benchmarks/corpus, seed 41): folds stand 4.1-16
#: times their back's scatter on every mesh, noisy mesh and cloud of 0.5 mm and more;
#: 2.4-12 on a body's 6,500 vertices, where the 4 under 4 read G 0.7-151 mm off (two
#: more, seed 21: 3.1 and 2.5, 132 and 120 mm off); 1.5-7.6 on a coarse body mesh (2-4k
#: vertices), whose 3 under 3 had no G found already.  No reading at 4 or more was off by
#: more than 8 mm.  The bound errs towards saying so: two noisy clouds whose G was right
#: (3.8 and 3.9 times, their designs within a point of their clean meshes':
#: benchmarks/bench_thigh_design.py 16 5) are refused, where at 3.5 a sparse cloud with
#: 3 mm of noise (tests/geometry/anatomy/test_thigh.py's) passed at 3.6 with G 20 mm off
FOLD_MIN_SIGNAL = 4.0
FOLD_NOISE_GAP_MM = 30.0
FOLD_NOISE_MIN_SAMPLES = 10
#: the fold's bend read beyond these shares of its maximum instead of THIGH_BACK_BEND: on
#: a fold symmetric about its middle G barely moves; on one whose bend is a long ramp with
#: a peak on top it moves towards the peak by as much as where the fold is taken to begin
#: decides, which G's height uncertainty then covers
PEAK_LEVELS = (1 / 3, 2 / 3)
#: the back of the leg: this percentile of a section's y (the rearmost 2%), averaged over
#: +-PROFILE_SMOOTH_MM of height
REAR_PERCENTILE = 2.0
PROFILE_SMOOTH_MM = 6.0
#: a cloud's points behind this percentile of their band (weighted as REAR_PERCENTILE is)
#: are tested for skin (app.geometry.anatomy.skin_points.Skin) and the strays among them
#: left out: the REAR_PERCENTILE of what is left lies among the tested points unless
#: strays hold more than the difference, 6% of a band's angle (a scanner's ghosts: 0.7%
#: of its points, scattered every way).  Behind the thigh at the scan's cut, where few
#: points are left in a band, one ghost 11 mm off the skin held the band's rearmost 2%
#: and put G 10 mm high (benchmarks/chart_accuracy.py 8 11, leg 3, cloud_outliers)
STRAY_TEST_PERCENTILE = 8.0
#: the points the test reads lie this far in front of the tested ones at most, mm
STRAY_SHELL_MM = 10.0


def _rearmost(group: np.ndarray, y: np.ndarray, weight: np.ndarray, n_heights: int,
              percentile: float = REAR_PERCENTILE) -> np.ndarray:
    """(n_heights,) the weighted ``percentile`` of ``y`` (m,) in each ``group`` (m,) of
    0..n_heights-1 (:func:`app.geometry.scan.sampling.grouped_weighted_quantiles`); NaN
    for an empty group.  mm."""
    return grouped_weighted_quantiles(group, y, weight, n_heights, percentile / 100)[:, 0]


def _sector_weights(group: np.ndarray, x: np.ndarray, y: np.ndarray, n_heights: int) -> np.ndarray:
    """(m,) each point's weight in its band: 1 / the number of its band's points in its
    sector (CLOUD_SECTORS about the band's mean x, y), so each sector of the section counts
    the same however densely the scanner sampled it or the mesh's triangles cut it.
    group (m,) bands 0..n_heights-1; x, y (m,) mm."""
    count = np.maximum(np.bincount(group, minlength=n_heights), 1)
    centre_x = np.bincount(group, x, minlength=n_heights) / count
    centre_y = np.bincount(group, y, minlength=n_heights) / count
    angle = np.arctan2(y - centre_y[group], x - centre_x[group])
    sector = np.minimum(((angle + np.pi) / (2 * np.pi) * CLOUD_SECTORS).astype(np.int64), CLOUD_SECTORS - 1)
    cell = group * CLOUD_SECTORS + sector
    return 1.0 / np.bincount(cell, minlength=n_heights * CLOUD_SECTORS)[cell]


def _skin_rows(points: np.ndarray, source: np.ndarray, group: np.ndarray, y: np.ndarray, weight: np.ndarray,
               n_heights: int) -> np.ndarray:
    """(m,) bool: the band rows (their ``source`` points (m,) of ``points`` (n, 3), ``group``
    (m,) bands, ``y`` (m,) mm, sector ``weight`` (m,)) whose point is skin, tested where
    it could be the back: behind its band's STRAY_TEST_PERCENTILE.  The test's k-d tree
    holds only the points within STRAY_SHELL_MM in front of that (the neighbours of a
    tested point lie within 4 spacings of it: a few mm), not the whole thigh."""
    level = _rearmost(group, y, weight, n_heights, STRAY_TEST_PERCENTILE)[group]
    shell = np.unique(source[y <= level + STRAY_SHELL_MM])
    tested = np.unique(source[y <= level])
    if not len(tested):
        return np.ones(len(source), dtype=bool)
    is_skin = Skin(points[shell], is_mesh=False).of_each(np.searchsorted(shell, tested))
    strays = tested[~is_skin]
    return ~np.isin(source, strays)


def _central_slopes(filled: np.ndarray) -> np.ndarray:
    """dy/dz over +-SLOPE_HALF_MM of a gap-free profile ``filled`` (k,) every STEP_MM: the
    (k - 2 lag,) slopes of its samples lag = SLOPE_HALF_MM / STEP_MM from either end."""
    lag = int(round(SLOPE_HALF_MM / STEP_MM))
    return (filled[2 * lag:] - filled[:-2 * lag]) / (2 * SLOPE_HALF_MM)


def _smoothed(heights: np.ndarray, rear: np.ndarray) -> np.ndarray:
    """``rear`` (k,) averaged over +-PROFILE_SMOOTH_MM of ``heights`` (k,), gaps read
    between their neighbours and left NaN.  mm."""
    finite = np.isfinite(rear)
    reach = int(round(PROFILE_SMOOTH_MM / STEP_MM))
    if finite.sum() <= 2 * reach + 1:
        return rear
    kernel = np.ones(2 * reach + 1) / (2 * reach + 1)
    smooth = np.convolve(np.pad(gaps_filled(heights, rear), reach, mode="edge"), kernel, mode="valid")
    return np.where(finite, smooth, np.nan)


def _profile_slope(heights: np.ndarray, rear: np.ndarray) -> np.ndarray:
    """dy/dz (k,) of the profile ``rear`` (k,, at least one finite) over +-SLOPE_HALF_MM
    (the fold's own slope, :func:`gluteal_fold`), gaps read between their neighbours; the
    ends held flat beyond the profile."""
    lag = int(round(SLOPE_HALF_MM / STEP_MM))
    return _central_slopes(np.pad(gaps_filled(heights, rear), lag, mode="edge"))


def _plane_profile(heights: np.ndarray, plane: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """The posterior profile (k,) of points lying on the planes ``heights`` (k,): ``plane``
    (m,) each point's plane, ``xy`` (m, 2) mm; the rearmost REAR_PERCENTILE of each
    section's angle, averaged over +-PROFILE_SMOOTH_MM."""
    x, y = xy[:, 0], xy[:, 1]
    return _smoothed(heights, _rearmost(plane, y, _sector_weights(plane, x, y, len(heights)), len(heights)))


def posterior_profile(points: np.ndarray, faces: np.ndarray | None, heights: np.ndarray,
                      edges: LimbGraph | None = None) -> np.ndarray:
    """The back of the leg at each height (k,), evenly spaced by STEP_MM (a sparse cloud's
    read on its neighbour graph ``edges``, a LimbGraph, the heights ascending): a low percentile
    (REAR_PERCENTILE) of the y of the section's points rather than their minimum, which a
    scanner's noise drags back by its largest excursion; then averaged over
    +-PROFILE_SMOOTH_MM.  NaN where there is nothing.  mm.

    A mesh's section points are its exact plane-section segment ends
    (:func:`app.geometry.sections.mesh_section_segments`), their percentile one of the
    section's angle as a cloud's is (below): of the segment ends, spread along the skin
    by its triangles, it reached less far round a flat back than the cloud's and put the
    clean meshes' G 1-3.7 mm under their own clouds' (benchmarks/chart_accuracy.py 8 11:
    every re-scan's lG read high, p95 5.2 mm).  A cloud has no points on the
    plane: its section is the band of points within CLOUD_PROFILE_HALF_MM of the height,
    each brought to the height along the back's slope - y less the slope times the point's
    height above the plane (a first-order Taylor step), the slope read on the band's
    profile taken as it is - so the band's rearmost points are the back at its height and
    not at its edge where the back slopes; and its percentile is one of the section's angle
    (:func:`_sector_weights`), not of its points, which a scanner spreads unevenly
    (CLOUD_PROFILE_HALF_MM's docstring gives what each step changed)."""
    if faces is not None and len(faces):
        plane, segments = mesh_section_segments(points, faces, heights)
        return _plane_profile(heights, np.repeat(plane, 2), segments.reshape(-1, 2))
    if edges is not None:
        # a sparse cloud: where its neighbour graph's edges cross each plane, as a mesh's
        # triangles do (app.geometry.fit.sparse_clouds): a body mesh's 6.5k vertices in
        # bands of points put G 146 mm down the thigh at a noise spike, unwarned, on one
        # held-out leg (benchmarks/chart_accuracy.py 8 5, leg 7) and no G on two others;
        # on the graph 14 of 16 such scans (seeds 11 and 5) read G, lG within 5.2 mm
        # - its mutual graph's alone (LimbGraph.mutual): read with the edges along the
        # limb too, on their bend or their chords, the back's profile moved lG by more
        # than 1 mm (up to 3.1) on 9 of the 85 body-vertex and sparse lower-leg re-scans
        # of chart_accuracy 8 3 to 8 13; read on the mutual graph, on 2 (up to 2.3)
        return _plane_profile(heights, *round_edge_crossings(points, edges.mutual, heights))
    reach = int(round(CLOUD_PROFILE_HALF_MM / STEP_MM))
    # only the points within reach of a height (the foot's and shank's are not the thigh's)
    points = points[(points[:, 2] >= heights[0] - (reach + 0.5) * STEP_MM)
                    & (points[:, 2] <= heights[-1] + (reach + 0.5) * STEP_MM)]
    index = np.rint((points[:, 2] - heights[0]) / STEP_MM).astype(np.int64)
    # each point counts for the heights within reach of it
    offsets = np.arange(-reach, reach + 1)
    group = (index[:, None] + offsets[None, :]).ravel()
    keep = (group >= 0) & (group < len(heights))
    group = group[keep]
    source = np.repeat(np.arange(len(points)), len(offsets))[keep]  # (m,) each row's point
    x, y, z = points[source].T
    weight = _sector_weights(group, x, y, len(heights))
    skin = _skin_rows(points, source, group, y, weight, len(heights))
    if not skin.all():  # a cloud's strays behind the back left out, each sector weighed again
        group, source, x, y, z = group[skin], source[skin], x[skin], y[skin], z[skin]
        weight = _sector_weights(group, x, y, len(heights))
    as_is = _smoothed(heights, _rearmost(group, y, weight, len(heights)))
    if not np.isfinite(as_is).any():
        return as_is
    slope = _profile_slope(heights, as_is)
    rear = _smoothed(heights, _rearmost(group, y - slope[group] * (z - heights[group]), weight, len(heights)))
    return np.where(np.isfinite(as_is), rear, np.nan)


@dataclass(frozen=True)
class GlutealFold:
    """The gluteal fold found in the posterior profile: G's ``height_mm`` (the centroid of
    the fold's bend beyond THIGH_BACK_BEND), or None with the ``reason``;
    ``excess_half_width_mm`` how much wider than a corner the bend's peak is (its half
    width at half maximum less SLOPE_HALF_MM, a sharp corner's own: the fold's own half
    extent for a smooth one; 1.7 mm for an ideal corner sampled on the STEP_MM planes,
    whose peak the profile's +-PROFILE_SMOOTH_MM average widens - left in, not taken
    off: a noisy mesh narrows a smooth fold's peak by as much and more, and this floor is
    part of what its stated uncertainty covers, benchmarks/chart_accuracy.py 8 5);
    ``level_shift_mm`` how much G depends on where the fold is taken to begin (its bend
    read beyond PEAK_LEVELS of its maximum instead of beyond THIGH_BACK_BEND);
    ``rival_mm`` how far from G the back bends as much as a fold does elsewhere (another
    peak of FOLD_MIN_BEND or more below the buttock, apart from G's own at half its
    maximum: G could as well lie there), signed (below G: negative), 0 where none."""

    height_mm: float | None
    reason: str | None
    excess_half_width_mm: float = 0.0
    #: how far G moves when the bend is read beyond PEAK_LEVELS of its maximum instead of
    #: beyond THIGH_BACK_BEND (0 for a crease or a fold symmetric about its middle), mm
    level_shift_mm: float = 0.0
    rival_mm: float = 0.0

    @property
    def height_uncertainty_mm(self) -> float:
        """How far G may lie from ``height_mm`` along the leg: the fold's own half extent
        beyond a crease's, how far it moves with where the fold is taken to begin, or how
        far away the back bends as much as a fold elsewhere, whichever is more (mm)."""
        return max(self.excess_half_width_mm, self.level_shift_mm, abs(self.rival_mm))

    @property
    def uncertainty_text(self) -> str:
        """Why G's height is uncertain, in words (the largest of the three causes of
        :attr:`height_uncertainty_mm`); the thigh's warning goes on with what it does to cG."""
        if abs(self.rival_mm) > max(self.excess_half_width_mm, self.level_shift_mm):
            return (f"the back of the thigh bends as much as a gluteal fold does {abs(self.rival_mm):.0f} mm "
                    f"{'below' if self.rival_mm < 0 else 'above'} G too (the scan is too sparse or uneven there to "
                    "tell which is the fold), so G may lie at either or between")
        if self.excess_half_width_mm >= self.level_shift_mm:
            return (f"the gluteal fold is smooth, not a crease: it spans about {self.excess_half_width_mm:.0f} mm of "
                    "height either side of G beyond a crease's width")
        return (f"the gluteal fold is smooth, not a crease: its bend rises along about {self.level_shift_mm:.0f} mm of "
                "height below or above G, so where G lies depends on where the fold is taken to begin")


def gluteal_fold(heights: np.ndarray, rear: np.ndarray, above_mm: float, top_mm: float) -> GlutealFold:
    """The gluteal fold in ``heights`` (k,), evenly spaced by STEP_MM.  ``rear`` (k,) the
    posterior profile (rearmost y, mm; NaN where empty).  The buttock is the profile's
    rearmost bulge above ``above_mm``: its rearmost point must lie BUTTOCK_BELOW_TOP_MM
    under the scan's top and the skin above it come forward again (else the scan was cut
    through the buttock or below it).  The fold is the sharpest bend of the profile below
    it: the largest drop of the profile's slope dy/dz (over +-SLOPE_HALF_MM, each side of
    the height), at least FOLD_MIN_BEND; G is the centroid of the bend beyond
    THIGH_BACK_BEND over the run of heights round it where the bend exceeds that: where
    the tangents to the profile at the run's ends meet, the corner of the fold.

    How wide the fold is: a corner of the profile (a crease) read by slopes over
    +-SLOPE_HALF_MM gives a triangular bend peak whose half width at half maximum is
    SLOPE_HALF_MM; a fold smoother than a crease widens it by its own half extent, over
    which a tape's "below the fold" is a matter of judgement."""
    lag = int(round(SLOPE_HALF_MM / STEP_MM))
    valid = np.flatnonzero(np.isfinite(rear) & (heights >= above_mm))
    cut = "the scan stops below the gluteal fold (the top of the thigh)"
    if len(valid) < 6 * lag:
        return GlutealFold(None, cut)
    back = int(valid[np.argmin(rear[valid])])
    above = np.flatnonzero(np.isfinite(rear) & (heights > heights[back]))
    if heights[back] > top_mm - BUTTOCK_BELOW_TOP_MM or not len(above) or rear[above].max() < rear[back] + BUTTOCK_RETURN_MM:
        return GlutealFold(None, cut)
    slope = np.full(len(heights), np.nan)
    slope[lag:-lag] = _central_slopes(gaps_filled(heights, rear))
    bend = np.full(len(heights), -np.inf)
    bend[lag:-lag] = slope[:-2 * lag] - slope[2 * lag:]  # slope below minus slope above
    search = valid[valid < back]
    bend_here = np.where(np.isfinite(bend[search]), bend[search], -np.inf)
    if not len(search) or not np.isfinite(bend_here.max()):
        return GlutealFold(None, cut)
    peak = int(np.argmax(bend_here))
    if bend_here[peak] < FOLD_MIN_BEND:
        # no crease: either the scan ends below the fold (the back of a thigh runs nearly
        # straight: a bend of a few hundredths) or the fold is too smooth to place
        reason = (f"no gluteal fold found: the back of the thigh bends at most {max(bend_here[peak], 0.0):.2f} below "
                  f"its rearmost point (a fold bends at least {FOLD_MIN_BEND:g}): the scan stops below the fold or the "
                  f"fold is too smooth to place; a tape at the fold decides")
        return GlutealFold(None, reason)
    heights_here = heights[search]
    # the fold must stand out of the back's own bend scatter (a sparse cloud's profile is
    # noisy: a body's 6,500 vertices put "G" 151 mm down the thigh at a noise spike)
    away = np.isfinite(bend_here) & (np.abs(heights_here - heights_here[peak]) > FOLD_NOISE_GAP_MM)
    if away.sum() >= FOLD_NOISE_MIN_SAMPLES:
        scatter = 1.4826 * float(np.median(np.abs(bend_here[away] - np.median(bend_here[away]))))
        if bend_here[peak] < FOLD_MIN_SIGNAL * scatter:
            return GlutealFold(None, f"no gluteal fold found: the back of the thigh's largest bend below its rearmost "
                                     f"point ({bend_here[peak]:.2f}) is only {bend_here[peak] / scatter:.1f} times the "
                                     f"scatter of its bend elsewhere ({scatter:.3f}; a fold stands out by at least "
                                     f"{FOLD_MIN_SIGNAL:g} times): the scan is too sparse or noisy there to tell the "
                                     f"fold from its noise; a tape at the fold decides")

    def centroid(floor: float) -> float:
        """The centroid (mm) of the bend beyond ``floor`` over the peak's run above it."""
        first, last = run_around(bend_here > floor, peak)
        weight = bend_here[first:last + 1] - floor
        return float(np.sum(weight * heights_here[first:last + 1]) / np.sum(weight))

    # the peak's run at half its maximum, its ends where the bend crosses that
    half = run_between_crossings(heights_here, -bend_here, np.isfinite(bend_here), peak, -bend_here[peak] / 2)
    half_width = (half.top_mm - half.bottom_mm) / 2
    g_mm = centroid(THIGH_BACK_BEND)
    shift = max(abs(centroid(level * bend_here[peak]) - g_mm) for level in PEAK_LEVELS)
    return GlutealFold(g_mm, None, max(half_width - SLOPE_HALF_MM, 0.0), shift,
                       _farthest_rival(heights_here, bend_here, g_mm, half.bottom_mm, half.top_mm))


def _farthest_rival(heights: np.ndarray, bend: np.ndarray, g_mm: float, bottom_mm: float, top_mm: float) -> float:
    """How far from G (signed, mm; 0 where none) the farthest other peak of the back's
    ``bend`` (k,) at ``heights`` (k,) lies that bends as much as a fold does
    (FOLD_MIN_BEND: a thigh's back without a fold bends at most 0.06): a local maximum
    outside G's own peak at half its maximum (``bottom_mm`` to ``top_mm``).  The largest
    bend is G, but where two fold-sized bends stand on the back, which is the fold is a
    matter of the scan's sampling: 6,000 of BodyParts3D's vertices drawn at random bent
    0.74 at 596 mm, where its mesh does not bend at all, and 0.40 at its crease (624 mm),
    and G was read 23 mm low, cG 8 mm short, said to be sure.  As E's rivals do
    (app.geometry.anatomy.knee_middle), the farthest such peak bounds where G may lie."""
    inner = np.isfinite(bend)
    peak = np.zeros(len(bend), dtype=bool)
    peak[1:-1] = inner[1:-1] & (bend[1:-1] >= bend[:-2]) & (bend[1:-1] >= bend[2:])
    rivals = np.flatnonzero(peak & (bend >= FOLD_MIN_BEND) & ((heights < bottom_mm) | (heights > top_mm)))
    if not rivals.size:
        return 0.0
    farthest = rivals[np.argmax(np.abs(heights[rivals] - g_mm))]
    return float(heights[farthest] - g_mm)

"""One candidate leg's calf axis, landmarks and anterior direction (paper section 2.1).

:func:`place_candidate` takes the points (and faces) of one leg - already cut out of its
scan by :mod:`app.geometry.placement.place` - and returns a :class:`CalfAxis`, in scan mm:

1. a first axis: area-weighted PCA of the leg's surface, then the line through the
   centroids of its compact (round, leg-like) slabs, which a flat foot does not drag
   (:func:`app.geometry.placement.first_axis.first_axis`);
2. the coarse circumference profile along it (:func:`_profile`: 36 rays every 3 mm),
   B, C, D found on it (:func:`app.geometry.anatomy.landmarks.find_feature_heights`), both ends
   tried when the scan's up is unknown, the foot's end down (:mod:`app.geometry.placement.leg_ends`);
3. the shank's long axis - the line through the section centroids from B to 85% of the
   way to D (:func:`_section_centre_line`) - adopted and the landmarks found again along
   it (:func:`_refine`);
4. for a bent knee, when the straight reading fails: the straight runs of the leg's
   centre line, each cut free of the thigh at the knee (:mod:`app.geometry.placement.knee_bend`);
5. anterior from the foot, else opposite the calf bulge; the origin at B's centroid.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial

import numpy as np

from app.geometry.anatomy.calf_candidates import FeatureHeights
from app.geometry.anatomy.landmark_refusals import failure_stage
from app.geometry.anatomy.landmarks import find_feature_heights
from app.geometry.errors import CalfWithoutBulge, FailureReason, FitFailure
from app.geometry.placement import calf_frame as cf
from app.geometry.placement.coverage import bridged_strip_refusal, partial_view
from app.geometry.placement.first_axis import AXIS_TOLERANCE_DEG, first_axis, pca_samples
from app.geometry.placement.knee_bend import hidden_knee_refusal, keep_index, seated_knee_refusals, shank_runs
from app.geometry.placement.leg_ends import landmarks_either_way, mirror_profile
from app.geometry.sections import PolarSections, polygon_centroid, slice_polar

#: a lower leg (ankle to knee, 250+ mm; with a flat foot about 1.4 x its foot length)
#: is longer than it is wide; a ball or a box is not
MIN_ASPECT = 1.2
#: spacing of the coarse profile used to find B, C, D along the whole leg, mm
COARSE_SPACING_MM = 2.0
#: spacing of the first profile over the whole scan (before the calf is known), mm
FIRST_SPACING_MM = 3.0
MAX_AXIS_ITERATIONS = 2
#: an axis update smaller than this (degrees) keeps the landmarks without re-slicing: a
#: 2 degree tilt moves a plane by +-1.7 mm across a 50 mm radius and its girth by 0.06%
REDETECT_DEG = 2.0
#: sections at the scan's ends seen over less than this share of their rays (meshes) or
#: angular bins (clouds) are partial cuts, not leg sections
MIN_END_COVERAGE = 0.9
#: an oblique crop (up to ~15 degrees across a 70 mm leg) spans this much of the axis, mm
END_CUT_MM = 25.0
#: a leg's girth rises at most ~1%/mm anywhere above the ankle (about 0.5%/mm at the
#: knee): a rise of 10% within 5 mm means the plane has reached another body part (a
#: bent knee's thigh); the corpus truth ends the shank's sections by the same rule
MERGE_RISE = 0.10
MERGE_RUN_MM = 5.0
#: rays of the coarse profile (circumference error of a 36-gon: 0.13%)
COARSE_ANGLES = 36
#: the shank's long axis is the line through the section centroids from B to this share
#: of the way to D (:func:`_section_centre_line`).  On 20 generated legs the line of the
#: sections from the ankle joint + 10% to the knee joint - 10% (the skeleton's shank)
#: is reproduced to 0.25 degrees median (p90 1.2) by B to 85%, 2.3 degrees by B to D.
SHANK_AXIS_SHARE = 0.85
#: the re-sliced profile after an axis update keeps this much leg beyond B and D, mm
PROFILE_MARGIN_MM = 70.0


@dataclass(frozen=True)
class CalfAxis:
    """A candidate leg placed: ``rotation`` (3, 3) rows x, y (anterior), z (up) and
    ``origin_mm`` (3,) at B's centroid, in scan mm; ``anterior_cue`` (foot, calf_bulge,
    undetermined); ``c_mm``, ``d_mm`` heights of C and D above B; the edge flags; a bent
    knee's cut ``half_spaces`` ((point (3,), normal (3,)), ...)."""

    rotation: np.ndarray
    origin_mm: np.ndarray
    anterior_cue: str
    c_mm: float
    d_mm: float
    d_at_window_edge: bool
    b_at_scan_edge: bool
    d_at_scan_edge: bool
    half_spaces: tuple


@dataclass(frozen=True)
class AxisProfile:
    """One reading of a leg along an axis: ``centre`` (3,) scan mm the points are taken
    about, ``local`` (n, 3) the points in the axis's basis (z along it), mm; the coarse
    profile ``heights`` (k,) mm, ``girth`` (k,) mm and its ``sections``; ``feats`` the
    B, C, D found on it; ``axis`` (3,) unit and ``basis`` (3, 3) rows x, y, z."""

    centre: np.ndarray
    local: np.ndarray
    heights: np.ndarray
    girth: np.ndarray
    sections: PolarSections
    feats: FeatureHeights
    axis: np.ndarray
    basis: np.ndarray


def _profile(local: np.ndarray, faces: np.ndarray | None, z_range: tuple[float, float] | None = None,
             cut_end: int = 0):
    """Coarse circumference profile along z (36 rays), for finding B, C, D.

    The whole leg every :data:`FIRST_SPACING_MM`; a window ``z_range`` every
    :data:`COARSE_SPACING_MM`.  ``cut_end`` +1 (-1): the leg was cut free of a bent
    knee's thigh at its top (bottom) end; the partial sections next to that cut are not
    measurements, however far they reach.  Returns heights (k,), girths (k,), the sections.
    """
    z = local[:, 2]
    if z_range is None:
        lo, hi, spacing = z.min(), z.max(), FIRST_SPACING_MM
    else:
        lo, hi, spacing = max(z.min(), z_range[0]), min(z.max(), z_range[1]), COARSE_SPACING_MM
    # planes at whole multiples of the spacing from the leg's centroid: the same planes
    # whichever way round the scan comes
    heights = np.arange(np.ceil((lo + 1.0) / spacing), np.floor((hi - 1.0) / spacing) + 1) * spacing
    if len(heights) < 20:
        raise FitFailure(FailureReason.NOT_A_LEG, "the scan is too short along its main axis to be a leg")
    sections = slice_polar(local, faces, heights, COARSE_ANGLES, recentre=False)
    girth = sections.circumferences()
    # a crop plane oblique to the slicing planes leaves partial sections at the scan's
    # ends, whose girth falls towards zero: they are not measurements of the leg
    # (only within END_CUT_MM of the ends: an oblique cut spans at most that much of the
    # axis, while a foot's sections can be incomplete over a longer run and are real)
    partial = (sections.coverage < MIN_END_COVERAGE) & (
        (heights - heights[0] <= END_CUT_MM) | (heights[-1] - heights <= END_CUT_MM))
    if cut_end:
        inwards = np.arange(len(heights))[::-cut_end]  # from the cut end into the leg
        whole = sections.coverage[inwards] >= MIN_END_COVERAGE
        partial[inwards[: int(np.argmax(whole)) if whole.any() else len(inwards)]] = True
        # whole sections can still reach the thigh on the shank's side of the cut (a knee
        # bent past ~60 degrees): from the middle of the leg towards the cut, the shank's
        # sections end at the first girth rise of MERGE_RISE within MERGE_RUN_MM
        outwards = inwards[::-1]
        g = np.where(partial, np.nan, girth)[outwards]
        run = max(int(round(MERGE_RUN_MM / spacing)), 1)
        with np.errstate(invalid="ignore"):
            rise = g[run:] > (1.0 + MERGE_RISE) * g[:-run]
        jumps = np.flatnonzero(rise[len(g) // 2 :]) + len(g) // 2
        if jumps.size:
            partial[outwards[jumps[0] + 1 :]] = True
    girth[partial] = np.nan
    return heights, girth, sections


def _cut_end(half_spaces, centre: np.ndarray, axis: np.ndarray) -> int:
    """Which end of the profile along ``axis`` a bent knee's cut lies at: +1 top, -1
    bottom, 0 no cut (the first half-space passes through the knee)."""
    if not half_spaces:
        return 0
    return 1 if (half_spaces[0][0] - centre) @ axis > 0 else -1


@contextmanager
def _strip_named(sections: PolarSections, half_spaces: tuple) -> Iterator[None]:
    """Re-raise a refusal about the leg's shape read on ``sections`` as the strip the
    scanner missed when a strip bridged at every height is the likelier cause
    (:func:`app.geometry.placement.coverage.bridged_strip_refusal`); not on a bent knee's
    run (``half_spaces``), whose cut opens sections by design."""
    try:
        yield
    except FitFailure as failure:
        strip = None if half_spaces else bridged_strip_refusal(failure, sections)
        if strip is None:
            raise
        raise strip from failure


def _orient(points, faces, axis, basis, up, half_spaces=()) -> AxisProfile:
    """B, C, D along ``axis`` (and the axis possibly reversed).  ``half_spaces``: a bent
    knee's cut."""
    centre = points.mean(axis=0)
    local = (points - centre) @ basis.T
    heights, girth, sections = _profile(local, faces, cut_end=_cut_end(half_spaces, centre, axis))
    one_sided = None if half_spaces else partial_view(sections)  # (a bent knee's cut opens sections by design)
    if one_sided is not None:  # before the landmarks: a missing arc reads as another shape
        raise one_sided
    with _strip_named(sections, half_spaces):
        if up is not None:
            feats, flipped = find_feature_heights(heights, girth, elongation=sections.elongations()), False
        else:
            feats, flipped = landmarks_either_way(heights, girth, sections.elongations())
    if flipped:  # the scan's axis pointed towards the foot
        axis = -axis
        basis = cf.perpendicular_basis(axis, basis[1])
        local = (points - centre) @ basis.T
        heights, girth, sections = mirror_profile(heights, girth, sections)
    return AxisProfile(centre, local, heights, girth, sections, feats, axis, basis)


def _section_centre_line(heights: np.ndarray, girth: np.ndarray, sections: PolarSections,
                         b_mm: float, d_mm: float) -> np.ndarray | None:
    """Direction (3,), in the slicing frame, of the shank's long axis: the least-squares
    line through the area centroids of the sections from B up to
    :data:`SHANK_AXIS_SHARE` of the way to D.  A tape is held perpendicular to it.

    Why not PCA of the calf's surface (the paper's section 2.1): the gastrocnemius bulges
    backwards in the upper calf only, so the surface's principal direction leans 2-3
    degrees towards it, and at the knee waist a plane tilted that much dips into the
    hollow of the knee and reads a girth 3-5 mm below a tape's.  The section centroids
    follow the limb; below the knee they lie on a nearly straight line (the tibial
    shaft's), but in the last ~15% below D the hamstring tendons and the femoral
    condyles pull them backwards.  Partial sections (NaN girth) are left out; None
    when fewer than 10 remain.
    """
    d_mm = b_mm + SHANK_AXIS_SHARE * (d_mm - b_mm)
    rows = (heights >= b_mm) & (heights <= d_mm) & np.isfinite(girth) & sections.valid
    if rows.sum() < 10:
        return None
    a = sections.angles_rad
    radii = sections.radii_mm[rows]
    contour = np.stack([radii * np.cos(a), radii * np.sin(a)], axis=-1)
    centres = sections.centroids_mm[rows] + polygon_centroid(contour)
    direction = cf.principal_axis(np.column_stack([centres, heights[rows]]))
    return direction if direction[2] > 0 else -direction


def _height_on(new_axis: np.ndarray, basis: np.ndarray, heights: np.ndarray, sections: PolarSections,
               z_mm: float) -> float:
    """Height along ``new_axis`` (both about the same centre, mm) of the centroid of the
    section at ``z_mm`` of the profile along ``basis``'s z (its rows: x, y, z axes);
    the point on the old axis when that section has no centroid."""
    row = int(np.clip(np.searchsorted(heights, z_mm), 0, len(heights) - 1))
    centroid = sections.centroids_mm[row]
    xy = centroid if np.isfinite(centroid).all() else np.zeros(2)
    point = basis.T @ np.array([xy[0], xy[1], z_mm])
    return float(point @ new_axis)


def _refine(oriented: AxisProfile, points, faces, samples, weights, half_spaces) -> AxisProfile:
    """The calf's long axis (:func:`_section_centre_line`; the paper's section 2.1
    uses PCA of the calf between B and D), the landmarks found again along it, at most
    :data:`MAX_AXIS_ITERATIONS` times or until the axis moves less than
    :data:`AXIS_TOLERANCE_DEG`.  ``oriented``: what :func:`_orient` found."""
    centre, local, heights, girth = oriented.centre, oriented.local, oriented.heights, oriented.girth
    sections, feats, axis, basis = oriented.sections, oriented.feats, oriented.axis, oriented.basis
    for _ in range(MAX_AXIS_ITERATIONS):
        line = _section_centre_line(heights, girth, sections, feats.b_mm, feats.d_mm)
        if line is None:
            sample_z = (samples - centre) @ basis[2]
            calf = (sample_z >= feats.b_mm) & (sample_z <= feats.d_mm)
            new_axis = cf.principal_axis(samples[calf], None if weights is None else weights[calf])
        else:
            new_axis = basis.T @ line
        if new_axis @ axis < 0:
            new_axis = -new_axis
        moved = cf.angle_deg(new_axis, axis)
        if moved < AXIS_TOLERANCE_DEG:
            break
        if moved < REDETECT_DEG:
            # a small tilt moves B and D by well under a millimetre: keep the landmarks
            # (re-expressed about the same centre) and only adopt the calf's axis
            axis = new_axis
            basis = cf.perpendicular_basis(axis, basis[1])
            local = (points - centre) @ basis.T
            break
        # the calf maximum's section centre, carried into the new axis's heights: the
        # hint for finding C again (a tilt moves a point off the old axis in height by
        # its offset x sin(tilt): tens of mm for a foot-heavy first axis)
        hint = _height_on(new_axis, basis, heights, sections, feats.c_mm)
        axis = new_axis
        basis = cf.perpendicular_basis(axis, basis[1])
        local = (points - centre) @ basis.T
        window = (feats.b_mm - PROFILE_MARGIN_MM, feats.d_mm + PROFILE_MARGIN_MM)
        heights, girth, sections = _profile(local, faces, window, _cut_end(half_spaces, centre, axis))
        # a bridged strip also pulls the sections' centroids, so the calf's axis, off the
        # limb's: the landmarks the first axis found may be lost along the new one
        # (benchmarks/coverage.py 20 37, leg 17, a 53-degree strip refused no_knee)
        with _strip_named(sections, half_spaces):
            feats = find_feature_heights(heights, girth, hint, sections.elongations(), feats.on_foot)
    return AxisProfile(centre, local, heights, girth, sections, feats, axis, basis)


def _place_run(run, points, faces, samples, weights, basis) -> tuple[AxisProfile, np.ndarray, np.ndarray | None]:
    """One run of a bent leg's centre line placed as :func:`place_candidate` places a
    straight leg (raises FitFailure): the profile and the run's points and faces."""
    run_basis = cf.perpendicular_basis(run.direction, basis[1])
    run_points, run_faces = clip_to_half_spaces(points, faces, run.half_spaces)
    kept = keep_index(samples, run.half_spaces)
    run_samples, run_weights = samples[kept], None if weights is None else weights[kept]
    placed = _refine(_orient(run_points, run_faces, run.direction, run_basis, None, run.half_spaces),
                     run_points, run_faces, run_samples, run_weights, run.half_spaces)
    return placed, run_points, run_faces


def _consensus_reading(points, faces, samples, weights, shape_axes, up, axis, failures) -> AxisProfile:
    """The leg read straight once more, along the consensus line of its compact slabs'
    centroids (:func:`app.geometry.placement.first_axis.first_axis`), before it is
    refused with the most informative of ``failures`` (raised when this reading fails
    too, or is not tried).

    Least squares through those centroids, the first reading's ``axis``, is pulled off
    the limb by a heel's or an instep's slabs, and iterated it can cycle (20 degrees off
    the shank on robustness 220's sparse knee-high vertex clouds of seeds 13, 17 and 19,
    refused no_knee); the consensus line is not.  Read last, and not when a knee was found
    bent: the consensus line follows one segment of a bent knee, and read straight along
    it the other segment's sections stand in the planes across the knee (robustness 220
    11 seated-00, a knee bent 97 degrees, read so put D in the thigh, 85 mm too high, where
    its runs say knee_bent)."""
    if not any(failure.reason is FailureReason.KNEE_BENT for failure in failures):
        line_axis, line_basis = first_axis(samples, weights, shape_axes, up, consensus=True)
        # (within REDETECT_DEG of the first axis: the same line, the same reading)
        if cf.angle_deg(line_axis, axis, undirected=True) >= REDETECT_DEG:
            try:
                return _refine(_orient(points, faces, line_axis, line_basis, up), points, faces, samples, weights, ())
            except FitFailure as failure:
                failures = [*failures, failure]
    raise max(failures, key=failure_stage)


def place_candidate(points: np.ndarray, faces: np.ndarray | None, up: np.ndarray | None) -> CalfAxis:
    """Axis, B/C/D, refined calf axis, anterior direction: one candidate leg's placement.

    Paper section 2.1: PCA of the whole leg gives a first axis (refined by the compact
    slabs' centre line); B, C, D are found on the profile along it; then the axis is
    re-estimated as the calf's long axis (:func:`_section_centre_line`; the paper uses
    PCA of the calf between B and D) and the landmarks found again, at
    most :data:`MAX_AXIS_ITERATIONS` times or until the axis moves less than
    :data:`AXIS_TOLERANCE_DEG`.  When the first axis finds no calf, the straight runs of
    the leg's centre line (a bent knee) are tried in turn, and when they fail without
    finding the knee bent, the leg is read straight along a second first axis
    (:func:`_consensus_reading`).

    points (n, 3) scan mm of one leg, faces (f, 3) or None; ``up`` (3,) the feet-to-head
    direction when known (a leg cut from a body).  Raises FitFailure with the reason.
    """
    samples, weights = pca_samples(points, faces)
    shape_axes = cf.principal_frame(samples, weights)
    extents = np.ptp(samples @ shape_axes.T, axis=0)
    if up is None and extents[2] < MIN_ASPECT * extents[:2].max():
        raise FitFailure(
            FailureReason.NOT_A_LEG,
            f"the scan is {extents[2]:.0f} mm long and {extents[:2].max():.0f} mm wide: "
            f"a leg is at least {MIN_ASPECT:g} times longer than it is wide",
        )
    axis, basis = first_axis(samples, weights, shape_axes, up)
    if faces is None:
        # a cloud is sliced along this axis and then along axes a few degrees from it:
        # sorted along it once, each slicing's sort is a pass over nearly sorted data
        points = points[np.argsort(points @ axis, kind="stable")]
    half_spaces: tuple = ()
    try:
        # a bent leg's first axis is the body's: its landmarks may be found, and then not
        # found again along the calf's own axis - that too sends the leg to its runs
        placed = _refine(_orient(points, faces, axis, basis, up), points, faces, samples, weights, ())
    except FitFailure as straight_failure:
        run_failures = [straight_failure]
        for run in shank_runs(samples, weights, axis):
            try:
                placed, run_points, run_faces = _place_run(run, points, faces, samples, weights, basis)
            except FitFailure as failure:
                run_failures.append(hidden_knee_refusal(failure, run))
                continue
            if isinstance(straight_failure, CalfWithoutBulge) and not placed.feats.on_foot:
                # the straight leg stood on its foot without a calf bulge: a run with no
                # ankle on a foot is a thigh over its knee waist, read as a calf over an
                # ankle (benchmarks/swollen.py), not the shank of a bent knee
                continue
            points, faces, half_spaces = run_points, run_faces, run.half_spaces
            break
        else:
            # the reading that got furthest up the leg (ankle found, then calf, then
            # knee): a reading that found the ankle and the calf but no knee names what is
            # really missing better than one that found no ankle - a foot read as the
            # calf, upside down, finds no ankle above it.  Ties: the straight axis's.
            # A straight leg that stood on its foot without a calf bulge is that leg: what
            # a bent knee's runs miss, cut off its foot, tells less
            if isinstance(straight_failure, CalfWithoutBulge):
                raise straight_failure
            run_failures += seated_knee_refusals(
                samples, weights, partial(_place_run, points=points, faces=faces, samples=samples, weights=weights,
                                          basis=basis))
            placed = _consensus_reading(points, faces, samples, weights, shape_axes, up, axis, run_failures)

    centre, local, heights, sections = placed.centre, placed.local, placed.heights, placed.sections
    feats, axis, basis = placed.feats, placed.axis, placed.basis
    # anterior: the foot when there is one, else opposite the calf bulge
    calf_rows = (heights >= feats.b_mm) & (heights <= feats.d_mm) & sections.valid
    if calf_rows.sum() < 10:
        raise FitFailure(FailureReason.NOT_A_LEG, "the calf's cross-sections could not be measured")
    b_centre = sections.centroids_mm[calf_rows][0]
    b_radius = float(sections.mean_radii()[calf_rows][0])
    shifted = local - np.array([0.0, 0.0, feats.b_mm])
    anterior = cf.anterior_from_foot(shifted, b_centre, b_radius)
    cue = "foot"
    if anterior is None:
        anterior = cf.anterior_from_calf_bulge(sections.centroids_mm[calf_rows], heights[calf_rows], feats.c_mm)
        cue = "calf_bulge"
    if anterior is None:
        anterior, cue = np.array([0.0, 1.0]), "undetermined"
    hint = anterior[0] * basis[0] + anterior[1] * basis[1]
    rotation = cf.perpendicular_basis(axis, hint)
    origin = centre + basis.T @ np.array([b_centre[0], b_centre[1], feats.b_mm])
    return CalfAxis(rotation, origin, cue, feats.c_mm - feats.b_mm, feats.d_mm - feats.b_mm,
                    feats.d_at_window_edge, feats.b_at_scan_edge, feats.d_at_scan_edge, half_spaces)


def clip_to_half_spaces(points: np.ndarray, faces: np.ndarray | None, half_spaces) -> tuple[np.ndarray, np.ndarray | None]:
    """The points (n, 3) and faces inside ``half_spaces`` (all of them when empty)."""
    if not half_spaces:
        return points, faces
    index = keep_index(points, half_spaces)
    return points[index], cf.submesh(index, faces, len(points))

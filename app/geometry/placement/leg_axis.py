"""One candidate leg's calf axis, landmarks and anterior direction (paper section 2.1).

:func:`place_candidate` takes the points (and faces) of one leg - already cut out of its
scan by :mod:`app.geometry.placement.place` - and returns a :class:`CalfAxis`, in scan mm:

1. a first axis: area-weighted PCA of the leg's surface, then the line through the
   centroids of its compact (round, leg-like) slabs, which a flat foot does not drag
   (:func:`app.geometry.placement.first_axis.first_axis`);
2. the coarse circumference profile along it (36 rays every 3 mm),
   B, C, D found on it (:func:`app.geometry.anatomy.landmarks.find_feature_heights`), both ends
   tried when the scan's up is unknown, the foot's end down (:mod:`app.geometry.placement.leg_ends`);
3. the shank's long axis - the line through the section centroids from B to 85% of the
   way to D - adopted and the landmarks found again along it (steps 2 and 3:
   :mod:`app.geometry.placement.straight_reading`);
4. for a bent knee, when the straight reading fails: the straight runs of the leg's
   centre line, each cut free of the thigh at the knee (:mod:`app.geometry.placement.knee_bend`);
5. anterior from the foot, else opposite the calf bulge; the origin at B's centroid.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from app.geometry.anatomy.landmark_refusals import failure_stage
from app.geometry.errors import CalfWithoutBulge, FailureReason, FitFailure
from app.geometry.placement import calf_frame as cf
from app.geometry.placement.caps import Cap, closing_caps, leave_out_caps
from app.geometry.placement.first_axis import first_axis, pca_samples
from app.geometry.placement.knee_bend import hidden_knee_refusal, keep_index, seated_knee_refusals, shank_runs
from app.geometry.placement.straight_reading import REDETECT_DEG, AxisProfile, orient, refine

#: a lower leg (ankle to knee, 250+ mm; with a flat foot about 1.4 x its foot length)
#: is longer than it is wide; a ball or a box is not
MIN_ASPECT = 1.2


@dataclass(frozen=True)
class CalfAxis:
    """A candidate leg placed: ``rotation`` (3, 3) rows x, y (anterior), z (up) and
    ``origin_mm`` (3,) at B's centroid, in scan mm; ``anterior_cue`` (foot, calf_bulge,
    undetermined); ``c_mm``, ``d_mm`` heights of C and D above B; the edge flags; a bent
    knee's cut ``half_spaces`` ((point (3,), normal (3,)), ...); the ``caps`` a mesh tool
    closed the scan's cut ends with, left out (:mod:`app.geometry.placement.caps`)."""

    rotation: np.ndarray
    origin_mm: np.ndarray
    anterior_cue: str
    c_mm: float
    d_mm: float
    d_at_window_edge: bool
    b_at_scan_edge: bool
    d_at_scan_edge: bool
    half_spaces: tuple
    caps: tuple[Cap, ...] = ()


def _place_run(run, points, faces, samples, weights, basis) -> tuple[AxisProfile, np.ndarray, np.ndarray | None]:
    """One run of a bent leg's centre line placed as :func:`place_candidate` places a
    straight leg (raises FitFailure): the profile and the run's points and faces."""
    run_basis = cf.perpendicular_basis(run.direction, basis[1])
    run_points, run_faces = clip_to_half_spaces(points, faces, run.half_spaces)
    kept = keep_index(samples, run.half_spaces)
    run_samples, run_weights = samples[kept], None if weights is None else weights[kept]
    placed = refine(orient(run_points, run_faces, run.direction, run_basis, None, run.half_spaces),
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
                return refine(orient(points, faces, line_axis, line_basis, up), points, faces, samples, weights, ())
            except FitFailure as failure:
                failures = [*failures, failure]
    raise max(failures, key=failure_stage)


def place_candidate(points: np.ndarray, faces: np.ndarray | None, up: np.ndarray | None) -> CalfAxis:
    """Axis, B/C/D, refined calf axis, anterior direction: one candidate leg's placement.

    Paper section 2.1: PCA of the whole leg gives a first axis (refined by the compact
    slabs' centre line); B, C, D are found on the profile along it; then the axis is
    re-estimated as the calf's long axis
    (:func:`app.geometry.placement.straight_reading.section_centre_line`; the paper uses
    PCA of the calf between B and D) and the landmarks found again, at
    most twice or until the axis moves less than a tolerance
    (:func:`app.geometry.placement.straight_reading.refine`).  When the first axis finds no calf, the straight runs of
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
    caps = closing_caps(points, faces, basis)
    if not caps:
        return _place_straight_or_bent(points, faces, up, samples, weights, shape_axes, axis, basis)
    # the leg as the scanner cut it, its axis read again without the caps' surface
    points, faces = leave_out_caps(points, faces, caps)
    samples, weights = pca_samples(points, faces)
    shape_axes = cf.principal_frame(samples, weights)
    axis, basis = first_axis(samples, weights, shape_axes, up)
    try:
        placed = _place_straight_or_bent(points, faces, up, samples, weights, shape_axes, axis, basis)
    except FitFailure as failure:  # said of the leg as cut: say what was cut away
        failure.detail = (f"{failure.detail.rstrip('.')}. (The scan was closed at {len(caps)} of its ends by a "
                          "surface that is not skin - a cap a mesh tool adds to make a scan watertight -, left out "
                          "and the leg read as cut there: export the scan without closing its holes.)")
        failure.args = (failure.detail,)
        raise
    return replace(placed, caps=caps)


def _place_straight_or_bent(points: np.ndarray, faces: np.ndarray | None, up: np.ndarray | None,
                            samples: np.ndarray, weights: np.ndarray | None, shape_axes: np.ndarray,
                            axis: np.ndarray, basis: np.ndarray) -> CalfAxis:
    """:func:`place_candidate` after the first axis: the leg read straight along it, else as
    a bent knee's runs, else along the consensus line (raises FitFailure)."""
    if faces is None:
        # a cloud is sliced along this axis and then along axes a few degrees from it:
        # sorted along it once, each slicing's sort is a pass over nearly sorted data
        points = points[np.argsort(points @ axis, kind="stable")]
    half_spaces: tuple = ()
    try:
        # a bent leg's first axis is the body's: its landmarks may be found, and then not
        # found again along the calf's own axis - that too sends the leg to its runs
        placed = refine(orient(points, faces, axis, basis, up), points, faces, samples, weights, ())
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

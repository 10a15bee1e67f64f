"""A leg read straight along an axis (paper section 2.1): the coarse circumference
profile along it (:func:`profile_along`: 36 rays every 3 mm), B, C, D found on it - both
ends tried when the scan's up is unknown, the foot's end down (:func:`orient`) - then the
shank's long axis, the line through the section centroids from B to 85% of the way to D
(:func:`section_centre_line`), adopted and the landmarks found again along it
(:func:`refine`).  :mod:`app.geometry.placement.leg_axis` chooses among such readings.

Frame: scan mm; a reading's ``local`` points are in its axis's basis (z along the axis).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from app.geometry.anatomy.calf_candidates import MERGE_RISE, MERGE_RUN_MM, FeatureHeights
from app.geometry.anatomy.landmark_refusals import lost_inside_window
from app.geometry.anatomy.landmarks import find_feature_heights
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.placement import calf_frame as cf
from app.geometry.placement.coverage import bridged_strip_refusal, partial_view
from app.geometry.placement.first_axis import AXIS_TOLERANCE_DEG
from app.geometry.placement.leg_ends import landmarks_either_way, mirror_profile
from app.geometry.sections import PolarSections, polygon_centroid, slice_polar

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
#: rays of the coarse profile (circumference error of a 36-gon: 0.13%)
COARSE_ANGLES = 36
#: the shank's long axis is the line through the section centroids from B to this share
#: of the way to D (:func:`section_centre_line`).  On 20 generated legs the line of the
#: sections from the ankle joint + 10% to the knee joint - 10% (the skeleton's shank)
#: is reproduced to 0.25 degrees median (p90 1.2) by B to 85%, 2.3 degrees by B to D.
SHANK_AXIS_SHARE = 0.85
#: the re-sliced profile after an axis update keeps this much leg beyond B and D, mm
PROFILE_MARGIN_MM = 70.0


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


def profile_along(local: np.ndarray, faces: np.ndarray | None, z_range: tuple[float, float] | None = None,
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
    # axis, while a foot's sections can be incomplete over a longer run and are real).
    # The cut takes one arc: a section seen over less than MIN_END_COVERAGE of its angle
    # is partial when what it misses includes an arc that long.  A sparse cloud's
    # sections miss bins scattered all round, its whole leg over (5,500 vertices of a
    # lower leg: 65-89% of the bins seen): read on coverage alone, the last END_CUT_MM
    # below its cut were all dropped, with the rise above the knee waist they held, and
    # the scan was refused no_knee (benchmarks/robustness.py 220 23, sparse_leg_vertices-02
    # and -04, cut 20 and 13 mm above D at the section's edge, where the leg's girth has
    # risen by a tape's 2 mm 10 and 12 mm above D)
    seen_short = sections.coverage < MIN_END_COVERAGE
    if sections.largest_gap_deg is not None:
        seen_short &= sections.largest_gap_deg > (1.0 - MIN_END_COVERAGE) * 360.0
    partial = seen_short & ((heights - heights[0] <= END_CUT_MM) | (heights[-1] - heights <= END_CUT_MM))
    if cut_end:
        inwards = np.arange(len(heights))[::-cut_end]  # from the cut end into the leg
        whole = ~seen_short[inwards]
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


def cut_side(half_spaces, centre: np.ndarray, axis: np.ndarray) -> int:
    """Which end of the profile along ``axis`` a bent knee's cut lies at: +1 top, -1
    bottom, 0 no cut (the first half-space passes through the knee)."""
    if not half_spaces:
        return 0
    return 1 if (half_spaces[0][0] - centre) @ axis > 0 else -1


@contextmanager
def strip_named(sections: PolarSections, half_spaces: tuple) -> Iterator[None]:
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


def orient(points, faces, axis, basis, up, half_spaces=()) -> AxisProfile:
    """B, C, D along ``axis`` (and the axis possibly reversed).  ``half_spaces``: a bent
    knee's cut."""
    centre = points.mean(axis=0)
    local = (points - centre) @ basis.T
    heights, girth, sections = profile_along(local, faces, cut_end=cut_side(half_spaces, centre, axis))
    one_sided = None if half_spaces else partial_view(sections)  # (a bent knee's cut opens sections by design)
    if one_sided is not None:  # before the landmarks: a missing arc reads as another shape
        raise one_sided
    with strip_named(sections, half_spaces):
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


def section_centre_line(heights: np.ndarray, girth: np.ndarray, sections: PolarSections,
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


def height_on(new_axis: np.ndarray, basis: np.ndarray, heights: np.ndarray, sections: PolarSections,
               z_mm: float) -> float:
    """Height along ``new_axis`` (both about the same centre, mm) of the centroid of the
    section at ``z_mm`` of the profile along ``basis``'s z (its rows: x, y, z axes);
    the point on the old axis when that section has no centroid."""
    row = int(np.clip(np.searchsorted(heights, z_mm), 0, len(heights) - 1))
    centroid = sections.centroids_mm[row]
    xy = centroid if np.isfinite(centroid).all() else np.zeros(2)
    point = basis.T @ np.array([xy[0], xy[1], z_mm])
    return float(point @ new_axis)


def found_again(heights: np.ndarray, girth: np.ndarray, hint_mm: float, elongation: np.ndarray,
                on_foot: bool) -> FeatureHeights:
    """B, C, D found again on the profile along the calf's own axis (heights (k,), girth
    (k,) mm; the sections' ``elongation`` (k,)), C kept within C_HINT_MM of ``hint_mm``
    (where the previous axis put it: among a crown's similar peaks the choice does not
    jump) - unless the profile read without the hint puts the knee waist D below that C:
    then the hint has led C over the knee waist into the knee's bulge, and the reading
    without it stands (C is the first calf bulge above the ankle,
    :func:`app.geometry.anatomy.landmarks.find_feature_heights`).

    How a hint goes wrong: a first axis far off the shank cuts the leg obliquely and
    blurs the knee waist between the calf and the knee's bulge, which then read as one
    plateau whose higher end, the knee, is taken for C.  A random 6,000 of BodyParts3D's
    vertices put the first axis 15 degrees off the shank and C and D 145 and 110 mm high,
    cD 28 mm long - warned only that D had no distinct minimum and that the surface
    stood off the skin; along the shank's axis the profile shows the calf (377 mm), the
    knee waist (356 mm) and the knee (387 mm) apart, and C and D are found within 3 mm of
    the mesh's (tests/geometry/test_fit_real.py)."""
    feats = find_feature_heights(heights, girth, hint_mm, elongation, on_foot)
    try:
        free = find_feature_heights(heights, girth, None, elongation, on_foot)
    except FitFailure:
        return feats
    return free if free.d_mm < feats.c_mm else feats


def refine(oriented: AxisProfile, points, faces, samples, weights, half_spaces) -> AxisProfile:
    """The calf's long axis (:func:`section_centre_line`; the paper's section 2.1
    uses PCA of the calf between B and D), the landmarks found again along it, at most
    :data:`MAX_AXIS_ITERATIONS` times or until the axis moves less than
    :data:`AXIS_TOLERANCE_DEG`.  ``oriented``: what :func:`orient` found."""
    centre, local, heights, girth = oriented.centre, oriented.local, oriented.heights, oriented.girth
    sections, feats, axis, basis = oriented.sections, oriented.feats, oriented.axis, oriented.basis
    for _ in range(MAX_AXIS_ITERATIONS):
        line = section_centre_line(heights, girth, sections, feats.b_mm, feats.d_mm)
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
        hint = height_on(new_axis, basis, heights, sections, feats.c_mm)
        axis = new_axis
        basis = cf.perpendicular_basis(axis, basis[1])
        local = (points - centre) @ basis.T
        window = (feats.b_mm - PROFILE_MARGIN_MM, feats.d_mm + PROFILE_MARGIN_MM)
        heights, girth, sections = profile_along(local, faces, window, cut_side(half_spaces, centre, axis))
        # a bridged strip also pulls the sections' centroids, so the calf's axis, off the
        # limb's: the landmarks the first axis found may be lost along the new one
        # (benchmarks/coverage.py 20 37, leg 17, a 53-degree strip refused no_knee)
        with strip_named(sections, half_spaces):
            try:
                feats = found_again(heights, girth, hint, sections.elongations(), feats.on_foot)
            except FitFailure as failure:  # the window's end is not the scan's (a bent knee's run: its cut)
                scan = (float(local[:, 2].min()), float(local[:, 2].max()))
                said = failure if half_spaces else lost_inside_window(failure, window, scan, moved)
                if said is failure:
                    raise
                raise said from failure
    return AxisProfile(centre, local, heights, girth, sections, feats, axis, basis)

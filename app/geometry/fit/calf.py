"""The paper's calf pipeline on a leg already placed (sections 2.1-2.6): 200 sections x
72 rays (2.1), the profile, B1 and the tape girths (2.2), feature points and k-means
(2.3), the surface (2.4-2.5) and the error index (2.6), with the surface-to-scan
distance.  :func:`fit_calf` takes the scan in the calf frame (mm, B at z = 0);
:mod:`app.geometry.fit.pipeline` finds the leg, calls it and measures the rest of the leg.
"""

from __future__ import annotations

import time

import numpy as np

from app.geometry.anatomy.calf_candidates import MIN_CALF_RATIO
from app.geometry.anatomy.feature_layers import (
    B1_TAPE_REACH_MM,
    B1_TAPE_STEP_MM,
    LANDMARK_NAMES,
    Landmark,
    Landmarks,
    b1_height,
    height_tolerances,
    layer_heights,
    level_crossing,
)
from app.geometry.anatomy.feature_points import candidate_angles, radii_at, shared_angles
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.fit.options import FitOptions
from app.geometry.fit.result import FitResult
from app.geometry.fit.sparse_clouds import (
    MIN_CLOUD_POINTS_PER_MM,
    MIN_SECTOR_COVERAGE,
    SPARSE_CLOUD_POINTS_PER_MM,
    b1_on_graph,
    calf_density,
    open_sections_on_graph,
    too_sparse,
)
from app.geometry.placement import calf_frame as cf
from app.geometry.placement.coverage import bridged_arc_warning, bridged_arcs, open_arcs_failure, without_open_arcs
from app.geometry.placement.leg_placement import LegPlacement
from app.geometry.scan.skin_layers import skin_layers
from app.geometry.scan.skin_seam import skin_seam
from app.geometry.sections import TAPE_BAND_OFFSETS_MM, LimbGraph, slice_polar, tape_band_girths, tape_girths
from app.geometry.sections.mesh import inner_contour_share
from app.geometry.sections.polar import bridge_sections
from app.geometry.spline.distance import error_statistics
from app.geometry.spline.lsq import LsqGrid, fit_lsq_surface
from app.geometry.spline.nurbs import surface_from_layers
from app.geometry.spline.skin_distance import surface_to_scan

#: the error index of a point cloud is computed on at most this many of its calf points
#: (a fixed stride along the leg, rounded up).  E is an RMS: from n points its relative
#: standard error is sqrt(kappa - 1) / (2 sqrt(n)), kappa = mean(e^4) / mean(e^2)^2 of
#: e = l / r_k (3 for normal residuals; 4-13 measured on corpus clouds without stray
#: points), so 20k points give E to 0.6-1.2% (measured against all points: within 1.5%);
#: the calf of a 100k-face mesh has about as many vertices.  With 2% stray points kappa
#: is in the hundreds: E is then the strays' and known to ~5% only
MAX_ERROR_POINTS = 20_000

#: an lsq net with fewer scan points per control point than this is warned about: a
#: least-squares fit averages noise over the points of each control point's support
#: (16 basis functions overlap a point in a bicubic net, so each control point sees
#: about 16 times its share); below ~10 per control point the sections and the
#: smoothing, not the scan, set the surface (a registered body mesh's calf: ~140 points
#: for a 12 x 24 net's 288)
MIN_POINTS_PER_CONTROL = 10
#: a mesh's triangles are skin between its vertices (the sections sample them exactly),
#: so a mesh is warned about only with fewer vertices than control points: its
#: triangles are then larger than the net's patches
MIN_VERTICES_PER_CONTROL = 1


def _section_heights(b: float, d: float, options: FitOptions) -> np.ndarray:
    if options.section_spacing_mm:
        return np.arange(b, d + 1e-9, options.section_spacing_mm)
    return np.linspace(b, d, options.n_sections)

#: a mesh whose calf sections hold, at their median, contours inside the skin this long
#: against the skin's own is said to hold a wall: a hollowed mesh's wall runs the whole
#: skin round (about 1); a skin's section holds none (0), an interior fragment a little
INNER_WALL_SHARE = 0.5


def inner_wall_warning(local: np.ndarray, faces: np.ndarray, b_mm: float, d_mm: float) -> list[str]:
    """The warning (a list of none or one) for a mesh (calf-frame mm: local (n, 3), faces
    (f, 3)) whose sections from B to D hold a second surface inside the skin, joined to
    it (a wall given for 3D printing: a wall of its own is set aside at placement,
    app.geometry.placement.leg_copies).  Its girths are read on the outer contours
    (app.geometry.sections.mesh.outer_contours); the clinic is told what the file is."""
    share = inner_contour_share(local, faces, np.linspace(b_mm, d_mm, 9))
    if not np.isfinite(share).any() or np.nanmedian(share) < INNER_WALL_SHARE:
        return []
    return ["the mesh holds a second surface inside the skin round the calf (a mesh hollowed or given a wall, as for "
            "3D printing): the girths are read on the outer surface, the skin a scanner sees; export the scan itself "
            "if it is not"]


def fit_calf(
    local: np.ndarray,
    faces: np.ndarray | None,
    c_mm: float,
    d_mm: float,
    options: FitOptions | None = None,
    *,
    placement: LegPlacement | None = None,
    n_scan_points: int | None = None,
    graph: LimbGraph | None = None,
) -> FitResult:
    """Sections 2.1-2.6 on a scan already in the calf frame, B at z = 0.

    local (n, 3) calf-frame mm; faces (f, 3) or None; ``c_mm`` and ``d_mm`` the calf
    maximum and the minimum below the knee (B1 is found here, from the resampled
    profile).  ``placement``: where the leg was found (its frame, side and edge flags);
    without one, the identity frame, no side, no edges.  ``n_scan_points``: the whole
    scan's points (default: ``len(local)``).  ``graph``: a sparse cloud's neighbour graph
    over ``local`` (:func:`sparse_cloud_graph`), its tape girths read on it.
    """
    options = options or FitOptions()
    options.validate()
    timings: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        timings[stage] = now - clock
        clock = now

    if placement is not None:
        frame, side, d_at_window_edge = placement.frame, placement.side, placement.d_at_window_edge
        edges = (placement.b_at_scan_edge, placement.d_at_scan_edge)
    else:
        frame, side, d_at_window_edge = cf.CalfFrame(np.eye(3), np.zeros(3), 1.0, "given"), None, False
        edges = (False, False)
    b_mm = 0.0
    band_faces = faces  # the landmarks' tape bands reach TAPE_BAND_OFFSETS_MM past B and D
    if faces is not None:  # only the triangles reaching the calf (and its landmarks' bands)
        fz = local[:, 2][faces]
        top, bottom = fz.max(axis=1), fz.min(axis=1)
        reach = float(np.abs(TAPE_BAND_OFFSETS_MM).max())
        band_faces = faces[(top >= b_mm - 2.0 - reach) & (bottom <= d_mm + 2.0 + reach)]
        faces = faces[(top >= b_mm - 2.0) & (bottom <= d_mm + 2.0)]
    else:  # a cloud is sliced three times below: sorted along z once, each sort is then a pass
        order = np.argsort(local[:, 2], kind="stable")
        local = local[order]
        if graph is not None:  # the graph's ends renumbered to the sorted points
            renumber = np.empty(len(order), dtype=np.int64)
            renumber[order] = np.arange(len(order))
            graph = graph.renumbered(renumber)
    heights = _section_heights(b_mm, d_mm, options)
    cut_at_knee = placement is not None and bool(placement.half_spaces)  # a bent knee's cut opens sections too

    sections = slice_polar(local, faces, heights, options.n_angles)
    if faces is not None:
        sections = without_open_arcs(sections)
    valid = sections.valid
    in_calf = np.flatnonzero((local[:, 2] >= b_mm) & (local[:, 2] <= d_mm))
    density = None if faces is not None else calf_density(local, d_mm)  # a cloud's points per mm
    covered = float(np.median(sections.coverage))
    sparse = density is not None and covered < MIN_SECTOR_COVERAGE
    # what a sparse cloud's slabs leave open read on its graph, if it is as dense as a
    # cloud must be (open_sections_on_graph: a random sample sparser than that fitted so)
    on_graph = graph if sparse and density is not None and density >= MIN_CLOUD_POINTS_PER_MM else None
    if density is not None and valid.mean() < 0.9:  # a sparse cloud's open slabs, from their neighbours
        sections = bridge_sections(sections, sections)
        if on_graph is not None and sections.valid.mean() < 0.9:  # and on its graph
            sections = open_sections_on_graph(local, on_graph, sections)
        valid = sections.valid
    if valid.mean() < 0.9:
        if sparse and density is not None:
            raise too_sparse("the calf's cross-sections", covered, density, valid.mean())
        raise (open_arcs_failure(sections, "the calf's cross-sections", cut_at_knee) or FitFailure(
            FailureReason.NOT_A_LEG, f"only {valid.mean():.0%} of the calf's cross-sections are closed contours"))
    lap("resample")

    girth = sections.circumferences()
    # B1 halfway up the rise of the tape's girths, not of the chords' perimeters, which a
    # scanner's noise zig-zags longer - by 5 mm at the ankle and 3 at the calf on a mesh
    # with 0.3-1 mm of noise, moving the level and B1 with it (b1_height) - and halfway
    # between the tape's cB and cC, whose sections read a hole along the leg, where B's
    # section, the calf's lowest, has none below it to read it from (a hole at the ankle
    # put B1 3.5 mm low: chart_accuracy 8 11, leg 3 holes)
    tape_b_c = tape_band_girths(local, band_faces, np.array([b_mm, c_mm]), graph)
    b1_mm = None if graph is None else b1_on_graph(local, graph, b_mm, c_mm)  # a sparse cloud's on its graph
    if b1_mm is None:
        level = float(tape_b_c.mean()) if np.isfinite(tape_b_c).all() else None
        b1_mm = b1_height(heights, sections.tape_perimeters(), b_mm, c_mm, level)
        if level is not None:  # and read again on the tape's girths, as cB and cC are: the
            # sections' 72-ray hulls pick up a scanner's noise (1-2 mm more girth on a mesh
            # with 0.3-1 mm of noise) and crossed the level 1.5 mm low, cB1 1.2-2.5 mm short
            near = b1_mm + np.arange(-B1_TAPE_REACH_MM, B1_TAPE_REACH_MM + 1e-9, B1_TAPE_STEP_MM)
            b1_mm = level_crossing(near, tape_girths(local, band_faces, near, graph), level, b1_mm)
    layers_z = layer_heights(b_mm, b1_mm, c_mm, d_mm)
    layer_sections = slice_polar(local, faces, layers_z, options.n_angles)
    if faces is not None:
        layer_sections = without_open_arcs(layer_sections)
    if sparse and not layer_sections.valid.all():
        layer_sections = bridge_sections(layer_sections, sections)
        if on_graph is not None and not layer_sections.valid.all():
            layer_sections = open_sections_on_graph(local, on_graph, layer_sections)
    if not layer_sections.valid.all():
        if sparse and density is not None:
            raise too_sparse("a feature layer of the calf", covered, density, layer_sections.valid.mean())
        raise (open_arcs_failure(layer_sections, "the calf's feature layers", cut_at_knee)
               or FitFailure(FailureReason.NOT_A_LEG, "a feature layer of the calf is not a closed contour"))
    layer_girth = layer_sections.circumferences()
    tape_b1_d = tape_band_girths(local, band_faces, layers_z[[2, 6]], graph)
    tape = np.array([tape_b_c[0], tape_b1_d[0], tape_b_c[1], tape_b1_d[1]])
    if not np.isfinite(tape).all():  # a sparse slab the 360-ray fit could not close: the layer's own hull
        fallback = layer_sections.tape_perimeters()[[0, 2, 4, 6]]
        tape = np.where(np.isfinite(tape), tape, fallback)
    # a missing arc of skin at a landmark; not on a sparse cloud, whose slabs leave gaps
    # wherever its few points fall (its own warning, below, covers its girths)
    sparse_warned = density is not None and density < SPARSE_CLOUD_POINTS_PER_MM
    landmark_z = dict(zip(LANDMARK_NAMES, layers_z[[0, 2, 4, 6]]))
    arcs = {} if sparse_warned else bridged_arcs(sections, landmark_z)
    landmarks = Landmarks(
        B=Landmark(float(layers_z[0]), float(layer_girth[0])),
        B1=Landmark(float(layers_z[2]), float(layer_girth[2])),
        C=Landmark(float(layers_z[4]), float(layer_girth[4])),
        D=Landmark(float(layers_z[6]), float(layer_girth[6])),
        layer_heights_mm=layers_z,
        d_at_window_edge=d_at_window_edge,
        b_at_scan_edge=edges[0],
        d_at_scan_edge=edges[1],
        tape_girths_mm={name: float(g) for name, g in zip(("B", "B1", "C", "D"), tape)},
        tolerances_mm=height_tolerances(heights, girth, landmark_z),
        girth_uncertainties_mm={name: bound for name, (_, bound) in arcs.items()} or None,
    )
    lap("landmarks")

    m = options.points_per_layer
    angles = shared_angles(candidate_angles(layer_sections.radii_mm, layer_sections.angles_rad, m), m)
    radii = radii_at(layer_sections.radii_mm, layer_sections.angles_rad, angles)
    centres = layer_sections.centroids_mm
    layer_points = np.stack(
        [
            centres[:, 0, None] + radii * np.cos(angles),
            centres[:, 1, None] + radii * np.sin(angles),
            np.broadcast_to(layers_z[:, None], radii.shape),
        ],
        axis=-1,
    )
    lap("feature_points")

    every_calf_point = in_calf
    if faces is None:
        in_calf = in_calf[:: -(-len(in_calf) // MAX_ERROR_POINTS)]
    lsq_fit = None
    if options.mode == "lsq":
        lsq_fit = fit_lsq_surface(sections, layers_z, local[in_calf], LsqGrid.parse(options.grid))
        surface = lsq_fit.surface
    else:
        try:
            surface = surface_from_layers(layer_points, mode=options.mode)
        except (ValueError, np.linalg.LinAlgError) as exc:
            raise FitFailure(
                FailureReason.DEGENERATE_SURFACE,
                "the feature points cannot be interpolated (two of them coincide or a layer folds over itself)",
            ) from exc
    lap("nurbs")

    error, _, _ = error_statistics(surface, local[in_calf], heights[valid], sections.mean_radii()[valid], layers_z)
    skin = surface_to_scan(surface, local, faces, b_mm, d_mm)
    fit_warnings = []
    if sparse_warned:
        # its girths, its knee waist D and B1 are read on its neighbour graph
        # (app.geometry.fit.sparse_clouds); B, C and the thigh's points on slabs: on the
        # sparse re-scans of benchmarks/chart_accuracy.py 8 11 their girths read within
        # 1.7 mm p95 of the clean mesh's, their lengths within 2.6-6.5 mm p95 (11 mm where
        # the scan ends at the knee waist, which its own warning says)
        fit_warnings.append(
            f"the cloud is sparse ({density:.1f} points per mm of the calf's height): its girths, the knee waist D and "
            "B1 are read where the edges between neighbouring points cross the tape's plane, but the ankle B, the calf "
            "C and the thigh's points (E, F and the gluteal fold G) are placed on slabs up to 20 mm thick, which can "
            "move them and the lengths several mm; a denser export measures them better, or take them by tape")
    layers = skin_layers(local[in_calf]) if faces is None else None  # a cloud's skin twice (a mesh's is one surface)
    # a cloud captured in parts while the leg moved steps along the seam: read on every
    # calf point (each window's fit needs its points)
    seam = skin_seam(local[every_calf_point], b_mm, d_mm) if faces is None else None
    if layers is not None and layers.doubled:
        fit_warnings.append(layers.doubled_text)
    if faces is not None:
        fit_warnings.extend(inner_wall_warning(local, faces, b_mm, d_mm))
    if seam is not None and seam.moved:
        fit_warnings.append(seam.moved_text)
    for name in LANDMARK_NAMES:
        tolerance = (landmarks.tolerances_mm or {}).get(name, 0.0)
        if not landmarks.at_edge(name) and landmarks.confidence(name) == "low":
            fit_warnings.append(
                f"{name}'s height is uncertain by about {tolerance:.0f} mm: the girth stays within a tape's reading "
                f"of {name}'s over that length, so {name}'s girth is sure but its height (and the lengths and layers "
                "measured from it) is not")
    tapes = landmarks.tape_girths_mm or {}
    if tapes.get("B") and tapes.get("C") and tapes["C"] < MIN_CALF_RATIO * tapes["B"]:
        # measured only because its ankle stands on its foot (calf_candidates.MIN_CALF_RATIO_ON_FOOT):
        # on such legs (benchmarks/swollen.py 40 19) cD read up to 4.2 mm off the leg's own
        fit_warnings.append(
            f"the calf bulges only {tapes['C'] / tapes['B']:.2f} times over the ankle (a healthy calf 1.4-2.3 times, "
            "ANSUR II): a swollen or wasted lower leg, measured because its ankle stands on its foot; B, C and D lie "
            "on a nearly flat girth profile and cD may read up to 4-5 mm off a tape held at the knee waist - check "
            "cD by tape")
    bridged = bridged_arc_warning(arcs)
    if bridged is not None:
        fit_warnings.append(bridged)
    if skin.off_skin:
        fit_warnings.append(
            f"the surface {skin.off_skin_text}, so its girths there are not the scan's"
            + (" (try mode=paper or a finer grid)" if options.mode == "lsq" else ""))
    if lsq_fit is not None:
        per_control = len(in_calf) / (lsq_fit.grid.around * lsq_fit.grid.along)
        needed = MIN_POINTS_PER_CONTROL if faces is None else MIN_VERTICES_PER_CONTROL
        if per_control < needed:
            what = "scan points" if faces is None else "mesh vertices"
            fit_warnings.append(
                f"the lsq net has {per_control:.1f} {what} per control point (fewer than {needed}): the surface is set "
                "by the resampled sections and the smoothing more than by the scan; use a coarser grid or a denser scan")
    lap("error")
    return FitResult(
        surface=surface,
        frame=frame,
        landmarks=landmarks,
        sections=sections,
        layer_sections=layer_sections,
        layer_points=layer_points,
        feature_angles_rad=angles,
        error=error,
        side=side,
        n_scan_points=int(n_scan_points if n_scan_points is not None else len(local)),
        options=options,
        timings=timings,
        placement=placement,
        lsq=lsq_fit,
        skin=skin,
        skin_layers=layers,
        skin_seam=seam,
        sparse_points_per_mm=float(density) if sparse_warned and density is not None else None,
        fit_warnings=tuple(fit_warnings),
    )

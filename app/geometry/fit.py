"""The paper's pipeline end to end: scan -> calf frame -> sections -> landmarks ->
feature points -> NURBS surface -> error index (sections 2.1-2.6).

:func:`fit_scan` returns a :class:`FitResult` or raises :class:`FitFailure` with the
reason.  Everything is in millimetres; the calf frame is described in
:mod:`app.geometry.calf_frame`.

Finding the calf (section 2.1: segmentation by anatomy, orientation by PCA):
1. a body is split into its legs (:func:`app.geometry.calf_frame.split_body_legs`); a
   leg scan must be longer than it is wide;
2. first axis: area-weighted PCA of the surface, then the line through the centroids of
   the leg-like (compact) slabs, which a flat foot does not drag;
3. the circumference profile along that axis gives B, C, D
   (:func:`app.geometry.landmarks.find_feature_heights`), both ends tried when the
   scan's up is unknown;
4. the calf's own PCA axis (B to D) is adopted, B, C, D re-detected if it moved more
   than :data:`REDETECT_DEG`;
5. anterior from the foot, else opposite the calf bulge; origin at the B centroid.
Then :func:`fit_calf`: 200 sections x 72 rays (2.1), the profile and B1 (2.2), feature
points and k-means (2.3), the surface (2.4-2.5) and the error index (2.6).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from app.geometry import calf_frame as cf
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.feature_points import candidate_angles, radii_at, shared_angles
from app.geometry.landmarks import (
    Landmark,
    Landmarks,
    b1_height,
    find_feature_heights,
    layer_heights,
)
from app.geometry.nurbs import NurbsSurface, surface_from_layers
from app.geometry.scan_io import Scan
from app.geometry.sections import PolarSections, slice_polar
from app.geometry.surface_error import SurfaceError, error_statistics

#: a lower leg (ankle to knee, 250+ mm; with a flat foot about 1.4 x its foot length)
#: is longer than it is wide; a ball or a box is not
MIN_ASPECT = 1.2
#: slabs of the surface whose spread is rounder than this (major/minor axis) are leg-like;
#: a 55 x 40 mm ellipse is 1.4, a footprint 2.5 or more
COMPACT_RATIO = 1.6
SLAB_MM = 5.0
PCA_SAMPLES = 30_000
CENTROID_LINE_ITERATIONS = 4
#: spacing of the coarse profile used to find B, C, D along the whole leg, mm
COARSE_SPACING_MM = 2.0
#: spacing of the first profile over the whole scan (before the calf is known), mm
FIRST_SPACING_MM = 3.0
#: the calf axis is re-estimated by PCA until it moves less than this, degrees
AXIS_TOLERANCE_DEG = 0.5
MAX_AXIS_ITERATIONS = 2
#: an axis update smaller than this (degrees) keeps the landmarks without re-slicing: a
#: 2 degree tilt moves a plane by +-1.7 mm across a 50 mm radius and its girth by 0.06%
REDETECT_DEG = 2.0
#: rays of the coarse profile (circumference error of a 36-gon: 0.13%)
COARSE_ANGLES = 36
#: the re-sliced profile after an axis update keeps this much leg beyond B and D, mm
PROFILE_MARGIN_MM = 70.0
SURFACE_MODES = ("paper", "paper_stacked")


@dataclass(frozen=True)
class FitOptions:
    """Options of a fit.

    side : "left" | "right" | None  - which leg of a body; recorded for a leg scan.
    points_per_layer : m, the shared feature angles per layer (paper: 8 or 15).
    n_sections : resampled sections between B and D (paper: 200).
    section_spacing_mm : if given, sections every this many mm instead (e.g. 1.0).
    n_angles : rays per section (paper: 72, i.e. 5 degrees).
    """

    side: str | None = None
    points_per_layer: int = 15
    n_sections: int = 200
    section_spacing_mm: float | None = None
    n_angles: int = 72
    mode: str = "paper"

    def validate(self) -> None:
        if self.side not in (None, "left", "right"):
            raise FitFailure(FailureReason.INVALID_OPTION, f"side must be left or right, not {self.side!r}")
        if not 4 <= self.points_per_layer <= 36:
            raise FitFailure(FailureReason.INVALID_OPTION, "points per layer must be between 4 and 36 (paper: 8 or 15)")
        if not 20 <= self.n_sections <= 2000:
            raise FitFailure(FailureReason.INVALID_OPTION, "sections must be between 20 and 2000")
        if self.section_spacing_mm is not None and not 0.2 <= self.section_spacing_mm <= 20:
            raise FitFailure(FailureReason.INVALID_OPTION, "section spacing must be 0.2-20 mm")
        if self.mode not in SURFACE_MODES:
            raise FitFailure(FailureReason.INVALID_OPTION, f"mode must be one of {', '.join(SURFACE_MODES)}")
        if self.n_angles not in (36, 72, 144, 360):
            raise FitFailure(FailureReason.INVALID_OPTION, "angles per section must be 36, 72, 144 or 360")


@dataclass(frozen=True)
class FitResult:
    """Everything the pipeline produced (calf-frame mm unless stated)."""

    surface: NurbsSurface
    frame: cf.CalfFrame
    landmarks: Landmarks
    sections: PolarSections  # the resampled sections between B and D
    layer_sections: PolarSections  # the 7 feature layers
    layer_points: np.ndarray  # (7, m, 3) the data grid
    feature_angles_rad: np.ndarray  # (m,)
    error: SurfaceError
    side: str | None
    n_scan_points: int
    options: FitOptions
    timings: dict = field(default_factory=dict)


@dataclass(frozen=True)
class _LegPlacement:
    """A leg with its refined axis, landmarks and anterior direction (scan mm).

    ``c_mm`` and ``d_mm`` are calf-frame heights of C and D; B is the frame's origin (0).
    """

    points: np.ndarray
    faces: np.ndarray | None
    frame: cf.CalfFrame
    c_mm: float
    d_mm: float
    d_at_window_edge: bool


def _profile(local: np.ndarray, faces: np.ndarray | None, z_range: tuple[float, float] | None = None):
    """Coarse circumference profile along z (36 rays), for finding B, C, D.

    The whole leg every :data:`FIRST_SPACING_MM`; a window ``z_range`` every
    :data:`COARSE_SPACING_MM`.
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
    return heights, sections.circumferences(), sections


def _mirror(heights: np.ndarray, girth: np.ndarray, sections: PolarSections):
    """The same profile seen from the other end: z -> -z, x -> -x, y kept (a rotation
    by 180 degrees about y), so that nothing has to be sliced again."""
    n = len(sections.angles_rad)
    rays = (n // 2 - np.arange(n)) % n  # theta -> pi - theta
    mirrored = PolarSections(
        -heights[::-1],
        sections.centroids_mm[::-1] * np.array([-1.0, 1.0]),
        sections.radii_mm[::-1][:, rays],
        sections.angles_rad,
        sections.coverage[::-1],
    )
    return -heights[::-1], girth[::-1], mirrored


def _pca_samples(points: np.ndarray, faces: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Area-weighted surface samples, thinned by a fixed stride to at most 30,000 (the
    principal axes of 30k samples of a leg agree with all of them to ~0.1 degree)."""
    samples, weights = cf.surface_samples(points, faces)
    stride = max(len(samples) // PCA_SAMPLES, 1)
    return samples[::stride], None if weights is None else weights[::stride]


def _place_leg(points: np.ndarray, faces: np.ndarray | None, up: np.ndarray | None, mm_per_unit: float,
               pca: tuple[np.ndarray, np.ndarray | None] | None = None, shape_axes: np.ndarray | None = None) -> _LegPlacement:
    """Axis by PCA, B/C/D, refined calf axis, anterior direction: the leg's calf frame.

    Paper section 2.1: PCA of the whole leg gives a first axis; B, C, D are found on
    the profile along it (both ways round when the scan's up is unknown); then the axis
    is re-estimated by PCA of the calf between B and D and the landmarks found again,
    at most :data:`MAX_AXIS_ITERATIONS` times or until the axis moves less than
    :data:`AXIS_TOLERANCE_DEG`.
    """
    samples, weights = pca if pca is not None else _pca_samples(points, faces)
    shape_axes = shape_axes if shape_axes is not None else cf.principal_frame(samples, weights)
    axis = shape_axes[2]
    if up is not None and axis @ up < 0:
        axis = -axis
    centre = points.mean(axis=0)
    basis = cf.perpendicular_basis(axis, shape_axes[1])
    # a flat foot drags the PCA axis; the line through the centroids of the compact
    # (leg-like, not footprint-like) slabs of the surface does not
    for _ in range(CENTROID_LINE_ITERATIONS):
        line = _centroid_line_axis((samples - centre) @ basis.T, weights)
        if line is None:
            break
        new_axis = basis.T @ line
        if new_axis @ axis < 0:
            new_axis = -new_axis
        moved = np.degrees(np.arccos(np.clip(new_axis @ axis, -1.0, 1.0)))
        axis = new_axis
        basis = cf.perpendicular_basis(axis, basis[1])
        if moved < AXIS_TOLERANCE_DEG:
            break
    local = (points - centre) @ basis.T
    heights, girth, sections = _profile(local, faces)
    if up is not None:
        feats = find_feature_heights(heights, girth)
    else:
        feats, flipped = _either_way(heights, girth)
        if flipped:  # the scan's axis pointed towards the foot
            axis = -axis
            basis = cf.perpendicular_basis(axis, basis[1])
            local = (points - centre) @ basis.T
            heights, girth, sections = _mirror(heights, girth, sections)
    for _ in range(MAX_AXIS_ITERATIONS):
        sample_z = (samples - centre) @ basis[2]
        calf = (sample_z >= feats.b_mm) & (sample_z <= feats.d_mm)
        new_axis = cf.principal_axis(samples[calf], None if weights is None else weights[calf])
        if new_axis @ axis < 0:
            new_axis = -new_axis
        moved = np.degrees(np.arccos(np.clip(new_axis @ axis, -1.0, 1.0)))
        if moved < AXIS_TOLERANCE_DEG:
            break
        if moved < REDETECT_DEG:
            # a small tilt moves B and D by well under a millimetre: keep the landmarks
            # (re-expressed about the same centre) and only adopt the calf's axis
            axis = new_axis
            basis = cf.perpendicular_basis(axis, basis[1])
            local = (points - centre) @ basis.T
            break
        axis = new_axis
        basis = cf.perpendicular_basis(axis, basis[1])
        local = (points - centre) @ basis.T
        window = (feats.b_mm - PROFILE_MARGIN_MM, feats.d_mm + PROFILE_MARGIN_MM)
        heights, girth, sections = _profile(local, faces, window)
        feats = find_feature_heights(heights, girth, feats.c_mm)

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
    frame = cf.CalfFrame(rotation, origin, mm_per_unit, cue)
    return _LegPlacement(
        points, faces, frame, feats.c_mm - feats.b_mm, feats.d_mm - feats.b_mm, feats.d_at_window_edge
    )


def _centroid_line_axis(local_samples: np.ndarray, weights: np.ndarray | None) -> np.ndarray | None:
    """Direction (3,), in the samples' frame, of the line through the centroids of the
    compact slabs of the surface.

    The surface samples are binned into :data:`SLAB_MM` slabs along z; each slab's
    weighted centroid and 2x2 covariance are accumulated with bincount.  A slab counts
    as leg-like when its spread is nearly round (sqrt of the eigenvalue ratio below
    :data:`COMPACT_RATIO`): a shin is, a footprint is not.  Returns None when fewer
    than 10 slabs qualify.
    """
    w = np.ones(len(local_samples)) if weights is None else weights
    z = local_samples[:, 2]
    slab = np.floor((z - z.min()) / SLAB_MM).astype(np.int64)
    n = int(slab.max()) + 1
    total = np.bincount(slab, weights=w, minlength=n)
    keep = total > 0
    moments = {}
    x, y = local_samples[:, 0], local_samples[:, 1]
    for name, values in (("x", x), ("y", y), ("xx", x * x), ("yy", y * y), ("xy", x * y), ("z", z)):
        moments[name] = np.bincount(slab, weights=w * values, minlength=n)[keep] / total[keep]
    cxx = moments["xx"] - moments["x"] ** 2
    cyy = moments["yy"] - moments["y"] ** 2
    cxy = moments["xy"] - moments["x"] * moments["y"]
    half_trace, det = (cxx + cyy) / 2, cxx * cyy - cxy**2
    root = np.sqrt(np.maximum(half_trace**2 - det, 0.0))
    small, large = half_trace - root, half_trace + root
    compact = (small > 0) & (large < COMPACT_RATIO**2 * np.maximum(small, 1e-12))
    if compact.sum() < 10:
        return None
    centres = np.column_stack([moments["x"], moments["y"], moments["z"]])[compact]
    direction = cf.principal_axis(centres, total[keep][compact])
    return direction if direction[2] > 0 else -direction


def _either_way(heights: np.ndarray, girth: np.ndarray):
    """Landmarks with the scan's axis as it is or reversed; (features, reversed?)."""
    try:
        return find_feature_heights(heights, girth), False
    except FitFailure as as_is:
        flipped_heights = -heights[::-1]
        try:
            return find_feature_heights(flipped_heights, girth[::-1]), True
        except FitFailure as reversed_failure:
            # report the failure of the more plausible orientation: knee end thicker
            tenth = max(len(girth) // 10, 1)
            ends_up = np.nanmean(girth[-tenth:]) >= np.nanmean(girth[:tenth])
            raise (as_is if ends_up else reversed_failure) from None


def _is_body(points: np.ndarray) -> bool:
    """A whole body: longer than :data:`app.geometry.calf_frame.BODY_MIN_LENGTH_MM` along
    its main axis (PCA of a 20k-point subsample)."""
    sample = points[:: max(len(points) // 20000, 1)]
    return float(np.ptp(points @ cf.principal_axis(sample))) >= cf.BODY_MIN_LENGTH_MM


def _choose_leg(scan: Scan, side: str | None) -> tuple[_LegPlacement, str | None]:
    points, faces = scan.points_mm, scan.faces
    if not _is_body(points):
        pca = _pca_samples(points, faces)
        shape_axes = cf.principal_frame(*pca)
        extents = np.ptp(pca[0] @ shape_axes.T, axis=0)
        if extents[2] < MIN_ASPECT * extents[:2].max():
            raise FitFailure(
                FailureReason.NOT_A_LEG,
                f"the scan is {extents[2]:.0f} mm long and {extents[:2].max():.0f} mm wide: "
                f"a leg is at least {MIN_ASPECT:g} times longer than it is wide",
            )
        return _place_leg(points, faces, None, scan.mm_per_unit, pca, shape_axes), side
    legs = []
    for cut in cf.split_body_legs(points):
        legs.append(
            _place_leg(points[cut.point_index], cf.submesh(cut.point_index, faces, len(points)), cut.up, scan.mm_per_unit)
        )
    # left/right from the two legs' shared anterior direction: right = anterior x up
    up = legs[0].frame.rotation[2] + legs[1].frame.rotation[2]
    anterior = legs[0].frame.rotation[1] + legs[1].frame.rotation[1]
    right = np.cross(anterior, up)
    first_is_right = (legs[0].frame.origin_mm - legs[1].frame.origin_mm) @ right > 0
    chosen_side = side or "right"
    pick = 0 if (chosen_side == "right") == first_is_right else 1
    return legs[pick], chosen_side


def _section_heights(b: float, d: float, options: FitOptions) -> np.ndarray:
    if options.section_spacing_mm:
        return np.arange(b, d + 1e-9, options.section_spacing_mm)
    return np.linspace(b, d, options.n_sections)


def placement_dict(leg: _LegPlacement, side: str | None) -> dict:
    """The calf placement as plain JSON (to hand from an upload check to the fit)."""
    frame = leg.frame
    return {
        "side": side,
        "rotation": frame.rotation.tolist(),
        "origin_mm": frame.origin_mm.tolist(),
        "mm_per_unit": frame.mm_per_unit,
        "anterior_cue": frame.anterior_cue,
        "c_mm": leg.c_mm,
        "d_mm": leg.d_mm,
        "d_at_window_edge": leg.d_at_window_edge,
    }


def _placed_leg(scan: Scan, placement: dict) -> tuple[_LegPlacement, str | None]:
    """Rebuild a leg placement found earlier on the same scan (no landmark search).

    For a body, the legs are cut apart again (cheap) and the one whose points lie
    around the stored calf origin is taken.
    """
    frame = cf.CalfFrame(
        np.asarray(placement["rotation"], dtype=float),
        np.asarray(placement["origin_mm"], dtype=float),
        float(placement["mm_per_unit"]),
        placement["anterior_cue"],
    )
    points, faces = scan.points_mm, scan.faces
    if _is_body(points):
        cuts = cf.split_body_legs(points)
        distance = [np.linalg.norm(np.median(points[c.point_index], axis=0) - frame.origin_mm) for c in cuts]
        cut = cuts[int(np.argmin(distance))]
        points, faces = points[cut.point_index], cf.submesh(cut.point_index, faces, len(scan.points_mm))
    leg = _LegPlacement(points, faces, frame, float(placement["c_mm"]), float(placement["d_mm"]), bool(placement["d_at_window_edge"]))
    return leg, placement["side"]


def fit_scan(scan: Scan, options: FitOptions | None = None, placement: dict | None = None) -> FitResult:
    """Fit the paper's NURBS calf model to a scan (see module docstring).

    ``placement`` (from :func:`check_scan` on the same scan and options) skips the search
    for the leg, its axis and its landmarks; the result is the same.
    """
    options = options or FitOptions()
    options.validate()
    started = time.perf_counter()
    leg, side = _placed_leg(scan, placement) if placement else _choose_leg(scan, options.side)
    placed = time.perf_counter()
    local = leg.frame.to_calf(leg.points)
    result = fit_calf(local, leg.faces, leg.c_mm, leg.d_mm, options, frame=leg.frame, side=side,
                      n_scan_points=len(scan.points_mm), d_at_window_edge=leg.d_at_window_edge)
    result.timings["calf_frame"] = placed - started
    return result


def fit_calf(
    local: np.ndarray,
    faces: np.ndarray | None,
    c_mm: float,
    d_mm: float,
    options: FitOptions | None = None,
    *,
    frame: cf.CalfFrame | None = None,
    side: str | None = None,
    n_scan_points: int | None = None,
    d_at_window_edge: bool = False,
) -> FitResult:
    """Sections 2.1-2.6 on a scan already in the calf frame, B at z = 0.

    local (n, 3) calf-frame mm; faces (f, 3) or None; ``c_mm`` and ``d_mm`` the calf
    maximum and the minimum below the knee (B1 is found here, from the resampled
    profile).  ``frame`` defaults to the identity placement.
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

    if frame is None:
        frame = cf.CalfFrame(np.eye(3), np.zeros(3), 1.0, "given")
    b_mm = 0.0
    if faces is not None:  # only the triangles reaching the calf
        fz = local[:, 2][faces]
        faces = faces[(fz.max(axis=1) >= b_mm - 2.0) & (fz.min(axis=1) <= d_mm + 2.0)]
    heights = _section_heights(b_mm, d_mm, options)
    sections = slice_polar(local, faces, heights, options.n_angles)
    valid = sections.valid
    if valid.mean() < 0.9:
        raise FitFailure(FailureReason.NOT_A_LEG, f"only {valid.mean():.0%} of the calf's cross-sections are closed contours")
    lap("resample")

    girth = sections.circumferences()
    b1_mm = b1_height(heights, girth, b_mm, c_mm)
    layers_z = layer_heights(b_mm, b1_mm, c_mm, d_mm)
    layer_sections = slice_polar(local, faces, layers_z, options.n_angles)
    if not layer_sections.valid.all():
        raise FitFailure(FailureReason.NOT_A_LEG, "a feature layer of the calf is not a closed contour")
    layer_girth = layer_sections.circumferences()
    landmarks = Landmarks(
        B=Landmark(float(layers_z[0]), float(layer_girth[0])),
        B1=Landmark(float(layers_z[2]), float(layer_girth[2])),
        C=Landmark(float(layers_z[4]), float(layer_girth[4])),
        D=Landmark(float(layers_z[6]), float(layer_girth[6])),
        layer_heights_mm=layers_z,
        d_at_window_edge=d_at_window_edge,
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

    try:
        surface = surface_from_layers(layer_points, mode=options.mode)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise FitFailure(FailureReason.DEGENERATE_SURFACE, f"the feature grid cannot be interpolated: {exc}") from exc
    lap("nurbs")

    in_calf = (local[:, 2] >= b_mm) & (local[:, 2] <= d_mm)
    error, _, _ = error_statistics(surface, local[in_calf], heights[valid], sections.mean_radii()[valid], layers_z)
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
    )


def check_scan(scan: Scan, options: FitOptions | None = None) -> dict:
    """Quick acceptance test of a scan: the options are valid and the calf can be placed
    (the leg found, B, C and D present).  Raises FitFailure with the reason otherwise;
    returns the placement (:func:`placement_dict`), which :func:`fit_scan` can reuse.
    Costs the calf-frame stage of a fit."""
    options = options or FitOptions()
    options.validate()
    leg, side = _choose_leg(scan, options.side)
    return placement_dict(leg, side)

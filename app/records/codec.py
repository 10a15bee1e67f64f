"""The calf record: the compact, exact result of a fit, as a frozen dataclass and JSON.

JSON layout (``schema_version`` 3; all lengths in millimetres, ``units`` = "mm")::

    schema_version, units, side ("left" | "right" | null)
    side_inference {side, confidence, source ("given" | "body" | "foot" | null)}
    warnings  [sentences]: what the fit noticed about the scan (landmarks at its edge,
              floor or pieces removed, side unknown)
    surface   {degree_u, degree_v, knots_u, knots_v, control_points [nu][nv][3],
               weights [nu][nv], periodic_u}
    frame     4x4 matrix taking calf-frame mm to the scan's own coordinates and units
              (so it includes the uniform scale 1/mm_per_unit)
    scan      {units, format, n_points, anterior_cue, sole_mm, sole_reason}: sole_mm, when
              the scan holds a foot standing flat down to its sole, is the calf-frame z
              of the heel's lowest skin (the floor under a standing person; heights
              above the floor are height_mm - sole_mm); sole_reason, when the foot is in
              the scan but its sole is not (cut through the foot, a pointed foot), says
              why (app.geometry.anatomy.sole)
    landmarks {B, B1, C, D: {height_mm, circumference_mm, tape_girth_mm, at_scan_edge,
              height_tolerance_mm, confidence, girth_uncertainty_mm (only where the scan
              misses an arc of skin there whose bridge may move the girth over 3 mm)}}
              (calf-frame z; B = 0).  circumference_mm is the perimeter of the section
              (72 rays, the paper's 3.2), tape_girth_mm the perimeter of its convex hull
              (what a tape reads: ANSUR, RAL-GZ 387), at_scan_edge: the scan stops there
    layers    {heights_mm [7], feature_angles_deg [m]}
    chart     (version 3) the order form's points off the calf, measured from the scan:
              the foot's (app.geometry.anatomy.foot) {foot_length, cA, cY: {value_mm,
              at_mm [3] (calf frame, where the tape lies), reason (why not measured, else
              null)}} and the thigh's (app.geometry.anatomy.thigh) {cE, cF, cG: {value_mm,
              height_mm (calf frame z), reason}}
    leg_model (version 3, optional) the leg from B to G when the scan reaches the top of
              the thigh (app.geometry.fit.leg_model): {range "B-G", grid, layers_mm {B, B1,
              C, D, E, F, G} (its v = k/6 at each), correction_rms_mm, surface_to_scan,
              surface (the calf's form, app.records.surface_codec)}, or {reason} when there
              is none; the calf's ``surface`` stays the paper's, B to D
    fit       {mode, layers, points_per_layer, sections, angles, error_index,
               error_index_exact, error_index_diameter, error_index_exact_diameter,
               max_error_mm, mean_error_mm, n_scan_points, n_error_points, seconds,
               stage_seconds, per_layer, d_at_window_edge, surface_to_scan, skin_layers and
               skin_seam (a cloud's: its skin twice, its skin stepping along a line up the
               calf), sparse_points_per_mm (a cloud too sparse for thin slabs: its points
               per mm of the calf's height; a thigh-high designed from it is "review")}
              surface_to_scan: the other side of E - the surface sampled densely, each
              sample's distance to the scan where the scan has data
              (app.geometry.spline.skin_distance): median_mm, p99_mm, max_mm, coverage,
              off_skin_share, worst_ring_share (of one ring, more than 3 mm off), ...

The surface is stored in the standard open form (see :mod:`app.geometry.spline.nurbs`): u runs
around the leg and is periodic but written unwrapped - the first ``degree_u`` control
columns are repeated at the end, ``knots_u`` has nu + degree_u + 1 entries and the
valid u domain is [knots_u[degree_u], knots_u[nu]]; v runs from B (layer 0) to D.
Error indices are fractions: 0.0037 means 0.37%.

Version 1 records (before tape girths, warnings and side inference) are still read as
they are: their landmarks simply have no ``tape_girth_mm`` and no warnings; version 2
records have no ``chart`` (their foot points read as not measured).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from app.geometry.anatomy import LANDMARK_NAMES
from app.geometry.errors import FitFailure
from app.geometry.fit.result import FitResult
from app.geometry.spline.bounds import check_leg_tube
from app.geometry.spline.nurbs import NurbsSurface
from app.records.surface_codec import MAX_CONTROL_MM, parse_surface, surface_document
from app.records.surface_codec import finite_array as _finite_array
from app.records.surface_codec import invalid_record as _invalid

SCHEMA_VERSION = 3
READABLE_VERSIONS = (1, 2, 3)
#: the chart's points (version 3) and the largest value any of them can have, mm
CHART_POINTS = ("foot_length", "cA", "cY", "cE", "cF", "cG")
MAX_CHART_MM = 1000.0
#: most samples of the stored thigh profile (D to G every 5 mm: a 2 m leg needs ~200)
MAX_THIGH_PROFILE = 400
@dataclass(frozen=True)
class LegModelRecord:
    """The record's leg model (``leg_model``, app.geometry.fit.leg_model): the surface
    from B to G with its anchors and fit, or None with the reason there is none."""

    surface: NurbsSurface | None
    reason: str | None = None
    layers_mm: dict = field(default_factory=dict)  # B, B1, C, D, E, F, G heights, calf frame
    grid: str | None = None
    correction_rms_mm: tuple = ()
    surface_to_scan: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        if self.surface is None:
            return {"reason": self.reason}
        return {"range": "B-G", "grid": self.grid, "layers_mm": self.layers_mm, "correction_rms_mm": list(self.correction_rms_mm),
                "surface_to_scan": self.surface_to_scan, "surface": surface_document(self.surface)}


@dataclass(frozen=True)
class CalfRecord:
    """A stored calf model (see the module docstring for the JSON form)."""

    surface: NurbsSurface
    frame: np.ndarray  # (4, 4) calf mm -> scan units
    landmarks: dict  # name -> {"height_mm", "circumference_mm"}
    side: str | None = None
    layers: dict = field(default_factory=dict)
    fit: dict = field(default_factory=dict)
    scan: dict = field(default_factory=dict)
    schema_version: int = SCHEMA_VERSION
    warnings: tuple = ()
    side_inference: dict | None = None
    chart: dict = field(default_factory=dict)  # version 3: foot_length, cA, cY (module docstring)
    leg_model: LegModelRecord | None = None  # version 3: the surface from B to G, or why there is none

    def surface_of(self, part: str) -> NurbsSurface:
        """The surface of ``part``: "calf" (the paper's, B to D) or "leg" (the leg model,
        B to G); FitFailure INVALID_RECORD saying why a record has no leg model."""
        if part != "leg":
            return self.surface
        if self.leg_model is None or self.leg_model.surface is None:
            why = (self.leg_model.reason if self.leg_model is not None
                   else "the record was fitted before leg models were made: fit the scan again")
            raise _invalid(f"the record has no leg model from B to G: {why}")
        return self.leg_model.surface

    def to_dict(self) -> dict:
        extra: dict = {}
        if self.schema_version >= 2:
            extra = {"warnings": list(self.warnings), "side_inference": self.side_inference}
        if self.schema_version >= 3:
            extra["chart"] = self.chart
            if self.leg_model is not None:
                extra["leg_model"] = self.leg_model.to_dict()
        return {
            "schema_version": self.schema_version,
            "units": "mm",
            "side": self.side,
            **extra,
            "surface": surface_document(self.surface),
            "frame": self.frame.tolist(),
            "scan": self.scan,
            "landmarks": self.landmarks,
            "layers": self.layers,
            "fit": self.fit,
        }

    @classmethod
    def from_dict(cls, data: dict) -> CalfRecord:
        """Validate and build a record; raises FitFailure(INVALID_RECORD) naming the problem."""
        return parse_record(data)


def record_from_fit(result: FitResult, scan_format: str, scan_units: str, seconds: float | None = None) -> CalfRecord:
    """Build the record of a fit."""
    err = result.error
    fit = {
        "mode": result.options.mode,
        "layers": int(result.layer_points.shape[0]),
        "points_per_layer": int(result.layer_points.shape[1]),
        "sections": int(len(result.sections.heights_mm)),
        "angles": int(len(result.sections.angles_rad)),
        "error_index": err.error_index,
        "error_index_exact": err.error_index_exact,
        "error_index_diameter": err.error_index_diameter,
        "error_index_exact_diameter": err.error_index_exact_diameter,
        "max_error_mm": err.max_error_mm,
        "mean_error_mm": err.mean_error_mm,
        "n_scan_points": result.n_scan_points,
        "n_error_points": err.n_points,
        "seconds": float(seconds if seconds is not None else sum(result.timings.values())),
        "stage_seconds": {k: float(v) for k, v in result.timings.items()},
        "per_layer": list(err.per_layer),
        "d_at_window_edge": bool(result.landmarks.d_at_window_edge),
    }
    if result.skin is not None:
        fit["surface_to_scan"] = result.skin.as_dict()
    if result.skin_layers is not None:
        fit["skin_layers"] = result.skin_layers.as_dict()
    if result.skin_seam is not None:
        fit["skin_seam"] = result.skin_seam.as_dict()
    if result.sparse_points_per_mm is not None:
        fit["sparse_points_per_mm"] = result.sparse_points_per_mm
    if result.lsq is not None:
        fit["grid"] = {"along": result.lsq.grid.along, "around": result.lsq.grid.around}
        fit["correction_rms_mm"] = list(result.lsq.rms_mm)
    placement = result.placement
    side_inference = {
        "side": result.side,
        "confidence": None if placement is None else placement.side_confidence,
        "source": None if placement is None else placement.side_source,
    }
    leg = result.leg_model
    leg_model = None if leg is None else (
        LegModelRecord(None, leg.reason) if leg.model is None else
        LegModelRecord(leg.model.fit.surface, None, **leg.model.as_dict()))
    return CalfRecord(
        leg_model=leg_model,
        surface=result.surface,
        chart={**(result.foot.as_dict() if result.foot is not None else {}),
               **(result.thigh.as_dict() if result.thigh is not None else {})},
        frame=result.frame.matrix(),
        landmarks=result.landmarks.as_dict(),
        side=result.side,
        warnings=tuple(result.warnings),
        side_inference=side_inference,
        layers={
            "heights_mm": result.landmarks.layer_heights_mm.tolist(),
            "feature_angles_deg": np.degrees(result.feature_angles_rad).tolist(),
        },
        fit=fit,
        scan={
            "units": scan_units,
            "format": scan_format,
            "n_points": result.n_scan_points,
            "anterior_cue": result.frame.anterior_cue,
            **({"sole_mm": result.sole_mm} if result.sole_mm is not None else {}),
            **({"sole_reason": result.sole_reason} if result.sole_reason is not None else {}),
        },
    )


def _parse_chart(chart) -> dict:
    """The version-3 ``chart``: each point {value_mm (0, MAX_CHART_MM] or null, at_mm [3]
    or null, height_mm or null, reason or null, uncertainty_mm [0, MAX_CHART_MM] when the
    scan leaves a measured point's girth uncertain, height_uncertainty_mm [0, MAX_CHART_MM]
    how far a point's height may be off}; a point with no value needs its reason."""
    if chart is None:
        return {}
    if not isinstance(chart, dict) or not set(chart) <= set(CHART_POINTS) | {"thigh_profile"}:
        raise _invalid(f"chart must be an object of {', '.join(CHART_POINTS)} and thigh_profile")
    clean: dict = {}
    if "thigh_profile" in chart:
        clean["thigh_profile"] = _parse_thigh_profile(chart["thigh_profile"])
    for name, entry in chart.items():
        if name == "thigh_profile":
            continue
        if not isinstance(entry, dict):
            raise _invalid(f"chart.{name} must be an object")
        value, at, reason, height = entry.get("value_mm"), entry.get("at_mm"), entry.get("reason"), entry.get("height_mm")
        if height is not None and (isinstance(height, bool) or not isinstance(height, (int, float))
                                   or not math.isfinite(height) or abs(height) > MAX_CONTROL_MM):
            raise _invalid(f"chart.{name}.height_mm must be a height within {MAX_CONTROL_MM:g} mm or null")
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                  or not 0 < value <= MAX_CHART_MM):
            raise _invalid(f"chart.{name}.value_mm must be a length in (0, {MAX_CHART_MM:g}] mm or null")
        if at is not None:
            at = _finite_array(at, f"chart.{name}.at_mm", 1)
            if at.shape != (3,) or np.abs(at).max() > MAX_CONTROL_MM:
                raise _invalid(f"chart.{name}.at_mm must be 3 coordinates within {MAX_CONTROL_MM:g} mm")
            at = at.tolist()
        if reason is not None and (not isinstance(reason, str) or len(reason) > 500):
            raise _invalid(f"chart.{name}.reason must be a sentence (at most 500 characters)")
        if value is None and reason is None:
            raise _invalid(f"chart.{name} has no value: it needs its reason")
        uncertainty = _chart_uncertainty(entry, name, "uncertainty_mm", value is not None, "a measured point")
        height_uncertainty = _chart_uncertainty(entry, name, "height_uncertainty_mm", height is not None,
                                                "a point with a height")
        clean[name] = {"value_mm": None if value is None else float(value), "reason": reason,
                       **({"at_mm": at} if "at_mm" in entry else {}),
                       **({"height_mm": None if height is None else float(height)} if "height_mm" in entry else {}),
                       **({"uncertainty_mm": uncertainty} if uncertainty is not None else {}),
                       **({"height_uncertainty_mm": height_uncertainty} if height_uncertainty is not None else {})}
    return clean


def _chart_uncertainty(entry: dict, name: str, key: str, of_what_exists: bool, of_what: str) -> float | None:
    """A chart point's optional uncertainty ``entry[key]`` (mm, in [0, MAX_CHART_MM], only
    on a point that has what it qualifies: ``of_what_exists``), or None when absent."""
    uncertainty = entry.get(key)
    if uncertainty is None:
        return None
    if (isinstance(uncertainty, bool) or not isinstance(uncertainty, (int, float))
            or not 0 <= uncertainty <= MAX_CHART_MM or not of_what_exists):
        raise _invalid(f"chart.{name}.{key} must be a length in [0, {MAX_CHART_MM:g}] mm of {of_what}, or absent")
    return float(uncertainty)


def _parse_thigh_profile(profile) -> dict:
    """chart.thigh_profile: {heights_mm (k,) rising, tape_girth_mm (k,) in (0, MAX_CHART_MM]},
    2 <= k <= MAX_THIGH_PROFILE."""
    if not isinstance(profile, dict):
        raise _invalid("chart.thigh_profile must be an object")
    heights = _finite_array(profile.get("heights_mm"), "chart.thigh_profile.heights_mm", 1)
    girths = _finite_array(profile.get("tape_girth_mm"), "chart.thigh_profile.tape_girth_mm", 1)
    if not 2 <= len(heights) <= MAX_THIGH_PROFILE or len(girths) != len(heights):
        raise _invalid(f"chart.thigh_profile needs 2-{MAX_THIGH_PROFILE} heights and as many girths")
    if np.any(np.diff(heights) <= 0) or np.abs(heights).max() > MAX_CONTROL_MM:
        raise _invalid(f"chart.thigh_profile.heights_mm must rise and lie within {MAX_CONTROL_MM:g} mm")
    if girths.min() <= 0 or girths.max() > MAX_CHART_MM:
        raise _invalid(f"chart.thigh_profile.tape_girth_mm must lie in (0, {MAX_CHART_MM:g}] mm")
    return {"heights_mm": heights.tolist(), "tape_girth_mm": girths.tolist()}


def parse_importable(data: dict) -> CalfRecord:
    """A record made elsewhere: :func:`parse_record`, and its surface must be a leg's
    tube (:func:`app.geometry.spline.bounds.check_leg_tube`: no zero radius, no
    self-overlap, height rising along v)."""
    record = parse_record(data)
    check_leg_tube(record.surface)
    return record


def parse_record(data: dict) -> CalfRecord:
    """Validate a record dictionary (knots, shapes, weights, finiteness, the cost bounds of
    :mod:`app.geometry.spline.bounds`) and build it."""
    if not isinstance(data, dict):
        raise _invalid("a record must be a JSON object")
    version = data.get("schema_version")
    if version not in READABLE_VERSIONS or isinstance(version, bool):
        raise _invalid(f"schema_version must be one of {', '.join(map(str, READABLE_VERSIONS))}, got {version!r}")
    if data.get("units", "mm") != "mm":
        raise _invalid("units must be 'mm'")
    surf = data.get("surface")
    if not isinstance(surf, dict):
        raise _invalid("surface is missing")
    surface = parse_surface(surf)
    leg_model = parse_leg_model(data.get("leg_model")) if version >= 3 else None
    frame = _finite_array(data.get("frame", np.eye(4).tolist()), "frame", 2)
    if frame.shape != (4, 4) or not np.allclose(frame[3], [0, 0, 0, 1]):
        raise _invalid("frame must be a 4x4 homogeneous matrix with last row 0 0 0 1")
    if abs(np.linalg.det(frame[:3, :3])) < 1e-12:
        raise _invalid("frame is singular")
    landmarks = data.get("landmarks") or {}
    if not isinstance(landmarks, dict):
        raise _invalid("landmarks must be an object")
    clean_landmarks = {}
    for name in LANDMARK_NAMES:
        if name not in landmarks:
            continue
        entry = landmarks[name]
        try:
            h, c = float(entry["height_mm"]), float(entry["circumference_mm"])
        except (KeyError, TypeError, ValueError) as exc:
            raise _invalid(f"landmarks.{name} needs numeric height_mm and circumference_mm") from exc
        if not (math.isfinite(h) and math.isfinite(c)) or c <= 0:
            raise _invalid(f"landmarks.{name} must be finite with a positive circumference")
        clean_landmarks[name] = {"height_mm": h, "circumference_mm": c}
        if entry.get("tape_girth_mm") is not None:
            try:
                tape = float(entry["tape_girth_mm"])
            except (TypeError, ValueError) as exc:
                raise _invalid(f"landmarks.{name}.tape_girth_mm must be a number") from exc
            if not math.isfinite(tape) or tape <= 0:
                raise _invalid(f"landmarks.{name}.tape_girth_mm must be finite and positive")
            clean_landmarks[name]["tape_girth_mm"] = tape
        if "at_scan_edge" in entry:
            clean_landmarks[name]["at_scan_edge"] = bool(entry["at_scan_edge"])
        for key in ("height_tolerance_mm", "girth_uncertainty_mm"):  # mm, finite and not negative
            if entry.get(key) is not None:
                try:
                    value = float(entry[key])
                except (TypeError, ValueError) as exc:
                    raise _invalid(f"landmarks.{name}.{key} must be a number") from exc
                if not math.isfinite(value) or value < 0:
                    raise _invalid(f"landmarks.{name}.{key} must be finite and not negative")
                clean_landmarks[name][key] = value
        if entry.get("confidence") is not None:
            if entry["confidence"] not in ("high", "medium", "low"):
                raise _invalid(f"landmarks.{name}.confidence must be 'high', 'medium' or 'low'")
            clean_landmarks[name]["confidence"] = entry["confidence"]
    side = data.get("side")
    if side not in (None, "left", "right"):
        raise _invalid("side must be 'left', 'right' or null")
    warnings = data.get("warnings") or []
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
        raise _invalid("warnings must be a list of sentences")
    side_inference = data.get("side_inference")
    if side_inference is not None and not isinstance(side_inference, dict):
        raise _invalid("side_inference must be an object or null")
    return CalfRecord(
        chart=_parse_chart(data.get("chart")) if version >= 3 else {},
        leg_model=leg_model,
        schema_version=int(version),
        warnings=tuple(warnings),
        side_inference=side_inference,
        surface=surface,
        frame=frame,
        landmarks=clean_landmarks,
        side=side,
        layers=data.get("layers") or {},
        fit=data.get("fit") or {},
        scan=data.get("scan") or {},
    )


def parse_leg_model(entry) -> LegModelRecord | None:
    """``leg_model`` (version 3, optional): {reason} when there is none, else {range "B-G",
    grid, layers_mm {B..G}, correction_rms_mm, surface_to_scan, surface} whose surface is
    validated as the calf's is (:func:`app.records.surface_codec.parse_surface`)."""
    if entry is None:
        return None
    if not isinstance(entry, dict):
        raise _invalid("leg_model must be an object or null")
    if entry.get("surface") is None:
        reason = entry.get("reason")
        if not isinstance(reason, str) or not reason or len(reason) > 500:
            raise _invalid("leg_model without a surface needs its reason (a sentence of at most 500 characters)")
        return LegModelRecord(None, reason)
    if not isinstance(entry["surface"], dict):
        raise _invalid("leg_model.surface must be an object")
    try:
        surface = parse_surface(entry["surface"])
    except FitFailure as failure:
        raise _invalid(f"leg_model.{failure.detail}") from None
    layers = entry.get("layers_mm") or {}
    if not isinstance(layers, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                                               and abs(v) <= MAX_CONTROL_MM for v in layers.values()):
        raise _invalid(f"leg_model.layers_mm must map points to heights within {MAX_CONTROL_MM:g} mm")
    rms = entry.get("correction_rms_mm") or []
    if not isinstance(rms, list) or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in rms):
        raise _invalid("leg_model.correction_rms_mm must be a list of numbers")
    grid, skin = entry.get("grid"), entry.get("surface_to_scan") or {}
    if grid is not None and (not isinstance(grid, str) or len(grid) > 16):
        raise _invalid("leg_model.grid must be ALONGxAROUND")
    if not isinstance(skin, dict):
        raise _invalid("leg_model.surface_to_scan must be an object")
    return LegModelRecord(surface, None, {str(k): float(v) for k, v in layers.items()}, grid, tuple(map(float, rms)), skin)


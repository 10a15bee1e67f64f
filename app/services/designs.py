"""Stocking designs: made from a stored record, stored with every input, exported as a
knitting specification (CSV), a pressure map (GLB with vertex colours and a legend, or
CSV) and PNG charts."""

from __future__ import annotations

import csv
import hashlib
import io
import json
from collections.abc import Callable

import numpy as np
import trimesh
from sqlalchemy.orm import Session

from app.db.models import Design
from app.db.repositories import DesignRepository
from app.errors import NotFound, from_fit_failure
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment.design import DesignCheck, DesignInputs, LandmarkPressure, StockingDesign, design_stocking
from app.geometry.garment.fabric import DEFAULT_MAX_STRAIN, Fabric
from app.geometry.garment.pressure import PA_PER_MMHG, HotSpot, pressure_map
from app.geometry.garment.standards import GRADIENT
from app.records.codec import CalfRecord
from app.records.meshes import apply_frame, surface_grid_faces
from app.services.records import RecordService

#: colour scale of pressure maps: 0 .. max(hot-spot limit, peak) mmHg
COLORMAP = "inferno"


def fabric_from_dict(fabric: dict) -> Fabric:
    """A validated fabric from ``{"stiffness_n_per_cm", "max_strain"}`` or ``{"table"}``
    (the request form and the stored form are the same)."""
    if fabric.get("table") is not None:
        rows = fabric["table"]
        if not isinstance(rows, list) or not all(isinstance(r, (list, tuple)) and len(r) == 2 for r in rows):
            raise FitFailure(FailureReason.INVALID_FABRIC, "fabric.table must be a list of [strain, tension_N_per_cm] rows")
        return Fabric.table([r[0] for r in rows], [r[1] for r in rows])
    if fabric.get("stiffness_n_per_cm") is not None:
        return Fabric.linear(float(fabric["stiffness_n_per_cm"]), float(fabric.get("max_strain", DEFAULT_MAX_STRAIN)))
    raise FitFailure(FailureReason.INVALID_FABRIC, "give the fabric as stiffness_n_per_cm or as a tension-strain table")


def inputs_from_request(data: dict) -> DesignInputs:
    """Validated design inputs from a request body (see DesignRequest in app.api.schemas)."""
    fabric = fabric_from_dict(data.get("fabric") or {})
    defaults = DesignInputs()
    return DesignInputs(
        standard=str(data.get("standard", defaults.standard)),
        compression_class=data.get("compression_class", defaults.compression_class),
        targets_mmhg=data.get("targets_mmHg"),
        fabric=fabric,
        hot_spot_limit_mmhg=float(data.get("hot_spot_limit_mmHg", defaults.hot_spot_limit_mmhg)),
        step_mm=float(data.get("step_mm", defaults.step_mm)),
        resolution_mm=float(data.get("resolution_mm", defaults.resolution_mm)),
        toe=str(data.get("toe", defaults.toe)),
        stocking_type=str(data.get("stocking_type", defaults.stocking_type)),
        top_band_mm=None if data.get("top_band_mm") is None else float(data["top_band_mm"]),
    )


def inputs_as_dict(inputs: DesignInputs) -> dict:
    return {
        "standard": inputs.standard,
        "compression_class": inputs.compression_class if inputs.targets_mmhg is None else None,
        "targets_mmHg": inputs.targets_mmhg,
        "fabric": inputs.fabric.as_dict(),
        "hot_spot_limit_mmHg": inputs.hot_spot_limit_mmhg,
        "step_mm": inputs.step_mm,
        "resolution_mm": inputs.resolution_mm,
        "toe": inputs.toe,
        "stocking_type": inputs.stocking_type,
        "top_band_mm": inputs.top_band_mm,
    }


def compute_design(record: CalfRecord, inputs: DesignInputs) -> dict:
    """The design of ``record`` as stored and sent (:func:`design_document`)."""
    chart = record.chart if record.schema_version >= 3 else None
    return design_document(design_stocking(record.surface, record.landmarks, record.side, inputs, chart, record.fit))


def _check_document(check: DesignCheck) -> dict:
    return {"name": check.name, "value": check.value, "pass": check.passed, "normative": check.normative}


def _hot_spot_document(spot: HotSpot) -> dict:
    return {"height_mm": spot.height_mm, "from_height_mm": spot.from_height_mm, "to_height_mm": spot.to_height_mm,
            "angle_deg": spot.angle_deg, "side": spot.side, "peak_mmHg": spot.peak_pa / PA_PER_MMHG,
            "peak_kPa": spot.peak_pa / 1000, "samples": spot.samples}


def _landmark_document(at: LandmarkPressure) -> dict:
    return {
        "height_mm": at.height_mm,
        "target_mmHg": at.target_mmhg,
        "mean_pressure_mmHg": at.mean_pressure_pa / PA_PER_MMHG,
        "mean_pressure_kPa": at.mean_pressure_pa / 1000,
        "peak_pressure_mmHg": at.peak_pressure_pa / PA_PER_MMHG,
        "stretched_circumference_mm": at.stretched_circumference_mm,
        "skin_circumference_mm": at.skin_circumference_mm,
        "relaxed_circumference_mm": at.relaxed_circumference_mm,
        "strain": at.strain,
        "tension_N_per_cm": at.tension_n_per_cm,
        "sides_mmHg": {k: v / PA_PER_MMHG for k, v in at.sides_pa.items()},
        "sides_kPa": {k: v / 1000 for k, v in at.sides_pa.items()},
    }


def _spec_rows(design: StockingDesign) -> list[dict]:
    """The knitting specification from the foot to the top, a row each: the foot's (cA,
    cY: part "foot"), the graded rows (part "leg"; ``point`` names a landmark's or a thigh
    level's row) and those the top band replaces (part "top band": the band's relaxed
    circumference and what it gives there)."""
    rows = [_spec_row("foot", r.point, r.height_mm, r.target_mmhg, r.stretched_circumference_mm, r.tension_n_per_cm,
                      r.strain, r.relaxed_circumference_mm, r.predicted_mean_mmhg)
            for r in (design.foot.part.rows if design.foot.part else ())]
    spec, band = design.knitting_spec, design.top_band
    named = {round(at.height_mm, 6): name for name, at in design.landmarks.items()}
    if design.thigh is not None:
        named.update({round(level.height_mm, 6): name for name, level in design.thigh.levels.items()})
    in_band = {} if band is None else {int(i): k for k, i in enumerate(band.replaces)}  # spec row -> band row
    for i, (h, t, L, T, e, L0, m) in enumerate(zip(spec.heights_mm, spec.target_mmhg, spec.stretched_circumference_mm,
                                                   spec.tension_n_per_cm, spec.strain, spec.relaxed_circumference_mm,
                                                   spec.predicted_mean_pa)):
        point = named.get(round(float(h), 6))
        if i in in_band:  # the band's one relaxed circumference and what it gives there
            k = in_band[i]
            rows.append(_spec_row("top band", point, h, t, L, band.band_tension_n_per_cm[k], band.band_strain[k],
                                  band.relaxed_circumference_mm, band.band_pressure_mmhg[k]))
        else:
            rows.append(_spec_row("leg", point, h, t, L, T, e, L0, m / PA_PER_MMHG))
    return rows


def _spec_row(part: str, point: str | None, height, target, stretched, tension, strain, relaxed, predicted_mmhg) -> dict:
    """One row of the knitting specification's wire form (app.api.schemas.KnittingRow)."""
    return {"part": part, "point": point, "height_mm": float(height), "target_mmHg": float(target),
            "stretched_circumference_mm": float(stretched), "tension_N_per_cm": float(tension), "strain": float(strain),
            "relaxed_circumference_mm": float(relaxed), "predicted_mean_mmHg": float(predicted_mmhg)}


def _ends_document(design: StockingDesign) -> dict:
    """The design's foot and top band (app.geometry.garment.stocking_ends)."""
    foot, band = design.foot.part, design.top_band
    return {
        "foot": {"designed": foot is not None, "reason": design.foot.reason,
                 **({} if foot is None else {
                     "toe": foot.toe, "foot_length_mm": foot.foot_length_mm, "knitted_length_mm": foot.knitted_length_mm,
                     "length_rule": foot.length_rule, "target_rule": "B's target: the graduation begins at B (no "
                     "standard sets the foot's pressure)", "points": [r.point for r in foot.rows]})},
        "top_band": None if band is None else {
            "width_mm": band.width_mm, "from_height_mm": band.from_height_mm, "to_height_mm": band.to_height_mm,
            "relaxed_circumference_mm": band.relaxed_circumference_mm,
            "band_mmHg": list(band.band_mmhg), "graded_mmHg": list(band.graded_mmhg),
            "rule": "one relaxed circumference, the largest of the graded rows it replaces: nowhere tighter than "
                    "the graded stocking (no tourniquet at the top)"},
    }


def design_document(design: StockingDesign) -> dict:
    """The JSON form of a design, as stored and as the API's DesignOut carries it
    (units named in ``units``; the one place a StockingDesign is shaped for the wire)."""
    verdict, reasons = design.verdict
    return {
        "units": {"length": "mm", "pressure": "mmHg (kPa where named)", "tension": "N/cm"},
        "class": design.compression_class,
        "targets_mmHg": design.targets_mmhg,
        "gradient_table": {k: {**v, "range": list(v["range"])} for k, v in GRADIENT.items()},
        "fabric": design.fabric.as_dict(),
        "landmarks": {name: _landmark_document(at) for name, at in design.landmarks.items()},
        "ratios": design.ratios,
        "checks": [_check_document(c) for c in design.checks],
        "passed": design.passed,
        "verdict": verdict,
        "verdict_reasons": reasons,
        "hot_spot_limit_mmHg": design.hot_spot_limit_mmhg,
        "hot_spots": [_hot_spot_document(s) for s in design.hot_spots],
        "side": design.side,
        "side_assumed": design.side_assumed,
        "stocking_type": design.stocking_type,
        "thigh": None if design.thigh is None else {
            "model": "mean pressure 2 pi T / L on the thigh's tape girths (the surface ends at D: no local pressure "
                     "or hot spots above it)",
            "levels": {name: {"height_mm": lv.height_mm, "target_mmHg": lv.target_mmhg,
                              "mean_pressure_mmHg": lv.mean_pressure_mmhg,
                              "stretched_circumference_mm": lv.stretched_circumference_mm,
                              "relaxed_circumference_mm": lv.relaxed_circumference_mm, "strain": lv.strain,
                              "tension_N_per_cm": lv.tension_n_per_cm} for name, lv in design.thigh.levels.items()},
        },
        **_ends_document(design),
        "knitting_spec": _spec_rows(design),
    }


class DesignService:
    def __init__(self, session: Session, tenant_id: str):
        self.session = session
        self.designs = DesignRepository(session, tenant_id)
        self.records = RecordService(session, tenant_id)

    def create(self, record_id: str, data: dict, before_commit: Callable[[Design], None] | None = None) -> Design:
        """Design from a stored record; stores it with its inputs; commits
        (``before_commit(design)`` runs in that transaction)."""
        row = self.records.get(record_id)
        try:
            record = CalfRecord.from_dict(row.body)
            inputs = inputs_from_request(data)
            result = compute_design(record, inputs)
        except FitFailure as failure:
            raise from_fit_failure(failure) from failure
        except (TypeError, ValueError) as exc:
            raise from_fit_failure(FitFailure(
                FailureReason.INVALID_TARGET, "invalid design input: a fabric or target value is not a number in range")) from exc
        stored_inputs = inputs_as_dict(inputs)
        etag = hashlib.sha256(json.dumps([row.etag, stored_inputs], sort_keys=True).encode()).hexdigest()
        design = self.designs.add(record_id, stored_inputs, result, etag)
        if before_commit is not None:
            before_commit(design)
        self.session.commit()
        return design

    def get(self, design_id: str) -> Design:
        design = self.designs.get(design_id)
        if design is None:
            raise NotFound(f"no design {design_id!r}", code="design_not_found")
        return design

    def for_record(self, record_id: str) -> list[Design]:
        self.records.get(record_id)
        return self.designs.for_record(record_id)

    def record_of(self, design: Design) -> CalfRecord:
        return CalfRecord.from_dict(self.records.get(design.record_id).body)


def design_view(design: Design) -> dict:
    base = f"/api/v1/designs/{design.id}"
    return {
        "id": design.id,
        "record_id": design.record_id,
        "case_ref": design.record.case_ref,
        "created_at": design.created_at,
        "inputs": design.inputs,
        **design.result,
        "links": {
            "self": base,
            "record": f"/api/v1/records/{design.record_id}",
            "knitting_spec": f"{base}/knitting-spec",
            "pressure_map": f"{base}/pressure-map",
            "order": f"{base}/order",
            **{f"chart_{name}": f"{base}/charts/{name}.png" for name in ("profile", "pressure", "map")},
        },
    }


def fabric_text(fabric: dict) -> str:
    """A fabric in words, for the knitting CSV's header and the order."""
    if fabric.get("stiffness_n_per_cm") is not None:
        return f"linear, K = {fabric['stiffness_n_per_cm']:g} N/cm per unit strain, max strain {fabric['max_strain']:g}"
    return f"measured tension-strain table of {len(fabric.get('table') or [])} rows"


def foot_text(foot: dict | None) -> str:
    """A design's foot (its ``foot`` document) in words: the CSV header, the order, the CLI."""
    if not foot:
        return "not designed (a design made before the foot was)"
    if not foot.get("designed"):
        return f"not designed: {foot.get('reason')}"
    length = foot.get("knitted_length_mm")
    return (f"{foot['toe']} toe, rows at {', '.join(foot['points'])}; "
            + (f"knitted length {length:.0f} mm ({foot['length_rule']})" if length is not None else foot["length_rule"]))


def band_text(band: dict | None) -> str:
    """A design's top band (its ``top_band`` document) in words, or "none"."""
    if not band:
        return "none"
    return (f"{band['width_mm']:g} mm wide from {band['from_height_mm']:.0f} to {band['to_height_mm']:.0f} mm, "
            f"relaxed circumference {band['relaxed_circumference_mm']:.0f} mm, {band['band_mmHg'][0]:.1f}-"
            f"{band['band_mmHg'][1]:.1f} mmHg (the graded rows: {band['graded_mmHg'][0]:.1f}-{band['graded_mmHg'][1]:.1f})")


def knitting_csv(design: Design) -> str:
    """The knitting specification as CSV: first ``# key: value`` lines naming what it
    belongs to (the record, the design, the side, the stocking type and toe, the standard
    and class or the explicit targets, the fabric, the verdict, the foot's length and the
    top band) - a manufacturer's file must not lose its leg - then one row per knitted row
    from the foot to the top, each naming its part (foot, leg, top band) and its
    measuring point where it has one (pandas: ``read_csv(..., comment="#")``)."""
    result = design.result
    out = io.StringIO()
    klass = result.get("class")
    header = {
        "calf-nurbs knitting specification": None,
        "record": design.record_id,
        "design": design.id,
        "side": result.get("side") or "unknown",
        "stocking": f"{result.get('stocking_type', 'AD')} "
                    f"{'thigh-high' if result.get('stocking_type') == 'AG' else 'knee-high'}, "
                    f"{design.inputs.get('toe', 'closed')} toe",
        "standard and class": f"{klass['standard']} class {klass['class']}" if klass else "explicit targets",
        "fabric": fabric_text(result.get("fabric") or {}),
        "verdict": result.get("verdict") or ("pass" if result.get("passed") else "fail"),
        "foot": foot_text(result.get("foot")),
        "top band": band_text(result.get("top_band")),
        "units": "mm, mmHg, N/cm",
    }
    for key, value in header.items():
        out.write(f"# {key}\n" if value is None else f"# {key}: {value}\n")
    writer = csv.writer(out)
    columns = ["part", "point", "height_mm", "target_mmHg", "predicted_mean_mmHg", "stretched_circumference_mm", "strain",
               "tension_N_per_cm", "relaxed_circumference_mm"]
    writer.writerow(columns)
    for row in result["knitting_spec"]:
        row = {"part": "leg", "point": None, **row}  # designs made before the foot and band had neither
        writer.writerow([f"{row[c]:.4f}" if isinstance(row[c], float) else ("" if row[c] is None else row[c]) for c in columns])
    return out.getvalue()


def pressure_grid(design: Design, record: CalfRecord, n_around: int = 360):
    return pressure_map(record.surface, design.result, fabric_from_dict(design.inputs["fabric"]), n_around)


def pressure_map_csv(design: Design, record: CalfRecord) -> str:
    rings, local = pressure_grid(design, record)
    k, n = local.shape
    out = io.StringIO()
    out.write("height_mm,angle_deg,x_mm,y_mm,z_mm,pressure_mmHg,pressure_kPa,in_contact\n")
    rows = np.column_stack([
        np.repeat(rings.heights_mm, n), np.degrees(rings.angle).ravel(), rings.points[..., 0].ravel(),
        rings.points[..., 1].ravel(), rings.z.ravel(), (local / PA_PER_MMHG).ravel(), (local / 1000).ravel(),
        rings.contact.ravel().astype(float),
    ])
    np.savetxt(out, rows, delimiter=",", fmt=["%.2f", "%.2f", "%.3f", "%.3f", "%.3f", "%.3f", "%.4f", "%d"])
    return out.getvalue()


def color_scale(design: Design, local_pa: np.ndarray) -> tuple[float, list[dict]]:
    """Top of the colour scale (mmHg) and the legend stops."""
    import matplotlib

    top = max(float(design.result["hot_spot_limit_mmHg"]), float(local_pa.max() / PA_PER_MMHG))
    cmap = matplotlib.colormaps[COLORMAP]
    stops = []
    for value in np.linspace(0, top, 7):
        rgba = cmap(value / top)
        stops.append({"mmHg": round(float(value), 2), "kPa": round(float(value) * PA_PER_MMHG / 1000, 3),
                      "rgba": [int(round(255 * c)) for c in rgba]})
    return top, stops


def pressure_map_glb(design: Design, record: CalfRecord) -> bytes:
    """The surface coloured by local pressure, in the scan's coordinates, with a colour-bar
    mesh beside it and the legend (stops in mmHg and kPa) in the glTF extras."""
    import matplotlib

    rings, local = pressure_grid(design, record)
    k, n = local.shape
    top, stops = color_scale(design, local)
    cmap = matplotlib.colormaps[COLORMAP]
    calf_vertices = np.concatenate([rings.points, rings.z[..., None]], axis=2).transpose(1, 0, 2).reshape(-1, 3)
    colors = (cmap(np.clip((local / PA_PER_MMHG) / top, 0, 1)).transpose(1, 0, 2).reshape(-1, 4) * 255).astype(np.uint8)
    frame = record.frame
    leg = trimesh.Trimesh(apply_frame(calf_vertices, frame), surface_grid_faces(n, k), process=False)
    leg.visual.vertex_colors = colors
    # colour bar: a vertical strip 20 mm wide, 40 mm beside the calf, as tall as the calf
    x0 = rings.points[..., 0].max() + 40.0
    z = np.linspace(rings.heights_mm[0], rings.heights_mm[-1], 64)
    bar_calf = np.array([[x0 + dx, rings.centroid[:, 1].mean(), zz] for zz in z for dx in (0.0, 20.0)])
    bar_faces = np.array([[2 * i, 2 * i + 1, 2 * i + 3] for i in range(63)] + [[2 * i, 2 * i + 3, 2 * i + 2] for i in range(63)])
    bar = trimesh.Trimesh(apply_frame(bar_calf, frame), bar_faces, process=False)
    bar.visual.vertex_colors = (np.repeat(cmap(np.linspace(0, 1, 64)), 2, axis=0) * 255).astype(np.uint8)
    scene = trimesh.Scene()
    scene.add_geometry(leg, node_name="pressure_map", geom_name="pressure_map")
    scene.add_geometry(bar, node_name="legend", geom_name="legend")
    scene.metadata["legend"] = {"quantity": "local skin pressure", "unit": "mmHg", "colormap": COLORMAP,
                                "bottom_of_bar_mmHg": 0.0, "top_of_bar_mmHg": top, "stops": stops}
    return scene.export(file_type="glb")

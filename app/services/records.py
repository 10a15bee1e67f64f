"""Records: import, read, list, delete, surface exports and surface measurements."""

from __future__ import annotations

import base64
import hashlib
import json
from datetime import datetime

import numpy as np
from sqlalchemy.orm import Session

from app.cad import CAD_MEDIA_TYPES, export_surface
from app.db.models import Record
from app.db.repositories import RecordRepository
from app.errors import BadRequest, InvalidRequest, NotFound, Unprocessable, from_fit_failure
from app.geometry.anatomy import LANDMARK_NAMES
from app.geometry.errors import FitFailure
from app.geometry.garment.measuring_points import chart_of_record
from app.geometry.measures.surface_girths import girths, surface_height_range
from app.records.codec import CalfRecord, parse_importable
from app.records.meshes import export_mesh, surface_mesh

MESH_MEDIA_TYPES = {"stl": "model/stl", "glb": "model/gltf-binary", "gltf": "model/gltf+json"}
#: the surface's formats: meshes (tessellated, scan coordinates) and the exact CAD ones
#: (the B-spline itself, calf frame mm; :mod:`app.cad`)
SURFACE_MEDIA_TYPES = {**MESH_MEDIA_TYPES, **CAD_MEDIA_TYPES}
#: tessellation density bounds for exports (samples around / along the leg), and their
#: product: 720 x 500 samples are 0.5 mm apart around a 400 mm girth and along a 250 mm
#: calf, 720k triangles (a 36 MB STL), finer than any garment CAD needs
AROUND_RANGE = (8, 720)
ALONG_RANGE = (2, 1000)
MAX_SURFACE_SAMPLES = 360_000


def record_etag(body: dict) -> str:
    """Strong validator of a record: SHA-256 of its canonical JSON."""
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _parse(body: dict) -> CalfRecord:
    try:
        return CalfRecord.from_dict(body)
    except FitFailure as failure:
        raise from_fit_failure(failure) from failure


class RecordService:
    """Records of one tenant (``tenant_id``): another tenant's ids are not found."""

    def __init__(self, session: Session, tenant_id: str):
        self.session = session
        self.records = RecordRepository(session, tenant_id)

    def get(self, record_id: str) -> Record:
        record = self.records.get(record_id)
        if record is None:
            raise NotFound(f"no record {record_id!r}", code="record_not_found")
        return record

    def import_record(self, data: dict) -> Record:
        """Validate a record made elsewhere and store its normalized form."""
        try:
            parsed = parse_importable(data)
        except FitFailure as failure:
            raise from_fit_failure(failure) from failure
        body = parsed.to_dict()
        return self.records.add(body, record_etag(body), "import", None)

    def add_population_average(self, body: dict) -> Record:
        """Store the average calf of a population (already a valid record body)."""
        return self.records.add(body, record_etag(body), "population", None)

    def delete(self, record_id: str) -> None:
        self.records.delete(self.get(record_id))

    def page(self, limit: int, cursor: str | None, side: str | None = None, since: datetime | None = None,
             until: datetime | None = None, case_ref: str | None = None) -> tuple[list[Record], str | None]:
        after = decode_cursor(cursor) if cursor else None
        if since is not None and until is not None and until <= since:
            raise InvalidRequest("until must be after since")
        rows = self.records.page(limit + 1, after, side, since, until, case_ref)
        more = len(rows) > limit
        rows = rows[:limit]
        next_cursor = encode_cursor(rows[-1].created_at, rows[-1].id) if more and rows else None
        return rows, next_cursor

    @staticmethod
    def surface(record: Record, file_format: str, around: int, along: int, part: str = "calf") -> bytes:
        """The record's surface (``part`` "calf", B to D) or its leg model ("leg", B to G):
        tessellated (around x along samples) in scan coordinates for a mesh format; exact,
        in the calf frame (mm), for a CAD format.  NotFound leg_model_not_found, saying
        why, for a record without a leg model."""
        parsed = _parse(record.body)
        try:
            surface = parsed.surface_of(part)
        except FitFailure as missing:
            raise NotFound(f"record {record.id!r}: {missing.detail}", code="leg_model_not_found") from None
        if file_format in CAD_MEDIA_TYPES:
            return export_surface(surface, file_format)
        for name, value, (lo, hi) in (("around", around, AROUND_RANGE), ("along", along, ALONG_RANGE)):
            if not lo <= value <= hi:
                raise Unprocessable(f"{name} must be between {lo} and {hi}, not {value}", code="invalid_density")
        if around * along > MAX_SURFACE_SAMPLES:
            raise Unprocessable(f"around x along is {around * along}; at most {MAX_SURFACE_SAMPLES} samples per export",
                                code="invalid_density")
        return export_mesh(surface_mesh(surface, parsed.frame, n_u=around, n_v=along), file_format)

    def measurements(self, record_id: str, extra_heights: list[float]) -> dict:
        record = self.get(record_id)
        parsed = _parse(record.body)
        z0, z1 = surface_height_range(parsed.surface)
        for h in extra_heights:
            if not np.isfinite(h) or h < z0 - 1e-6 or h > z1 + 1e-6:
                raise Unprocessable(
                    f"height {h:g} mm is outside the modelled calf ({z0:.1f} to {z1:.1f} mm above B)",
                    code="height_out_of_range",
                )
        names = [n for n in LANDMARK_NAMES if n in parsed.landmarks]
        heights = [parsed.landmarks[n]["height_mm"] for n in names] + list(extra_heights)
        measured = girths(parsed.surface, np.array(heights, dtype=float)) if heights else []
        landmarks = {
            name: {
                "height_mm": g.height_mm,
                "circumference_mm": g.circumference_mm,
                "tape_circumference_mm": g.tape_mm,
                "scan_circumference_mm": parsed.landmarks[name]["circumference_mm"],
                "scan_tape_girth_mm": parsed.landmarks[name].get("tape_girth_mm"),
                "at_scan_edge": bool(parsed.landmarks[name].get("at_scan_edge", False)),
                "height_tolerance_mm": parsed.landmarks[name].get("height_tolerance_mm"),
                "confidence": parsed.landmarks[name].get("confidence"),
            }
            for name, g in zip(names, measured[: len(names)])
        }
        lengths = {}
        for a, b in zip(names[:-1], names[1:]):
            lengths[f"{a}-{b}"] = parsed.landmarks[b]["height_mm"] - parsed.landmarks[a]["height_mm"]
        if "B" in parsed.landmarks and "D" in parsed.landmarks:
            lengths["B-D"] = parsed.landmarks["D"]["height_mm"] - parsed.landmarks["B"]["height_mm"]
        sole = (parsed.scan or {}).get("sole_mm")
        above_floor = None
        if isinstance(sole, (int, float)) and np.isfinite(sole):
            above_floor = {name: parsed.landmarks[name]["height_mm"] - float(sole) for name in names}
        return {
            "record_id": record.id,
            "units": "mm",
            "height_range_mm": [z0, z1],
            "above_floor_mm": above_floor,
            "landmarks": landmarks,
            "heights": [
                {"height_mm": g.height_mm, "circumference_mm": g.circumference_mm, "tape_circumference_mm": g.tape_mm}
                for g in measured[len(names):]
            ],
            "lengths_mm": lengths,
            "chart": record_chart(parsed),
            "warnings": list(parsed.warnings),
        }


def record_chart(parsed: CalfRecord, stocking_type: str = "AG") -> list[dict]:
    """The order form's measuring points of a record (mm), in the form's order: each with
    its value or the reason it has none, where it is (height in the calf frame; the foot's
    points also at_mm), the stocking types that ask for it and whether ``stocking_type``
    does (app.geometry.garment.measuring_points)."""
    sole = (parsed.scan or {}).get("sole_mm")
    sole = float(sole) if isinstance(sole, (int, float)) and np.isfinite(sole) else None
    foot = parsed.chart if parsed.schema_version >= 3 else None
    return [{"point": m.point.name, "kind": m.point.kind, "description": m.point.description,
             "needed_for": list(m.point.needed_for), "needed": m.needed, "value_mm": m.value_mm,
             "height_mm": m.height_mm, "at_mm": None if m.at_mm is None else list(m.at_mm), "reason": m.reason,
             **({"uncertainty_mm": m.uncertainty_mm} if m.uncertainty_mm is not None else {})}
            for m in chart_of_record(parsed.landmarks, sole, stocking_type, foot, (parsed.scan or {}).get("sole_reason"))]


def surface_etag(record_etag_value: str, file_format: str, around: int, along: int, part: str = "calf") -> str:
    key = f"{record_etag_value}:{file_format}:{around}:{along}" + ("" if part == "calf" else f":{part}")  # calf: as before
    return hashlib.sha256(key.encode()).hexdigest()[:40]


def encode_cursor(created_at: datetime, record_id: str) -> str:
    return base64.urlsafe_b64encode(f"{created_at.isoformat()}|{record_id}".encode()).decode().rstrip("=")


def decode_cursor(cursor: str) -> tuple[datetime, str]:
    try:
        raw = base64.urlsafe_b64decode(cursor + "=" * (-len(cursor) % 4)).decode()
        stamp, record_id = raw.split("|", 1)
        return datetime.fromisoformat(stamp), record_id
    except (ValueError, UnicodeDecodeError) as exc:
        raise BadRequest("the page cursor is not one this service issued", code="invalid_cursor") from exc

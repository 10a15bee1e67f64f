"""The order of a made-to-measure stocking: one document a clinic sends and a manufacturer
knits from, built from a stored design, its record and a size chart's decision.

What it carries (issue 22's list, as the RAL-GZ 387 order forms ask): the case reference,
the side, the stocking type and toe, the standard, class and fabric, every measuring point
of the form with its value or the reason it has none, the lengths from the floor, the
ready-to-wear size decision, the knitting specification, the record and design ids, the
date, the verdict and every warning.  The JSON form (:func:`order_document`) is the
content; the PDF (:mod:`app.services.order_pdf`) prints it with a leg diagram.
"""

from __future__ import annotations

from datetime import datetime

import numpy as np
from sqlalchemy.orm import Session

from app.db.models import Design, Record, utcnow
from app.geometry.garment.measuring_points import STOCKING_TYPES
from app.geometry.measures.surface_girths import girths
from app.records.codec import CalfRecord
from app.services.designs import DesignService, fabric_text
from app.services.records import record_chart
from app.services.size_charts import SizeChartService, example_chart_id

ORDER_FORMAT = "calf-nurbs order 1"
#: samples of the leg diagram's outline from B to D (and to G of a thigh-high)
DIAGRAM_SAMPLES = 41


def _warnings(record: CalfRecord, result: dict, inputs: dict, measured, decision: dict) -> list[str]:
    """Every warning an order must carry, a sentence each: the record's own, the side, the
    points the form needs that the scan does not give, the design's verdict, the chart."""
    warnings = list(record.warnings)
    if result.get("side_assumed") or not result.get("side"):
        warnings.append("the side of the leg was not inferred from the scan: confirm left or right before knitting")
    missing = [m["point"] for m in measured if m["needed"] and m["value_mm"] is None]
    if missing:
        warnings.append(f"not measured from the scan: {', '.join(missing)}; take them by tape (RAL-GZ 387) before ordering")
    verdict = result.get("verdict") or ("pass" if result.get("passed") else "fail")
    if verdict != "pass":
        reasons = result.get("verdict_reasons") or []
        warnings.append(f"the design's verdict is {verdict}" + (f": {'; '.join(reasons)}" if reasons else ""))
    if "toe" not in inputs:
        warnings.append("the design was made before the toe was asked: closed toe assumed")
    if decision["chart"]["example"]:
        warnings.append("the size decision is against the shipped EXAMPLE chart (ANSUR II percentiles), not a product's chart")
    if result.get("stocking_type", "AD") == "AG":
        warnings.append("above D the knitting specification is designed on the thigh's tape girths (mean pressure, "
                        "no local pressure map)")
    foot = result.get("foot")
    if not foot:
        warnings.append("the design was made before the foot and the top band were designed: the specification covers "
                        "the leg only; the foot is made from cA and cY to the manufacturer's practice")
    elif not foot.get("designed"):
        warnings.append(f"the foot is not in the knitting specification: {foot.get('reason')}")
    return warnings


def leg_outline(record: CalfRecord, thigh_high: bool = False, samples: int = DIAGRAM_SAMPLES) -> list[dict]:
    """The leg diagram's outline: the surface's tape girth (mm) at ``samples`` heights (mm,
    calf frame) evenly from B to D (:func:`app.geometry.measures.surface_girths.girths`),
    and for a thigh-high on along the record's thigh profile to G."""
    low, high = record.landmarks["B"]["height_mm"], record.landmarks["D"]["height_mm"]
    heights = np.linspace(low, high, samples)
    outline = [{"height_mm": float(g.height_mm), "tape_girth_mm": float(g.tape_mm)} for g in girths(record.surface, heights)]
    profile = (record.chart or {}).get("thigh_profile") if thigh_high else None
    if profile:
        outline += [{"height_mm": float(z), "tape_girth_mm": float(g)}
                    for z, g in zip(profile["heights_mm"], profile["tape_girth_mm"]) if z > high]
    return outline


def order_document(design: Design, row: Record, record: CalfRecord, decision: dict, issued_at: datetime) -> dict:
    """The order as JSON (mm, mmHg, N/cm): see the module docstring for what it carries."""
    result, inputs = design.result, design.inputs
    sole = (record.scan or {}).get("sole_mm")
    sole = float(sole) if isinstance(sole, (int, float)) and np.isfinite(sole) else None
    stocking_type = result.get("stocking_type", "AD")
    measured = record_chart(record, stocking_type)
    klass = result.get("class")
    return {
        "format": ORDER_FORMAT,
        "units": {"length": "mm", "pressure": "mmHg", "tension": "N/cm"},
        "issued_at": issued_at,
        "case_ref": row.case_ref,
        "record_id": row.id,
        "design_id": design.id,
        "design_created_at": design.created_at,
        "side": result.get("side"),
        "side_assumed": bool(result.get("side_assumed")),
        "stocking": {
            "type": stocking_type,
            "description": STOCKING_TYPES[stocking_type],
            "toe": inputs.get("toe", "closed"),
            "standard": klass["standard"] if klass else inputs.get("standard"),
            "compression_class": klass["class"] if klass else None,
            "class_range_mmHg_at_B": list(klass["range_mmHg"]) if klass else None,
            "targets_mmHg": result.get("targets_mmHg"),
            "fabric": result.get("fabric"),
            "fabric_text": fabric_text(result.get("fabric") or {}),
        },
        "measurements": measured,
        "sole_height_mm": sole,
        "leg_outline": leg_outline(record, stocking_type == "AG"),
        "size_decision": decision,
        "verdict": result.get("verdict") or ("pass" if result.get("passed") else "fail"),
        "verdict_reasons": result.get("verdict_reasons") or [],
        "checks": result.get("checks", []),
        "hot_spots": result.get("hot_spots", []),
        "foot": result.get("foot"),
        "top_band": result.get("top_band"),
        "knitting_spec": result["knitting_spec"],
        "warnings": _warnings(record, result, inputs, measured, decision),
    }


class OrderService:
    def __init__(self, session: Session, tenant_id: str):
        self.designs = DesignService(session, tenant_id)
        self.charts = SizeChartService(session, tenant_id)

    def order(self, design_id: str, chart_id: str | None = None) -> dict:
        """The order of a design, its size decision against ``chart_id`` (the shipped
        example of the design's stocking type when None: the order always states a
        decision, and says whose chart)."""
        design = self.designs.get(design_id)
        row = design.record
        stocking_type = (design.result or {}).get("stocking_type", "AD")
        decision = self.charts.decide_for(row, chart_id or example_chart_id(stocking_type))
        return order_document(design, row, CalfRecord.from_dict(row.body), decision, utcnow())

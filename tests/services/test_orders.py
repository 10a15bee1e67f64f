"""The order document from a design, its record and a size decision, without HTTP: a
design made before the toe was asked, and a record without its side or its floor."""

from __future__ import annotations

from dataclasses import asdict, replace
from datetime import UTC, datetime

from app.db.models import Design, Record
from app.geometry.garment.size_charts import record_chart_measures, size_decision
from app.records.codec import record_from_fit
from app.services.designs import compute_design, inputs_as_dict, inputs_from_request
from app.services.order_pdf import order_pdf
from app.services.orders import order_document
from app.services.size_charts import example_chart
from tests.conftest import fitted


def test_an_older_design_and_a_record_without_side_or_floor_are_ordered_with_warnings():
    _, result = fitted("bodyparts3d_right_leg.stl", None)
    fitted_record = record_from_fit(result, "stl", "mm")
    # the foot in the scan but not its sole (app.geometry.anatomy.sole): the record says why
    why = "the scan is cut through the foot above the heel's underside"
    record = replace(fitted_record, scan={**{k: v for k, v in fitted_record.scan.items() if k != "sole_mm"},
                                          "sole_reason": why})
    inputs = inputs_as_dict(inputs_from_request({"fabric": {"stiffness_n_per_cm": 12.0}}))
    del inputs["toe"]  # as stored before 2026-12-02
    design = Design(id="d" * 32, record_id="r" * 32, inputs=inputs, result=compute_design(record, inputs_from_request(inputs)),
                    etag="e", created_at=datetime(2026, 11, 1, tzinfo=UTC))
    row = Record(id="r" * 32, case_ref=None, body=record.to_dict())
    decision = {"record_id": row.id, "chart": {"id": "example-ansur2-ad", "product": "x", "type": "AD", "example": True},
                **asdict(size_decision(example_chart(), record_chart_measures(record.landmarks, None)))}
    order = order_document(design, row, record, decision, datetime(2026, 12, 2, tzinfo=UTC))
    assert order["stocking"]["toe"] == "closed"
    assert "the design was made before the toe was asked: closed toe assumed" in order["warnings"]
    lengths = {m["point"]: m for m in order["measurements"] if m["point"] in ("lB", "lB1", "lC", "lD")}
    assert len(lengths) == 4
    assert all(m["value_mm"] is None and m["reason"] == why for m in lengths.values())
    assert order["case_ref"] is None and order["sole_height_mm"] is None
    pdf = order_pdf(order)  # a diagram without a floor still draws
    assert pdf.startswith(b"%PDF-") and len(pdf) > 2000

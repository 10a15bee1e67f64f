"""Ready-to-wear size charts: registered by a clinic or a manufacturer (JSON or CSV),
listed with the shipped example, and the size decision for a record
(app.geometry.garment.size_charts)."""

from __future__ import annotations

import json
from dataclasses import asdict
from functools import cache
from importlib import resources

from sqlalchemy.orm import Session

from app.db.models import Record, SizeChartRow
from app.db.repositories import SizeChartRepository
from app.errors import NotFound, from_fit_failure
from app.geometry.errors import FitFailure
from app.geometry.garment.size_charts import SizeChart, record_chart_measures, size_chart_as_dict, size_chart_from_dict, size_decision
from app.services.records import RecordService

#: the shipped examples (benchmarks/size_chart_example.py), under fixed ids every tenant
#: sees: knee-high (AD) and thigh-high (AG)
EXAMPLE_CHART_ID = "example-ansur2-ad"
EXAMPLE_AG_CHART_ID = "example-ansur2-ag"
EXAMPLE_CHARTS = {EXAMPLE_CHART_ID: "example_ansur2_ad.json", EXAMPLE_AG_CHART_ID: "example_ansur2_ag.json"}
#: most bytes a chart upload may have (60 sizes x 16 points fit in a few kB)
MAX_CHART_BYTES = 64 * 1024


@cache
def example_chart(chart_id: str = EXAMPLE_CHART_ID) -> SizeChart:
    text = resources.files("app.data").joinpath(f"size_charts/{EXAMPLE_CHARTS[chart_id]}").read_text()
    return size_chart_from_dict(json.loads(text))


def example_chart_id(stocking_type: str) -> str:
    """The shipped example for a stocking type (AD knee-high, AG thigh-high)."""
    return EXAMPLE_AG_CHART_ID if stocking_type == "AG" else EXAMPLE_CHART_ID


def chart_view(chart_id: str, chart: SizeChart, example: bool) -> dict:
    return {"id": chart_id, "example": example, **size_chart_as_dict(chart),
            "links": {"self": f"/api/v1/size-charts/{chart_id}"}}


class SizeChartService:
    def __init__(self, session: Session, tenant_id: str):
        self.session = session
        self.charts = SizeChartRepository(session, tenant_id)
        self.records = RecordService(session, tenant_id)

    def register(self, data: dict) -> tuple[SizeChartRow, SizeChart]:
        """Validate and store a chart; commits.  Returns the row and the chart."""
        try:
            chart = size_chart_from_dict(data)
        except FitFailure as failure:
            raise from_fit_failure(failure) from failure
        row = self.charts.add(chart.product, chart.stocking_type, size_chart_as_dict(chart))
        self.session.commit()
        return row, chart

    def get(self, chart_id: str) -> tuple[SizeChart, bool]:
        """(chart, is the shipped example)."""
        if chart_id in EXAMPLE_CHARTS:
            return example_chart(chart_id), True
        row = self.charts.get(chart_id)
        if row is None:
            raise NotFound(f"no size chart {chart_id!r}", code="size_chart_not_found")
        return size_chart_from_dict(row.body), False

    def listing(self) -> list[dict]:
        return [chart_view(chart_id, example_chart(chart_id), True) for chart_id in EXAMPLE_CHARTS] + [
            chart_view(row.id, size_chart_from_dict(row.body), False) for row in self.charts.all()]

    def decide(self, record_id: str, chart_id: str) -> dict:
        return self.decide_for(self.records.get(record_id), chart_id)

    def decide_for(self, record: Record, chart_id: str) -> dict:
        """The size decision of a record row already read (the order has it)."""
        chart, example = self.get(chart_id)
        body = record.body
        measures = record_chart_measures(body.get("landmarks", {}), (body.get("scan") or {}).get("sole_mm"), body.get("chart"))
        decision = size_decision(chart, measures)
        return {
            "record_id": record.id,
            "chart": {"id": chart_id, "product": chart.product, "type": chart.stocking_type, "example": example},
            "measures_mm": measures,
            **asdict(decision),
        }

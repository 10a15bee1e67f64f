"""Ready-to-wear size charts, and the decision a clinic takes before it orders made to
measure: which sizes of a chart fit a leg at every point, the best of them, or "made to
measure" with each point outside its range and by how much.

A chart (a manufacturer's or a clinic's; the one shipped with the service is an example
derived from ANSUR II percentiles, see ``benchmarks/size_chart_example.py``) names its
product and stocking type (AD knee-high, AG thigh-high) and lists sizes, each with a range
[min, max] in mm for some of the RAL-GZ 387 measuring points: circumferences cB, cB1, cC,
cD (and for AG cE, cF, cG), lengths from the floor lB, lC, lD (and lG).  A leg fits a size
when every point the size names lies within its range (inclusive: a chart's ranges are
what its manufacturer stands behind).  The best fitting size is the one whose ranges the
leg sits most centrally in: the smallest worst-case relative offset
max_p |x_p - centre_p| / half_width_p (0 at every centre, 1 on an edge).  With none
fitting, the nearest size by the same measure is reported with every point outside its
range and the signed excess in mm, and the decision is "made_to_measure".  A point the
chart needs and the record lacks (a knee-high chart's lD on a record without the floor) is
reported as missing, and no size can be confirmed: the decision is "not_measured".
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

import numpy as np

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment.measuring_points import chart_of_record

#: the measuring points a chart may name (RAL-GZ 387 letters; c = circumference, l = length
#: from the floor), in the order of an order form
CHART_POINTS = ("cA", "cY", "cB", "cB1", "cC", "cD", "cE", "cF", "cG", "lB", "lB1", "lC", "lD", "lE", "lF", "lG")
STOCKING_TYPES = ("AD", "AG")
MAX_SIZES = 60


@dataclass(frozen=True)
class ChartSize:
    """One size: its name and the ranges (mm) [low, high] of the points it names."""

    name: str
    ranges: dict[str, tuple[float, float]]


@dataclass(frozen=True)
class SizeChart:
    product: str
    stocking_type: str
    sizes: tuple[ChartSize, ...]
    source: str = ""

    @property
    def points(self) -> tuple[str, ...]:
        named = {p for s in self.sizes for p in s.ranges}
        return tuple(p for p in CHART_POINTS if p in named)


def size_chart_from_dict(data: dict) -> SizeChart:
    """A validated chart from its JSON form: {"product", "type": "AD"|"AG", "source"?,
    "sizes": [{"name", "ranges": {"cB": [min, max], ...}}]}.  Raises FitFailure
    (INVALID_SIZE_CHART) naming what is wrong."""
    def bad(detail: str) -> FitFailure:
        return FitFailure(FailureReason.INVALID_SIZE_CHART, f"size chart: {detail}")

    if not isinstance(data, dict):
        raise bad("must be a JSON object")
    product, kind = data.get("product"), data.get("type")
    if not isinstance(product, str) or not 0 < len(product) <= 100:
        raise bad("product must be a name of 1-100 characters")
    if kind not in STOCKING_TYPES:
        raise bad(f"type must be one of {', '.join(STOCKING_TYPES)} (knee-high, thigh-high)")
    rows = data.get("sizes")
    if not isinstance(rows, list) or not 0 < len(rows) <= MAX_SIZES:
        raise bad(f"sizes must be a list of 1-{MAX_SIZES} sizes")
    sizes = []
    for row in rows:
        name = row.get("name") if isinstance(row, dict) else None
        ranges = row.get("ranges") if isinstance(row, dict) else None
        if not isinstance(name, str) or not 0 < len(name) <= 40:
            raise bad("every size needs a name of 1-40 characters")
        if not isinstance(ranges, dict) or not ranges:
            raise bad(f"size {name!r} needs ranges for at least one point")
        parsed = {}
        for point, bounds in ranges.items():
            if point not in CHART_POINTS:
                raise bad(f"size {name!r}: unknown point {point!r}; points are {', '.join(CHART_POINTS)}")
            try:
                low, high = (float(b) for b in bounds)
            except (TypeError, ValueError):
                raise bad(f"size {name!r}, {point}: the range must be [min, max] in mm") from None
            if not (np.isfinite(low) and np.isfinite(high) and 0 < low < high <= 2500):
                raise bad(f"size {name!r}, {point}: the range must satisfy 0 < min < max <= 2500 mm")
            parsed[point] = (low, high)
        sizes.append(ChartSize(name, parsed))
    if len({s.name for s in sizes}) != len(sizes):
        raise bad("size names must be unique")
    source = data.get("source", "")
    if not isinstance(source, str) or len(source) > 500:
        raise bad("source must be a text of at most 500 characters")
    return SizeChart(product, kind, tuple(sizes), source)


def size_chart_dict_from_csv(text: str) -> dict:
    """A chart's JSON form from its CSV form: '# product: ...', '# type: AD|AG' (and
    '# source: ...') lines, then a table with the columns size, point, min_mm, max_mm, one
    row per range.  Validate the result with :func:`size_chart_from_dict`."""
    meta, table = {}, []
    for line in text.splitlines():
        if line.startswith("#"):
            key, _, value = line[1:].partition(":")
            meta[key.strip().lower()] = value.strip()
        elif line.strip():
            table.append(line)
    rows = list(csv.DictReader(io.StringIO("\n".join(table))))
    if not rows or not {"size", "point", "min_mm", "max_mm"} <= set(rows[0]):
        raise FitFailure(FailureReason.INVALID_SIZE_CHART, "size chart CSV: the table needs the columns size, point, min_mm, max_mm")
    sizes: dict[str, dict] = {}
    for row in rows:
        sizes.setdefault(row["size"] or "", {})[row["point"] or ""] = [row["min_mm"], row["max_mm"]]
    return {"product": meta.get("product"), "type": meta.get("type"), "source": meta.get("source", ""),
            "sizes": [{"name": name, "ranges": ranges} for name, ranges in sizes.items()]}


def size_chart_as_dict(chart: SizeChart) -> dict:
    return {"product": chart.product, "type": chart.stocking_type, "source": chart.source,
            "sizes": [{"name": s.name, "ranges": {p: list(r) for p, r in s.ranges.items()}} for s in chart.sizes]}


@dataclass(frozen=True)
class PointCheck:
    """One point of a leg against one size's range: mm; ``excess_mm`` is negative below
    the range, positive above it, 0 inside."""

    point: str
    measured_mm: float
    low_mm: float
    high_mm: float
    excess_mm: float


@dataclass(frozen=True)
class SizeDecision:
    """``decision``: "ready_to_wear" (``best`` fits at every point), "made_to_measure"
    (no size fits; ``outside`` lists the nearest size's points outside their ranges) or
    "not_measured" (the record lacks ``missing`` points the chart needs)."""

    decision: str
    fitting: tuple[str, ...]
    best: str | None
    nearest: str | None
    outside: tuple[PointCheck, ...]
    missing: tuple[str, ...]
    checks: dict[str, tuple[PointCheck, ...]]


def size_decision(chart: SizeChart, measures_mm: dict[str, float]) -> SizeDecision:
    """The size decision for a leg measured at ``measures_mm`` (point -> mm: tape girths
    and lengths) on ``chart`` (module docstring)."""
    missing = tuple(p for p in chart.points if p not in measures_mm)
    checks: dict[str, tuple[PointCheck, ...]] = {}
    offsets = []
    for size in chart.sizes:
        named = [p for p in size.ranges if p in measures_mm]
        x = np.array([measures_mm[p] for p in named], dtype=float)
        low = np.array([size.ranges[p][0] for p in named])
        high = np.array([size.ranges[p][1] for p in named])
        excess = np.where(x < low, x - low, np.where(x > high, x - high, 0.0))
        checks[size.name] = tuple(PointCheck(p, float(m), float(lo), float(hi), float(e))
                                  for p, m, lo, hi, e in zip(named, x, low, high, excess))
        offset = np.abs(x - (low + high) / 2) / ((high - low) / 2)
        offsets.append(float(offset.max()) if len(offset) else np.inf)
    order = np.argsort(offsets, kind="stable")
    fitting = tuple(chart.sizes[i].name for i in order
                    if all(c.excess_mm == 0 for c in checks[chart.sizes[i].name]))
    nearest = chart.sizes[int(order[0])].name if np.isfinite(offsets[int(order[0])]) else None
    if missing:
        return SizeDecision("not_measured", (), None, nearest, (), missing, checks)
    if fitting:
        return SizeDecision("ready_to_wear", fitting, fitting[0], fitting[0], (), (), checks)
    outside = tuple(c for c in checks[nearest] if c.excess_mm != 0) if nearest else ()
    return SizeDecision("made_to_measure", (), None, nearest, outside, (), checks)


def record_chart_measures(landmarks: dict, sole_mm: float | None, foot: dict | None = None) -> dict[str, float]:
    """The chart points a calf record measures (mm): tape girths cB, cB1, cC, cD (the
    convex-hull girth, as a tape and a chart measure), and when the foot's sole is in the
    scan, the lengths lB, lB1, lC, lD from the floor (height above the sole plane) and the
    record's cA, cY from ``foot`` (its version-3 chart); as the order form has them
    (:func:`app.geometry.garment.measuring_points.chart_of_record`)."""
    return {m.point.name: m.value_mm for m in chart_of_record(landmarks, sole_mm, "AG", foot)
            if m.value_mm is not None and m.point.name in CHART_POINTS}

"""Run the service's fitting core on a generated case and compare it with the truth."""

from __future__ import annotations

import time

import numpy as np

from app.geometry.errors import FitFailure
from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan
from app.geometry.scan.reader import load_scan
from app.records.codec import record_from_fit
from benchmarks.corpus.cases import Case

LANDMARKS = ("B", "B1", "C", "D")


def run_case(case: Case) -> dict:
    """Load, check and fit ``case`` as the upload flow does; returns a flat result dict:
    outcome ("fit" or the failure reason), correct (outcome == expect), seconds,
    girth_error_mm / height_error_mm per landmark (fitted cases), side found."""
    started = time.perf_counter()
    result: dict = {"case": case.spec.case_id, "kind": case.spec.kind, "expect": case.expect,
                    "cloud": case.is_cloud, "notes": case.notes}
    try:
        scan = load_scan(case.data, file_type=case.file_type, units=case.units)
        options = FitOptions(side=case.side)
        placement = check_scan(scan, options)
        fit = fit_scan(scan, options, placement=placement)
        record = record_from_fit(fit, scan.source_format, scan.units)
    except FitFailure as failure:
        result.update(outcome=failure.reason.value, detail=failure.detail)
    else:
        result["outcome"] = "fit"
        result.update(compare(case, record.to_dict()))
    result["seconds"] = time.perf_counter() - started
    result["correct"] = result["outcome"] == case.expect
    return result


def compare(case: Case, record: dict) -> dict:
    """Girth and height errors (mm) of a record against the case's truth."""
    to_gen = np.linalg.inv(case.to_scan) @ np.asarray(record["frame"])
    origin = to_gen[:3, 3]
    axis = case.truth.axis
    b_shift = float((origin - case.truth.points_mm["B"]) @ axis)
    girth_error, height_error = {}, {}
    for name in LANDMARKS:
        mark = record["landmarks"][name]
        girth = mark.get("tape_girth_mm", mark["circumference_mm"])
        girth_error[name] = float(girth - case.truth.girths_mm[name])
        height_error[name] = float(b_shift + mark["height_mm"] - case.truth.heights_mm[name])
    out = {"girth_error_mm": girth_error, "height_error_mm": height_error,
           # the uncertainty the record states on each landmark's height (mm, None where none)
           "height_tolerance_mm": {n: record["landmarks"][n].get("height_tolerance_mm") for n in LANDMARKS},
           "side_found": record.get("side"), "warnings": record.get("warnings", [])}
    side_info = record.get("side_inference") or {}
    out["side_inferred"] = side_info.get("side")
    out["side_confidence"] = side_info.get("confidence")
    out["at_scan_edge"] = [n for n in LANDMARKS if record["landmarks"][n].get("at_scan_edge")]
    return out

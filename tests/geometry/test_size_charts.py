"""Size charts (app.geometry.garment.size_charts): validation, fitting sizes, the best
one, made to measure with the excess per point, points not measured."""

import pytest

from app.geometry.errors import FitFailure
from app.geometry.garment.size_charts import record_chart_measures, size_chart_from_dict, size_decision

CHART = {"product": "test AD", "type": "AD", "sizes": [
    {"name": "S", "ranges": {"cB": [190, 212], "cC": [320, 380]}},
    {"name": "M", "ranges": {"cB": [205, 225], "cC": [340, 400]}},
    {"name": "L", "ranges": {"cB": [220, 240], "cC": [360, 420]}},
]}


def test_every_fitting_size_is_listed_and_the_most_central_is_best():
    chart = size_chart_from_dict(CHART)
    decision = size_decision(chart, {"cB": 210.0, "cC": 372.0})
    assert decision.decision == "ready_to_wear"
    assert set(decision.fitting) == {"S", "M"}
    # M: |210-215|/10 = 0.5, |372-370|/30 = 0.07 -> 0.5; S: |210-201|/11 = 0.82 -> M is more central
    assert decision.best == "M" and decision.fitting[0] == "M"


def test_no_fitting_size_gives_made_to_measure_with_the_excess_of_each_point():
    decision = size_decision(size_chart_from_dict(CHART), {"cB": 245.0, "cC": 371.0})
    assert decision.decision == "made_to_measure" and decision.best is None and decision.nearest == "L"
    assert [(c.point, c.excess_mm) for c in decision.outside] == [("cB", 5.0)]
    below = size_decision(size_chart_from_dict(CHART), {"cB": 185.0, "cC": 300.0})
    assert below.nearest == "S" and {c.point: c.excess_mm for c in below.outside} == {"cB": -5.0, "cC": -20.0}


def test_a_point_the_record_lacks_is_named_and_no_size_is_confirmed():
    chart = size_chart_from_dict({**CHART, "sizes": [{"name": "S", "ranges": {"cB": [190, 212], "lD": [300, 360]}}]})
    decision = size_decision(chart, {"cB": 200.0})
    assert decision.decision == "not_measured" and decision.missing == ("lD",) and decision.best is None


@pytest.mark.parametrize("change,words", [
    ({"type": "XX"}, "type must be one of AD, AG"),
    ({"sizes": []}, "sizes must be a list"),
    ({"sizes": [{"name": "S", "ranges": {"cQ": [1, 2]}}]}, "unknown point 'cQ'"),
    ({"sizes": [{"name": "S", "ranges": {"cB": [220, 210]}}]}, "0 < min < max"),
    ({"sizes": [{"name": "S", "ranges": {"cB": ["a", 2]}}]}, "[min, max] in mm"),
    ({"sizes": [{"name": "S", "ranges": {"cB": [1, 2]}}, {"name": "S", "ranges": {"cB": [1, 2]}}]}, "unique"),
])
def test_bad_charts_are_refused_naming_the_fault(change, words):
    with pytest.raises(FitFailure) as info:
        size_chart_from_dict({**CHART, **change})
    assert words in info.value.detail


def test_a_record_gives_tape_girths_and_lengths_from_the_floor_when_it_has_the_sole():
    landmarks = {"B": {"height_mm": 0.0, "circumference_mm": 216.0, "tape_girth_mm": 215.0},
                 "C": {"height_mm": 200.0, "circumference_mm": 380.0}}
    assert record_chart_measures(landmarks, None) == {"cB": 215.0, "cC": 380.0}
    assert record_chart_measures(landmarks, -95.0) == {"cB": 215.0, "lB": 95.0, "cC": 380.0, "lC": 295.0}


def test_a_chart_reads_from_csv_as_from_json():
    from app.geometry.garment.size_charts import size_chart_as_dict, size_chart_dict_from_csv

    text = "# product: test AD\n# type: AD\nsize,point,min_mm,max_mm\n" + "".join(
        f"{s['name']},{p},{lo},{hi}\n" for s in CHART["sizes"] for p, (lo, hi) in s["ranges"].items())
    assert size_chart_as_dict(size_chart_from_dict(size_chart_dict_from_csv(text))) == size_chart_as_dict(size_chart_from_dict(CHART))
    with pytest.raises(FitFailure, match="columns size, point, min_mm, max_mm"):
        size_chart_dict_from_csv("# type: AD\nname,low,high\nS,1,2\n")

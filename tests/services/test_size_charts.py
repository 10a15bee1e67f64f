"""The shipped example charts (app/data/size_charts, made by benchmarks/size_chart_example.py
from ANSUR II): a knee-high and a thigh-high one, labelled as examples, read as any chart."""

from app.geometry.garment.size_charts import size_decision
from app.services.size_charts import EXAMPLE_AG_CHART_ID, EXAMPLE_CHART_ID, example_chart, example_chart_id


def test_the_examples_are_a_knee_high_and_a_thigh_high_chart_on_the_same_ankle_bands():
    knee, thigh = example_chart(EXAMPLE_CHART_ID), example_chart(EXAMPLE_AG_CHART_ID)
    assert (knee.stocking_type, thigh.stocking_type) == ("AD", "AG")
    assert "EXAMPLE" in knee.product and "EXAMPLE" in thigh.product and "ANSUR II" in thigh.source
    assert knee.points == ("cB", "cC") and thigh.points == ("cB", "cC", "cG", "lG")
    for a, b in zip(knee.sizes, thigh.sizes):
        assert a.name == b.name and a.ranges["cB"] == b.ranges["cB"] and a.ranges["cC"] == b.ranges["cC"]
    # bigger sizes for bigger legs: every range's ends rise from S to XXL
    for point in thigh.points:
        lows = [s.ranges[point][0] for s in thigh.sizes]
        assert lows == sorted(lows)
    assert example_chart_id("AG") == EXAMPLE_AG_CHART_ID and example_chart_id("AD") == EXAMPLE_CHART_ID


def test_a_thigh_high_decision_reads_the_thigh_and_its_length():
    thigh = example_chart(EXAMPLE_AG_CHART_ID)
    m = thigh.sizes[2].ranges  # L, at the centre of every range
    centre = {p: (lo + hi) / 2 for p, (lo, hi) in m.items()}
    assert size_decision(thigh, centre).best == "L"
    too_wide = size_decision(thigh, {**centre, "cG": max(s.ranges["cG"][1] for s in thigh.sizes) + 20.0})
    assert too_wide.decision == "made_to_measure" and "cG" in {c.point for c in too_wide.outside}
    no_floor = size_decision(thigh, {p: v for p, v in centre.items() if p != "lG"})
    assert no_floor.decision == "not_measured"

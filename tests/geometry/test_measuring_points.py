"""The order form's measuring points on a calf record: values where the record has them,
a reason everywhere else, and the points each stocking type needs."""

from __future__ import annotations

import pytest

from app.geometry.garment.measuring_points import MEASURING_POINTS, chart_of_record
from app.records.codec import record_from_fit
from tests.conftest import fitted


@pytest.fixture(scope="module")
def landmarks():
    _, result = fitted("bodyparts3d_right_leg.stl", None)
    return record_from_fit(result, "stl", "mm").landmarks


def test_a_record_with_its_floor_gives_girths_and_lengths(landmarks):
    sole = -80.0
    chart = {m.point.name: m for m in chart_of_record(landmarks, sole, "AD")}
    assert list(chart) == [p.name for p in MEASURING_POINTS]
    for name in ("B", "B1", "C", "D"):
        assert chart[f"c{name}"].value_mm == landmarks[name]["tape_girth_mm"]
        assert chart[f"l{name}"].value_mm == pytest.approx(landmarks[name]["height_mm"] - sole)
        assert chart[f"c{name}"].height_mm == chart[f"l{name}"].height_mm == landmarks[name]["height_mm"]
    # the lengths climb with the landmarks, and every point without a value says why
    assert chart["lB"].value_mm < chart["lB1"].value_mm < chart["lC"].value_mm < chart["lD"].value_mm
    assert all((m.value_mm is None) == bool(m.reason) for m in chart.values())
    assert [n for n, m in chart.items() if m.needed] == ["cA", "cY", "cB", "cB1", "cC", "cD", "foot_length",
                                                        "lB", "lB1", "lC", "lD"]
    assert all(m.needed for m in chart_of_record(landmarks, sole, "AG"))


def test_without_the_floor_the_lengths_say_so_and_a_bad_type_is_refused(landmarks):
    chart = {m.point.name: m for m in chart_of_record(landmarks, None, "AG")}
    assert chart["lC"].value_mm is None and "sole is not in the scan" in chart["lC"].reason
    assert chart["cC"].value_mm == landmarks["C"]["tape_girth_mm"]
    # a foot in the scan without its sole (cut through, pointed): every length says why
    why = "the foot is pointed: its forefoot reaches 60 mm below the heel"
    pointed = chart_of_record(landmarks, None, "AG", no_sole_reason=why)
    assert [m.reason for m in pointed if m.point.name in ("lB", "lB1", "lC", "lD")] == [why] * 4
    without_b1 = {k: v for k, v in landmarks.items() if k != "B1"}
    assert "no landmark B1" in {m.point.name: m for m in chart_of_record(without_b1, None, "AD")}["cB1"].reason
    with pytest.raises(ValueError, match="AD, AG"):
        chart_of_record(landmarks, None, "AT")

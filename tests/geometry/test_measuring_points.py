"""The order form's measuring points on a calf record: values where the record has them,
a reason everywhere else, and the points each stocking type needs."""

from __future__ import annotations

import pytest

from app.geometry.garment.measuring_points import LENGTH_TOLERANCE_MM, MEASURING_POINTS, chart_of_record
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


def test_a_length_whose_point_the_scan_places_loosely_says_how_loosely(landmarks):
    """BodyParts3D's calf: C's crown is flat over about 24 mm (height tolerance 12 mm),
    B1 on the calf's steep rise is placed within 1 mm.  lC carries C's tolerance as its
    uncertainty, lB1 none (within the 10 mm a point placed by hand is reproducible to);
    the thigh's lengths carry their points' height uncertainty past that, and a record
    made before it was kept has none."""
    sole = -120.0
    chart = {m.point.name: m for m in chart_of_record(landmarks, sole, "AG")}
    for name in ("B", "B1", "C", "D"):
        tolerance = landmarks[name]["height_tolerance_mm"]
        assert chart[f"l{name}"].uncertainty_mm == (tolerance if tolerance > LENGTH_TOLERANCE_MM else None)
        assert chart[f"c{name}"].uncertainty_mm is None  # the girth is sure: a tape reads it alike along the crown
    assert chart["lC"].uncertainty_mm is not None and chart["lB1"].uncertainty_mm is None
    thigh = {"cE": {"value_mm": 390.0, "height_mm": 330.0, "reason": None, "height_uncertainty_mm": 3.0},
             "cF": {"value_mm": 480.0, "height_mm": 470.0, "reason": None, "height_uncertainty_mm": 12.5},
             "cG": {"value_mm": 560.0, "height_mm": 610.0, "reason": None}}
    chart = {m.point.name: m for m in chart_of_record(landmarks, sole, "AG", thigh)}
    assert (chart["lE"].uncertainty_mm, chart["lF"].uncertainty_mm, chart["lG"].uncertainty_mm) == (None, 12.5, None)
    assert chart["lF"].value_mm == pytest.approx(590.0) and chart["cF"].uncertainty_mm is None
    older = {name: {k: v for k, v in entry.items() if k != "height_tolerance_mm"} for name, entry in landmarks.items()}
    assert all(m.uncertainty_mm is None for m in chart_of_record(older, sole, "AD") if m.point.kind == "length")

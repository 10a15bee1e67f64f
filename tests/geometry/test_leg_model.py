"""The leg model from B to G (app.geometry.fit.leg_model): on the real leg that reaches
its gluteal fold it lies on the skin and reads the thigh's tape girths; a leg without G,
or with a bent knee, says why; the record carries it and reads it back."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.anatomy.thigh import ThighMeasures, thigh_measures
from app.geometry.errors import FitFailure
from app.geometry.fit.leg_model import LEG_POINTS, leg_model_of
from app.geometry.measures.surface_girths import girths
from app.geometry.placement.place import place_leg
from app.geometry.spline.distance import foot_points
from app.geometry.spline.nurbs import evaluate_grid
from app.records.codec import parse_record, record_from_fit
from tests.conftest import fitted


def test_the_leg_model_runs_from_b_to_g_on_the_skin_through_the_thighs_points():
    scan, result = fitted("bodyparts3d_right_leg.stl", None)
    model = result.leg_model.model
    assert model is not None and result.leg_model.reason is None
    layers = dict(zip(LEG_POINTS, model.layer_heights_mm))
    chart = result.thigh
    assert layers["G"] == chart.top_of_thigh.height_mm and layers["D"] == result.landmarks.D.height_mm
    # its ends are the planes of B and G (v = 0, 1), its v anchored at the seven points
    ends = evaluate_grid(model.fit.surface, np.linspace(0, 1, 24, endpoint=False), np.array([0.0, 1.0]))
    assert np.allclose(ends[:, 0, 2], layers["B"], atol=1e-6) and np.allclose(ends[:, 1, 2], layers["G"], atol=1e-6)
    # on the skin: the scan's points and the surface within a few mm of each other
    assert model.skin.coverage > 0.95 and model.skin.median_mm < 0.5 and model.skin.p99_mm < 3.0
    # and the scan on it: its points between B and G within a millimetre of the surface (p95)
    leg = place_leg(scan, None)
    local = leg.placement.frame.to_calf(leg.points)
    inside = local[(local[:, 2] >= layers["B"]) & (local[:, 2] <= layers["G"])]
    distance = foot_points(model.fit.surface, inside, layers["G"] - layers["B"])[0]
    assert np.percentile(distance, 95) < 1.0 and distance.max() < 3.0
    # its tape girths at E, F, G are the ones measured from the scan (the section's hull, within 1.5%)
    measured = [chart.knee.girth_mm, chart.mid_thigh.girth_mm, chart.top_of_thigh.girth_mm]
    modelled = [g.tape_mm for g in girths(model.fit.surface, np.array([layers["E"], layers["F"], layers["G"] - 1.0]))]
    assert modelled == pytest.approx(measured, rel=0.015)


def test_a_leg_without_its_thigh_or_with_a_bent_knee_has_no_model_and_says_why():
    _, result = fitted("vh_female_skin.glb", "right")
    assert result.leg_model.model is None and "gluteal fold" in result.leg_model.reason
    scan, paper = fitted("bodyparts3d_right_leg.stl", None)
    bent = thigh_measures(np.zeros((10, 3)), None, 0.0, knee_bent=True)
    outcome = leg_model_of(np.zeros((10, 3)), None, paper.landmarks, bent)
    assert outcome.model is None and "bent" in outcome.reason
    assert "not measured" in leg_model_of(np.zeros((10, 3)), None, paper.landmarks, None).reason
    assert isinstance(bent, ThighMeasures)


def test_the_record_carries_the_leg_model_and_reads_it_back():
    scan, result = fitted("bodyparts3d_right_leg.stl", None)
    body = record_from_fit(result, "stl", "mm").to_dict()
    leg = body["leg_model"]
    assert leg["range"] == "B-G" and leg["grid"] == "24x24" and list(leg["layers_mm"]) == list(LEG_POINTS)
    again = parse_record(body)
    assert np.array_equal(again.leg_model.surface.control_points, result.leg_model.model.fit.surface.control_points)
    assert again.to_dict()["leg_model"] == leg
    # the calf record is the paper's, as before: its own surface, B to D
    assert np.array_equal(again.surface.control_points, result.surface.control_points)
    # a broken leg surface is refused by name; a record without G keeps the reason
    broken = {**body, "leg_model": {**leg, "surface": {**leg["surface"], "knots_v": leg["surface"]["knots_v"][:-1]}}}
    with pytest.raises(FitFailure, match="leg_model.surface.knots_v must have"):
        parse_record(broken)
    _, female = fitted("vh_female_skin.glb", "right")
    without = parse_record(record_from_fit(female, "glb", "m").to_dict())
    assert without.leg_model.surface is None and "gluteal fold" in without.leg_model.reason
    with pytest.raises(FitFailure, match="needs its reason"):
        parse_record({**body, "leg_model": {"reason": ""}})

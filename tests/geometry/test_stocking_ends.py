"""The stocking's foot and top band (app.geometry.garment.stocking_ends): the foot's rows
knitted for B's pressure from cA and cY, its length by toe, a missing point saying why;
the band one relaxed circumference that nowhere presses more than the rows it replaces."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment.design import design_verdict
from app.geometry.garment.fabric import Fabric
from app.geometry.garment.knitting import KnittingSpec, knit_rows
from app.geometry.garment.pressure import PA_PER_MMHG, PA_PER_N_PER_CM_PER_MM, laplace_mean_pa
from app.geometry.garment.stocking_ends import foot_part, top_band

FABRIC = Fabric.linear(10.0)
SOLE = -110.0


def _chart(**overrides) -> dict:
    """A foot's chart: a 250 mm foot whose middle is on the sole at the origin's x, y and
    whose ball lies 62 mm ahead of it (cA at 0.748 of the length from the heel)."""
    chart = {"foot_length": {"value_mm": 250.0, "at_mm": [3.0, 40.0, SOLE], "reason": None},
             "cA": {"value_mm": 240.0, "at_mm": [3.0, 102.0, SOLE + 25.0], "reason": None},
             "cY": {"value_mm": 330.0, "at_mm": [3.0, 10.0, SOLE + 45.0], "reason": None}}
    chart.update(overrides)
    return chart


def test_the_foot_is_knitted_for_bs_pressure_toe_to_heel_and_to_its_length():
    closed = foot_part(_chart(), 27.5, "closed", FABRIC, 1.0).part
    assert [r.point for r in closed.rows] == ["cA", "cY"]
    for row, girth in zip(closed.rows, (240.0, 330.0)):
        assert row.stretched_circumference_mm == girth and row.relaxed_circumference_mm < girth
        assert row.relaxed_circumference_mm == round(row.relaxed_circumference_mm)  # to the 1 mm resolution
        # what the knitted row gives: Laplace's 2 pi T / L of its rounded L0, within rounding of B's target
        strain = girth / row.relaxed_circumference_mm - 1
        assert row.strain == pytest.approx(strain) and row.tension_n_per_cm == pytest.approx(10.0 * strain)
        laplace = 2 * np.pi * row.tension_n_per_cm * PA_PER_N_PER_CM_PER_MM / girth / PA_PER_MMHG
        assert row.predicted_mean_mmhg == pytest.approx(laplace) == pytest.approx(27.5, rel=0.02)
    assert closed.rows[0].height_mm == SOLE + 25.0 and closed.toe == "closed"
    assert closed.foot_length_mm == closed.knitted_length_mm == 250.0
    opened = foot_part(_chart(), 27.5, "open", FABRIC, 1.0).part
    assert opened.knitted_length_mm == pytest.approx(125.0 + 62.0) and "metatarsal heads" in opened.length_rule
    assert [r.relaxed_circumference_mm for r in opened.rows] == [r.relaxed_circumference_mm for r in closed.rows]


def test_a_foot_the_scan_does_not_have_says_why_and_makes_the_verdict_review():
    missing = foot_part(_chart(cY={"value_mm": None, "reason": "no closed loop round the heel (a hole or a crop)"}),
                        27.5, "closed", FABRIC, 1.0)
    assert missing.part is None and "cY is not measured" in missing.reason and "a hole or a crop" in missing.reason
    assert "before the foot was measured" in foot_part(None, 27.5, "closed", FABRIC, 1.0).reason
    no_length = foot_part(_chart(foot_length={"value_mm": None, "reason": "cut"}), 27.5, "closed", FABRIC, 1.0).part
    assert no_length.knitted_length_mm is None and "by tape" in no_length.length_rule
    verdict, reasons = design_verdict([], [], 60.0, [f"the foot is not in the knitting specification: {missing.reason}"])
    assert verdict == "review" and "cY is not measured" in reasons[0]
    assert design_verdict([], [], 60.0, [])[0] == "pass"
    with pytest.raises(FitFailure) as refused:  # B's pressure round the foot needs more than the fabric's strain limit
        foot_part(_chart(), 27.5, "closed", Fabric.linear(0.5), 1.0)
    assert refused.value.reason is FailureReason.UNREACHABLE_PRESSURE and "on the foot at" in refused.value.detail


def _spec(girth: np.ndarray, target: np.ndarray) -> KnittingSpec:
    heights = np.arange(len(girth)) * 5.0
    knitted = knit_rows(heights, target, girth, FABRIC, 1.0)
    return KnittingSpec(heights, target, girth, knitted.tension_n_per_cm, knitted.strain, knitted.relaxed_mm,
                        laplace_mean_pa(knitted.tension_n_per_cm, girth))


@pytest.mark.parametrize("shape", ["narrowing to the knee", "widening up the thigh"])
def test_the_band_is_one_circumference_nowhere_tighter_than_the_rows_it_replaces(shape):
    rows = np.arange(40)
    girth = 380.0 - 0.8 * rows if shape == "narrowing to the knee" else 450.0 + 2.5 * rows
    spec = _spec(girth, np.linspace(30.0, 12.0, 40))
    band = top_band(spec, 25.0, FABRIC)
    assert list(band.replaces) == [34, 35, 36, 37, 38, 39]  # the rows within 25 mm of the top (every 5 mm)
    assert band.from_height_mm == 170.0 and band.to_height_mm == 195.0
    assert band.relaxed_circumference_mm == spec.relaxed_circumference_mm[band.replaces].max()
    graded = spec.predicted_mean_pa[band.replaces] / PA_PER_MMHG
    assert np.all(band.band_pressure_mmhg <= graded + 1e-9)
    assert band.band_mmhg == (band.band_pressure_mmhg.min(), band.band_pressure_mmhg.max())
    assert band.graded_mmhg == pytest.approx((graded.min(), graded.max()))
    # at the row whose L0 it takes, the band gives what the graded row gives
    widest = int(np.argmax(spec.relaxed_circumference_mm[band.replaces]))
    assert band.band_pressure_mmhg[widest] == pytest.approx(graded[widest])
    assert top_band(spec, 0.0, FABRIC) is None

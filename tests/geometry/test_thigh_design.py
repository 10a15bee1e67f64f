"""The thigh part of a thigh-high stocking (app.geometry.garment.thigh_design) on a thigh
whose tape girth rises linearly from D to G."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment.fabric import Fabric
from app.geometry.garment.pressure import PA_PER_MMHG, PA_PER_N_PER_CM_PER_MM
from app.geometry.garment.standards import THIGH_GRADIENT
from app.geometry.garment.thigh_design import thigh_part

D, G = 250.0, 620.0
LEVELS = {"E": 320.0, "F": 470.0, "G": G}


def _profile() -> tuple[np.ndarray, np.ndarray]:
    heights = np.linspace(D, G, 75)
    return heights, 360.0 + 0.6 * (heights - D)  # 360 mm at D, 582 mm at G


def test_the_thigh_grades_from_d_to_the_standards_rows_and_meets_its_targets():
    heights, girths = _profile()
    part = thigh_part(heights, girths, LEVELS, 27.5, 14.0, Fabric.linear(10.0), 5.0, 1.0)
    rows = part.rows
    assert rows.heights_mm[0] > D and rows.heights_mm[-1] == pytest.approx(G)
    for name in ("F", "G"):
        assert part.levels[name].target_mmhg == pytest.approx(THIGH_GRADIENT[name]["target"] * 27.5)
    # E lies between D and F, on the line from D's pressure to F's
    e_target = np.interp(LEVELS["E"], [D, LEVELS["F"]], [14.0, THIGH_GRADIENT["F"]["target"] * 27.5])
    assert part.levels["E"].target_mmhg == pytest.approx(e_target, rel=1e-6)
    # the targets fall all the way; Laplace on the knitted rows (L0 rounded to 1 mm, which
    # moves a row by up to ~0.25 mmHg) stays within 3% of them
    predicted = rows.predicted_mean_pa / PA_PER_MMHG
    assert np.all(np.diff(rows.target_mmhg) < 0)
    assert np.allclose(predicted, rows.target_mmhg, rtol=0.03)
    assert np.allclose(rows.relaxed_circumference_mm % 1.0, 0.0, atol=1e-9)
    assert np.allclose(predicted * PA_PER_MMHG, 2 * np.pi * rows.tension_n_per_cm * PA_PER_N_PER_CM_PER_MM
                       / rows.stretched_circumference_mm)
    names = {check.name: (check.passed, check.normative) for check in part.checks}
    assert names["graded D > E > F > G"] == (True, True)
    assert all(not normative for name, (_, normative) in names.items() if name.startswith(("F ", "G ")))


def test_a_fabric_that_cannot_reach_the_thigh_targets_is_refused():
    heights, girths = _profile()
    with pytest.raises(FitFailure) as refused:
        thigh_part(heights, girths, LEVELS, 60.0, 40.0, Fabric.linear(1.0, max_strain=0.2), 5.0, 1.0)
    assert refused.value.reason is FailureReason.UNREACHABLE_PRESSURE and "on the thigh at" in refused.value.detail

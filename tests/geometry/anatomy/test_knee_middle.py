"""The knee's girth slope that E is read on (app.geometry.anatomy.knee_middle.girth_slope),
on girth profiles of known slope; E itself is tested on whole legs in test_thigh.py."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.anatomy.knee_middle import girth_slope
from app.geometry.anatomy.level_runs import SLOPE_HALF_MM, STEP_MM


def _knee(heights: np.ndarray) -> np.ndarray:
    """A knee's girth (mm) at heights above D: rising 0.6 mm/mm, levelling to 0.2 at 70 mm,
    then rising again (a cubic: the spline reproduces it exactly)."""
    return 340.0 + 0.6 * heights - 0.0057 * heights**2 + 2.7e-5 * heights**3


def _knee_slope(heights: np.ndarray) -> np.ndarray:
    return 0.6 - 0.0114 * heights + 8.1e-5 * heights**2


HEIGHTS = np.arange(0.0, 162.0, STEP_MM)


def test_the_slope_of_a_smooth_knee_is_its_derivative_and_undefined_at_the_ends():
    slope = girth_slope(HEIGHTS, _knee(HEIGHTS))
    inside = (HEIGHTS >= HEIGHTS[0] + SLOPE_HALF_MM) & (HEIGHTS <= HEIGHTS[-1] - SLOPE_HALF_MM)
    assert np.isnan(slope[~inside]).all()
    assert slope[inside] == pytest.approx(_knee_slope(HEIGHTS[inside]), abs=1e-6)


def test_a_noisy_knees_slope_is_the_splines_not_the_noises():
    """1 mm of girth noise: the local slope over +-SLOPE_HALF_MM errs by ~0.05 mm/mm (its
    docstring), the spline's by a fraction of that."""
    rng = np.random.default_rng(3)
    errors = []
    for _ in range(20):
        slope = girth_slope(HEIGHTS, _knee(HEIGHTS) + rng.normal(0.0, 1.0, len(HEIGHTS)))
        inside = np.isfinite(slope)
        errors.append(np.abs(slope[inside] - _knee_slope(HEIGHTS[inside])).max())
    assert np.median(errors) < 0.05


def test_a_hole_in_the_knee_leaves_the_slope_undefined_only_near_it():
    girth = _knee(HEIGHTS)
    hole = (HEIGHTS >= 80.0) & (HEIGHTS <= 84.0)
    girth[hole] = np.nan
    slope = girth_slope(HEIGHTS, girth)
    near = np.abs(HEIGHTS - 82.0) <= 2.0 + SLOPE_HALF_MM
    assert np.isnan(slope[near]).all()
    away = np.isfinite(slope)
    assert away.sum() > 40
    assert slope[away] == pytest.approx(_knee_slope(HEIGHTS[away]), abs=0.02)

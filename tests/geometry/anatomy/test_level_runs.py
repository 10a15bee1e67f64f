"""Runs of a sampled profile read between the samples (app.geometry.anatomy.level_runs)."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.anatomy.level_runs import STEP_MM, run_between_crossings


def test_a_run_ends_where_its_value_crosses_the_threshold_between_samples_or_at_its_window():
    heights = np.arange(0.0, 40.0, STEP_MM)
    value = np.abs(heights - 17.3)  # below 5 from 12.3 to 22.3 mm, sampled every 2 mm
    run = run_between_crossings(heights, value, np.ones(len(heights), bool), 9, 5.0)
    assert (run.bottom_mm, run.top_mm, run.middle_mm) == pytest.approx((12.3, 22.3, 17.3))
    assert heights[run.first] == 14.0 and heights[run.last] == 22.0
    window = heights >= 16.0  # the run stops at the window's first sample, not at a crossing
    cut = run_between_crossings(heights, value, window, 9, 5.0)
    assert (cut.bottom_mm, cut.top_mm) == pytest.approx((16.0, 22.3))


def test_a_run_that_never_crosses_spans_its_window_and_noise_moves_its_ends_by_less_than_a_step():
    heights = np.arange(0.0, 100.0, STEP_MM)
    inside = (heights >= 10.0) & (heights <= 90.0)
    flat = run_between_crossings(heights, np.zeros(len(heights)), inside, 25, 1.0)
    assert (flat.bottom_mm, flat.top_mm) == (10.0, 90.0)
    # a V-shaped value crossing 3.0 at 38.0 and 62.0 mm, with noise of 0.05: each end moves
    # by about noise / slope (0.5 mm), not by a whole step as a sample-held end does
    rng = np.random.default_rng(4)
    v = np.abs(heights - 50.0) / 4.0
    ends = np.array([[r.bottom_mm, r.top_mm] for r in (
        run_between_crossings(heights, v + rng.normal(0.0, 0.05, len(v)), inside, 25, 3.0) for _ in range(50))])
    assert np.abs(ends - [38.0, 62.0]).max() < 1.0
    assert np.abs(ends.mean(axis=0) - [38.0, 62.0]).max() < 0.2

"""The landmarks as a record holds them (app.geometry.anatomy.feature_layers): how sharply
a synthetic girth profile (mm) places each one."""

import numpy as np
import pytest

from app.geometry.anatomy.feature_layers import HIGH_CONFIDENCE_MM, height_tolerances, level_crossing


def test_tolerances_are_long_on_a_flat_crown_and_short_on_a_steep_rise():
    """A calf profile B (0) - B1 (steep rise) - C (a crown flat within 0.5% over 60 mm)."""
    heights = np.arange(0.0, 360.5, 1.0)
    rise = 1.0 / (1.0 + np.exp(-(heights - 100.0) / 15.0))
    crown = np.where(np.abs(heights - 230.0) < 30.0, 0.0, -0.002 * (np.abs(heights - 230.0) - 30.0) ** 2)
    girth = 220.0 + 170.0 * rise + crown
    tolerances = height_tolerances(heights, girth, {"B": 0.0, "B1": 100.0, "C": 230.0})
    assert tolerances["B1"] < 2.0
    assert tolerances["C"] > 25.0
    assert tolerances["B1"] <= HIGH_CONFIDENCE_MM



def test_b1_is_read_again_where_the_tapes_girths_cross_the_level():
    """level_crossing: the least-squares line through a few tape girths round a first
    reading (a rise of 1.3 mm per mm with 0.4 mm of reading noise) reaches the level
    within 0.3 mm of where the rise does; a level outside the planes, a flat or falling
    run, or too few girths leave the first reading as it is."""
    rng = np.random.default_rng(2)
    near = 150.0 + np.arange(-8.0, 8.1, 2.0)
    girth = 300.0 + 1.3 * (near - 153.0) + rng.normal(0.0, 0.4, len(near))
    assert level_crossing(near, girth, 300.0, 150.0) == pytest.approx(153.0, abs=0.3)
    assert level_crossing(near, girth, 330.0, 150.0) == 150.0  # 23 mm away: outside the planes
    assert level_crossing(near, np.full(len(near), 300.0), 300.0, 150.0) == 150.0
    assert level_crossing(near, np.where(near < 148, girth, np.nan), 300.0, 150.0) == 150.0

"""The landmarks as a record holds them (app.geometry.anatomy.feature_layers): how sharply
a synthetic girth profile (mm) places each one."""

import numpy as np

from app.geometry.anatomy.feature_layers import HIGH_CONFIDENCE_MM, height_tolerances


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


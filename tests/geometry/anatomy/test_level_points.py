"""A point's girth uncertainty where its height is uncertain (app.geometry.anatomy.level_points)."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.anatomy.level_points import girth_spread


def test_a_points_girth_uncertainty_is_the_most_its_girth_changes_where_it_may_lie():
    """girth_spread reads the girth either side of the point: a thigh whose girth rises 0.2
    mm per mm below a smooth fold and 1.5 above it (the buttock) is uncertain by the rise
    above it (7.5 mm within 5 mm of the fold, where the slope below says 1), a plane without
    a closed section (NaN) is read between its neighbours, and no reach is no uncertainty."""
    heights = np.arange(0.0, 101.0, 5.0)
    girths = np.where(heights <= 50.0, 500.0 + 0.2 * heights, 510.0 + 1.5 * (heights - 50.0))
    assert girth_spread(heights, girths, 50.0, 5.0) == pytest.approx(7.5)
    assert girth_spread(heights, girths, 25.0, 5.0) == pytest.approx(1.0)
    holed = girths.copy()
    holed[heights == 55.0] = np.nan
    assert girth_spread(heights, holed, 50.0, 5.0) == pytest.approx(7.5)
    assert girth_spread(heights, girths, 50.0, 0.0) == 0.0

"""Landmarks at the scan's edge: when does a scan that stops at a waist reach its
minimum?  Synthetic girth profiles (mm) of a smooth waist cut near its minimum."""

import numpy as np
import pytest

from app.geometry.landmarks import CROWN_FRACTION, EDGE_REACH_MM, _minimum_reached_at_edge


def _waist(vertex_beyond_mm: float, depth_fraction: float, girth_mm: float = 220.0, reach_mm: float = 40.0):
    """Heights 0..reach (the scan's bottom edge at 0) and the girth of a parabolic waist
    whose minimum lies ``vertex_beyond_mm`` below the edge and ``depth_fraction`` of the
    edge girth lower than it."""
    heights = np.arange(0.0, reach_mm + 0.5, 1.0)
    edge_girth = girth_mm
    depth = depth_fraction * edge_girth
    c = depth / vertex_beyond_mm**2  # g(x) = g_min + c (x + v)^2, g(0) = g_min + depth
    girth = edge_girth - depth + c * (heights + vertex_beyond_mm) ** 2
    return heights, girth


@pytest.mark.parametrize("beyond,depth,reached", [
    (5.0, 0.02, True),                   # the minimum just past the edge
    (EDGE_REACH_MM + 10, 0.6 * CROWN_FRACTION, True),   # further, but a tape reads the same
    (EDGE_REACH_MM + 10, 3.0 * CROWN_FRACTION, False),  # further and deeper: still narrowing
    (80.0, 0.10, False),                 # a scan cut well above the ankle
])
def test_a_waist_at_the_edge_is_reached_when_near_or_too_shallow_for_a_tape(beyond, depth, reached):
    heights, girth = _waist(beyond, depth)
    assert _minimum_reached_at_edge(heights, girth, 0.0, +1) is reached


def test_a_girth_that_rises_from_the_edge_has_its_minimum_inside():
    heights = np.arange(0.0, 40.5, 1.0)
    assert _minimum_reached_at_edge(heights, 220.0 + 0.05 * (heights - 10.0) ** 2, 0.0, +1)

"""A profile's waists read to a tape's resolution (app.geometry.anatomy.waists): when does
a scan that stops at a waist reach its minimum, and where is a noisy waist's vertex?
Synthetic girth profiles (mm) of a smooth waist."""

import numpy as np
import pytest

from app.geometry.anatomy.landmarks import smooth_profile
from app.geometry.anatomy.waists import (
    CROWN_FRACTION,
    EDGE_REACH_MM,
    WAIST_MIN_FLANK_MM,
    minimum_reached_at_edge,
    waist_vertex,
)


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
    assert minimum_reached_at_edge(heights, girth, 0.0, +1) is reached


def test_a_girth_that_rises_from_the_edge_has_its_minimum_inside():
    heights = np.arange(0.0, 40.5, 1.0)
    assert minimum_reached_at_edge(heights, 220.0 + 0.05 * (heights - 10.0) ** 2, 0.0, +1)


# --- the waists' vertex ---------------------------------------------------------------


def _noisy_waist(rng, vertex_mm: float, noise_mm: float = 0.3):
    """A knee waist 0..300 mm: 330 mm round at ``vertex_mm``, rising 0.004 mm/mm^2 (a
    flat waist: 1.6 mm over +-20 mm), with ``noise_mm`` of girth noise per section."""
    heights = np.arange(0.0, 300.5, 1.0)
    girth = 330.0 + 0.004 * (heights - vertex_mm) ** 2 + rng.normal(0.0, noise_mm, heights.size)
    return heights, girth


def test_the_waist_vertex_moves_less_with_noise_than_the_lowest_section():
    """Over 200 re-draws of the noise, the parabola's vertex stays within 1.5 mm of the
    true waist (p95) where the lowest single section wanders several times as far."""
    rng = np.random.default_rng(4)
    vertex_errors, lowest_errors = [], []
    for _ in range(200):
        heights, girth = _noisy_waist(rng, 150.0)
        lowest = int(np.argmin(girth))
        vertex_errors.append(waist_vertex(heights, girth, lowest, 0.0, 300.0) - 150.0)
        lowest_errors.append(heights[lowest] - 150.0)
    vertex_p95 = np.percentile(np.abs(vertex_errors), 95)
    lowest_p95 = np.percentile(np.abs(lowest_errors), 95)
    assert vertex_p95 < 1.5
    assert lowest_p95 > 3 * vertex_p95


def test_a_waist_nearer_the_scan_end_than_a_flank_keeps_its_lowest_section():
    rng = np.random.default_rng(5)
    heights, girth = _noisy_waist(rng, 6.0)
    lowest = int(np.argmin(girth))
    assert heights[lowest] < WAIST_MIN_FLANK_MM
    assert waist_vertex(heights, girth, lowest, 0.0, 300.0) == heights[lowest]


def test_a_waist_whose_window_the_scan_cuts_short_is_fitted_as_far_as_it_goes():
    """A knee-high scan stopping 15 mm above D: the clipped window (20 mm below, 15
    above) still finds the vertex, over 200 re-draws of the noise, much closer than the
    lowest single section does."""
    rng = np.random.default_rng(6)
    vertex_errors, lowest_errors = [], []
    for _ in range(200):
        heights, girth = _noisy_waist(rng, 150.0)
        girth[heights > 165.0] = np.nan  # the scan ends 15 mm above the waist
        lowest = int(np.nanargmin(smooth_profile(heights, girth)))  # as find_feature_heights picks it
        vertex_errors.append(waist_vertex(heights, girth, lowest, 0.0, 165.0) - 150.0)
        lowest_errors.append(heights[lowest] - 150.0)
    vertex_p95 = np.percentile(np.abs(vertex_errors), 95)
    assert vertex_p95 < 2.5
    assert np.percentile(np.abs(lowest_errors), 95) > 2 * vertex_p95

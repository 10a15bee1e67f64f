"""Landmarks at the scan's edge: when does a scan that stops at a waist reach its
minimum?  Synthetic girth profiles (mm) of a smooth waist cut near its minimum."""

import numpy as np
import pytest

from app.geometry.anatomy.landmarks import (
    CROWN_FRACTION,
    EDGE_REACH_MM,
    WAIST_MIN_FLANK_MM,
    _minimum_reached_at_edge,
    smooth_profile,
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
    assert _minimum_reached_at_edge(heights, girth, 0.0, +1) is reached


def test_a_girth_that_rises_from_the_edge_has_its_minimum_inside():
    heights = np.arange(0.0, 40.5, 1.0)
    assert _minimum_reached_at_edge(heights, 220.0 + 0.05 * (heights - 10.0) ** 2, 0.0, +1)


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


def _calf_with_a_flank_bump(top_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """A lower leg's girth every 2 mm from below the ankle to ``top_mm`` (mm): the
    ankle's waist (225 mm round at 40 mm), a calf maximum of 385 mm at 280 mm, a knee
    waist of 335 mm at 390 mm, and on the calf's rising flank a bump of a sparse cloud's
    noise (+6 mm at 170 mm, over +-12 mm)."""
    z = np.arange(0.0, top_mm, 2.0)
    calf = np.interp(z, [0, 40, 280, 390, 460], [250, 225, 385, 335, 400])
    calf = np.convolve(np.pad(calf, 15, mode="edge"), np.ones(31) / 31, mode="valid")  # round the corners
    bump = 6.0 * np.clip(1.0 - np.abs(z - 170.0) / 12.0, 0.0, None)
    return z, calf + bump


def test_a_bump_on_the_calfs_rising_flank_is_not_the_calf():
    """The bump is a local maximum with an ankle below it and the flank rising above it:
    read as a calf whose "knee waist" is the flank 30 mm up, wider than the bump.  A knee
    waist wider than the calf's maximum by more than MAX_KNEE_OVER_CALF is no knee
    waist: with the knee in the scan the real calf is found; with the scan stopping on
    the calf's falling side, the refusal says the knee waist is missing, not a record of
    a 290 mm "calf" 110 mm below the real one."""
    from app.geometry.anatomy.landmarks import find_feature_heights
    from app.geometry.errors import FailureReason, FitFailure

    z, girth = _calf_with_a_flank_bump(460.0)
    found = find_feature_heights(z, girth)
    assert abs(found.c_mm - 280.0) < 15.0 and abs(found.d_mm - 390.0) < 15.0
    z, girth = _calf_with_a_flank_bump(350.0)  # stops 70 mm above C, the leg still narrowing
    with pytest.raises(FitFailure) as caught:
        find_feature_heights(z, girth)
    assert caught.value.reason is FailureReason.NO_KNEE, caught.value.detail


def test_a_pointed_foots_narrow_toes_are_not_the_ankle():
    """A foot pointed in line with the shank (plantar flexion 44 degrees, as a corpus scan
    that was refused): going down from the calf the girth narrows to the ankle (225 mm),
    swells over the heel and instep (295 mm) and narrows again along the toes (a dip to
    208 mm, then less) - sections as elongated as a foot's (1.4-2.0, a calf's 1.0-1.1).  The
    toes' minimum is not B: B is the ankle's, and the calf and knee waist above it are
    found; read without the elongation the toes' minimum is taken for B and refused."""
    from app.geometry.anatomy.landmarks import MAX_CALF_ELONGATION, find_feature_heights
    from app.geometry.errors import FitFailure

    z = np.arange(0.0, 800.0, 2.0)
    girth = np.interp(z, [0, 40, 60, 80, 110, 130, 170, 300, 400, 470, 560, 700, 800],
                      [150, 212, 208, 215, 295, 293, 225, 232, 379, 345, 340, 420, 500])
    elongation = np.interp(z, [0, 60, 90, 110, 140, 170, 800], [2.0, 1.5, 1.4, 1.5, 1.42, 1.2, 1.03])
    assert elongation[np.argmin(np.abs(z - 60))] > MAX_CALF_ELONGATION
    found = find_feature_heights(z, girth, elongation=elongation)
    assert 150.0 < found.b_mm < 300.0 and abs(found.c_mm - 400.0) < 20.0 and 460.0 < found.d_mm < 600.0
    with pytest.raises(FitFailure):
        find_feature_heights(z, girth)

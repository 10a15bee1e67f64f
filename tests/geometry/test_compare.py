"""Two records of one leg compared (girth profiles, volume change, signed map)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from app.geometry.measures.compare import compare_surfaces, signed_differences
from tests.conftest import fitted


@pytest.fixture(scope="module")
def calf():
    _, result = fitted("bodyparts3d_right_leg.stl", None)
    return result.surface, result.landmarks.as_dict()


def test_a_record_compared_with_itself_gives_zeros(calf):
    surface, landmarks = calf
    comparison = compare_surfaces(surface, landmarks, surface, landmarks)
    assert comparison.heights_mm[1] - comparison.heights_mm[0] == pytest.approx(5.0)
    assert np.abs(comparison.girth_b_mm - comparison.girth_a_mm).max() == 0.0
    assert comparison.volume_change_mm3 == 0.0 and comparison.volume_change_percent == 0.0
    _, _, signed = signed_differences(surface, surface, comparison.shift_mm, 72, 40)
    assert np.nanmax(np.abs(signed)) < 1e-6 and np.isfinite(signed).mean() > 0.9


def test_a_swollen_copy_shifted_along_the_leg_is_found_swollen_by_its_amount(calf):
    """b: the same calf 2% wider around (x, y scaled about the axis) and moved 30 mm up
    the frame (its landmarks with it): aligned at B, girths +2% everywhere, volume
    +4.04% (1.02^2), and the signed map ~ +2% of the radius, positive everywhere."""
    surface, landmarks = calf
    control = surface.control_points * np.array([1.02, 1.02, 1.0]) + np.array([0.0, 0.0, 30.0])
    swollen = replace(surface, control_points=control)
    moved = {name: {**mark, "height_mm": mark["height_mm"] + 30.0} for name, mark in landmarks.items()}
    comparison = compare_surfaces(surface, landmarks, swollen, moved)
    assert comparison.shift_mm == pytest.approx(30.0)
    ratio = comparison.girth_b_mm / comparison.girth_a_mm
    assert np.allclose(ratio, 1.02, atol=2e-4)
    assert comparison.volume_change_percent == pytest.approx(4.04, abs=0.01)
    _, _, signed = signed_differences(surface, swollen, comparison.shift_mm, 72, 40)
    finite = signed[np.isfinite(signed)]
    assert (finite > 0).all() and 0.5 < np.median(finite) < 1.5  # 2% of a 35-65 mm radius


def test_aligned_at_another_landmark_and_too_little_overlap(calf):
    surface, landmarks = calf
    comparison = compare_surfaces(surface, landmarks, surface, landmarks, align="C")
    assert comparison.heights_mm.min() < 0 < comparison.heights_mm.max()  # heights from C
    far = {name: {**mark, "height_mm": mark["height_mm"] + 1000.0} for name, mark in landmarks.items()}
    with pytest.raises(ValueError):
        compare_surfaces(surface, landmarks, surface, far)

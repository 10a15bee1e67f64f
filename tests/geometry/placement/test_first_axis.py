"""A leg's first axis (app.geometry.placement.first_axis): the consensus line of the
compact slabs' centroids stays on the limb where least squares is pulled off it by a
foot's slabs - on a synthetic shank on a dense foot, and the centroids' consensus on
their own."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from app.geometry.placement import calf_frame as cf
from app.geometry.placement.first_axis import LINE_INLIER_MM, consensus_line, first_axis


def _shank_on_a_foot(foot_points: int) -> tuple[np.ndarray, np.ndarray]:
    """A cloud (n, 3) mm of a 420 mm shank (a 45 mm-radius cylinder) standing on a
    240 x 90 x 60 mm foot that reaches 200 mm forward of it, the foot sampled as densely as
    ``foot_points`` say (a body scan's vertices crowd on the toes), tilted 23 degrees;
    and the shank's axis (3,)."""
    shank = trimesh.creation.cylinder(radius=45.0, height=420.0, sections=64)
    shank.apply_translation([0.0, 0.0, 270.0])
    foot = trimesh.creation.box(extents=(240.0, 90.0, 60.0))
    foot.apply_translation([80.0, 0.0, 30.0])
    points = np.vstack([trimesh.sample.sample_surface(shank, 4000, seed=1)[0],
                        trimesh.sample.sample_surface(foot, foot_points, seed=2)[0]])
    tilt = trimesh.transformations.rotation_matrix(0.4, [1.0, 1.0, 0.0])[:3, :3]
    return points @ tilt.T, tilt @ np.array([0.0, 0.0, 1.0])


def _degrees(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(min(1.0, abs(float(a @ b))))))


@pytest.mark.parametrize("foot_points", [1000, 3000])
def test_the_consensus_line_follows_the_shank_where_least_squares_leans_to_the_foot(foot_points):
    points, shank_axis = _shank_on_a_foot(foot_points)
    shape_axes = cf.principal_frame(points)
    least_squares, _ = first_axis(points, None, shape_axes, None)
    consensus, basis = first_axis(points, None, shape_axes, None, consensus=True)
    assert _degrees(consensus, shank_axis) < 1.5
    # the slabs through the heel and instep pull least squares off the shank
    assert _degrees(least_squares, shank_axis) > 3.0
    assert np.allclose(basis[2], consensus) and np.allclose(basis @ basis.T, np.eye(3))


def test_the_consensus_keeps_the_centroids_on_the_line_and_drops_the_ones_off_it():
    z = np.arange(0.0, 400.0, 5.0)
    line = np.column_stack([0.1 * z, -0.05 * z, z])
    heel = np.column_stack([60.0 + 0.8 * z[:12], np.zeros(12), z[:12]])  # 60-110 mm off the line
    centres = np.vstack([heel, line])
    order = np.argsort(centres[:, 2], kind="stable")
    on_line = consensus_line(centres[order])
    is_line = np.r_[np.zeros(12, dtype=bool), np.ones(len(z), dtype=bool)][order]
    assert np.array_equal(on_line, is_line)
    # a bow within the inlier distance (a shank's centroids behind the calf) stays on it
    bowed = line + np.column_stack([0.8 * LINE_INLIER_MM * np.sin(np.pi * z / 400.0), 0 * z, 0 * z])
    assert consensus_line(bowed).all()

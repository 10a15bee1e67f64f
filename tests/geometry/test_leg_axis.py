"""One leg's calf axis and landmarks (app.geometry.placement.leg_axis) on legs whose axis is known."""

import numpy as np
import trimesh

from app.geometry.placement.leg_axis import clip_to_half_spaces, place_candidate
from tests.phantoms import revolution_leg, revolution_truth


def _tilted(mesh: trimesh.Trimesh, axis: np.ndarray, shift: np.ndarray) -> trimesh.Trimesh:
    moved = mesh.copy()
    moved.apply_transform(trimesh.geometry.align_vectors([0.0, 0.0, 1.0], axis))
    moved.apply_translation(shift)
    return moved


def test_the_shank_axis_and_landmarks_of_a_tilted_leg_are_found_either_way_up():
    truth = revolution_truth()
    axis = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    for up in (axis, -axis):  # the scan upside down: the knee end is found by anatomy
        leg = _tilted(revolution_leg(), up, np.array([120.0, -40.0, 900.0]))
        placed = place_candidate(np.asarray(leg.vertices), np.asarray(leg.faces), None)
        z = placed.rotation[2]
        assert np.degrees(np.arccos(np.clip(z @ up, -1, 1))) < 0.5  # the leg's own axis, knee up
        assert np.allclose(placed.rotation @ placed.rotation.T, np.eye(3), atol=1e-9)
        # origin on the axis at B; C and D heights above B as built
        along = (placed.origin_mm - np.array([120.0, -40.0, 900.0])) @ up
        assert abs(along - truth["B"][0]) < 3.0
        assert abs(placed.c_mm - (truth["C"][0] - truth["B"][0])) < 3.0
        assert abs(placed.d_mm - (truth["D"][0] - truth["B"][0])) < 3.0


def test_clip_keeps_the_points_and_faces_on_the_inner_side():
    leg = revolution_leg()
    points, faces = np.asarray(leg.vertices), np.asarray(leg.faces)
    cut = ((np.array([0.0, 0.0, 150.0]), np.array([0.0, 0.0, 1.0])),)
    kept, kept_faces = clip_to_half_spaces(points, faces, cut)
    assert kept[:, 2].max() <= 150.0 and len(kept) == int((points[:, 2] <= 150.0).sum())
    assert kept_faces.max() < len(kept) and len(kept_faces) > 0
    assert clip_to_half_spaces(points, faces, ())[0] is points

"""The calf frame's building blocks (app.geometry.placement.calf_frame) on shapes whose
answer is known: a tilted cylinder's axis, an orthonormal basis, the frame's matrix."""

from __future__ import annotations

import numpy as np

from app.geometry.placement.calf_frame import CalfFrame, perpendicular_basis, principal_axis


def _tilted_cylinder(axis: np.ndarray, n: int = 20_000, seed: int = 1) -> np.ndarray:
    """(n, 3) points on a 400 mm long, 50 mm radius cylinder along ``axis`` (mm)."""
    rng = np.random.default_rng(seed)
    basis = perpendicular_basis(axis)
    t, z = rng.uniform(0, 2 * np.pi, n), rng.uniform(-200, 200, n)
    local = np.column_stack([50 * np.cos(t), 50 * np.sin(t), z])
    return local @ basis + np.array([10.0, -20.0, 30.0])


def test_the_principal_axis_of_a_tilted_cylinder_is_its_axis():
    axis = np.array([0.3, -0.2, 0.93])
    axis /= np.linalg.norm(axis)
    found = principal_axis(_tilted_cylinder(axis))
    assert abs(abs(found @ axis) - 1.0) < 1e-4


def test_a_perpendicular_basis_is_orthonormal_with_the_axis_last():
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    basis = perpendicular_basis(axis, np.array([0.0, 1.0, 0.0]))
    assert np.allclose(basis @ basis.T, np.eye(3), atol=1e-12)
    assert np.allclose(basis[2], axis)
    assert np.linalg.det(basis) > 0  # right-handed


def test_the_frame_matrix_undoes_to_calf_in_scan_units():
    """to_calf maps scan-mm points into the frame; matrix() maps them back into scan
    units (here cm: 10 mm per unit)."""
    rotation = perpendicular_basis(np.array([0.0, 0.6, 0.8]))
    frame = CalfFrame(rotation, np.array([5.0, 6.0, 7.0]), 10.0, "foot")
    points_mm = np.random.default_rng(2).normal(0, 100, (50, 3))
    local = frame.to_calf(points_mm)
    back = (frame.matrix() @ np.column_stack([local, np.ones(len(local))]).T).T[:, :3]
    assert np.allclose(back * 10.0, points_mm, atol=1e-9)

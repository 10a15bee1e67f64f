"""The shank of a bent leg: its own axis, and the thigh cut off at the knee."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.placement.knee_bend import keep_index, shank_runs


def _bent_limbs(flexion_deg: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (n, 3) mm on two 60 mm-radius cylinders meeting at the knee (origin): the
    shank (400 mm) down -z, the thigh (450 mm) bent ``flexion_deg`` away from +z; and
    the two unit axes."""
    shank_axis = np.array([0.0, 0.0, -1.0])
    a = np.radians(flexion_deg)
    thigh_axis = np.array([np.sin(a), 0.0, np.cos(a)])

    def cylinder(axis, length, n):
        t = rng.uniform(0, length, n)
        phi = rng.uniform(0, 2 * np.pi, n)
        u = np.cross(axis, [0.0, 1.0, 0.0] if abs(axis[1]) < 0.9 else [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(axis, u)
        return np.outer(t, axis) + 60.0 * (np.outer(np.cos(phi), u) + np.outer(np.sin(phi), v))

    points = np.vstack([cylinder(shank_axis, 400.0, 40000), cylinder(thigh_axis, 450.0, 45000)])
    return points, shank_axis, thigh_axis


@pytest.mark.parametrize("flexion", [45.0, 90.0])
def test_the_runs_are_shank_and_thigh_and_the_cut_keeps_the_shank(flexion):
    points, shank_axis, thigh_axis = _bent_limbs(flexion, np.random.default_rng(3))
    main = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[2][0]
    runs = shank_runs(points, None, main)
    assert len(runs) >= 2
    directions = [abs(r.direction @ shank_axis) for r in runs]
    shank = runs[int(np.argmax(directions))]
    assert max(directions) > np.cos(np.radians(8.0))
    assert len(shank.half_spaces) == 1
    kept = points[keep_index(points, shank.half_spaces)]
    # the kept part is the shank: nothing of the thigh more than a radius past the knee
    along_thigh = kept @ thigh_axis
    assert (along_thigh < 60.0 + 30.0).all()
    # and almost all of the shank below the knee region survives
    shank_points = points[:40000]
    low = shank_points[shank_points[:, 2] < -120.0]
    assert len(keep_index(low, shank.half_spaces)) == len(low)


def test_a_straight_leg_is_not_cut():
    rng = np.random.default_rng(5)
    t = rng.uniform(0, 800, 50000)
    phi = rng.uniform(0, 2 * np.pi, 50000)
    points = np.column_stack([60 * np.cos(phi), 60 * np.sin(phi), t])
    runs = shank_runs(points, None, np.array([0.0, 0.0, 1.0]))
    assert runs and all(not r.half_spaces for r in runs)

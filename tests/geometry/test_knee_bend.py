"""The shank of a bent leg: its own axis, and the thigh cut off at the knee."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.placement.knee_bend import geodesic_shank_runs, keep_index, shank_runs


def _bent_limbs(flexion_deg: float, rng: np.random.Generator, shank_radius: float = 60.0,
                thigh_radius: float = 60.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (n, 3) mm on two cylinders meeting at the knee (origin), the shank's first:
    the shank (400 mm) down -z, the thigh (450 mm) bent ``flexion_deg`` away from +z;
    and the two unit axes."""
    shank_axis = np.array([0.0, 0.0, -1.0])
    a = np.radians(flexion_deg)
    thigh_axis = np.array([np.sin(a), 0.0, np.cos(a)])

    def cylinder(axis, radius, length, n):
        t = rng.uniform(0, length, n)
        phi = rng.uniform(0, 2 * np.pi, n)
        u = np.cross(axis, [0.0, 1.0, 0.0] if abs(axis[1]) < 0.9 else [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(axis, u)
        return np.outer(t, axis) + radius * (np.outer(np.cos(phi), u) + np.outer(np.sin(phi), v))

    # as many points per mm^2 of skin on either limb: 40,000 on a 60 mm by 400 mm shank
    def count(radius, length):
        return int(40000 * radius * length / (60.0 * 400.0))

    points = np.vstack([cylinder(shank_axis, shank_radius, 400.0, count(shank_radius, 400.0)),
                        cylinder(thigh_axis, thigh_radius, 450.0, count(thigh_radius, 450.0))])
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


def test_a_knee_bent_past_a_right_angle_is_followed_along_the_surface():
    """A shank 50 mm round under a thigh 80 mm round, the knee bent 100 degrees (a leg
    scanned seated): the main axis is the L's diagonal, and the centre line binned along
    it mixes shank and thigh in every bin - no run lies along the shank.  Binned by the
    distance along the surface from one end, it follows the limbs: a run along the shank,
    cut free of the thigh at the knee, the flexion read within 15 degrees."""
    points, shank_axis, thigh_axis = _bent_limbs(100.0, np.random.default_rng(3), 50.0, 80.0)
    main = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[2][0]
    assert max(abs(r.direction @ shank_axis) for r in shank_runs(points, None, main)) < np.cos(np.radians(30.0))
    runs = geodesic_shank_runs(points, None)
    shank = max(runs, key=lambda r: abs(r.direction @ shank_axis))
    assert abs(shank.direction @ shank_axis) > np.cos(np.radians(8.0))
    assert len(shank.half_spaces) == 1 and abs(shank.flexion_deg - 100.0) < 15.0
    n_shank = int(40000 * 50.0 / 60.0)
    thigh_points = points[n_shank:]
    beyond_knee = thigh_points[thigh_points @ thigh_axis > 80.0 + 30.0]  # the thigh past its radius
    assert len(keep_index(beyond_knee, shank.half_spaces)) == 0
    shank_points = points[:n_shank]
    low = shank_points[shank_points[:, 2] < -120.0]
    assert len(keep_index(low, shank.half_spaces)) == len(low)

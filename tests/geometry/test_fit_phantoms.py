"""The pipeline on analytic phantoms whose answer is known (paper sections 2.1-2.6)."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from app.geometry.fit.pipeline import FitOptions, fit_calf, fit_scan
from app.geometry.scan.reader import load_scan
from tests.conftest import REAL
from tests.phantoms import revolution_leg, revolution_truth, tube_mesh


def _tube(rx, ry):
    heights = np.arange(-10.0, 311.0, 1.0)
    return tube_mesh(heights, np.full(len(heights), rx), np.full(len(heights), ry), n_around=720)


def test_circular_cylinder_error_below_0_01_percent():
    mesh = _tube(50.0, 50.0)
    result = fit_calf(np.asarray(mesh.vertices), np.asarray(mesh.faces), 150.0, 300.0, FitOptions(points_per_layer=15))
    assert result.error.error_index_exact < 1e-4
    assert result.error.error_index < 1e-4
    assert result.error.error_index_diameter == pytest.approx(result.error.error_index / 2)
    assert result.error.max_error_mm < 0.02


def test_elliptic_cylinder_55_40_error_below_0_05_percent():
    mesh = _tube(55.0, 40.0)
    result = fit_calf(np.asarray(mesh.vertices), np.asarray(mesh.faces), 150.0, 300.0, FitOptions(points_per_layer=15))
    assert result.error.error_index_exact < 5e-4
    assert result.error.error_index < 5e-4
    # the surface's own girth matches the ellipse's perimeter (Ramanujan) within 0.1 mm
    a, b = 55.0, 40.0
    h = ((a - b) / (a + b)) ** 2
    perimeter = np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h)))
    from app.geometry.spline.nurbs import evaluate_grid

    ring = evaluate_grid(result.surface, np.linspace(0, 1, 2001), np.array([0.5]))[:, 0]
    assert np.hypot(*np.diff(ring[:, :2], axis=0).T).sum() == pytest.approx(perimeter, abs=0.1)


def test_body_of_revolution_landmarks_match_the_known_profile():
    mesh = revolution_leg()
    scan = load_scan(mesh.export(file_type="stl"), file_type="stl")
    result = fit_scan(scan)
    truth = revolution_truth()
    b_scan_z = result.frame.origin_mm[2]  # the calf frame starts at B
    assert b_scan_z == pytest.approx(truth["B"][0], abs=3.0)
    for name in ("B", "B1", "C", "D"):
        found = getattr(result.landmarks, name)
        assert found.height_mm + b_scan_z == pytest.approx(truth[name][0], abs=3.0), name
        assert found.circumference_mm == pytest.approx(truth[name][1], abs=1.0), name
    # z runs up the leg: the frame's z axis is the scan's +z
    assert result.frame.rotation[2] @ np.array([0, 0, 1.0]) > 0.999


def test_body_of_revolution_upside_down_gives_the_same_landmarks():
    mesh = revolution_leg()
    flipped = trimesh.Trimesh(mesh.vertices * np.array([1, -1, -1]), mesh.faces, process=False)
    up = fit_scan(load_scan(mesh.export(file_type="stl"), file_type="stl"))
    down = fit_scan(load_scan(flipped.export(file_type="stl"), file_type="stl"))
    for name in ("B1", "C", "D"):
        assert getattr(down.landmarks, name).height_mm == pytest.approx(getattr(up.landmarks, name).height_mm, abs=1.0)
    assert down.frame.rotation[2] @ np.array([0, 0, -1.0]) > 0.999


@pytest.mark.parametrize("seed", [0, 1])
def test_the_same_leg_rotated_translated_in_metres_gives_the_same_model(seed):
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    base = fit_scan(load_scan(leg.export(file_type="stl"), file_type="stl"))
    rotation = Rotation.random(random_state=seed).as_matrix()
    moved = trimesh.Trimesh((leg.vertices @ rotation.T + [120.0, -340.0, 55.0]) / 1000.0, leg.faces, process=False)
    scan = load_scan(moved.export(file_type="stl"), file_type="stl")
    assert scan.units == "m"
    result = fit_scan(scan)
    for name in ("B", "B1", "C", "D"):
        a, b = getattr(base.landmarks, name), getattr(result.landmarks, name)
        assert a.height_mm == pytest.approx(b.height_mm, abs=1.0)
        assert a.circumference_mm == pytest.approx(b.circumference_mm, abs=1.0)
    assert abs(base.error.error_index_exact - result.error.error_index_exact) < 2e-4  # 0.02 points
    # the frame maps the calf frame into the moved scan's metres: same anatomy
    assert np.allclose(result.frame.rotation, base.frame.rotation @ rotation.T, atol=1e-3)
    origin_m = result.frame.matrix()[:3, 3]
    assert np.allclose(origin_m, (base.frame.origin_mm @ rotation.T + [120.0, -340.0, 55.0]) / 1000.0, atol=2e-4)


def test_one_millimetre_section_spacing_works():
    leg = load_scan(REAL / "bodyparts3d_right_leg.stl")
    result = fit_scan(leg, FitOptions(section_spacing_mm=1.0))
    length = result.landmarks.D.height_mm
    assert len(result.sections.heights_mm) == int(np.floor(length)) + 1
    assert np.allclose(np.diff(result.sections.heights_mm), 1.0)
    assert result.error.error_index_exact < 0.02

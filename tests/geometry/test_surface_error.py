"""Point-to-surface distances and the error index (paper section 2.6) on surfaces whose
distances are known in closed form."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from app.geometry.spline import distance as se
from app.geometry.spline.nurbs import NurbsSurface


def _brute_triangle_distance(p, a, b, c, n=400):
    """Distance from p (3,) to triangle abc by dense barycentric sampling (an upper
    bound within ~|edge| / n of the exact one)."""
    s, t = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    keep = s + t <= 1.0
    samples = a + s[keep, None] * (b - a) + t[keep, None] * (c - a)
    return np.linalg.norm(samples - p, axis=1).min()


def test_point_triangle_distance_in_every_voronoi_region():
    rng = np.random.default_rng(4)
    a, b, c = np.array([0.0, 0.0, 0.0]), np.array([10.0, 0.0, 0.0]), np.array([2.0, 8.0, 0.0])
    # points over the face, beyond each edge and beyond each vertex, above and below
    points = np.column_stack([rng.uniform(-8, 18, 300), rng.uniform(-8, 16, 300), rng.uniform(-5, 5, 300)])
    exact = se.point_triangle_distances(points, a, b, c)
    brute = np.array([_brute_triangle_distance(p, a, b, c) for p in points])
    assert np.all(exact <= brute + 1e-9)
    assert np.max(brute - exact) < 0.05  # the sampling's own resolution
    # broadcasting: (N, 8, 3) triangles against one point per row, as Algorithm 1 uses it
    many = se.point_triangle_distances(points[:, None, :], np.stack([a, b]), np.stack([b, c]), np.stack([c, a]))
    assert many.shape == (300, 2)
    assert np.allclose(many[:, 0], exact)


def test_a_degenerate_triangle_is_measured_as_its_edges():
    """Rounding a mesh's vertices to a grid collapses triangles: two corners on one point
    (an edge of zero length, whose parameter is 0/0) or three on a line (no face).  Each is
    measured as the nearest of its edges - never NaN, which dropped samples and crashed
    the fit of a mesh rounded to 2 mm."""
    rng = np.random.default_rng(8)
    points = rng.uniform(-6.0, 16.0, (200, 3))
    a, b = np.array([0.0, 0.0, 0.0]), np.array([10.0, 2.0, 1.0])
    for corners in ((a, a, b), (a, b, b), (b, a, a), (a, (a + b) / 2, b), (a, b, (a + b) / 2), (a, a, a)):
        exact = se.point_triangle_distances(points, *corners)
        along = np.linspace(0.0, 1.0, 2001)[:, None]
        ends = np.vstack([corners[i] + along * (corners[j] - corners[i]) for i, j in ((0, 1), (1, 2), (2, 0))])
        brute = np.linalg.norm(points[:, None, :] - ends[None, :, :], axis=2).min(axis=1)
        assert np.all(np.isfinite(exact)), corners
        assert np.all(exact <= brute + 1e-9) and np.max(brute - exact) < 0.01, corners


def _cylinder(radius: float, length: float) -> NurbsSurface:
    """An exact rational circular cylinder (9-point circle, The NURBS Book 7.5), u around
    (periodic in the open form the records use), v along z from 0 to ``length``."""
    w = np.sqrt(0.5)
    circle = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]], float)
    weights_u = np.array([1, w, 1, w, 1, w, 1, w, 1])
    knots_u = np.array([0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]) * 2 * np.pi
    ctrl = np.stack([np.column_stack([radius * circle, np.full(9, z)]) for z in (0.0, length)], axis=1)
    weights = np.repeat(weights_u[:, None], 2, axis=1)
    return NurbsSurface(2, 1, knots_u, np.array([0.0, 0.0, 1.0, 1.0]), ctrl, weights, periodic_u=False)


@pytest.fixture(scope="module")
def cylinder_points():
    rng = np.random.default_rng(9)
    theta = rng.uniform(0, 2 * np.pi, 5000)
    z = rng.uniform(5.0, 195.0, 5000)
    offset = rng.normal(0.0, 1.5, 5000)  # signed distance from the skin
    points = np.column_stack([(50.0 + offset) * np.cos(theta), (50.0 + offset) * np.sin(theta), z])
    return points, np.abs(offset)


def test_algorithm1_and_newton_distances_of_a_cylinder(cylinder_points):
    points, truth = cylinder_points
    surface = _cylinder(50.0, 200.0)
    u, v, grid = se.dense_grid(surface, 200.0)
    tree = cKDTree(grid.reshape(-1, 3))
    approx, iu, iv = se.algorithm1_distances(points, grid, tree)
    # the grid's chords lie inside the circle by at most r (1 - cos(step / 2)), step the
    # widest angle between neighbouring grid rays (~1 degree; the rational circle's
    # parameter is not proportional to the angle)
    ring = np.unwrap(np.arctan2(grid[:, 0, 1], grid[:, 0, 0]))
    step = np.max(np.diff(np.append(ring, ring[0] + 2 * np.pi)))
    chord = 50.0 * (1.0 - np.cos(step / 2.0))
    assert chord < 0.003
    assert np.max(np.abs(approx - truth)) <= chord + 1e-9
    exact, _, _ = se.newton_distances(surface, points, *se.refine_seeds(points, u, v, grid, iu, iv))
    assert np.max(np.abs(exact - truth)) < 1e-3  # the Newton step tolerance


def test_error_index_is_the_rms_of_distance_over_radius(cylinder_points):
    points, truth = cylinder_points
    heights = np.linspace(0.0, 200.0, 201)
    stats, _, exact = se.error_statistics(_cylinder(50.0, 200.0), points, heights, np.full(201, 50.0),
                                          np.linspace(0.0, 200.0, 7))
    assert stats.error_index_exact == pytest.approx(np.sqrt(np.mean((truth / 50.0) ** 2)), rel=1e-4)
    assert stats.error_index_diameter == pytest.approx(stats.error_index / 2.0)
    assert stats.max_error_mm == pytest.approx(truth.max(), abs=1e-3)
    assert sum(layer["n_points"] for layer in stats.per_layer) == len(points)

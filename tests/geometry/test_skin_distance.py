"""The surface -> scan distance (app.geometry.spline.skin_distance): the other side of E."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.spline.lsq import surface_from_net
from app.geometry.spline.skin_distance import OFF_SKIN_MM, _offsets_to_mesh, surface_to_scan
from tests.phantoms import cylinder


def _tube_surface(radius: float, length: float = 300.0, bulge: float = 0.0):
    """A cubic lsq-layout tube of ``radius`` (mm), with a bulge of ``bulge`` mm added on
    one arc (u near 0) of its middle rows."""
    around, along = 24, 12
    theta = 2 * np.pi * np.arange(around) / around + np.pi / 2
    z = np.linspace(0.0, length, along)
    r = np.full((around, along), radius)
    r[[23, 0, 1], 5:7] += bulge
    net = np.stack([r * np.cos(theta)[:, None], r * np.sin(theta)[:, None], np.broadcast_to(z, r.shape)], axis=-1)
    return surface_from_net(net)


@pytest.fixture(scope="module")
def skin():
    mesh = cylinder(50.0, 50.0, length=300.0)  # a tube of radius 50 mm, z 0..300
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def test_a_surface_on_the_skin_is_measured_near_zero_on_a_mesh_and_a_cloud(skin):
    vertices, faces = skin
    surface = _tube_surface(50.0 / np.cos(np.pi / 24) ** 0.5)  # the control polygon sits outside the curve
    on_mesh = surface_to_scan(surface, vertices, faces, 0.0, 300.0)
    assert on_mesh.coverage == pytest.approx(1.0) and on_mesh.p99_mm < 1.0 and not on_mesh.off_skin
    on_cloud = surface_to_scan(surface, vertices, None, 0.0, 300.0)
    assert on_cloud.p99_mm < 2.0 and not on_cloud.off_skin


def test_a_mesh_rounded_to_a_grid_is_measured_on_every_sample(skin):
    """A scanner or exporter that writes its vertices to 2 mm collapses most of this
    tube's small triangles (two corners on one point, or three on a line): the closest
    point of such a triangle is on its edges, not NaN (which dropped samples and crashed
    the fit of a generated leg rounded to 2 mm)."""
    vertices, faces = skin
    rounded = np.round(vertices / 2.0) * 2.0
    corners = rounded[faces]
    flat = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1) < 1e-9
    assert flat.mean() > 0.3  # the case: many degenerate triangles
    result = surface_to_scan(_tube_surface(50.0 / np.cos(np.pi / 24) ** 0.5), rounded, faces, 0.0, 300.0)
    assert result.coverage == pytest.approx(1.0) and result.n_samples > 0
    assert result.p99_mm < 1.0 + np.sqrt(3.0) and not result.off_skin  # the grid moves a vertex up to sqrt(3) mm


def test_an_arc_off_the_skin_is_found_and_located(skin):
    vertices, faces = skin
    result = surface_to_scan(_tube_surface(50.0, bulge=12.0), vertices, faces, 0.0, 300.0)
    assert result.off_skin and result.max_mm > OFF_SKIN_MM
    assert 100.0 < result.worst_height_mm < 200.0 and 100.0 < result.worst_ring_height_mm < 200.0


def test_a_hole_in_the_scan_is_not_counted_against_the_surface(skin):
    """Where the scan has no data the surface bridges by design: an arc missing from the
    scan over the bulge leaves the bulge unmeasured, not off the skin."""
    vertices, faces = skin
    angle = np.degrees(np.arctan2(vertices[:, 0], vertices[:, 1]))  # 0 at +y, where the bulge is
    hole = (np.abs(angle) < 60.0) & (vertices[:, 2] > 30.0) & (vertices[:, 2] < 270.0)  # the bulge's support
    keep = ~hole[faces].any(axis=1)
    result = surface_to_scan(_tube_surface(50.0, bulge=12.0), vertices, faces[keep], 0.0, 300.0)
    assert result.coverage < 0.97 and not result.off_skin


def test_the_closest_point_deep_inside_a_large_triangle_is_found():
    """A sample 1 mm over a 600 mm triangle whose corners are far, beside a patch of 8 small
    triangles 5 mm above it: the patch's vertices are the nearest, yet the skin is the
    large triangle's inside, 1 mm away; its centroid, 70 mm off, is among the nearest
    centroids (the nearest vertices alone read the patch, 8.9 mm: on BodyParts3D's coarse
    calf they read a sample on the skin 8.8 mm off)."""
    big = np.array([[-300.0, -300.0, 0.0], [300.0, -300.0, 0.0], [0.0, 400.0, 0.0]])
    grid = np.stack(np.meshgrid(np.arange(8.0, 20.0, 4.0), np.arange(-4.0, 8.0, 4.0), indexing="ij"), -1).reshape(-1, 2)
    patch = np.column_stack([grid, np.full(len(grid), 5.0)])
    vertices = np.vstack([big, patch])
    n = 3  # the patch is a 3 x 3 grid of vertices: two triangles per cell
    cell = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel() + 3
    faces = np.vstack([[0, 1, 2], np.column_stack([cell, cell + n, cell + 1]), np.column_stack([cell + 1, cell + n, cell + n + 1])])
    offset = _offsets_to_mesh(np.array([[0.0, 0.0, 1.0]]), vertices, faces)
    assert np.linalg.norm(offset[0]) == pytest.approx(1.0) and offset[0][2] == pytest.approx(-1.0)


def test_the_faces_round_each_vertex_are_listed_once_each_in_rising_order():
    from app.geometry.spline.skin_distance import FACES_PER_VERTEX, _faces_of_vertices

    # a fan of 10 faces round vertex 0 (more than a table row holds) and a face naming vertex 1 twice
    fan = np.array([[0, i, i + 1] for i in range(1, 11)] + [[1, 1, 12]])
    table = _faces_of_vertices(fan, 14)
    assert table.shape == (14, FACES_PER_VERTEX)
    np.testing.assert_array_equal(table[0], np.arange(FACES_PER_VERTEX))  # the first 8 of its 10
    np.testing.assert_array_equal(table[1], [0, 10, -1, -1, -1, -1, -1, -1])  # face 10 once
    np.testing.assert_array_equal(table[13], -np.ones(FACES_PER_VERTEX))  # a vertex no face uses

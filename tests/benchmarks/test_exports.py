"""The exporters' shapes of benchmarks/corpus/exports.py on an open tube: what a tool
leaves must be what the benchmark says it is (benchmarks/exported_meshes.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from benchmarks.corpus import exports


@pytest.fixture(scope="module")
def open_tube() -> trimesh.Trimesh:
    """A tube of radius 50 mm, 300 mm long, its two ends open."""
    tube = trimesh.creation.cylinder(radius=50.0, height=300.0, sections=64)
    side = tube.faces[np.abs(tube.face_normals[:, 2]) < 0.5]
    mesh = trimesh.Trimesh(tube.vertices, side, process=True)
    mesh.remove_unreferenced_vertices()
    return mesh


def test_an_open_tube_has_two_boundary_loops_that_caps_close(open_tube):
    loops = exports.boundary_loops(open_tube)
    assert len(loops) == 2 and all(len(loop) == 64 for loop in loops)
    assert sorted(round(float(open_tube.vertices[loop, 2].mean())) for loop in loops) == [-150, 150]
    for style, height in exports.CAP_HEIGHTS.items():
        closed = exports.capped(open_tube, style)
        closed.merge_vertices()
        assert closed.is_watertight and closed.is_winding_consistent, style
        assert closed.extents[2] == pytest.approx(300.0 + 2 * height * 50.0, abs=1.0), style


def test_a_hollowed_tube_has_its_wall_inside_and_rims_join_it(open_tube):
    apart = exports.hollowed(open_tube, 3.0, rims=False)
    assert apart.body_count == 2
    radius = np.hypot(apart.vertices[:, 0], apart.vertices[:, 1])
    assert np.allclose(np.sort(np.unique(radius.round(3))), [47.0, 50.0], atol=0.05)
    joined = exports.hollowed(open_tube, 3.0, rims=True)
    joined.merge_vertices()
    assert joined.body_count == 1 and joined.is_watertight


def test_rounding_keeps_the_faces_and_puts_every_vertex_on_the_grid(open_tube):
    rounded = exports.rounded_to_grid(open_tube, 2.0)
    assert np.array_equal(rounded.faces, open_tube.faces)
    assert np.allclose(rounded.vertices / 2.0, np.round(rounded.vertices / 2.0))
    assert np.abs(rounded.vertices - open_tube.vertices).max() <= 1.0 + 1e-9

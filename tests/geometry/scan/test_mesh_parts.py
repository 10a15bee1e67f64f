"""The vertices some faces use, renumbered (app.geometry.scan.mesh_parts)."""

from __future__ import annotations

import numpy as np

from app.geometry.scan import load_scan
from app.geometry.scan.mesh_parts import used_vertices
from tests.conftest import REAL


def test_the_calf_band_of_a_real_leg_keeps_its_own_vertices_in_order():
    scan = load_scan(REAL / "bodyparts3d_right_leg.stl")
    points, faces = scan.points_mm, scan.faces
    z = points[:, 2][faces]
    band = faces[(z.min(axis=1) > np.percentile(points[:, 2], 30)) & (z.max(axis=1) < np.percentile(points[:, 2], 60))]
    used, renumbered = used_vertices(band, len(points))
    assert 0 < len(used) < len(points)
    assert np.all(np.diff(used) > 0)  # ascending, each once
    assert set(used.tolist()) == set(band.ravel().tolist())  # exactly the corners the band uses
    np.testing.assert_array_equal(points[used][renumbered], points[band])  # the same triangles
    assert renumbered.max() == len(used) - 1


def test_unused_points_at_either_end_and_a_degenerate_face_are_handled():
    faces = np.array([[2, 3, 5], [5, 5, 3], [7, 2, 3]])
    used, renumbered = used_vertices(faces, 9)
    np.testing.assert_array_equal(used, [2, 3, 5, 7])
    np.testing.assert_array_equal(renumbered, [[0, 1, 2], [2, 2, 1], [3, 0, 1]])
    used, renumbered = used_vertices(np.empty((0, 3), dtype=np.int64), 4)
    assert used.size == 0 and renumbered.shape == (0, 3)

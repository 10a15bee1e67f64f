"""A sparse cloud's knee waist read again on its neighbour graph
(app.geometry.fit.sparse_clouds.knee_waist_on_graph), on a tessellation's vertices of a
leg of revolution whose knee waist is known."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.fit.sparse_clouds import knee_waist_on_graph, sparse_cloud_graph

WAIST = 300.0  # mm: the height of the least radius


def _radius(z: np.ndarray) -> np.ndarray:
    """A knee waist: 50 mm at WAIST, the girth 3.8 mm more 20 mm either side (mm)."""
    return 50.0 + 0.0015 * (z - WAIST) ** 2


def _vertices(top: float, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) mm: rings every 6 mm from 0 to ``top``, 40 vertices each, every other ring
    turned half a step (a tessellation's), 0.3 mm of noise: 6.7 points per mm."""
    z = np.arange(0.0, top, 6.0)
    turn = (np.arange(len(z)) % 2)[:, None] * np.pi / 40
    angle = np.linspace(0.0, 2 * np.pi, 40, endpoint=False)[None, :] + turn
    r = _radius(z)[:, None]
    ring = np.stack([r * np.cos(angle), r * np.sin(angle), np.broadcast_to(z[:, None], angle.shape)], axis=-1)
    return ring.reshape(-1, 3) + rng.normal(0.0, 0.3, (ring.size // 3, 3))


@pytest.mark.parametrize("slabs_d", [WAIST - 12.0, WAIST + 12.0])
def test_the_graph_puts_a_knee_waist_the_slabs_missed_where_it_is(slabs_d):
    cloud = _vertices(420.0, np.random.default_rng(3))
    graph = sparse_cloud_graph(cloud, None, slabs_d)
    assert graph is not None  # a sparse cloud
    d_mm, at_edge = knee_waist_on_graph(cloud, graph, slabs_d, at_scan_edge=False)
    assert d_mm == pytest.approx(WAIST, abs=2.0) and not at_edge


def test_a_waist_taken_at_the_scans_edge_moves_only_inside_the_scan():
    """The scan ends 30 mm above the waist, the slabs took D at its edge: the graph reads
    the waist inside (its girth rises 9 mm to the edge) and D is no longer at the edge.
    Ended 7 mm above the waist, the girth does not rise enough within the scan to tell a
    waist reached: D stays where the slabs took it, at the edge."""
    rng = np.random.default_rng(5)
    cloud = _vertices(WAIST + 32.0, rng)
    top = float(cloud[:, 2].max())
    d_mm, at_edge = knee_waist_on_graph(cloud, sparse_cloud_graph(cloud, None, top - 4.0), top - 4.0, at_scan_edge=True)
    assert d_mm == pytest.approx(WAIST, abs=2.0) and not at_edge
    cloud = _vertices(WAIST + 10.0, rng)
    top = float(cloud[:, 2].max())
    assert knee_waist_on_graph(cloud, sparse_cloud_graph(cloud, None, top - 4.0), top - 4.0, at_scan_edge=True) == (
        top - 4.0, True)


def test_a_short_section_at_the_cut_does_not_draw_the_waist_to_it():
    """The scan is cut 32 mm above the waist and its last ring reads 7% short (a cut's
    ragged ring: the graph loses the edges across the cut - a sparse lower leg's last
    sections read 6 mm less than its waist, benchmarks/chart_accuracy.py 8 3).  The graph's
    least girth is then at the cut, with no rise after it: no waist reached, so D stays
    where the slabs took it, inside the scan, not drawn 20 mm up to the cut."""
    cloud = _vertices(WAIST + 32.0, np.random.default_rng(7))
    top = float(cloud[:, 2].max())
    last_ring = cloud[:, 2] > top - 3.0
    cloud[last_ring, :2] *= 0.93
    slabs_d = WAIST + 8.0
    d_mm, at_edge = knee_waist_on_graph(cloud, sparse_cloud_graph(cloud, None, slabs_d), slabs_d, at_scan_edge=False)
    assert d_mm == slabs_d and not at_edge

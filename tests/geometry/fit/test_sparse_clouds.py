"""A sparse cloud's knee waist and B1 read again on its neighbour graph
(app.geometry.fit.sparse_clouds), on a tessellation's vertices of a leg of revolution
whose knee waist or calf rise is known."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.geometry.fit.sparse_clouds import b1_on_graph, knee_waist_on_graph, sparse_cloud_graph
from app.geometry.sections import limb_graph, neighbour_edges, tape_girths

WAIST = 300.0  # mm: the height of the least radius


def _radius(z: np.ndarray) -> np.ndarray:
    """A knee waist: 50 mm at WAIST, the girth 3.8 mm more 20 mm either side (mm)."""
    return 50.0 + 0.0015 * (z - WAIST) ** 2


def _vertices(top: float, rng: np.random.Generator, spacing_mm: float = 6.0, per_ring: int = 40) -> np.ndarray:
    """(n, 3) mm: rings every ``spacing_mm`` from 0 to ``top``, ``per_ring`` vertices each,
    every other ring turned half a step (a tessellation's), 0.3 mm of noise: 6.7 points
    per mm by default."""
    z = np.arange(0.0, top, spacing_mm)
    turn = (np.arange(len(z)) % 2)[:, None] * np.pi / per_ring
    angle = np.linspace(0.0, 2 * np.pi, per_ring, endpoint=False)[None, :] + turn
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


@pytest.mark.parametrize("slabs_d", [WAIST + 44.0, WAIST + 60.0])
def test_a_knee_waist_below_the_window_draws_d_down_to_it(slabs_d):
    """The slabs took D on the knee's rise, more than WAIST_FIT_MM above the waist (the
    Visible Human male's 5,000 vertices: 43 mm): read within its window alone, D stays
    on the rise; with C's height given, the graph's thinner waist below the window is D."""
    cloud = _vertices(420.0, np.random.default_rng(11))
    graph = sparse_cloud_graph(cloud, None, slabs_d)
    windowed, _ = knee_waist_on_graph(cloud, graph, slabs_d, at_scan_edge=False)
    assert windowed > WAIST + 8.0
    d_mm, at_edge = knee_waist_on_graph(cloud, graph, slabs_d, at_scan_edge=True, c_mm=150.0)
    assert d_mm == pytest.approx(WAIST, abs=2.0) and not at_edge


def test_a_calf_still_narrowing_below_the_window_keeps_d():
    """Below a waist the slabs found, the calf narrows all the way up to it: nothing
    below the window is thinner, so C's height changes nothing."""
    cloud = _vertices(420.0, np.random.default_rng(13))
    graph = sparse_cloud_graph(cloud, None, WAIST + 6.0)
    assert (knee_waist_on_graph(cloud, graph, WAIST + 6.0, at_scan_edge=False, c_mm=150.0)
            == knee_waist_on_graph(cloud, graph, WAIST + 6.0, at_scan_edge=False))


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


def _coarse_calf(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) mm: a calf of revolution whose radius rises from 35 mm at B (z = 0) to 58 at
    C (z = 250) on a smooth step, tessellated as a body mesh's lower calf is - rings 28 mm
    apart, 40 vertices 5-9 mm apart round each, every other ring turned half a step, 0.1
    mm of noise (chart_accuracy 8 11, leg 5, body_vertices); and its girths' truth
    2 pi r(z) on a 1 mm grid (the rings are circles), as (2, k) heights and girths."""
    z = np.arange(-56.0, 400.0, 28.0)
    def radius(h):  # noqa: E306 - the step is the calf's rise, steepest 125 mm above B
        return 35.0 + 23.0 / (1.0 + np.exp(-(h - 125.0) / 30.0))
    turn = (np.arange(len(z)) % 2)[:, None] * np.pi / 40
    angle = np.linspace(0.0, 2 * np.pi, 40, endpoint=False)[None, :] + turn
    r = radius(z)[:, None]
    ring = np.stack([r * np.cos(angle), r * np.sin(angle), np.broadcast_to(z[:, None], angle.shape)], axis=-1)
    cloud = ring.reshape(-1, 3) + rng.normal(0.0, 0.1, (ring.size // 3, 3))
    heights = np.arange(0.0, 251.0)
    return cloud, np.stack([heights, 2 * np.pi * radius(heights)])


def test_a_coarse_tessellations_rings_are_joined_along_the_limb():
    """Rings four times farther apart than their points: a point's nearest all lie on its
    own ring, so the mutual graph joins no ring to the next (and its streak test took the
    rings' arcs for a scanner's streaks), and every plane between two rings was open -
    B1's whole rise, its girth then read on thick slabs.  The limb graph joins each point
    to its nearest above and below: every plane from B to C closes.  Read on the chords
    between rings, a girth is short of the girth of revolution by no more than the
    profile's bend over a ring's gap (girth'' x 28^2 / 8, 1.5 mm where the rise bends
    most) and the noise; on the cubic Hermite curve through each chain of points along
    the limb it reads closer.  B1, halfway up the rise, is read on the graph within 2 mm
    of where the leg of revolution has it."""
    cloud, (heights, truth) = _coarse_calf(np.random.default_rng(11))
    graph = sparse_cloud_graph(cloud, None, 250.0)
    assert graph is not None
    girth = tape_girths(cloud, None, heights, graph)
    assert np.isfinite(girth).all()
    # a chord between rings reads short by the profile's bend over the gap at most (+ the
    # noise); the crossings on the Hermite curve through the chain read closer than chords
    bend = float(np.abs(np.gradient(np.gradient(truth, heights), heights)).max()) * 28.0**2 / 8
    chords = dataclasses.replace(graph, beyond=np.full_like(graph.beyond, -1))  # no chain beyond
    chord_error = np.abs(tape_girths(cloud, None, heights, chords) - truth).max()
    assert chord_error < bend + 0.3
    assert np.abs(girth - truth).max() < 0.75 * chord_error
    b1 = b1_on_graph(cloud, graph, 0.0, 250.0)
    halfway = float(np.interp(0.5 * (truth[0] + truth[-1]), truth, heights))
    assert b1 is not None and abs(b1 - halfway) < 2.0


def test_edges_along_the_limb_stay_on_its_side():
    """Each point is joined to the ring above (but the top ring's) by an edge within 45
    degrees of the limb's axis: none crosses the limb from one side to the other."""
    cloud, _ = _coarse_calf(np.random.default_rng(13))
    along = limb_graph(cloud, neighbour_edges(cloud, drop_streaks=False)).along
    z = cloud[:, 2]
    assert (z[along[:, 1]] > z[along[:, 0]]).all()  # lower point first
    joined_up = np.zeros(len(cloud), dtype=bool)
    joined_up[along[:, 0]] = True
    assert joined_up[z < z.max() - 14.0].all()
    run = cloud[along[:, 1]] - cloud[along[:, 0]]
    assert (run[:, 2] >= np.cos(np.radians(45.0)) * np.linalg.norm(run, axis=1) - 1e-9).all()
    assert np.linalg.norm(run, axis=1).max() < 35.0  # the next ring, not the far side


def test_a_layer_no_slab_closes_is_read_where_the_graph_crosses_its_plane():
    """A body mesh's long triangles leave a stretch of skin without a vertex: rings every
    12 mm, 30 points round each (2.4 points per mm, as the knee-high body-mesh clouds of
    robustness 220 17 and 19, sparse_leg_vertices-00 and -01), whose points are missing
    over 130 degrees of the back for 48 mm of height (those clouds had a 120-degree arc
    without a point in 20 mm slabs at C).  No 20 mm slab at the stretch's middle closes;
    the graph's edges along the limb join the rings above and below it, and its plane
    closes on their crossings with the girth of the leg there (within 1%).  The layers
    the slabs closed are left exactly as they were."""
    from app.geometry.fit.sparse_clouds import open_sections_on_graph
    from app.geometry.sections import slice_points_polar

    cloud = _vertices(420.0, np.random.default_rng(11), spacing_mm=12.0, per_ring=30)
    angle = np.degrees(np.arctan2(cloud[:, 1], cloud[:, 0])) % 360
    cloud = cloud[~((angle > 150) & (angle < 280) & (cloud[:, 2] > 190) & (cloud[:, 2] < 238))]
    heights = np.array([100.0, 214.0, 380.0])
    slabs = slice_points_polar(cloud, heights, 72, half_thickness=10.0, widen=False)
    assert slabs.valid.tolist() == [True, False, True]
    graph = sparse_cloud_graph(cloud, None, 400.0)
    assert graph is not None
    layers = open_sections_on_graph(cloud, graph, slabs)
    assert layers.valid.all()
    assert layers.circumferences()[1] == pytest.approx(2 * np.pi * _radius(heights[1]), rel=0.01)
    for name in ("radii_mm", "centroids_mm", "coverage"):
        np.testing.assert_array_equal(getattr(layers, name)[[0, 2]], getattr(slabs, name)[[0, 2]])

"""A sparse cloud's limb graph (app.geometry.sections.limb_graph): its edges along the
limb cross a plane on the skin's bend along it, not on the chord."""

from __future__ import annotations

import dataclasses

import numpy as np

from app.geometry.sections import limb_crossings, limb_graph, neighbour_edges


def _bulge(z: np.ndarray) -> np.ndarray:
    """A calf's bulge along the limb: the radius (mm) a parabola in z, 60 mm at z = 100,
    10 mm less 100 mm either side."""
    return 60.0 - 0.001 * (z - 100.0) ** 2


def _rings(spacing_mm: float, per_ring: int = 36) -> np.ndarray:
    """(n, 3) mm: rings every ``spacing_mm`` from 0 to 200 round the bulge, points
    evenly round each, every ring's points at the same angles (columns along the limb)."""
    z = np.arange(0.0, 200.0 + 1e-9, spacing_mm)
    angle = np.linspace(0.0, 2 * np.pi, per_ring, endpoint=False)
    r = _bulge(z)[:, None]
    ring = np.stack([r * np.cos(angle), r * np.sin(angle), np.broadcast_to(z[:, None], (len(z), per_ring))], axis=-1)
    return ring.reshape(-1, 3)


def test_a_crossing_between_rings_lies_on_the_bulge_not_on_the_chord():
    """Rings 25 mm apart on a parabolic bulge: a plane halfway between two rings crosses
    the columns' edges where the skin is.  The chord lies inside it by the bend, c L^2 / 4
    (0.16 mm of radius over 25 mm); the Hermite curve with Catmull-Rom's tangents
    reproduces a parabola sampled evenly, so the crossing is on the skin - where the
    chain goes on both ways (the top and bottom gaps keep their chords)."""
    points = _rings(25.0)
    graph = limb_graph(points, neighbour_edges(points, drop_streaks=False))
    heights = np.array([37.5, 87.5, 112.5, 162.5])  # halfway between rings, the chain whole
    plane, crossings = limb_crossings(points, graph, heights)
    along = np.linalg.norm(crossings, axis=1)
    chord_graph = dataclasses.replace(graph, beyond=np.full_like(graph.beyond, -1))  # no chain beyond: chords
    _, chords = limb_crossings(points, chord_graph, heights)
    skin = _bulge(heights[plane])
    assert len(plane) >= 4 * 36  # every column crosses each plane
    assert np.abs(along - skin).max() < 0.01  # (a diagonal edge's bend round the limb: 0.6 um)
    bend = 0.001 * 25.0**2 / 4
    assert np.abs((skin - np.linalg.norm(chords, axis=1)) - bend).max() < 0.02


def test_renumbering_keeps_each_edge_and_its_chain():
    """Reordered points (as a cloud sorted along z is), the graph renumbered reads the
    same crossings."""
    points = _rings(25.0)
    graph = limb_graph(points, neighbour_edges(points, drop_streaks=False))
    order = np.random.default_rng(3).permutation(len(points))
    new_index = np.empty(len(order), dtype=np.int64)
    new_index[order] = np.arange(len(order))
    moved = graph.renumbered(new_index)
    heights = np.linspace(5.0, 195.0, 9)
    plane, crossings = limb_crossings(points, graph, heights)
    plane_moved, crossings_moved = limb_crossings(points[order], moved, heights)
    for k in range(len(heights)):
        mine = crossings[plane == k][np.lexsort(crossings[plane == k].T)]
        theirs = crossings_moved[plane_moved == k][np.lexsort(crossings_moved[plane_moved == k].T)]
        np.testing.assert_allclose(mine, theirs, atol=1e-9)

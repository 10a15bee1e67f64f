"""Cutting apart the legs of a body or of a pair joined at the hips
(app.geometry.placement.leg_pairs) on shapes whose answer is known."""

from __future__ import annotations

import numpy as np
import trimesh

from app.geometry.placement.leg_pairs import split_body_legs, split_legs


def test_a_bodys_legs_are_cut_from_its_feet_end():
    """Two parallel tubes (the legs, 800 mm) under one wide block (the trunk, 900 mm):
    the two-blob end is the feet, the legs are cut apart at the mid-plane, up points to
    the trunk."""
    rng = np.random.default_rng(3)
    legs = [np.column_stack([x + 60 * np.cos(t), 60 * np.sin(t), z]) for x in (-120.0, 120.0)
            for t, z in [(rng.uniform(0, 2 * np.pi, 8000), rng.uniform(0, 800, 8000))]]
    trunk = np.column_stack([rng.uniform(-200, 200, 12000), rng.uniform(-120, 120, 12000), rng.uniform(800, 1700, 12000)])
    body = np.vstack([*legs, trunk])
    first, second = split_body_legs(body, spacing_p95_mm=8.0)
    assert first.up @ np.array([0.0, 0.0, 1.0]) > 0.99
    sides = {float(np.sign(body[cut.point_index, 0].mean())) for cut in (first, second)}
    assert sides == {-1.0, 1.0}
    for cut in (first, second):
        assert body[cut.point_index, 2].min() < 50.0


def test_a_coarse_meshs_two_legs_are_cut_apart_on_its_triangles():
    """Two tubes 800 mm long, 100 mm wide and 40 mm apart under a 150 mm block (a pair of
    legs joined at the hips) in a coarse mesh: ten vertices round each ring and rings only
    at the ends, so the vertices lie 30-800 mm apart.  On the vertices alone the slabs
    between 10% and 50% of the length hold no point at all and the pair is one leg; on
    points sampled on its triangles the two tubes are cut apart, each with its own
    vertices and the block's half over it."""
    legs = [trimesh.creation.cylinder(radius=50.0, height=800.0, sections=10).apply_translation([x, 0.0, 400.0])
            for x in (-70.0, 70.0)]
    hips = trimesh.creation.box(extents=[260.0, 120.0, 150.0]).apply_translation([0.0, 0.0, 875.0])
    pair = trimesh.util.concatenate([*legs, hips])
    points, faces = np.asarray(pair.vertices), np.asarray(pair.faces)
    assert split_legs(points, None) is None
    cuts = split_legs(points, faces)
    assert cuts is not None
    owner = np.full(len(points), -1)
    for k, cut in enumerate(cuts):
        assert cut.up @ np.array([0.0, 0.0, 1.0]) > 0.99
        owner[cut.point_index] = k
    first, second = len(legs[0].vertices), len(legs[0].vertices) + len(legs[1].vertices)
    assert len(set(owner[:first])) == 1 and len(set(owner[first:second])) == 1
    assert owner[0] != owner[first] and (owner >= 0).all()

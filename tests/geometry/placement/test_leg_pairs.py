"""Cutting apart the legs of a body or of a pair joined at the hips
(app.geometry.placement.leg_pairs) on shapes whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from app.geometry.placement.leg_pairs import _two_touching_lobes, split_body_legs, split_legs


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
    assert cuts is not None and not any(cut.touching for cut in cuts)
    owner = np.full(len(points), -1)
    for k, cut in enumerate(cuts):
        assert cut.up @ np.array([0.0, 0.0, 1.0]) > 0.99
        owner[cut.point_index] = k
    first, second = len(legs[0].vertices), len(legs[0].vertices) + len(legs[1].vertices)
    assert len(set(owner[:first])) == 1 and len(set(owner[first:second])) == 1
    assert owner[0] != owner[first] and (owner >= 0).all()


def _ring(centre_x: float, radius: float, angles: np.ndarray) -> np.ndarray:
    return np.column_stack([centre_x + radius * np.cos(angles), radius * np.sin(angles)])


def _tube(section: np.ndarray, length_mm: float, rings: int) -> np.ndarray:
    """(rings * len(section), 3): the 2-D ``section`` repeated every length / rings mm."""
    z = np.repeat(np.linspace(0.0, length_mm, rings), len(section))
    return np.column_stack([np.tile(section, (rings, 1)), z])


def test_touching_lobes_are_two_legs_and_a_convex_or_open_section_is_not():
    """A slab of two legs that touch: two rings 50 mm round whose centres are 96 mm apart,
    as the skins of a generator cross (each ring whole) and as a scanner sees a pair pressed
    together (the union's outline, the contact missing); both are two lobes.  One leg is
    not: an ellipse twice as wide as deep (its chords' length along its long axis is
    concave, no waist), a ring seen from one side (a C missing 110 degrees, its middle on
    one side only), half a ring."""
    t = np.linspace(0.0, 2 * np.pi, 400, endpoint=False)
    crossing = np.vstack([_ring(-48.0, 50.0, t), _ring(48.0, 50.0, t)])
    left, right = _ring(-48.0, 50.0, t), _ring(48.0, 50.0, t)
    outline = np.vstack([left[np.hypot(left[:, 0] - 48.0, left[:, 1]) > 50.0],
                         right[np.hypot(right[:, 0] + 48.0, right[:, 1]) > 50.0]])
    assert _two_touching_lobes(crossing, 3.0)
    assert _two_touching_lobes(outline, 3.0)
    ellipse = np.column_stack([100.0 * np.cos(t), 50.0 * np.sin(t)])
    seen_from_one_side = _ring(0.0, 55.0, t[(t > np.radians(55)) & (t < np.radians(305))] + np.pi / 2)
    half = _ring(0.0, 55.0, t[t < np.pi])
    for one_leg in (ellipse, seen_from_one_side, half):
        assert not _two_touching_lobes(one_leg, 3.0)


def test_two_legs_that_touch_are_cut_apart_at_their_contact():
    """Two tubes 800 mm long and 100 mm wide whose sections touch (centres 96 mm apart,
    seen as their union's outline: no air between them, one blob per slab) under a
    block (the hips): cut apart, each tube's points on its own side of the contact; a single tube of
    the pair's width (an ellipse) is one leg."""
    t = np.linspace(0.0, 2 * np.pi, 120, endpoint=False)
    left, right = _ring(-48.0, 50.0, t), _ring(48.0, 50.0, t)
    legs = [_tube(left[np.hypot(left[:, 0] - 48.0, left[:, 1]) > 50.0], 800.0, 200),
            _tube(right[np.hypot(right[:, 0] + 48.0, right[:, 1]) > 50.0], 800.0, 200)]
    rng = np.random.default_rng(4)
    hips = np.column_stack([rng.uniform(-110, 110, 6000), rng.uniform(-55, 55, 6000), rng.uniform(800, 950, 6000)])
    pair = np.vstack([*legs, hips])
    cuts = split_legs(pair, None)
    assert cuts is not None and all(cut.touching for cut in cuts)
    owner = np.full(len(pair), -1)
    for k, cut in enumerate(cuts):
        owner[cut.point_index] = k
    n = len(legs[0])
    # every point off the contact with its own tube (the contact's own points, within
    # 5 mm of the mid-plane, may go either way: they are both legs' skin)
    off_contact = np.abs(pair[:, 0]) > 5.0
    first, second = owner[:n][off_contact[:n]], owner[n:2 * n][off_contact[n:2 * n]]
    assert len(set(first)) == 1 and len(set(second)) == 1 and first[0] != second[0]
    ellipse = _tube(np.column_stack([98.0 * np.cos(t), 50.0 * np.sin(t)]), 800.0, 200)
    assert split_legs(np.vstack([ellipse, hips]), None) is None


def _standing_leg(sign: float, bottom_mm: float) -> np.ndarray:
    """One leg of a pair standing apart (mm): rings every 2 mm from ``bottom_mm`` to the
    hips at 800 mm, round a centre 150 mm out at the feet and 100 mm out at the top
    (``sign`` the side), radii of a foot, ankle, calf, knee and thigh."""
    z = np.arange(bottom_mm, 800.0, 2.0)
    radius = np.interp(z, [0.0, 80.0, 120.0, 350.0, 450.0, 800.0], [60.0, 45.0, 35.0, 55.0, 45.0, 80.0])
    centre = sign * np.interp(z, [0.0, 800.0], [150.0, 100.0])
    t = np.linspace(0.0, 2 * np.pi, 90, endpoint=False)
    x = centre[:, None] + radius[:, None] * np.cos(t)
    y = radius[:, None] * np.sin(t)
    return np.column_stack([x.ravel(), y.ravel(), np.repeat(z, len(t))])


@pytest.mark.parametrize("stump_mm", [150.0, 200.0, 300.0])
def test_a_pair_whose_one_leg_is_cut_above_its_ankle_is_cut_apart_from_its_feet_end(stump_mm):
    """Two legs joined at the hips, one cut ``stump_mm`` above the floor (no ankle: a
    stump of calf, knee and thigh).  The thighs pair in more of their slabs than the
    shins, yet the feet end is the thinner one: up points to the hips, and the pair is
    cut apart along the legs (before, the thighs' end was taken for the feet and the
    pair was one leg, refused as a partial view or a bent knee with the stump beside
    it).  Every point of the whole leg is in one half, none of it in the stump's."""
    whole, stump = _standing_leg(-1.0, 0.0), _standing_leg(1.0, stump_mm)
    rng = np.random.default_rng(4)
    hips = np.column_stack([rng.uniform(-190, 190, 8000), rng.uniform(-80, 80, 8000), rng.uniform(800, 950, 8000)])
    pair = np.vstack([whole, stump, hips])
    cuts = split_legs(pair, None)
    assert cuts is not None
    for cut in cuts:
        assert cut.up @ np.array([0.0, 0.0, 1.0]) > 0.9
    of_whole = [int(np.isin(cut.point_index, np.arange(len(whole))).sum()) for cut in cuts]
    assert sorted(of_whole) == [0, len(whole)]

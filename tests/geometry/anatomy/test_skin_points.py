"""Which of a cloud's points are skin (app.geometry.anatomy.skin_points): a scanner's
ghosts off the skin are not, the skin is - also where the scanner sampled one side
sparser, for the test that reads each point's spacing off the skin round it."""

from __future__ import annotations

import numpy as np

from app.geometry.anatomy.skin_points import Skin


def _tube(rng: np.random.Generator, radius: float = 60.0, height: float = 200.0) -> np.ndarray:
    """(n, 3) mm: a tube's skin sampled at random, about 1 mm apart on its front half
    (y > 0) and 4 times sparser on its back (the corpus's cloud_uneven)."""
    count = int(2 * np.pi * radius * height)
    theta, z = rng.uniform(0.0, 2 * np.pi, count), rng.uniform(0.0, height, count)
    keep = (np.sin(theta) > 0) | (rng.random(count) < 0.25)
    return np.column_stack([radius * np.cos(theta[keep]), radius * np.sin(theta[keep]), z[keep]])


def _ghosts(rng: np.random.Generator, skin: np.ndarray, count: int, low: float, high: float) -> np.ndarray:
    """(count, 3): points ``low``-``high`` mm off random skin points, outwards."""
    near = skin[rng.choice(len(skin), count)]
    outwards = near * np.array([1.0, 1.0, 0.0]) / np.linalg.norm(near[:, :2], axis=1, keepdims=True)
    return near + outwards * rng.uniform(low, high, (count, 1))


def test_each_points_own_spacing_keeps_a_sparse_sides_skin_and_drops_ghosts_far_off_it():
    """Skin on both the dense front and the 4x sparser back stays skin (a random
    sample's clumps put a few points' 8 nearest along a line, a streak: 0.13-0.14% of
    either side here); ghosts 15-40 mm off
    either side, more than 4 of the skin's spacings round them, are strays.  One median
    spacing over the whole tube (Skin.of, the sole's test) reaches too short on the
    sparse back and takes its skin for strays."""
    rng = np.random.default_rng(7)
    skin = _tube(rng)
    ghosts = _ghosts(rng, skin, 200, 15.0, 40.0)
    points = np.vstack([skin, ghosts])
    everything = np.arange(len(points))
    found = Skin(points, is_mesh=False).of_each(everything)
    back = skin[:, 1] < 0
    assert (~found[: len(skin)][back]).mean() < 3e-3 and (~found[: len(skin)][~back]).mean() < 3e-3
    assert not found[len(skin):].any()
    one_median = Skin(points, is_mesh=False).of(everything)
    assert (~one_median[: len(skin)][back]).mean() > 0.05


def test_a_mesh_is_skin_throughout():
    rng = np.random.default_rng(1)
    points = np.vstack([_tube(rng), _ghosts(rng, _tube(rng), 20, 15.0, 40.0)])
    assert Skin(points, is_mesh=True).of_each(np.arange(len(points))).all()


def test_a_streak_among_strays_is_no_skin_and_the_skin_is():
    """A scanner's streak 30 mm long leaving the tube's skin, 40 points 0.1 mm about a line,
    with 12 stray points scattered 1.5-6 mm beside it (a floor's strays round a streak
    running along the floor): they spread its points' 8 nearest off one line past the
    streak share, and the streak passed as skin - a foot's end was read at such a streak's
    tip (chart_accuracy 8 19, leg 3, cloud_outliers).  Most of its points' 24 nearest lie
    within a spacing of their principal axis, the skin's do not: the streak's points past
    the skin are no skin, and the skin stays skin (98% of it: a random sample's clumps put
    some of the skin's points on a line of their neighbours), on its dense and its sparse
    side."""
    rng = np.random.default_rng(9)
    skin = _tube(rng)
    root = np.array([60.0, 0.0, 100.0])
    reach = np.sort(rng.uniform(0.0, 30.0, 40))
    streak = root + reach[:, None] * np.array([1.0, 0.0, 0.0]) + rng.normal(0.0, 0.1, (40, 3)) * np.array([0.0, 1.0, 1.0])
    side = rng.normal(size=(12, 2))
    side *= rng.uniform(1.5, 6.0, (12, 1)) / np.linalg.norm(side, axis=1, keepdims=True)
    strays = root + np.column_stack([rng.uniform(5.0, 30.0, 12), side])
    points = np.vstack([skin, streak, strays])
    tested = Skin(points, is_mesh=False)
    past_the_skin = len(skin) + np.flatnonzero(reach > 4.0)
    outermost = np.argsort(-points[:, 0])[:2000]  # where the decision is (the streak's end of the scan)
    assert not tested.of(past_the_skin, outermost).any()
    front = np.flatnonzero((skin[:, 1] > 0) & (np.abs(skin[:, 2] - 100.0) < 40.0))[:2000]
    back = np.flatnonzero((skin[:, 1] < 0) & (np.abs(skin[:, 2] - 100.0) < 40.0))[:2000]
    assert tested.of(front).mean() > 0.98 and tested.of(back).mean() > 0.98

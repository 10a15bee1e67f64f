"""A cloud's skin as one layer or two (app.geometry.scan.skin_layers), on clouds sampled
from BodyParts3D's leg: one layer clean or noisy is one layer; the same skin twice, a few
mm apart, is doubled and its separation is read; the fit says so."""

from __future__ import annotations

import re

import numpy as np
import pytest
import trimesh

from app.geometry.scan.skin_layers import BIMODAL_COEFFICIENT, DOUBLED_MM, SkinLayers, skin_layers
from tests.conftest import REAL


@pytest.fixture(scope="module")
def leg_cloud():
    """Points on BodyParts3D's leg (mm, z up): 60k drawn by area, and 30k more, drawn
    independently (a second pass of the scanner)."""
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    first, _ = trimesh.sample.sample_surface(leg, 60_000, seed=1)
    second, _ = trimesh.sample.sample_surface(leg, 30_000, seed=2)
    return np.asarray(first), np.asarray(second)


@pytest.mark.parametrize("noise_mm", [0.0, 0.5, 1.0])
def test_one_layer_clean_or_noisy_is_one_layer(leg_cloud, noise_mm):
    first, _ = leg_cloud
    points = first + np.random.default_rng(3).normal(0.0, noise_mm, first.shape)
    layers = skin_layers(points)
    assert not layers.doubled
    assert layers.bimodality < BIMODAL_COEFFICIENT
    assert layers.separation_p90_mm < 3.0 * noise_mm + 0.6  # twice the sd (a coarse mesh's facets: 0.5 mm)


@pytest.mark.parametrize(("apart_mm", "second_share"), [(3.0, 0.5), (5.0, 0.5), (5.0, 0.2)])
def test_the_skin_twice_is_doubled_and_its_separation_read(leg_cloud, apart_mm, second_share):
    """The second pass moved ``apart_mm`` sideways, with half or a fifth of the points:
    the layers are apart along the normal where the skin faces the move, and the 90th
    percentile reads that side's."""
    first, second = leg_cloud
    n_second = int(second_share * 60_000)
    layers = skin_layers(np.vstack([first[: 60_000 - n_second], second[:n_second] + [apart_mm, 0.0, 0.0]]))
    assert layers.doubled and layers.bimodality > BIMODAL_COEFFICIENT and layers.separation_p90_mm >= DOUBLED_MM
    assert 0.6 * apart_mm <= layers.separation_p90_mm <= 1.2 * apart_mm


def test_too_few_points_are_not_measured():
    assert skin_layers(np.random.default_rng(0).normal(size=(100, 3))) is None


def test_the_fit_warns_about_a_doubled_cloud_and_not_about_a_single_one(leg_cloud, cloud_verdict):
    """... and the record keeps the layers (``fit.skin_layers``), so a stocking designed
    from a doubled cloud's record is for review, naming why; a single layer's is judged
    on its checks alone."""
    first, second = leg_cloud
    for name, points, doubled in (("single", first, False), ("twice", np.vstack([first[:30_000], second + [5.0, 0, 0]]), True)):
        read = cloud_verdict(points, name)
        warned = [w for w in read.fit.warnings if "holds the skin twice" in w]
        assert bool(warned) is doubled
        if doubled:
            wide = float(re.search(r"up to (\d+) mm wide", warned[0]).group(1))
            assert 8.0 <= wide <= 12.0  # twice the layers' ~5 mm
        assert read.record.fit["skin_layers"]["doubled"] is doubled
        assert bool([r for r in read.reasons if "holds the skin twice" in r and "by tape" in r]) is doubled
        if doubled:
            assert read.verdict in ("review", "fail")
    # a record imported from elsewhere carries its fit as it likes: no such dict is no reason
    for junk in ("two", {"bimodality": "x"}, {"bimodality": 0.9}):
        assert SkinLayers.from_dict(junk) is None

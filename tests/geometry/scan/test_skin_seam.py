"""A cloud captured in parts while the leg moved (app.geometry.scan.skin_seam), on clouds
drawn from BodyParts3D's leg: one cloud, clean or noisy, has no seam (its tibial crest is
a ridge, not a step); the same cloud with one half moved a few mm has, whichever way the
half moved; the fit says so and a stocking designed from it is for review."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from app.geometry.scan.skin_seam import SEAM_SHARE, SkinSeam, skin_seam
from tests.conftest import REAL


@pytest.fixture(scope="module")
def calf_cloud():
    """80k points drawn by area from BodyParts3D's leg, in its own mm (z up the leg, the
    calf from about 130 to 380 mm), and the calf's stretch."""
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    points, _ = trimesh.sample.sample_surface(leg, 80_000, seed=4)
    return np.asarray(points), (130.0, 380.0)


def _half_moved(points: np.ndarray, move_mm: list[float]) -> np.ndarray:
    """``points`` with those on the +x side of the leg's middle moved by ``move_mm``."""
    moved = points.copy()
    moved[points[:, 0] > np.median(points[:, 0])] += move_mm
    return moved


@pytest.mark.parametrize("noise_mm", [0.0, 0.5])
def test_one_cloud_has_no_seam(calf_cloud, noise_mm):
    points, (low, high) = calf_cloud
    seam = skin_seam(points + np.random.default_rng(5).normal(0.0, noise_mm, points.shape), low, high)
    assert seam is not None and not seam.moved
    assert seam.share < SEAM_SHARE / 2  # the crest's ridge and the noise step nowhere for long


@pytest.mark.parametrize("move_mm", [[4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, -3.0, 0.0]])
def test_a_half_moved_has_a_seam(calf_cloud, move_mm):
    """Away from the other half (a gap at the seams) or along the cut (a step): the seam
    runs up the calf.  (Moved straight into the other half, the halves overlap and the
    skin bends rather than steps: this cloud reads 0.45-0.61 for 3-6 mm, on the bound -
    the module docstring's "not caught".)"""
    points, (low, high) = calf_cloud
    seam = skin_seam(_half_moved(points, move_mm), low, high)
    assert seam.moved and seam.share >= SEAM_SHARE
    assert 0.5 <= seam.step_mm <= 5.0
    assert seam.length_mm == pytest.approx(high - low)


def test_a_cloud_too_sparse_or_too_short_is_not_measured(calf_cloud):
    points, (low, high) = calf_cloud
    assert skin_seam(points[::40], low, high) is None  # 2,000 points: under 10 per window side
    assert skin_seam(points, low, low + 20.0) is None


def test_the_fit_warns_about_a_moved_half_and_the_design_asks_for_tape(calf_cloud, cloud_verdict):
    """The record keeps the seam (``fit.skin_seam``), so a stocking designed from a moved
    cloud's record is for review, naming why; the single cloud's is judged on its checks
    alone."""
    points, _ = calf_cloud
    for name, cloud, moved in (("single", points, False), ("halves", _half_moved(points, [5.0, 0.0, 0.0]), True)):
        read = cloud_verdict(cloud, name)
        assert bool([w for w in read.fit.warnings if "skin steps by about" in w]) is moved
        assert read.record.fit["skin_seam"]["moved"] is moved
        assert bool([r for r in read.reasons if "skin steps" in r and "by tape" in r]) is moved
        if moved:
            assert read.verdict in ("review", "fail")
    # a record imported from elsewhere carries its fit as it likes: no such dict is no reason
    for junk in ("seam", {"share": "x"}, {"share": 0.9}):
        assert SkinSeam.from_dict(junk) is None
    assert SkinSeam.from_dict(SkinSeam(0.7, 2.0, 30, 250.0).as_dict()).moved

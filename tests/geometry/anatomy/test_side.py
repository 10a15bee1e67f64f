"""Left or right from the foot (app.geometry.anatomy.side): the BodyParts3D right leg and
its mirror image, whose foot is a left foot."""

from __future__ import annotations

import io

import numpy as np
import trimesh

from app.geometry.anatomy.side import infer_side
from app.geometry.fit import FitOptions, check_scan
from app.geometry.scan import load_scan
from tests.conftest import REAL


def _placed(path):
    scan = load_scan(path)
    placement = check_scan(scan, FitOptions())
    return scan, placement


def test_a_mirrored_right_foot_is_a_left_foot(tmp_path):
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    mirrored = leg.copy()
    mirrored.apply_transform(np.diag([-1.0, 1.0, 1.0, 1.0]))  # trimesh flips the winding too
    path = tmp_path / "left_leg.stl"
    mirrored.export(path)
    _, right = _placed(REAL / "bodyparts3d_right_leg.stl")
    scan, left = _placed(path)
    assert right.side == "right" and left.side == "left"
    assert left.side_source == "foot" and left.side_confidence >= 0.9
    guess = infer_side(left.frame.to_calf(scan.points_mm), left.anterior_cue)
    assert guess.side == "left" and guess.confidence == left.side_confidence


def test_without_a_foot_no_side_is_guessed():
    """The calf seen from its bulge (no foot in the points): the side is not told."""
    rng = np.random.default_rng(0)
    t, z = rng.uniform(0, 2 * np.pi, 5000), rng.uniform(0, 300, 5000)
    calf = np.column_stack([50 * np.cos(t), 45 * np.sin(t), z])
    guess = infer_side(calf, "calf_bulge")
    assert guess.side is None and guess.reason


def test_a_cloud_sparser_on_one_side_reads_the_foots_side_every_way():
    """BodyParts3D's right leg as an 80,000-point cloud, 4 times sparser on one half of it
    (a scanner that saw one side at a slant), split 8 ways round the leg: the foot is a
    right foot every way.  The points' own means and medians turned the frame and read a
    left foot at 135, 180 and 225 degrees, sure to 0.98-1.0 (app.geometry.scan.sampling)."""
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    points = np.asarray(trimesh.sample.sample_surface(leg, 80_000, seed=3)[0])
    thinning = np.random.default_rng(12345)  # not the sampler's seed: its draws placed the points
    centre = points.mean(axis=0)
    for degrees in range(0, 360, 45):
        across = np.array([np.cos(np.radians(degrees)), np.sin(np.radians(degrees)), 0.0])
        sparse_half = (points - centre) @ across > 0
        cloud = points[~sparse_half | (thinning.random(len(points)) < 0.25)]
        text = io.StringIO()
        np.savetxt(text, cloud, fmt="%.3f")
        placement = check_scan(load_scan(text.getvalue().encode(), file_type="xyz"), FitOptions())
        assert placement.side == "right" and placement.side_confidence >= 0.75, (degrees, placement.side_confidence)

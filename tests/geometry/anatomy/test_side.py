"""Left or right from the foot (app.geometry.anatomy.side): the BodyParts3D right leg and
its mirror image, whose foot is a left foot."""

from __future__ import annotations

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

"""The calf-nurbs command line."""

import json

import trimesh

from app.cli import main
from tests.conftest import REAL


def test_fit_then_export(tmp_path, capsys):
    record_path = tmp_path / "leg.json"
    assert main(["fit", str(REAL / "bodyparts3d_right_leg.stl"), "--points", "8", "-o", str(record_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert set(summary["landmarks"]) == {"B", "B1", "C", "D"}
    assert summary["points_per_layer"] == 8 and summary["seconds"] > 0
    record = json.loads(record_path.read_text())
    assert len(record["surface"]["control_points"]) == 8 + 3
    for fmt in ("stl", "glb"):
        out = tmp_path / f"leg.{fmt}"
        assert main(["export", str(record_path), "--format", fmt, "-o", str(out)]) == 0
        capsys.readouterr()
        mesh = trimesh.load(out, force="mesh")
        assert len(mesh.faces) == 2 * 144 * 99


def test_fit_failure_exits_3_with_the_reason(tmp_path, capsys):
    bad = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=4, radius=120).export(bad)
    assert main(["fit", str(bad)]) == 3
    error = json.loads(capsys.readouterr().err)
    assert error["error"] == "not_a_leg" and "wide" in error["detail"]


def test_body_side_and_units_options(tmp_path, capsys):
    assert main(["fit", str(REAL / "vh_male_skin.glb"), "--side", "left", "--units", "m"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["side"] == "left"

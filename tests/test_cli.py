"""The calf-nurbs command line."""

import json

import pytest
import trimesh

from app.cli import main
from tests.conftest import REAL


@pytest.fixture(scope="module")
def record_path(tmp_path_factory):
    """The BodyParts3D right leg fitted once by the CLI (paper mode, 7 x 15), for the
    commands that read a record."""
    path = tmp_path_factory.mktemp("cli") / "leg.json"
    assert main(["fit", str(REAL / "bodyparts3d_right_leg.stl"), "--side", "right", "-o", str(path)]) == 0
    return path


def test_fit_then_export(tmp_path, capsys):
    record_path = tmp_path / "leg.json"
    assert main(["fit", str(REAL / "bodyparts3d_right_leg.stl"), "--points", "8", "-o", str(record_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert set(summary["landmarks"]) == {"B", "B1", "C", "D"}
    assert summary["points_per_layer"] == 8 and summary["seconds"] > 0
    record = json.loads(record_path.read_text())
    assert len(record["surface"]["control_points"]) == 8 + 3
    # the foot is in this scan: its order-form points, as the record holds them
    assert summary["chart"] == {name: p["value_mm"] for name, p in record["chart"].items() if name != "thigh_profile"}
    assert set(summary["chart"]) == {"foot_length", "cA", "cY", "cE", "cF", "cG"} and 200 < summary["chart"]["foot_length"] < 300
    for fmt in ("stl", "glb"):
        out = tmp_path / f"leg.{fmt}"
        assert main(["export", str(record_path), "--format", fmt, "-o", str(out)]) == 0
        capsys.readouterr()
        mesh = trimesh.load(out, force="mesh")
        assert len(mesh.faces) == 2 * 144 * 99
    # the leg model from B to G (this leg reaches the gluteal fold), exactly and as a mesh
    assert main(["export", str(record_path), "--part", "leg", "--format", "step", "-o", str(tmp_path / "leg.step")]) == 0
    written = json.loads(capsys.readouterr().out)
    assert written["part"] == "leg" and written["control_points"] == [24 + 3, 24]
    assert (tmp_path / "leg.step").read_bytes().startswith(b"ISO-10303-21")
    assert main(["export", str(record_path), "--part", "leg", "-o", str(tmp_path / "leg.stl")]) == 0
    capsys.readouterr()
    assert trimesh.load(tmp_path / "leg.stl").extents.max() > 550  # B to G, 617 mm
    without = tmp_path / "calf-only.json"
    without.write_text(json.dumps({k: v for k, v in record.items() if k != "leg_model"}))
    assert main(["export", str(without), "--part", "leg", "-o", str(tmp_path / "x.stl")]) == 3
    assert "no leg model from B to G" in json.loads(capsys.readouterr().err)["detail"]


def test_fit_failure_exits_3_with_the_reason(tmp_path, capsys):
    bad = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=4, radius=120).export(bad)
    assert main(["fit", str(bad)]) == 3
    error = json.loads(capsys.readouterr().err)
    assert error["error"] == "not_a_leg" and "wide" in error["detail"]


def test_a_reader_that_stops_reading_ends_the_command_quietly(record_path):
    """`calf-nurbs design ... | true`: the reader is gone before the design is printed.
    Not a file error of the command's (it once said {"error": "file_error", "detail":
    "Broken pipe"}): no word on stderr, and the status a tool SIGPIPE ends has."""
    import subprocess
    import sys
    from pathlib import Path

    cli = Path(sys.executable).parent / "calf-nurbs"
    run = subprocess.run(["bash", "-c", f"'{cli}' design '{record_path}' --class II --stiffness 10 --json | true; "
                          "exit ${PIPESTATUS[0]}"], capture_output=True, text=True, timeout=120)
    assert run.stderr == "" and run.returncode == 141, (run.returncode, run.stderr)


def test_body_side_and_units_options(tmp_path, capsys):
    assert main(["fit", str(REAL / "vh_male_skin.glb"), "--side", "left", "--units", "m"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["side"] == "left"


def test_design_prints_a_table_and_json(record_path, capsys):
    assert main(["design", str(record_path), "--class", "II", "--stiffness", "10"]) == 0
    table = capsys.readouterr().out
    assert "RAL class II" in table and "[pass] B in RAL class II" in table
    assert main(["design", str(record_path), "--class", "II", "--stiffness", "10", "--json"]) == 0
    design = json.loads(capsys.readouterr().out)
    for name in ("B", "B1", "C", "D"):
        lm = design["landmarks"][name]
        for key in ("mean_pressure_mmHg", "stretched_circumference_mm", "relaxed_circumference_mm"):
            assert lm[key] > 0
        assert set(lm["sides_mmHg"]) == {"medial", "lateral", "anterior", "posterior"}
    assert 23 <= design["landmarks"]["B"]["mean_pressure_mmHg"] <= 32
    # a thigh-high on the same leg (it reaches the hip): the table adds E, F, G
    assert main(["design", str(record_path), "--type", "AG", "--toe", "open"]) == 0
    table = capsys.readouterr().out
    assert "thigh-high (AG)" in table and all(f"\n{n}  " in table for n in ("E", "F", "G"))
    assert main(["design", str(record_path), "--type", "AG", "--json"]) == 0
    thigh_high = json.loads(capsys.readouterr().out)
    assert thigh_high["stocking_type"] == "AG" and thigh_high["inputs"]["stocking_type"] == "AG"


def test_design_with_a_fabric_table_and_a_refusal(record_path, tmp_path, capsys):
    table = tmp_path / "fabric.csv"
    table.write_text("strain,tension_N_per_cm\n0.0,0.0\n0.2,1.5\n0.4,3.5\n0.8,9.0\n")
    capsys.readouterr()
    assert main(["design", str(record_path), "--standard", "BS", "--class", "2", "--table", str(table), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["class"]["standard"] == "BS"
    assert main(["design", str(record_path), "--class", "IV", "--stiffness", "1"]) == 3
    assert json.loads(capsys.readouterr().err)["error"] == "unreachable_pressure"


@pytest.mark.parametrize("command", [
    ["design", "{record}", "--table", "{tmp}/missing.csv"],
    ["export", "{record}", "--format", "step", "-o", "/nonexistent/dir/x.step"],
    ["export", "{record}", "--format", "stl", "-o", "{tmp}"],
    ["fit", "{tmp}/missing.stl"],
    ["export", "{tmp}/missing.json", "-o", "{tmp}/x.stl"],
    ["design", "{tmp}/missing.json"],
    ["design", "{tmp}/binary"],
    ["design", "{tmp}/not.json"],
    ["design", "{record}", "--table", "{tmp}/binary"],
    ["size", "{record}", "--chart", "{tmp}/binary"],
    ["size", "{record}", "--chart", "{tmp}/not.json"],
])
def test_every_failure_exits_3_with_json_and_no_traceback(command, record_path, tmp_path, capsys):
    """A missing file, one that is not text (it once raised a traceback), one that is not
    JSON: exit 3 and a sentence, without the exception's own words ([Errno 2] ...)."""
    (tmp_path / "binary").write_bytes(b"\xff\xfe\x00binary")
    (tmp_path / "not.json").write_text("{x")
    argv = [part.format(record=record_path, tmp=tmp_path) for part in command]
    assert main(argv) == 3
    captured = capsys.readouterr()
    error = json.loads(captured.err)
    assert set(error) == {"error", "detail"} and error["detail"]
    assert "Traceback" not in captured.err and "Errno" not in error["detail"]


def test_help_lists_examples_formats_classes_and_exit_codes(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--help"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    for part in ("examples:", "calf-nurbs fit leg.stl", "scan formats: stl", "step", "RAL I, II, III, IV",
                 "BS 1, 2, 3", "exit codes:"):
        assert part in text
    assert "``" not in text


def test_size_decides_on_the_example_chart_and_on_a_csv_chart(record_path, tmp_path, capsys):
    assert main(["size", str(record_path), "--json"]) == 0
    decision = json.loads(capsys.readouterr().out)
    assert "EXAMPLE" in decision["chart"] and decision["decision"] in ("ready_to_wear", "made_to_measure")
    record = json.loads(record_path.read_text())
    tape_b = record["landmarks"]["B"]["tape_girth_mm"]
    chart = tmp_path / "chart.csv"  # one size just too small at B: made to measure, by how much
    chart.write_text(f"# product: test\n# type: AD\nsize,point,min_mm,max_mm\nS,cB,150,{tape_b - 4:.3f}\n")
    assert main(["size", str(record_path), "--chart", str(chart)]) == 0
    out = capsys.readouterr().out
    assert "made_to_measure" in out and "4 mm above size S" in out
    chart.write_text("# product: test\n# type: XX\nsize,point,min_mm,max_mm\nS,cB,1,2\n")
    assert main(["size", str(record_path), "--chart", str(chart)]) == 3
    assert "type must be one of AD, AG" in json.loads(capsys.readouterr().err)["detail"]

"""Exact CAD exports, each read back by its own library and evaluated point for point
against the service's own evaluation of the surface (The NURBS Book A3.5)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app import cad
from app.cli import main as cli_main
from app.geometry.fit.pipeline import FitOptions, fit_scan
from app.geometry.scan.reader import load_scan
from app.geometry.spline.nurbs import evaluate_grid
from app.records.codec import record_from_fit
from tests.conftest import REAL, fitted

TOLERANCE_MM = 1e-6


@pytest.fixture(scope="module")
def surfaces():
    """A paper-mode record's surface (7 x 15, chord-length knots) and an lsq one (12 x 24)."""
    _, paper = fitted("bodyparts3d_right_leg.stl", None)
    lsq = fit_scan(load_scan(REAL / "bodyparts3d_right_leg.stl"), FitOptions(mode="lsq", grid="12x24"))
    return {"paper": paper.surface, "lsq": lsq.surface}


def _grid(surface):
    u = np.linspace(*surface.domain_u, 37)
    v = np.linspace(*surface.domain_v, 23)
    return u, v, evaluate_grid(surface, u, v)


def _occ_surface(data: bytes, suffix: str, tmp_path):
    from OCP.BRep import BRep_Tool
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.IGESControl import IGESControl_Reader
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    path = tmp_path / f"calf.{suffix}"
    path.write_bytes(data)
    reader = STEPControl_Reader() if suffix == "step" else IGESControl_Reader()
    assert reader.ReadFile(str(path)) == IFSelect_RetDone
    reader.TransferRoots()
    faces = TopExp_Explorer(reader.OneShape(), TopAbs_FACE)
    assert faces.More()
    return BRep_Tool.Surface_s(TopoDS.Face(faces.Current()))


@pytest.mark.parametrize("kind", ["paper", "lsq"])
@pytest.mark.parametrize("fmt", ["step", "iges"])
def test_step_and_iges_read_back_by_opencascade_are_the_surface(surfaces, kind, fmt, tmp_path):
    surface = surfaces[kind]
    data = cad.export_surface(surface, fmt)
    if fmt == "step":
        assert b"AUTOMOTIVE_DESIGN" in data and b"B_SPLINE_SURFACE_WITH_KNOTS" in data  # AP214, exact
    occ = _occ_surface(data, fmt, tmp_path)
    # (OpenCASCADE may hand the closed surface back in its periodic form: the same
    # surface, the 3 repeated control columns folded)
    assert occ.UDegree() == 3 and occ.VDegree() == 3 and occ.NbUPoles() in (surface.shape[0], surface.shape[0] - 3)
    assert occ.NbVPoles() == surface.shape[1]
    u, v, ours = _grid(surface)
    theirs = np.array([[[p.X(), p.Y(), p.Z()] for p in (occ.Value(a, b) for b in v)] for a in u])
    assert np.abs(theirs - ours).max() < TOLERANCE_MM


@pytest.mark.parametrize("kind", ["paper", "lsq"])
def test_3dm_read_back_by_opennurbs_is_the_surface(surfaces, kind, tmp_path):
    import rhino3dm

    surface = surfaces[kind]
    path = tmp_path / "calf.3dm"
    path.write_bytes(cad.export_surface(surface, "3dm"))
    model = rhino3dm.File3dm.Read(str(path))
    assert model.Settings.ModelUnitSystem == rhino3dm.UnitSystem.Millimeters
    nurbs = model.Objects[0].Geometry
    assert isinstance(nurbs, rhino3dm.NurbsSurface) and nurbs.Points.CountU == surface.shape[0]
    u, v, ours = _grid(surface)
    theirs = np.array([[[p.X, p.Y, p.Z] for p in (nurbs.PointAt(a, b) for b in v)] for a in u])
    assert np.abs(theirs - ours).max() < TOLERANCE_MM


@pytest.mark.parametrize("kind", ["paper", "lsq"])
def test_geomdl_json_read_back_by_geomdl_is_the_surface(surfaces, kind, tmp_path):
    """geomdl normalizes knot vectors to [0, 1] when it reads them: the same surface,
    its parameters mapped affinely."""
    from geomdl import exchange

    surface = surfaces[kind]
    path = tmp_path / "calf.json"
    path.write_bytes(cad.export_surface(surface, "geomdl"))
    nurbs = exchange.import_json(str(path))[0]
    assert (nurbs.ctrlpts_size_u, nurbs.ctrlpts_size_v) == surface.shape
    u, v, ours = _grid(surface)

    def mapped(x, ours_knots, their_knots):
        return their_knots[0] + (x - ours_knots[0]) / (ours_knots[-1] - ours_knots[0]) * (their_knots[-1] - their_knots[0])

    params = [(mapped(a, surface.knots_u, nurbs.knotvector_u), mapped(b, surface.knots_v, nurbs.knotvector_v))
              for a in u for b in v]
    theirs = np.array(nurbs.evaluate_list(params)).reshape(ours.shape)
    assert np.abs(theirs - ours).max() < TOLERANCE_MM


def test_cli_exports_every_cad_format(surfaces, tmp_path, capsys):
    scan = load_scan(REAL / "bodyparts3d_right_leg.stl")
    record = record_from_fit(fit_scan(scan, FitOptions(mode="lsq")), "stl", "mm")
    record_path = tmp_path / "record.json"
    record_path.write_text(json.dumps(record.to_dict()))
    for fmt in cad.CAD_FORMATS:
        out = tmp_path / f"calf.{cad.CAD_EXTENSIONS[fmt]}"
        assert cli_main(["export", str(record_path), "--format", fmt, "-o", str(out)]) == 0
        summary = json.loads(capsys.readouterr().out)
        assert summary["exact"] and summary["control_points"] == [18, 7] and out.stat().st_size > 1000

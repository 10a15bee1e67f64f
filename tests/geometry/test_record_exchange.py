"""Record JSON round trip and validation; exports overlay the scan they came from."""

import copy
import json

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.spline.nurbs import evaluate_grid
from app.records.codec import CalfRecord, record_from_fit
from app.records.meshes import export_mesh, surface_mesh
from tests.conftest import fitted


@pytest.fixture(scope="module")
def record_dict():
    scan, result = fitted("vh_female_skin.glb", "right")
    return record_from_fit(result, scan.source_format, scan.units).to_dict()


def test_record_has_the_documented_fields(record_dict):
    assert record_dict["schema_version"] == 3 and record_dict["units"] == "mm"
    surface = record_dict["surface"]
    nu, nv = len(surface["control_points"]), len(surface["control_points"][0])
    assert (nu, nv) == (15 + 3, 7)
    assert len(surface["knots_u"]) == nu + surface["degree_u"] + 1
    assert len(surface["knots_v"]) == nv + surface["degree_v"] + 1
    assert np.array(surface["weights"]).shape == (nu, nv) and surface["periodic_u"] is True
    assert np.array(record_dict["frame"]).shape == (4, 4)
    assert set(record_dict["landmarks"]) == {"B", "B1", "C", "D"}
    fit = record_dict["fit"]
    for key in ("mode", "layers", "points_per_layer", "error_index", "error_index_exact", "max_error_mm", "n_scan_points", "seconds"):
        assert key in fit
    assert fit["error_index_diameter"] == pytest.approx(fit["error_index"] / 2)
    json.dumps(record_dict)  # plain JSON


def test_record_round_trips_exactly(record_dict):
    again = CalfRecord.from_dict(json.loads(json.dumps(record_dict))).to_dict()
    assert again == record_dict
    # a point the scan leaves uncertain keeps its uncertainty
    unsure = copy.deepcopy(record_dict)
    unsure["chart"]["cE"]["uncertainty_mm"] = 4.5
    unsure["chart"]["cE"]["height_uncertainty_mm"] = 21.0
    assert CalfRecord.from_dict(json.loads(json.dumps(unsure))).to_dict() == unsure


def _broken(record_dict, mutate):
    data = copy.deepcopy(record_dict)
    mutate(data)
    with pytest.raises(FitFailure) as info:
        CalfRecord.from_dict(data)
    assert info.value.reason == FailureReason.INVALID_RECORD
    return info.value.detail


@pytest.mark.parametrize(
    "mutate,words",
    [
        (lambda d: d["surface"]["knots_u"].pop(), "knots_u must have"),
        (lambda d: d["surface"]["knots_v"].__setitem__(5, 2.0), "non-decreasing"),
        (lambda d: d["surface"]["weights"][2].__setitem__(3, -1.0), "positive"),
        (lambda d: d["surface"]["control_points"][0][0].__setitem__(1, float("nan")), "NaN"),
        (lambda d: d["surface"]["control_points"][0][0].__setitem__(1, "a"), "numbers"),
        (lambda d: d["surface"]["control_points"][-1][0].__setitem__(0, 999.0), "periodic_u"),
        (lambda d: d.__setitem__("schema_version", 7), "schema_version"),
        (lambda d: d.__setitem__("frame", [[1, 0, 0], [0, 1, 0]]), "frame"),
        (lambda d: d["landmarks"]["C"].__setitem__("circumference_mm", -3), "landmarks.C"),
        (lambda d: d["landmarks"]["B"].__setitem__("height_tolerance_mm", "wide"), "landmarks.B.height_tolerance_mm must be a number"),
        (lambda d: d["landmarks"]["C"].__setitem__("girth_uncertainty_mm", -1.0), "landmarks.C.girth_uncertainty_mm must be finite"),
        (lambda d: d["landmarks"]["D"].__setitem__("girth_uncertainty_mm", float("inf")), "landmarks.D.girth_uncertainty_mm"),
        (lambda d: d.pop("surface"), "surface"),
        (lambda d: d["chart"]["cE"].__setitem__("uncertainty_mm", -2.0), "chart.cE.uncertainty_mm"),
        (lambda d: d["chart"]["cG"].__setitem__("uncertainty_mm", 5.0), "chart.cG.uncertainty_mm"),  # cG not measured
        (lambda d: d["chart"]["cE"].__setitem__("height_uncertainty_mm", -1.0), "chart.cE.height_uncertainty_mm"),
        (lambda d: d["chart"]["cG"].__setitem__("height_uncertainty_mm", 5.0), "chart.cG.height_uncertainty_mm"),  # no height
    ],
)
def test_malformed_records_are_refused_with_the_reason(record_dict, mutate, words):
    assert words in _broken(record_dict, mutate)


@pytest.mark.parametrize("fmt", ["stl", "glb", "gltf"])
def test_exports_lie_on_the_scanned_calf_in_scan_coordinates(fmt):
    scan, result = fitted("bodyparts3d_right_leg.stl", None)
    record = record_from_fit(result, scan.source_format, scan.units)
    data = export_mesh(surface_mesh(record.surface, record.frame, n_u=720, n_v=400), fmt)
    loaded = trimesh.load(trimesh.util.wrap_as_stream(data), file_type=fmt, force="mesh")
    # calf part of the scan (between B and D) against the exported surface vertices
    local = result.frame.to_calf(scan.points_mm)
    calf = scan.points_mm[(local[:, 2] > 5) & (local[:, 2] < result.landmarks.D.height_mm - 5)]
    distance, _ = cKDTree(loaded.vertices).query(calf)
    assert np.median(distance) < 1.0
    # the export is the surface: its vertices are surface points mapped by the frame
    grid = evaluate_grid(record.surface, np.array([0.0]), np.array([0.0]))[0, 0]
    mapped = grid @ record.frame[:3, :3].T + record.frame[:3, 3]
    assert cKDTree(loaded.vertices).query(mapped)[0] < 1e-3


def test_export_in_metres_overlays_a_metre_scan():
    scan, result = fitted("vh_female_skin.glb", "left")
    assert scan.units == "m"
    record = record_from_fit(result, scan.source_format, scan.units)
    mesh = surface_mesh(record.surface, record.frame)
    assert mesh.bounds[1, 1] - mesh.bounds[0, 1] == pytest.approx(result.landmarks.D.height_mm / 1000, rel=0.1)
    # outward normals: the tube's signed volume is positive
    capped_volume = mesh.volume
    assert capped_volume > 0

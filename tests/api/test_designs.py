"""Stocking designs over HTTP: create, read, knitting spec, pressure map, charts, refusals."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
import trimesh

from tests.api.conftest import wait_for_job
from tests.conftest import REAL


@pytest.fixture(scope="module")
def record_id(client):
    data = (REAL / "vh_female_skin.glb").read_bytes()
    response = client.post("/api/v1/scans", content=data, params={"side": "right"}, headers={"Content-Type": "model/gltf-binary"})
    job = wait_for_job(client, response.headers["location"])
    assert job["status"] == "succeeded"
    return job["record_id"]


@pytest.fixture(scope="module")
def design(client, record_id):
    body = {"standard": "RAL", "compression_class": "II", "fabric": {"stiffness_n_per_cm": 10.0}}
    response = client.post(f"/api/v1/records/{record_id}/designs", json=body)
    assert response.status_code == 201, response.text
    assert response.headers["location"] == f"/api/v1/designs/{response.json()['id']}"
    return response.json()


def test_design_is_stored_with_its_inputs_and_meets_the_class(client, record_id, design):
    again = client.get(f"/api/v1/designs/{design['id']}").json()
    assert again["inputs"] == {"standard": "RAL", "compression_class": "II", "targets_mmHg": None,
                               "fabric": {"stiffness_n_per_cm": 10.0, "max_strain": 1.0},
                               "hot_spot_limit_mmHg": 60.0, "step_mm": 5.0, "resolution_mm": 1.0, "toe": "closed",
                               "stocking_type": "AD", "top_band_mm": None}
    assert again["record_id"] == record_id and again["passed"] is True
    b = again["landmarks"]["B"]
    assert 23 <= b["mean_pressure_mmHg"] <= 32 and b["mean_pressure_kPa"] == pytest.approx(b["mean_pressure_mmHg"] * 0.133322, rel=1e-6)
    assert set(b["sides_mmHg"]) == {"medial", "lateral", "anterior", "posterior"}
    assert set(again["ratios"]) == {"B1/B", "C/B", "D/B"}
    listed = client.get(f"/api/v1/records/{record_id}/designs").json()
    assert [d["id"] for d in listed] == [design["id"]]
    # reproducible: the same inputs give the same design
    twin = client.post(f"/api/v1/records/{record_id}/designs", json=again["inputs"] | {"targets_mmHg": None}).json()
    assert twin["knitting_spec"] == again["knitting_spec"]


def test_knitting_spec_csv(client, design):
    response = client.get(f"/api/v1/designs/{design['id']}/knitting-spec")
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    lines = response.text.splitlines()
    header = {line[2:].split(": ", 1)[0]: line.split(": ", 1)[-1] for line in lines if line.startswith("# ")}
    assert header["record"] == design["record_id"] and header["design"] == design["id"]
    assert header["side"] in ("left", "right") and header["standard and class"].startswith("RAL class")
    assert header["stocking"] == "AD knee-high, closed toe"
    assert header["fabric"].startswith("linear, K = ") and header["verdict"] in ("pass", "review", "fail")
    rows = list(csv.DictReader(io.StringIO("\n".join(line for line in lines if not line.startswith("#")))))
    assert len(rows) == len(design["knitting_spec"])
    # from the foot to the top: the foot's rows (toe to heel), the leg's from B, the top band's to D
    parts = [r["part"] for r in rows]
    assert parts == sorted(parts, key=["foot", "leg", "top band"].index) and set(parts) == {"foot", "leg", "top band"}
    assert [r["point"] for r in rows if r["part"] == "foot"] == ["cA", "cY"]
    assert header["foot"].startswith("closed toe, rows at cA, cY; knitted length") and header["top band"].startswith("25 mm wide")
    heights = [float(r["height_mm"]) for r in rows if r["part"] != "foot"]
    assert heights == sorted(heights) and heights[0] == 0.0 and rows[parts.index("leg")]["point"] == "B"
    assert rows[-1]["point"] == "D" and float(rows[-1]["height_mm"]) == pytest.approx(design["landmarks"]["D"]["height_mm"], abs=1e-3)
    for row in rows:
        stretched, relaxed = float(row["stretched_circumference_mm"]), float(row["relaxed_circumference_mm"])
        assert relaxed < stretched and float(row["strain"]) == pytest.approx(stretched / relaxed - 1, abs=1e-3)
    # the band is one relaxed circumference, nowhere pressing more than the graded rows it replaces
    band = [r for r in design["knitting_spec"] if r["part"] == "top band"]
    assert len({r["relaxed_circumference_mm"] for r in band}) == 1
    assert all(r["predicted_mean_mmHg"] <= r["target_mmHg"] * 1.03 for r in band)


def test_pressure_map_glb_has_vertex_colours_and_a_legend(client, design):
    response = client.get(f"/api/v1/designs/{design['id']}/pressure-map", headers={"Accept": "model/gltf-binary"})
    assert response.status_code == 200 and response.headers["content-type"] == "model/gltf-binary"
    scene = trimesh.load(trimesh.util.wrap_as_stream(response.content), file_type="glb")
    assert {"pressure_map", "legend"} <= set(scene.geometry)
    colours = scene.geometry["pressure_map"].visual.vertex_colors
    assert len(np.unique(colours[:, :3], axis=0)) > 20  # a real colour map, not one flat colour
    legend = scene.metadata["legend"]
    assert legend["unit"] == "mmHg" and legend["top_of_bar_mmHg"] >= 60 and len(legend["stops"]) == 7
    # in the scan's coordinates (metres for the VH skins), around the calf
    assert scene.bounds[1][1] - scene.bounds[0][1] < 0.5


def test_pressure_map_csv_agrees_with_the_design(client, design):
    response = client.get(f"/api/v1/designs/{design['id']}/pressure-map", params={"format": "csv"})
    assert response.headers["content-type"].startswith("text/csv")
    table = np.genfromtxt(io.StringIO(response.text), delimiter=",", names=True)
    assert table["pressure_mmHg"].min() == 0.0  # the fabric bridges somewhere
    at_b = table["height_mm"] == 0.0  # the ring at B is the design's own ring at B
    assert at_b.sum() == 360
    assert table["pressure_mmHg"][at_b].max() == pytest.approx(design["landmarks"]["B"]["peak_pressure_mmHg"], abs=2e-3)
    mean_b = (table["pressure_mmHg"][at_b]).mean()
    assert 0 < mean_b < design["landmarks"]["B"]["peak_pressure_mmHg"]
    assert set(np.unique(table["in_contact"])) <= {0.0, 1.0}
    assert client.get(f"/api/v1/designs/{design['id']}/pressure-map", headers={"Accept": "image/png"}).status_code == 406


@pytest.mark.parametrize("name", ["profile", "pressure", "map"])
def test_charts_are_png(client, design, name):
    response = client.get(f"/api/v1/designs/{design['id']}/charts/{name}.png")
    assert response.status_code == 200 and response.headers["content-type"] == "image/png"
    assert response.content[:8] == b"\x89PNG\r\n\x1a\n" and len(response.content) > 10_000


@pytest.mark.parametrize(
    "body,code",
    [
        ({"compression_class": "IV", "fabric": {"stiffness_n_per_cm": 1.0}}, "unreachable_pressure"),
        ({"compression_class": "III", "fabric": {"table": [[0.0, 0.0], [0.05, 0.5]]}}, "unreachable_pressure"),
        ({"fabric": {"stiffness_n_per_cm": -4}}, "invalid_fabric"),
        ({"fabric": {"stiffness_n_per_cm": 1e6}}, "invalid_fabric"),
        ({"fabric": {"table": [[0.0, 1.0], [0.5, 0.5]]}}, "invalid_fabric"),
        ({"fabric": {}}, "invalid_fabric"),
        ({"compression_class": "V", "fabric": {"stiffness_n_per_cm": 10}}, "invalid_target"),
        ({"targets_mmHg": {"B": 30, "B1": 20, "C": 10, "D": -1}, "fabric": {"stiffness_n_per_cm": 10}}, "invalid_target"),
        ({"fabric": {"stiffness_n_per_cm": 10}, "colour": "red"}, "invalid_request"),
        ({"fabric": {"stiffness_n_per_cm": "stiff"}}, "invalid_request"),
    ],
)
def test_bad_designs_are_refused_and_nothing_is_stored(client, record_id, design, body, code):
    before = client.get(f"/api/v1/records/{record_id}/designs").json()
    response = client.post(f"/api/v1/records/{record_id}/designs", json=body)
    assert response.status_code == 422 and response.headers["content-type"] == "application/problem+json"
    assert response.json()["code"] == code and response.json()["detail"]
    assert client.get(f"/api/v1/records/{record_id}/designs").json() == before


def test_design_of_a_missing_record_and_missing_design(client):
    body = {"fabric": {"stiffness_n_per_cm": 10}}
    assert client.post("/api/v1/records/nope/designs", json=body).json()["code"] == "record_not_found"
    assert client.get("/api/v1/designs/nope").json()["code"] == "design_not_found"
    assert client.get("/api/v1/designs/nope/charts/map.png").status_code == 404


def test_deleting_a_record_deletes_its_designs(client):
    data = (REAL / "bodyparts3d_right_leg.stl").read_bytes()
    job = wait_for_job(client, client.post("/api/v1/scans", content=data, params={"points": 8}, headers={"Content-Type": "model/stl"}).headers["location"])
    made = client.post(f"/api/v1/records/{job['record_id']}/designs", json={"fabric": {"stiffness_n_per_cm": 10}}).json()
    assert client.delete(f"/api/v1/records/{job['record_id']}").status_code == 204
    assert client.get(f"/api/v1/designs/{made['id']}").status_code == 404

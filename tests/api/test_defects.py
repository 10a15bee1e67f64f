"""Each defect found by the hostile test of the service (issue 8), reproduced on the
real app: it must now give a clear 2xx/4xx, never a 500, a server path or raw
exception text."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import trimesh

from tests.api.conftest import serve, wait_for_job

LEG = Path(__file__).resolve().parents[1] / "data" / "real" / "bodyparts3d_right_leg.stl"


def _problem(response, status: int, code: str | None = None) -> dict:
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == "application/problem+json"
    body = response.json()
    if code:
        assert body["code"] == code, body
    for leak in ("/work/", "/tmp/", "Traceback", "Error:", "self.", "site-packages"):
        assert leak not in body["detail"], body["detail"]
    return body


def test_a_utf8_multipart_file_name_is_accepted(client):
    response = client.post("/api/v1/scans", files={"file": ("脚-Müller.stl", LEG.read_bytes())}, data={"points": "8"})
    assert response.status_code == 202, response.text
    assert wait_for_job(client, response.headers["location"])["status"] == "succeeded"


def test_a_scan_in_a_field_not_named_file_is_a_clear_400(client):
    body = _problem(client.post("/api/v1/scans", files={"数据": ("a.stl", LEG.read_bytes())}), 400, "bad_request")
    assert "field named 'file'" in body["detail"]


def test_an_ascii_stl_with_a_latin1_solid_name_is_read(client):
    text = trimesh.exchange.stl.export_stl_ascii(trimesh.load(LEG))
    data = text.replace("solid", "solid Fußteil Größe 3", 1).encode("latin-1")
    with pytest.raises(UnicodeDecodeError):
        data.decode("utf-8")
    response = client.post("/api/v1/scans", content=data, params={"points": 8}, headers={"Content-Type": "model/stl"})
    assert response.status_code == 202, response.text
    assert wait_for_job(client, response.headers["location"])["status"] == "succeeded"


@pytest.fixture(scope="module")
def record_body(fitted_record) -> dict:
    """The session's fitted record as a body to import (without what the service assigns)."""
    return {k: v for k, v in fitted_record.items() if k not in ("id", "source", "created_at", "scan_id")}


def test_an_imported_record_with_huge_coordinates_is_refused(client, record_body):
    body = json.loads(json.dumps(record_body))
    body["surface"]["control_points"] = [[[c * 1e9 for c in point] for point in row] for row in body["surface"]["control_points"]]
    problem = _problem(client.post("/api/v1/records", json=body), 422, "invalid_record")
    assert "control_points" in problem["detail"]


def test_measurements_of_any_accepted_record_answer_200(client, record_body):
    imported = client.post("/api/v1/records", json=record_body)
    assert imported.status_code == 201
    url = f"/api/v1/records/{imported.json()['id']}/measurements"
    assert client.get(url, params={"heights": "50,120.5"}).status_code == 200
    _problem(client.get(url, params={"heights": "-1e9,50"}), 422, "height_out_of_range")
    _problem(client.get(url, params={"heights": "nan"}), 422)


def test_a_huge_export_is_refused_before_it_is_built(client, record_body):
    record_id = client.post("/api/v1/records", json=record_body).json()["id"]
    _problem(client.get(f"/api/v1/records/{record_id}/surface", params={"around": 1440, "along": 2000}), 422, "invalid_request")
    _problem(client.get(f"/api/v1/records/{record_id}/surface", params={"around": 720, "along": 1000}), 422, "invalid_density")


@pytest.mark.parametrize("method,path,allowed", [
    ("PUT", "/api/v1/records", "GET, POST"),
    ("PATCH", "/api/v1/records/0123", "GET, DELETE"),
    ("DELETE", "/api/v1/scans", "POST"),
])
def test_405_names_every_allowed_method(client, method, path, allowed):
    response = client.request(method, path)
    _problem(response, 405, "method_not_allowed")
    assert response.headers["allow"] == allowed


def test_every_422_and_400_is_documented_as_problem_json(client):
    spec = client.get("/openapi.json").json()
    for path, operations in spec["paths"].items():
        for method, operation in operations.items():
            for status in ("400", "401", "403", "404", "422"):
                if status in operation["responses"]:
                    content = operation["responses"][status]["content"]
                    assert list(content) == ["application/problem+json"], (method, path, status)
    assert "HTTPValidationError" not in json.dumps(spec)


def test_query_parameters_document_their_bounds(client):
    spec = client.get("/openapi.json").json()
    params = {p["name"]: p["schema"] for p in spec["paths"]["/api/v1/records/{record_id}/surface"]["get"]["parameters"]}
    assert params["around"]["maximum"] == 720 and params["around"]["minimum"] == 8
    assert params["along"]["maximum"] == 1000


def test_a_file_the_fit_cannot_read_gives_words_not_library_errors(client):
    garbage = b"solid x\nfacet normal a b c\nouter loop\nvertex 1 2\nendsolid"
    response = client.post("/api/v1/scans", content=garbage, headers={"Content-Type": "model/stl"})
    _problem(response, 422)


def test_a_scan_with_more_triangles_than_the_limit_is_refused(tmp_path):


    with serve(tmp_path, max_scan_faces=5000, max_scan_points=100_000) as small:
        response = small.post("/api/v1/scans", content=LEG.read_bytes(), headers={"Content-Type": "model/stl"})
        body = _problem(response, 422, "scan_too_large")
        assert "at most 5000" in body["detail"]
        cloud = "\n".join(f"{i % 97} {i % 89} {i * 0.003:.3f}" for i in range(100_001)).encode()
        _problem(small.post("/api/v1/scans", content=cloud, headers={"Content-Type": "text/x-xyz"}), 422, "scan_too_large")


def test_cors_allows_only_the_configured_origins(tmp_path):


    with serve(tmp_path, cors_origins=["https://portal.clinic.example"]) as app_client:
        allowed = app_client.get("/api/v1/records", headers={"Origin": "https://portal.clinic.example"})
        assert allowed.headers["access-control-allow-origin"] == "https://portal.clinic.example"
        exposed = allowed.headers["access-control-expose-headers"].lower()
        assert all(h in exposed for h in ("etag", "location", "retry-after"))
        other = app_client.get("/api/v1/records", headers={"Origin": "https://evil.example"})
        assert "access-control-allow-origin" not in other.headers
        preflight = app_client.options("/api/v1/scans", headers={
            "Origin": "https://portal.clinic.example", "Access-Control-Request-Method": "POST",
            "Access-Control-Request-Headers": "authorization, content-type"})
        assert preflight.status_code == 200 and "authorization" in preflight.headers["access-control-allow-headers"].lower()

"""Bad input over HTTP: each case its own 4xx problem+json, and nothing stored changes."""

from __future__ import annotations

import copy

import pytest
import trimesh
from fastapi.testclient import TestClient

from app.db.repositories import JobRepository, RecordRepository, ScanRepository
from tests.api.conftest import serve, wait_for_job
from tests.conftest import REAL

LEG = (REAL / "bodyparts3d_right_leg.stl").read_bytes()


@pytest.fixture(scope="module")
def small_limit_client(tmp_path_factory):
    """A service that accepts at most 1 MiB, with one good record already stored."""
    data_dir = tmp_path_factory.mktemp("limited")
    with serve(data_dir, max_upload_mb=1.0) as client:
        leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
        small = leg.export(file_type="ply")  # binary PLY of the leg: < 1 MiB
        assert len(small) < 1024 * 1024
        response = client.post("/api/v1/scans", content=small, headers={"Content-Type": "application/x-ply"})
        assert response.status_code == 202, response.text
        job = wait_for_job(client, response.headers["location"])
        assert job["status"] == "succeeded"
        client.stored_record_id = job["record_id"]
        yield client, data_dir


def snapshot(client: TestClient, data_dir) -> tuple:
    sessions = client.app.state.sessions
    with sessions() as session:
        counts = (ScanRepository(session).count(), JobRepository(session).count(), RecordRepository(session).count())
    files = sorted(str(p.relative_to(data_dir)) for p in (data_dir / "scans").rglob("*") if p.is_file())
    leftovers = sorted(p.name for p in (data_dir / "tmp").iterdir())
    return counts, files, leftovers


def _mesh_bytes(mesh: trimesh.Trimesh) -> bytes:
    return mesh.export(file_type="stl")


def _cut(keep) -> bytes:
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    return _mesh_bytes(trimesh.Trimesh(leg.vertices, leg.faces[keep(leg.triangles_center)]))


def _one_view() -> bytes:
    """The leg as one depth camera sees it: the triangles facing the camera (+y)."""
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    return _mesh_bytes(trimesh.Trimesh(leg.vertices, leg.faces[leg.face_normals[:, 1] > 0.17]))


CASES = {
    "empty body": (dict(content=b"", headers={"Content-Type": "model/stl"}), 400, "empty_body"),
    "truncated STL": (dict(content=LEG[: len(LEG) // 3], headers={"Content-Type": "model/stl"}), 422, "truncated_file"),
    "wrong media type": (dict(content=b"\x89PNG\r\n\x1a\n" + b"0" * 100, headers={"Content-Type": "image/png"}), 415, "unsupported_media_type"),
    "octet-stream without format": (dict(content=b"solid x", headers={"Content-Type": "application/octet-stream"}), 415, "unsupported_media_type"),
    "unknown ?format=": (dict(content=b"solid x", params={"format": "docx"}, headers={"Content-Type": "application/octet-stream"}), 422, "invalid_request"),
    "garbage PLY": (dict(content=b"ply\nformat nonsense\n" * 10, headers={"Content-Type": "application/x-ply"}), 422, "unreadable_file"),
    "a cube": (dict(content=_mesh_bytes(trimesh.creation.box(extents=(300, 300, 300)).subdivide_to_size(25)), headers={"Content-Type": "model/stl"}), 422, "not_a_leg"),
    "a sphere": (dict(content=_mesh_bytes(trimesh.creation.icosphere(subdivisions=5, radius=150)), headers={"Content-Type": "model/stl"}), 422, "not_a_leg"),
    "a scan cut above the ankle": (dict(content=_cut(lambda c: (c[:, 2] > 170) & (c[:, 2] < 480)), headers={"Content-Type": "model/stl"}), 422, "no_ankle"),
    "a leg seen from one side": (dict(content=_one_view(), headers={"Content-Type": "model/stl"}), 422, "partial_view"),
    "a scan cut below the knee": (dict(content=_cut(lambda c: c[:, 2] < 335), headers={"Content-Type": "model/stl"}), 422, "no_knee"),
    "bad side option": (dict(content=b"solid x", params={"side": "middle"}, headers={"Content-Type": "model/stl"}), 422, "invalid_request"),
    "bad side form field": (dict(files={"file": ("leg.stl", b"solid x", "model/stl")}, data={"side": "middle"}), 422, "invalid_option"),
    "points out of range": (dict(content=b"solid x", params={"points": 99}, headers={"Content-Type": "model/stl"}), 422, "invalid_request"),
    "multipart without file": (dict(files={"scan": ("x.stl", b"solid", "model/stl")}), 400, "bad_request"),
    "multipart of unknown type": (dict(files={"file": ("leg.bin", LEG[:2000], "application/octet-stream")}), 415, "unsupported_media_type"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_upload_is_a_specific_problem_and_changes_nothing(small_limit_client, case):
    client, data_dir = small_limit_client
    kwargs, status, code = CASES[case]
    before = snapshot(client, data_dir)
    response = client.post("/api/v1/scans", **kwargs)
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == "application/problem+json"
    problem = response.json()
    assert problem["code"] == code and problem["type"].endswith(":" + code)
    assert problem["status"] == status and problem["title"] and problem["detail"]
    assert snapshot(client, data_dir) == before


def test_the_reason_a_scan_cannot_be_fitted_is_spelled_out(small_limit_client):
    client, _ = small_limit_client
    problem = client.post("/api/v1/scans", **CASES["a scan cut above the ankle"][0]).json()
    assert "the ankle (B" in problem["detail"] and "Re-scan from below the ankle bones" in problem["detail"]


@pytest.mark.parametrize("chunked", [False, True])
def test_an_oversized_body_is_refused_on_the_bytes_received(small_limit_client, chunked):
    client, data_dir = small_limit_client
    before = snapshot(client, data_dir)
    body = LEG  # 1.3 MB > 1 MiB
    if chunked:  # no Content-Length: the limit must hold on what actually arrives
        content = (body[i : i + 65536] for i in range(0, len(body), 65536))
        response = client.post("/api/v1/scans", content=content, headers={"Content-Type": "model/stl"})
    else:
        response = client.post("/api/v1/scans", content=body, headers={"Content-Type": "model/stl"})
    assert response.status_code == 413 and response.json()["code"] == "payload_too_large"
    assert snapshot(client, data_dir) == before
    multipart = client.post("/api/v1/scans", files={"file": ("leg.stl", body, "model/stl")})
    assert multipart.status_code == 413 and multipart.json()["code"] == "payload_too_large"
    assert snapshot(client, data_dir) == before


def _record(client) -> dict:
    body = client.get(f"/api/v1/records/{client.stored_record_id}").json()
    for key in ("id", "source", "created_at", "scan_id"):
        body.pop(key)
    return body


def _open_sheet(surface: dict) -> None:
    """The record's tube with its repeated closing columns dropped: an open sheet
    (clamped in u) that still claims nothing about closure."""
    p = surface["degree_u"]
    surface["periodic_u"] = False
    del surface["control_points"][-p:], surface["weights"][-p:]
    n = len(surface["control_points"])
    surface["knots_u"] = [0.0] * (p + 1) + [i / (n - p) for i in range(1, n - p)] + [1.0] * (p + 1)


@pytest.mark.parametrize(
    "mutate,words",
    [
        (lambda r: r["surface"]["knots_u"].pop(), "knots_u"),
        (lambda r: r["surface"]["knots_v"].reverse(), "non-decreasing"),
        (lambda r: r["surface"]["weights"][0].__setitem__(0, 0.0), "weights"),
        (lambda r: r["surface"]["control_points"][0][0].__setitem__(0, 1e12), "control_points"),
        (lambda r: _open_sheet(r["surface"]), "not closed around the leg"),
        (lambda r: r["surface"].__setitem__("control_points", [[1, 2, 3]]), "control_points"),
        (lambda r: r.__setitem__("schema_version", 99), "schema_version"),
    ],
)
def test_malformed_imported_record_is_refused_and_changes_nothing(small_limit_client, mutate, words):
    client, data_dir = small_limit_client
    record = copy.deepcopy(_record(client))
    mutate(record)
    before = snapshot(client, data_dir)
    response = client.post("/api/v1/records", json=record)
    assert response.status_code == 422 and response.headers["content-type"] == "application/problem+json"
    assert response.json()["code"] == "invalid_record" and words in response.json()["detail"]
    assert snapshot(client, data_dir) == before


def test_import_that_is_not_json_is_a_problem(small_limit_client):
    client, data_dir = small_limit_client
    before = snapshot(client, data_dir)
    response = client.post("/api/v1/records", content=b"{not json", headers={"Content-Type": "application/json"})
    assert response.status_code == 422 and response.json()["code"] == "invalid_request"
    assert client.post("/api/v1/records", json=[1, 2]).status_code == 422
    assert snapshot(client, data_dir) == before


def test_unknown_ids_and_routes_are_problems(small_limit_client):
    client, _ = small_limit_client
    for url, code in (("/api/v1/jobs/nope", "job_not_found"), ("/api/v1/records/nope", "record_not_found"),
                      ("/api/v1/records/nope/surface", "record_not_found"), ("/api/v1/nothing", "not_found")):
        response = client.get(url)
        assert response.status_code == 404 and response.json()["code"] == code
        assert response.headers["content-type"] == "application/problem+json"
    assert client.put("/api/v1/scans").status_code == 405

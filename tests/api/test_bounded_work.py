"""Bounded work for every request (issue 19): costly or degenerate imports refused
before any evaluation, keys and sizes checked before a body is read, per-clinic fair
share, the operator's scope, HEAD, no-store, and no 500 from input."""

from __future__ import annotations

import socket
import subprocess
import time

import pytest

from app.db.migrate import upgrade_to_head
from app.db.session import session_factory
from app.services.keys import KeyService
from benchmarks.hostile_inputs import huge_coordinate_xyz, leg_in_inches, obj_with_2d_vertices, tube_record
from benchmarks.served import BIN, free_port, start, stop, wait_ready
from tests.api.conftest import make_settings, serve_settings
from tests.conftest import REAL

LEG = (REAL / "bodyparts3d_right_leg.stl").read_bytes()


@pytest.fixture(scope="module")
def clinics(tmp_path_factory):
    """A service with keys required, its jobs left queued (run_jobs off: the queue is the
    subject), at most 2 active jobs per clinic; keys of two clinics, a clinic admin and
    the operator."""
    settings = make_settings(tmp_path_factory.mktemp("bounded"), auth="required", run_jobs=False, tenant_max_jobs=2)
    upgrade_to_head(settings.resolved_database_url)
    with session_factory(settings.resolved_database_url)() as session:
        keys = {name: KeyService(session).create(tenant, scopes).key for name, tenant, scopes in
                (("a", "clinic-a", ("upload", "read", "design")), ("b", "clinic-b", ("upload", "read", "design")),
                 ("admin", "clinic-a", ("admin",)), ("operator", "operators", ("operator",)))}
    with serve_settings(settings) as client:
        yield client, {name: {"Authorization": f"Bearer {key}"} for name, key in keys.items()}


def _problem(response, status: int, code: str) -> dict:
    assert response.status_code == status, response.text
    assert response.headers["content-type"] == "application/problem+json"
    body = response.json()
    assert body["code"] == code and "/" not in body["detail"].split(" ")[0]
    return body


@pytest.mark.parametrize("net, code", [((128, 128, 3), "surface_too_costly"), ((48, 48, 5), "surface_too_costly")])
def test_an_import_too_costly_to_evaluate_is_refused_naming_the_limit(clinics, net, code):
    client, auth = clinics
    before = client.get("/api/v1/records", headers=auth["a"]).json()["items"]
    body = _problem(client.post("/api/v1/records", json=tube_record(*net), headers=auth["a"]), 422, code)
    assert "50,000" in body["detail"]
    assert client.get("/api/v1/records", headers=auth["a"]).json()["items"] == before


@pytest.mark.parametrize("shape", [dict(radius_mm=0.0, circumference_mm=300.0), dict(radius_mm=0.001),
                                   dict(height_mm=5.0)])
def test_a_degenerate_tube_is_refused_at_import(clinics, shape):
    client, auth = clinics
    _problem(client.post("/api/v1/records", json=tube_record(16, 8, 3, **shape), headers=auth["a"]), 422, "invalid_record")


def test_the_largest_accepted_import_is_measured_and_compared(clinics):
    client, auth = clinics
    tall = client.post("/api/v1/records", json=tube_record(72, 40, 3, height_mm=1150.0), headers=auth["a"])
    assert tall.status_code == 201
    rid = tall.json()["id"]
    measured = client.get(f"/api/v1/records/{rid}/measurements", params={"heights": "600"}, headers=auth["a"]).json()
    assert measured["heights"][0]["tape_circumference_mm"] == pytest.approx(2 * 3.14159 * 50, rel=0.05)
    compared = client.get(f"/api/v1/records/{rid}/compare/{rid}", headers=auth["a"]).json()
    assert compared["volume"]["change_ml"] == pytest.approx(0.0, abs=1e-6)


def test_keys_are_checked_before_a_json_body_is_parsed(clinics):
    client, auth = clinics
    no_key = client.post("/api/v1/records", content=b"{bad", headers={"Content-Type": "application/json"})
    _problem(no_key, 401, "missing_key")
    wrong = client.post("/api/v1/records", content=b"{bad", headers={"Content-Type": "application/json",
                                                                     "Authorization": "Bearer cnk_00000000_" + "A" * 43})
    _problem(wrong, 401, "invalid_key")
    big = client.post("/api/v1/records", content=b"[" + b"1," * 600_000 + b"1]", headers={**auth["a"], "Content-Type": "application/json"})
    assert _problem(big, 413, "payload_too_large")["limit_bytes"] == 1024 * 1024


def test_a_clinic_past_its_job_bound_gets_429_and_another_clinic_is_not_held(clinics):
    client, auth = clinics
    stl = {"Content-Type": "model/stl"}
    for points in (8, 9):  # the clinic's two jobs stay queued (nothing runs them here)
        assert client.post("/api/v1/scans", content=LEG, params={"points": points}, headers={**auth["a"], **stl}).status_code == 202
    refused = client.post("/api/v1/scans", content=LEG, params={"points": 10}, headers={**auth["a"], **stl})
    assert _problem(refused, 429, "too_many_jobs")["limit"] == 2 and refused.headers["Retry-After"]
    assert client.post("/api/v1/scans", content=LEG, params={"points": 8}, headers={**auth["b"], **stl}).status_code == 202
    usage = client.get("/api/v1/usage", headers=auth["a"]).json()
    assert usage["jobs"]["queued"] == 2 and usage["limits"]["max_active_jobs"] == 2


@pytest.mark.parametrize("content, media, code", [
    (obj_with_2d_vertices(), "model/obj", "unreadable_file"),
    (huge_coordinate_xyz(), "chemical/x-xyz", "implausible_size"),
    (leg_in_inches(), "model/stl", "implausible_size"),
])
def test_hostile_scans_get_their_4xx_not_a_500(clinics, content, media, code):
    client, auth = clinics
    body = _problem(client.post("/api/v1/scans", content=content, headers={**auth["b"], "Content-Type": media}), 422, code)
    if content[:5] == b"solid" or media == "model/stl":
        assert "units=in" in body["detail"]


@pytest.mark.parametrize("change, code", [({"resolution_mm": 1e-310}, "invalid_request"), ({"step_mm": 0}, "invalid_request"),
                                          ({"fabric": {"stiffness_n_per_cm": 10, "table": [[0, 0], [1, 5]]}}, "invalid_fabric"),
                                          ({"fabric": {"table": [[i / 1000, i / 100] for i in range(1000)]}}, "invalid_fabric"),
                                          ({"targets_mmHg": {"B": 30, "knee": 10}}, "invalid_target")])
def test_design_inputs_out_of_bounds_are_refused(clinics, change, code):
    client, auth = clinics
    rid = client.post("/api/v1/records", json=tube_record(24, 10, 3, radius_mm=45.0), headers=auth["a"]).json()["id"]
    body = {"compression_class": "II", "fabric": {"stiffness_n_per_cm": 10}, **change}
    _problem(client.post(f"/api/v1/records/{rid}/designs", json=body, headers=auth["a"]), 422, code)


def test_metrics_and_readiness_details_are_the_operators(clinics):
    client, auth = clinics
    assert client.get("/metrics", headers=auth["admin"]).status_code == 403
    assert client.get("/metrics", headers=auth["operator"]).status_code == 200
    assert client.get("/readyz").json() == {"status": "ok"}
    assert client.get("/readyz", headers=auth["admin"]).json() == {"status": "ok"}
    assert set(client.get("/readyz", headers=auth["operator"]).json()) == {"status", "database", "revision"}


def test_head_answers_like_get_without_a_body_and_health_data_is_never_stored(clinics):
    client, auth = clinics
    got = client.get("/api/v1/records", headers=auth["a"])
    head = client.head("/api/v1/records", headers=auth["a"])
    assert head.status_code == 200 and head.content == b""
    assert head.headers["content-length"] == got.headers["content-length"]
    for response in (got, head, client.get("/api/v1/records/nope", headers=auth["a"]), client.get("/readyz")):
        assert response.headers["cache-control"] == "no-store"
    assert "no-store" not in client.get("/").headers.get("cache-control", "")


def _raw(port: int, request: bytes, wait_s: float = 10.0) -> tuple[bytes, float]:
    """Send ``request`` (headers only: the body promised is never sent) and read the
    answer; returns (status line and headers, seconds)."""
    started = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=wait_s) as conn:
        conn.sendall(request)
        answer = b""
        while b"\r\n\r\n" not in answer:
            chunk = conn.recv(65536)
            if not chunk:
                break
            answer += chunk
    return answer, time.monotonic() - started


@pytest.mark.slow  # a served process or the CLI run end to end: 8-13 s (`make test-slow`)
def test_a_served_instance_answers_from_the_headers_without_waiting_for_the_body(tmp_path):
    """Over a real socket: a POST that promises a body and never sends it gets its 401
    (no key) or 413 (too large) at once - the server does not wait to read it."""
    env = {"CALF_DATA_DIR": str(tmp_path), "CALF_WORKERS": "1", "CALF_AUTH": "required", "CALF_LOG_LEVEL": "WARNING"}
    key = subprocess.run([str(BIN / "calf-nurbs"), "keys", "create", "--tenant", "clinic"], env={**__import__("os").environ, **env},
                         capture_output=True, text=True, check=True).stdout.strip().splitlines()[-1]
    port = free_port()
    server = start(["serve", "--port", str(port)], env)
    try:
        wait_ready(f"http://127.0.0.1:{port}", server)
        no_key, seconds = _raw(port, b"POST /api/v1/records HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\n"
                                     b"Content-Length: 500000\r\n\r\n")
        assert no_key.startswith(b"HTTP/1.1 401") and seconds < 5
        huge, seconds = _raw(port, f"POST /api/v1/scans HTTP/1.1\r\nHost: x\r\nContent-Type: model/stl\r\n"
                                   f"Authorization: Bearer {key}\r\nContent-Length: 3000000000\r\n\r\n".encode())
        assert huge.startswith(b"HTTP/1.1 413") and seconds < 5
        assert b"application/problem+json" in huge
    finally:
        stop(server)

"""Request ids, JSON logs without keys or patient data, Prometheus metrics, rate limits.
The real app on a migrated temporary SQLite database, auth required."""

from __future__ import annotations

import io
import json
import logging
import re
from pathlib import Path

import pytest

from app.db.migrate import upgrade_to_head
from app.db.session import session_factory
from app.logs import configure_logging, redact
from app.services.keys import KeyService
from tests.api.conftest import make_settings, serve_settings, wait_for_job

LEG = Path(__file__).resolve().parents[1] / "data" / "real" / "bodyparts3d_right_leg.stl"
#: a file name as a clinic's export may write it: the patient's name
PATIENT_FILE = "Doe_Jane_1961-03-04_left.stl"


def _service(tmp_path, **overrides):
    settings = make_settings(tmp_path, auth="required", **overrides)
    upgrade_to_head(settings.resolved_database_url)
    with session_factory(settings.resolved_database_url)() as session:
        keys = {name: KeyService(session).create(tenant, scopes).key for name, tenant, scopes in
                (("clinic", "clinic-a", ("upload", "read", "design")), ("other", "clinic-b", ("read",)),
                 ("admin", "clinic-a", ("admin",)), ("operator", "operators", ("operator",)))}
    return settings, keys


@pytest.fixture()
def captured_logs():
    """The service's logging set up as `calf-nurbs serve` does, on a buffer."""
    root = logging.getLogger()
    saved = (root.handlers[:], root.level)
    stream = io.StringIO()
    configure_logging("INFO", stream=stream)
    yield stream
    root.handlers, _ = saved
    root.setLevel(saved[1])
    logging.getLogger("uvicorn.access").disabled = False


def test_request_id_is_made_echoed_and_quoted_in_problems(tmp_path):
    settings, keys = _service(tmp_path)
    with serve_settings(settings) as client:
        made = client.get("/livez")
        assert re.fullmatch(r"[0-9a-f]{32}", made.headers["x-request-id"])
        echoed = client.get("/livez", headers={"X-Request-ID": "portal-42.a:b"})
        assert echoed.headers["x-request-id"] == "portal-42.a:b"
        # not a plain token (a header injection attempt, or too long): a new id instead
        for bad in ("a b", "x" * 129, "<script>"):
            replaced = client.get("/livez", headers={"X-Request-ID": bad})
            assert replaced.headers["x-request-id"] != bad
        problem = client.get("/api/v1/records/nope", headers={"Authorization": f"Bearer {keys['clinic']}", "X-Request-ID": "trace-7"})
        assert problem.status_code == 404
        assert problem.json()["request_id"] == "trace-7" == problem.headers["x-request-id"]


def test_logs_are_json_with_the_request_id_and_no_key_or_patient_data(tmp_path, captured_logs):
    settings, keys = _service(tmp_path)
    clinic = {"Authorization": f"Bearer {keys['clinic']}"}
    with serve_settings(settings) as client:
        upload = client.post("/api/v1/scans", files={"file": (PATIENT_FILE, LEG.read_bytes(), "model/stl")},
                             data={"points": "8"}, headers={**clinic, "X-Request-ID": "upload-1"})
        assert upload.status_code == 202, upload.text
        client.headers.update(clinic)
        job = wait_for_job(client, upload.headers["location"])
        assert job["status"] == "succeeded"
        client.headers.clear()
        # a wrong key (the secret of a real one, altered), sent as X-API-Key
        wrong = keys["clinic"][:-4] + "AAAA"
        assert client.get("/api/v1/records", headers={"X-API-Key": wrong}).status_code == 401
    lines = [line for line in captured_logs.getvalue().splitlines() if line.strip()]
    events = [json.loads(line) for line in lines]  # every line is one JSON object
    requests = [e for e in events if e.get("event") == "request"]
    upload_line = next(e for e in requests if e["request_id"] == "upload-1")
    assert upload_line["route"] == "/api/v1/scans" and upload_line["status"] == 202
    assert upload_line["tenant"] is not None and upload_line["duration_ms"] > 0
    assert any(e["route"] == "/api/v1/jobs/{job_id}" for e in requests)  # templates, not ids
    text = captured_logs.getvalue()
    # the secret is url-safe base64, which may itself hold '_': split off the two-part prefix only
    secret_part = keys["clinic"].split("_", 2)[2]
    for secret in (keys["clinic"], wrong, secret_part, "Doe_Jane", "1961-03-04"):
        assert secret not in text


def test_a_key_in_a_log_message_keeps_only_its_prefix():
    key = "cnk_0123abcd_" + "x" * 43
    assert redact(f"refused {key} at the door") == "refused cnk_0123abcd_[redacted] at the door"


def test_metrics_show_latency_checks_fits_and_outcomes_to_an_operator_only(tmp_path):
    settings, keys = _service(tmp_path)
    clinic = {"Authorization": f"Bearer {keys['clinic']}"}
    with serve_settings(settings) as client:
        upload = client.post("/api/v1/scans", content=LEG.read_bytes(), params={"points": 8},
                             headers={**clinic, "Content-Type": "model/stl"})
        assert upload.status_code == 202
        refused = client.post("/api/v1/scans", content=b"solid x\nendsolid x\n", headers={**clinic, "Content-Type": "model/stl"})
        assert refused.status_code == 422
        client.headers.update(clinic)
        job = wait_for_job(client, upload.headers["location"])
        client.get(f"/api/v1/records/{job['record_id']}")
        client.headers.clear()
        assert client.get("/metrics").status_code == 401
        assert client.get("/metrics", headers=clinic).status_code == 403
        # a clinic's admin key holds every clinic scope but not the operator's: the
        # metrics count every clinic's jobs
        assert client.get("/metrics", headers={"Authorization": f"Bearer {keys['admin']}"}).status_code == 403
        scraped = client.get("/metrics", headers={"Authorization": f"Bearer {keys['operator']}"})
    assert scraped.status_code == 200
    assert scraped.headers["content-type"].startswith("text/plain")
    text = scraped.text

    def value(pattern: str) -> float:
        match = re.search(pattern + r" ([0-9.e+]+)$", text, re.M)
        assert match, pattern
        return float(match.group(match.lastindex))

    assert value(r'calf_http_request_duration_seconds_count\{method="GET",route="/api/v1/records/\{record_id\}",status="200"\}') >= 1
    assert value(r'calf_http_request_duration_seconds_count\{method="POST",route="/api/v1/scans",status="202"\}') == 1
    assert value(r'calf_upload_check_duration_seconds_count\{outcome="accepted"\}') == 1
    assert value(r'calf_upload_check_duration_seconds_count\{outcome="(?:empty_scan|too_few_points|truncated_file)"\}') == 1
    assert value(r'calf_fit_duration_seconds_count\{outcome="succeeded"\}') == 1
    assert value(r'calf_fit_duration_seconds_sum\{outcome="succeeded"\}') > 0
    assert value(r'calf_jobs_total\{outcome="succeeded",reason=""\}') == 1
    assert value(r'calf_jobs_by_status\{status="succeeded"\}') == 1
    assert "clinic-a" not in text and job["record_id"] not in text


def test_a_key_over_its_rate_gets_429_with_retry_after_and_others_go_on(tmp_path):
    settings, keys = _service(tmp_path, rate_limit=6.0, rate_burst=3)  # one token per 10 s
    with serve_settings(settings) as client:
        clinic = {"Authorization": f"Bearer {keys['clinic']}"}
        codes = [client.get("/api/v1/records", headers=clinic).status_code for _ in range(4)]
        assert codes == [200, 200, 200, 429]
        limited = client.get("/api/v1/records", headers=clinic)
        assert limited.status_code == 429
        assert limited.headers["content-type"] == "application/problem+json"
        assert limited.json()["code"] == "rate_limited"
        assert 1 <= int(limited.headers["retry-after"]) <= 10
        assert client.get("/api/v1/records", headers={"Authorization": f"Bearer {keys['other']}"}).status_code == 200


def test_uploads_have_their_own_smaller_rate(tmp_path):
    settings, keys = _service(tmp_path, upload_rate_limit=1.0, upload_rate_burst=1)
    with serve_settings(settings) as client:
        clinic = {"Authorization": f"Bearer {keys['clinic']}", "Content-Type": "model/stl"}
        first = client.post("/api/v1/scans", content=b"solid x\nendsolid x\n", headers=clinic)
        second = client.post("/api/v1/scans", content=b"solid x\nendsolid x\n", headers=clinic)
        assert first.status_code == 422  # the upload was taken (and refused for what it is)
        assert second.status_code == 429 and int(second.headers["retry-after"]) >= 30
        # reads are not uploads
        assert client.get("/api/v1/records", headers={"Authorization": clinic["Authorization"]}).status_code == 200

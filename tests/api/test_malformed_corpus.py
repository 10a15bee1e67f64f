"""The malformed-scan corpus (tests/api/malformed_scans.py) sent as a clinic's portal
sends scans (multipart, with the file's own name): each gets its own 4xx problem, or a
job that fails with its reason in words, or, where the file holds a readable leg, a
record.  No answer shows a server path or a library's words, and after all of them the
database is intact and the record stored before is unchanged."""

from __future__ import annotations

import re
import sqlite3
import uuid

import pytest

from app.db.migrate import upgrade_to_head
from tests.api.conftest import make_settings, serve_settings, wait_for_job
from tests.api.malformed_scans import FITS, malformed_scans
from tests.conftest import REAL

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

CORPUS = {case.name: case for case in malformed_scans()}
#: what a detail must never show: a server path, a traceback, a library's exception name
LEAKS = re.compile(r"/(tmp|work|home|root|usr|var|etc)/|Traceback|\b[A-Z]\w*(Error|Exception)\b|File \"")


def test_the_corpus_is_large_and_every_case_has_an_expectation():
    assert len(CORPUS) >= 40
    assert all(case.expect for case in CORPUS.values())


def _multipart(filename: str | bytes, data: bytes, media_type: str) -> tuple[bytes, str]:
    """A multipart body written byte for byte (a client may send a name in any encoding)."""
    boundary = uuid.uuid4().hex
    name = filename if isinstance(filename, bytes) else filename.encode("utf-8")
    body = (f"--{boundary}\r\n".encode() + b'Content-Disposition: form-data; name="file"; filename="' + name + b'"\r\n'
            + f"Content-Type: {media_type}\r\n\r\n".encode() + data + f"\r\n--{boundary}--\r\n".encode())
    return body, f"multipart/form-data; boundary={boundary}"


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    data_dir = tmp_path_factory.mktemp("malformed")
    settings = make_settings(data_dir, max_scan_points=1_000_000, max_upload_mb=64.0)
    upgrade_to_head(settings.resolved_database_url)
    with serve_settings(settings) as client:
        stored = client.post("/api/v1/scans", content=(REAL / "bodyparts3d_right_leg.stl").read_bytes(),
                             params={"points": 8}, headers={"Content-Type": "model/stl"})
        record_id = wait_for_job(client, stored.headers["location"])["record_id"]
        before = client.get(f"/api/v1/records/{record_id}")
        yield client, settings, data_dir, {"id": record_id, "etag": before.headers["etag"], "body": before.json()}


@pytest.mark.parametrize("name", list(CORPUS))
def test_a_malformed_scan_gets_its_own_answer(service, name):
    client, _, _, _ = service
    case = CORPUS[name]
    body, content_type = _multipart(case.filename, case.data, case.media_type)
    response = client.post("/api/v1/scans", content=body, params=case.params, headers={"Content-Type": content_type})
    if response.status_code == 202:
        job = wait_for_job(client, response.headers["location"], timeout=180)
        if job["status"] == "succeeded":
            outcome, detail = FITS, ""
        else:
            outcome, detail = job["error"]["code"], job["error"]["detail"]
    else:
        assert 400 <= response.status_code < 500, response.text
        assert response.headers["content-type"] == "application/problem+json"
        outcome, detail = response.json()["code"], response.json()["detail"]
    assert outcome in case.expect, f"{name}: {outcome} ({detail})"
    assert not LEAKS.search(detail), detail
    assert outcome == FITS or len(detail) > 20  # a reason in words


def test_after_the_corpus_the_database_is_intact_and_nothing_stored_changed(service):
    client, settings, data_dir, stored = service
    for case in CORPUS.values():  # the whole corpus again, in one go, before the checks
        body, content_type = _multipart(case.filename, case.data, case.media_type)
        client.post("/api/v1/scans", content=body, params=case.params, headers={"Content-Type": content_type})
    client.app.state.runner  # noqa: B018 - the runner of this app finishes its jobs:
    import anyio

    anyio.run(client.app.state.runner.idle, 300.0)
    database = settings.resolved_database_url.removeprefix("sqlite:///")
    with sqlite3.connect(database) as connection:
        assert connection.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        assert connection.execute("PRAGMA foreign_key_check").fetchall() == []
        unfinished = connection.execute("SELECT count(*) FROM jobs WHERE status NOT IN ('succeeded', 'failed')").fetchone()[0]
    assert unfinished == 0
    again = client.get(f"/api/v1/records/{stored['id']}")
    assert again.headers["etag"] == stored["etag"] and again.json() == stored["body"]
    assert not any((data_dir / "tmp").iterdir())  # no upload left half-written
    stored_files = [p for p in (data_dir / "scans").rglob("*") if p.is_file()]
    assert all(p.resolve().is_relative_to((data_dir / "scans").resolve()) for p in stored_files)

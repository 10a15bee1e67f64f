"""Idempotency-Key on uploads and design creation: a replay returns the first response,
the same key with other content answers 409, a failed first request frees its key.
The real app on a migrated temporary SQLite database, auth required, two clinics."""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import pytest
from sqlalchemy import func, select, update

from app.db.migrate import upgrade_to_head
from app.db.models import Design, IdempotentRequest, Job, utcnow
from app.db.session import session_factory
from app.errors import Conflict
from app.services.idempotency import PENDING_TAKEOVER, IdempotencyService, Replay, Reservation
from app.services.keys import KeyService
from tests.api.conftest import make_settings, serve_settings, wait_for_job
from tests.conftest import REAL

LEG = Path(__file__).resolve().parents[1] / "data" / "real" / "bodyparts3d_right_leg.stl"


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    settings = make_settings(tmp_path_factory.mktemp("idempotency"), auth="required")
    upgrade_to_head(settings.resolved_database_url)
    sessions = session_factory(settings.resolved_database_url)
    with sessions() as session:
        keys = {t: KeyService(session).create(t, ("upload", "read", "design")).key for t in ("clinic-a", "clinic-b")}
    with serve_settings(settings) as client:
        yield client, sessions, keys


def _count(sessions, model) -> int:
    with sessions() as session:
        return session.scalar(select(func.count()).select_from(model))


def _upload(client, key, idempotency_key, data=None, points=8):
    headers = {"Authorization": f"Bearer {key}", "Content-Type": "model/stl", "Idempotency-Key": idempotency_key}
    return client.post("/api/v1/scans", content=data if data is not None else LEG.read_bytes(), params={"points": points},
                       headers=headers)


def test_an_upload_retried_with_its_key_gets_the_same_job(service):
    client, sessions, keys = service
    first = _upload(client, keys["clinic-a"], "upload-7f3a")
    assert first.status_code == 202, first.text
    jobs = _count(sessions, Job)
    again = _upload(client, keys["clinic-a"], "upload-7f3a")
    assert again.status_code == 202
    assert again.headers["idempotent-replayed"] == "true"
    assert again.json()["id"] == first.json()["id"]
    assert again.headers["location"] == first.headers["location"]
    assert _count(sessions, Job) == jobs  # nothing queued twice
    # other content under the same key: other options, or other bytes
    assert _upload(client, keys["clinic-a"], "upload-7f3a", points=15).json()["code"] == "idempotency_key_reused"
    other_bytes = _upload(client, keys["clinic-a"], "upload-7f3a", data=LEG.read_bytes() + b"\0")
    assert other_bytes.status_code == 409 and other_bytes.json()["code"] == "idempotency_key_reused"
    settings = client.app.state.settings
    assert not any(settings.tmp_dir.iterdir())  # neither a replay nor a 409 leaves its upload behind
    # another clinic's key space is its own
    theirs = _upload(client, keys["clinic-b"], "upload-7f3a")
    assert theirs.status_code == 202 and theirs.json()["id"] != first.json()["id"]
    assert "idempotent-replayed" not in theirs.headers
    client.headers.update({"Authorization": f"Bearer {keys['clinic-a']}"})
    assert wait_for_job(client, first.headers["location"])["status"] == "succeeded"
    client.headers.clear()


def test_a_failed_first_request_frees_its_key(service):
    client, _, keys = service
    refused = _upload(client, keys["clinic-a"], "retry-me", data=b"solid nothing\nendsolid nothing\n")
    assert refused.status_code == 422
    retried = _upload(client, keys["clinic-a"], "retry-me")
    assert retried.status_code == 202 and "idempotent-replayed" not in retried.headers


def test_a_design_retried_with_its_key_is_made_once(service):
    client, sessions, keys = service
    auth = {"Authorization": f"Bearer {keys['clinic-a']}"}
    upload = _upload(client, keys["clinic-a"], "upload-for-design")
    client.headers.update(auth)
    record_id = wait_for_job(client, upload.headers["location"])["record_id"]
    client.headers.clear()
    body = {"compression_class": "II", "fabric": {"stiffness_n_per_cm": 10}}
    url = f"/api/v1/records/{record_id}/designs"
    first = client.post(url, json=body, headers={**auth, "Idempotency-Key": "design-1"})
    assert first.status_code == 201, first.text
    designs = _count(sessions, Design)
    again = client.post(url, json=body, headers={**auth, "Idempotency-Key": "design-1"})
    assert again.status_code == 201 and again.json()["id"] == first.json()["id"]
    assert again.headers["location"] == first.headers["location"] and again.headers["idempotent-replayed"] == "true"
    assert _count(sessions, Design) == designs
    changed = client.post(url, json={**body, "compression_class": "I"}, headers={**auth, "Idempotency-Key": "design-1"})
    assert changed.status_code == 409 and changed.json()["code"] == "idempotency_key_reused"
    # without a key, each request is a new design
    assert client.post(url, json=body, headers=auth).json()["id"] != first.json()["id"]


@pytest.mark.parametrize("bad", ["has space", "x" * 256, "tab\there"])
def test_a_malformed_key_is_refused(service, bad):
    client, _, keys = service
    response = _upload(client, keys["clinic-a"], bad, data=b"solid\nendsolid\n")
    assert response.status_code in (400, 422)
    assert response.headers["content-type"] == "application/problem+json"


def test_a_key_in_use_answers_409_until_its_request_ends_or_dies(service):
    _, sessions, _ = service
    with sessions() as session:
        tenant = session.scalar(select(IdempotentRequest.tenant_id).limit(1))
        ids = IdempotencyService(session, tenant, keep_hours=24)
        reservation = ids.begin("in-flight", "create_design", "f" * 64)
        assert isinstance(reservation, Reservation)
        with pytest.raises(Conflict) as in_use:
            ids.begin("in-flight", "create_design", "f" * 64)
        assert in_use.value.code == "idempotency_key_in_use" and in_use.value.headers["Retry-After"] == "1"
        # a reservation older than the takeover time belongs to a request that died
        session.execute(update(IdempotentRequest).where(IdempotentRequest.key == "in-flight").values(
            created_at=utcnow() - PENDING_TAKEOVER - timedelta(seconds=1)))
        session.commit()
        taken = ids.begin("in-flight", "create_design", "f" * 64)
        assert isinstance(taken, Reservation) and taken != reservation
        ids.finish(taken, 201, {"id": "d1"}, "/api/v1/designs/d1")
        assert ids.begin("in-flight", "create_design", "f" * 64) == Replay(201, {"id": "d1"}, "/api/v1/designs/d1")


def test_a_reservation_whose_process_died_is_taken_over_at_once(service):
    """After a crash the retry does the work (once) instead of waiting out a 409: the
    reservation names its process, and a process of this host that is gone - or our own
    pid under another tag, a restart that got the same pid - holds nothing."""
    import os
    import socket
    import subprocess
    import sys

    _, sessions, _ = service
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead_pid = int(ended.stdout)
    owners = {"dead-pid": f"{socket.gethostname()}:{dead_pid}:0badc0de",
              "restarted": f"{socket.gethostname()}:{os.getpid()}:0badc0de"}
    with sessions() as session:
        tenant = session.scalar(select(IdempotentRequest.tenant_id).limit(1))
        ids = IdempotencyService(session, tenant, keep_hours=24)
        for key, owner in owners.items():
            first = ids.begin(key, "upload_scan", "e" * 64)
            session.execute(update(IdempotentRequest).where(IdempotentRequest.key == key).values(owner=owner))
            session.commit()
            taken = ids.begin(key, "upload_scan", "e" * 64)
            assert isinstance(taken, Reservation) and taken != first
        # a live owner on another host keeps its key for the hold time only
        ids.begin("elsewhere", "upload_scan", "e" * 64)
        session.execute(update(IdempotentRequest).where(IdempotentRequest.key == "elsewhere").values(
            owner="another-host:1:0badc0de"))
        session.commit()
        with pytest.raises(Conflict):
            ids.begin("elsewhere", "upload_scan", "e" * 64)
        session.execute(update(IdempotentRequest).where(IdempotentRequest.key == "elsewhere").values(
            created_at=utcnow() - ids.hold - timedelta(seconds=1)))
        session.commit()
        assert isinstance(ids.begin("elsewhere", "upload_scan", "e" * 64), Reservation)


def test_the_answer_is_stored_in_the_transaction_of_the_job(service, monkeypatch):
    """The job and its stored answer are one commit: nothing is written for the key after
    the job's commit (a crash there - here: any later write failing - cannot leave a job
    whose retry would queue a second one)."""
    client, sessions, keys = service

    def crash(*args, **kwargs):
        raise RuntimeError("the process died after the job's commit")

    monkeypatch.setattr(IdempotencyService, "finish", crash)
    leg = (REAL / "bodyparts3d_right_leg.stl").read_bytes()
    headers = {"Content-Type": "model/stl", "Idempotency-Key": "one-commit", "Authorization": f"Bearer {keys['clinic-a']}"}
    first = client.post("/api/v1/scans", content=leg, headers=headers)
    assert first.status_code == 202
    with sessions() as session:
        row = session.scalar(select(IdempotentRequest).where(IdempotentRequest.key == "one-commit"))
        assert row.state == "done" and row.response_body["id"] == first.json()["id"]
    again = client.post("/api/v1/scans", content=leg, headers=headers)
    assert again.headers["Idempotent-Replayed"] == "true" and again.json()["id"] == first.json()["id"]

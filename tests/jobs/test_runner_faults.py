"""The embedded runner under faults, on the real app, a migrated temporary SQLite database
and real worker processes killed with SIGKILL: every accepted job ends exactly once."""

from __future__ import annotations

import os
import signal
import time
from datetime import timedelta
from pathlib import Path

import pytest
from sqlalchemy import func, select, update

from app.db.migrate import upgrade_to_head
from app.db.models import Job, Record, utcnow
from tests.api.conftest import make_settings, serve_settings, wait_for_job
from tests.conftest import REAL

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

LEG = (REAL / "bodyparts3d_right_leg.stl").read_bytes()
BODY = (REAL / "vh_male_skin.glb").read_bytes()  # a whole body: a fit of a few seconds


def _settings(tmp_path: Path, **overrides):
    settings = make_settings(tmp_path, **overrides)
    upgrade_to_head(settings.resolved_database_url)
    return settings


def _upload(client, data=LEG, media="model/stl", **params):
    response = client.post("/api/v1/scans", content=data, params=params, headers={"Content-Type": media})
    assert response.status_code == 202, response.text
    return response.headers["location"]


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    # a killed child stays a zombie until reaped: read its state
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"
    except FileNotFoundError:
        return True


def _kill(pids) -> None:
    for pid in pids:
        os.kill(pid, signal.SIGKILL)


def _wait_running(client, location, timeout=60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if client.get(location).json()["status"] == "running":
            return
        time.sleep(0.01)
    raise AssertionError("the job never ran")


def test_a_killed_check_worker_is_replaced_and_later_uploads_work(tmp_path):
    with serve_settings(_settings(tmp_path)) as client:
        runner = client.app.state.runner
        client.post("/api/v1/scans", content=LEG, headers={"Content-Type": "model/stl"})  # the pool is up
        pids = runner.check_pool.pids()
        assert pids
        _kill(pids)
        time.sleep(0.5)
        job = wait_for_job(client, _upload(client, points=8))
        assert job["status"] == "succeeded"
        assert client.get("/readyz").status_code == 200
        assert not set(runner.check_pool.pids()) & set(pids)


def test_a_worker_killed_mid_fit_is_retried_and_succeeds_once(tmp_path):
    """The fit is an lsq 40 x 72 (about 3 s: the worker is surely still fitting when it
    is killed; a 0.3 s paper fit could end first once the pool's workers were started
    ahead of the first job)."""
    with serve_settings(_settings(tmp_path)) as client:
        runner = client.app.state.runner
        location = _upload(client, BODY, "model/gltf-binary", side="left", mode="lsq", grid="40x72")
        _wait_running(client, location)
        time.sleep(0.05)
        _kill(runner.fit_pool.pids())
        job = wait_for_job(client, location, timeout=180)
        assert job["status"] == "succeeded" and job["attempts"] == 2
        with client.app.state.sessions() as session:
            assert session.scalar(select(func.count()).select_from(Record)) == 1


def test_a_job_over_its_time_limit_fails_its_process_is_killed_and_the_next_runs(tmp_path):
    with serve_settings(_settings(tmp_path, job_timeout_s=0.05)) as client:
        runner = client.app.state.runner
        first = _upload(client, points=8)
        _wait_running(client, first)
        pids = runner.fit_pool.pids()
        job = wait_for_job(client, first)
        assert job["status"] == "failed" and job["error"]["code"] == "timeout"
        deadline = time.monotonic() + 10
        while not all(_gone(p) for p in pids) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert all(_gone(p) for p in pids)
        runner.job_timeout_s = 600.0
        assert wait_for_job(client, _upload(client, points=15))["status"] == "succeeded"


def test_a_second_runner_started_mid_fit_takes_nothing(tmp_path):
    settings = _settings(tmp_path)
    with serve_settings(settings) as first:
        location = _upload(first, BODY, "model/gltf-binary", side="right")
        _wait_running(first, location)
        with serve_settings(settings) as second:  # a second `calf-nurbs serve` on the same data
            job = wait_for_job(first, location, timeout=180)
            second.app.state.runner.notify()
            time.sleep(1.0)
        assert job["status"] == "succeeded" and job["attempts"] == 1
        with first.app.state.sessions() as session:
            assert session.scalar(select(func.count()).select_from(Record)) == 1


def _orphan(settings, attempts: int) -> str:
    """A job left running by a runner that died: accepted by an API that runs no jobs,
    then marked running under a lease that has expired."""
    with serve_settings(settings.model_copy(update={"run_jobs": False})) as api:
        location = _upload(api, points=8)
        job_id = location.rsplit("/", 1)[1]
        with api.app.state.sessions() as session, session.begin():
            session.execute(update(Job).where(Job.id == job_id).values(
                status="running", attempts=attempts, lease_owner="dead-host:1:0000",
                lease_expires_at=utcnow() - timedelta(seconds=1)))
    return location


def test_a_job_whose_runner_died_is_taken_over_when_its_lease_expires(tmp_path):
    settings = _settings(tmp_path)
    location = _orphan(settings, attempts=1)
    with serve_settings(settings) as client:
        job = wait_for_job(client, location)
    assert job["status"] == "succeeded" and job["attempts"] == 2


def test_a_job_interrupted_too_often_fails_with_the_reason(tmp_path):
    settings = _settings(tmp_path, job_max_attempts=3)
    location = _orphan(settings, attempts=3)
    with serve_settings(settings) as client:
        job = wait_for_job(client, location)
    assert job["status"] == "failed" and job["error"]["code"] == "worker_crashed"
    assert "interrupted 3 times" in job["error"]["detail"]


def test_readyz_reports_a_runner_that_cannot_run_jobs(tmp_path):
    with serve_settings(_settings(tmp_path)) as client:
        assert client.get("/readyz").status_code == 200
        client.app.state.runner._dispatcher.cancel()
        time.sleep(0.2)
        response = client.get("/readyz")
        assert response.status_code == 503 and response.json()["code"] == "runner_unavailable"


def test_temporary_uploads_left_by_a_crash_are_removed_at_start_up(tmp_path):
    import socket
    import subprocess
    import sys

    settings = _settings(tmp_path)
    settings.tmp_dir.mkdir(parents=True, exist_ok=True)
    host = socket.gethostname().replace("-", "_")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True).stdout.strip()
    crashed = settings.tmp_dir / f"upload-{host}-{dead}-x1"  # its process is gone
    old = settings.tmp_dir / "upload-otherhost-123-x2"
    live = settings.tmp_dir / f"upload-{host}-{os.getppid()}-x3"  # a running process's upload in progress
    elsewhere = settings.tmp_dir / "upload-otherhost-456-x4"  # another host's, recent
    crashed_leg = settings.tmp_dir / f"upload-{host}-{dead}-x1.leg.npz"  # the leg its check cut out (placed_legs)
    live_leg = settings.tmp_dir / f"upload-{host}-{os.getppid()}-x3.leg.npz"
    for path in (crashed, old, live, elsewhere, crashed_leg, live_leg):
        path.write_bytes(b"part of a scan")
    two_hours_ago = time.time() - 7200
    os.utime(old, (two_hours_ago, two_hours_ago))
    with serve_settings(settings):
        assert not crashed.exists() and not old.exists() and not crashed_leg.exists()
        assert live.exists() and elsewhere.exists() and live_leg.exists()


def test_re_uploading_the_same_bytes_restores_a_missing_scan_file(tmp_path):
    with serve_settings(_settings(tmp_path)) as client:
        job = wait_for_job(client, _upload(client, points=8))
        stored = client.app.state.store.path_for(job["scan_sha256"])
        stored.unlink()
        again = wait_for_job(client, _upload(client, points=8))
        assert stored.is_file() and again["status"] == "succeeded" and again["scan_id"] == job["scan_id"]


def test_the_runner_leaves_no_worker_behind_on_stop(tmp_path):
    with serve_settings(_settings(tmp_path)) as client:
        wait_for_job(client, _upload(client, points=8))
        pids = client.app.state.runner.fit_pool.pids() + client.app.state.runner.check_pool.pids()
    deadline = time.monotonic() + 10
    while not all(_gone(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(_gone(p) for p in pids)

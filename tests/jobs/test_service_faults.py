"""The deployed service (`calf-nurbs serve`) under process and server faults:
- the API SIGKILLed during a burst of uploads: after a restart, every upload that was
  answered 202 ends as exactly one record (or a failed job with a reason);
- the PostgreSQL server restarted under a running service: it recovers by itself.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import threading
import time
from pathlib import Path

import httpx
import pytest
from sqlalchemy import create_engine, text

from tests.api.test_processes import free_port, postgres_url, start, stop, wait_ready  # noqa: F401 - a fixture
from tests.conftest import REAL

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

LEG = (REAL / "bodyparts3d_right_leg.stl").read_bytes()


def _wait_all(base: str, locations: list[str], timeout: float = 300.0) -> list[dict]:
    deadline = time.monotonic() + timeout
    done: dict[str, dict] = {}
    while len(done) < len(locations) and time.monotonic() < deadline:
        for location in locations:
            if location not in done:
                job = httpx.get(base + location, timeout=10).json()
                if job["status"] in ("succeeded", "failed"):
                    done[location] = job
        time.sleep(0.2)
    assert len(done) == len(locations), f"{len(locations) - len(done)} jobs never ended"
    return [done[location] for location in locations]


def test_the_api_killed_during_a_burst_of_uploads_loses_and_doubles_nothing(tmp_path):
    env = {"CALF_DATA_DIR": str(tmp_path / "var"), "CALF_WORKERS": "2", "CALF_JOB_LEASE_S": "2",
           "CALF_UPLOAD_RATE_LIMIT": "0", "CALF_LOG_LEVEL": "WARNING"}
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    server = start(["serve", "--port", str(port)], env)
    accepted: list[str] = []
    lock = threading.Lock()

    def client(n: int) -> None:
        for i in range(n):
            try:
                r = httpx.post(f"{base}/api/v1/scans", content=LEG, params={"points": 8 + i % 8},
                               headers={"Content-Type": "model/stl"}, timeout=60)
            except httpx.TransportError:
                return  # the server died under this request: it was not accepted
            if r.status_code == 202:
                with lock:
                    accepted.append(r.headers["location"])

    try:
        wait_ready(base, server)
        clients = [threading.Thread(target=client, args=(6,)) for _ in range(4)]
        for c in clients:
            c.start()
        deadline = time.monotonic() + 60
        while len(accepted) < 6 and time.monotonic() < deadline:
            time.sleep(0.05)
        server.send_signal(signal.SIGKILL)  # mid-burst: uploads in flight, jobs queued and running
        server.wait(timeout=30)
        for c in clients:
            c.join(timeout=120)
        assert accepted, "no upload was accepted before the kill"
        server = start(["serve", "--port", str(port)], env)
        wait_ready(base, server)
        jobs = _wait_all(base, list(accepted))
    finally:
        stop(server)
    assert all(job["status"] == "succeeded" for job in jobs), [j["error"] for j in jobs if j["status"] != "succeeded"]
    engine = create_engine(f"sqlite:///{tmp_path / 'var' / 'calf.db'}")
    with engine.connect() as connection:
        per_job = connection.execute(text("SELECT count(*), count(DISTINCT record_id) FROM jobs WHERE status = 'succeeded'")).one()
        records = connection.execute(text("SELECT count(*) FROM records")).scalar_one()
        unfinished = connection.execute(text("SELECT count(*) FROM jobs WHERE status IN ('queued', 'running')")).scalar_one()
    engine.dispose()
    assert per_job[0] == per_job[1] == records  # one record per succeeded job, none extra
    assert unfinished == 0  # jobs accepted without their 202 reaching the client end too
    assert not any((tmp_path / "var" / "tmp").iterdir())  # uploads cut off by the kill: cleaned at restart


def _pg_cluster() -> tuple[str, str] | None:
    if shutil.which("pg_ctlcluster") is None or not Path("/etc/postgresql").is_dir() or os.geteuid() != 0:
        return None
    versions = sorted(os.listdir("/etc/postgresql"))
    return (versions[-1], "main") if versions else None


def test_the_service_recovers_by_itself_when_postgresql_restarts(tmp_path, postgres_url):  # noqa: F811
    cluster = _pg_cluster()
    if cluster is None:
        pytest.skip("restarting PostgreSQL needs this machine's own cluster (pg_ctlcluster, as root)")
    env = {"CALF_DATA_DIR": str(tmp_path / "var"), "CALF_DATABASE_URL": postgres_url, "CALF_WORKERS": "1",
           "CALF_LOG_LEVEL": "WARNING"}
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    server = start(["serve", "--port", str(port)], env)
    try:
        wait_ready(base, server)
        first = httpx.post(f"{base}/api/v1/scans", content=LEG, params={"points": 8},
                           headers={"Content-Type": "model/stl"}, timeout=60)
        assert _wait_all(base, [first.headers["location"]])[0]["status"] == "succeeded"
        subprocess.run(["pg_ctlcluster", "--skip-systemctl-redirect", *cluster, "restart"], check=True, timeout=120)
        wait_ready(base, server, timeout=60)  # readyz comes back without touching the service
        second = httpx.post(f"{base}/api/v1/scans", content=LEG, params={"points": 15},
                            headers={"Content-Type": "model/stl"}, timeout=60)
        assert second.status_code == 202, second.text
        assert _wait_all(base, [second.headers["location"]])[0]["status"] == "succeeded"
    finally:
        stop(server)

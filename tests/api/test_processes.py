"""The service as deployed: `calf-nurbs serve` (migrates, then serves) on embedded SQLite,
and an API that runs no jobs plus a separate `calf-nurbs worker`, both on PostgreSQL."""

from __future__ import annotations

import os
import time
import uuid

import httpx
import pytest
from sqlalchemy import create_engine, text
from sqlalchemy.exc import OperationalError

from benchmarks.served import BIN, free_port, start, stop, wait_ready  # noqa: F401 - used by other test modules
from tests.conftest import REAL

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

PG_ADMIN_URL = os.environ.get("CALF_TEST_PG_ADMIN", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres")


def fit_one(base: str, auth: dict | None = None) -> dict:
    data = (REAL / "bodyparts3d_right_leg.stl").read_bytes()
    response = httpx.post(f"{base}/api/v1/scans", content=data, headers={"Content-Type": "model/stl", **(auth or {})}, timeout=60)
    assert response.status_code == 202, response.text
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        job = httpx.get(base + response.headers["location"], headers=auth, timeout=10).json()
        if job["status"] in ("succeeded", "failed"):
            return job
        time.sleep(0.2)
    raise AssertionError("job did not finish")


def test_serve_migrates_an_empty_data_dir_then_fits(tmp_path):
    port = free_port()
    server = start(["serve", "--port", str(port)], {"CALF_DATA_DIR": str(tmp_path / "var"), "CALF_WORKERS": "1"})
    try:
        base = f"http://127.0.0.1:{port}"
        wait_ready(base, server)
        from app.db.migrate import head_revision

        assert httpx.get(f"{base}/readyz").json()["revision"] == head_revision("sqlite://")
        job = fit_one(base)
        assert job["status"] == "succeeded"
        assert (tmp_path / "var" / "calf.db").is_file()
    finally:
        stop(server)


@pytest.fixture
def postgres_url():
    """A fresh database on the machine's PostgreSQL server, dropped afterwards."""
    name = f"calf_test_{uuid.uuid4().hex[:10]}"
    admin = create_engine(PG_ADMIN_URL, isolation_level="AUTOCOMMIT", pool_pre_ping=True)  # survives a server restart
    try:
        with admin.connect() as conn:
            conn.execute(text(f'CREATE DATABASE "{name}"'))
    except OperationalError as exc:  # no server here: make test needs none (.ci/run starts one)
        admin.dispose()
        pytest.skip(f"no PostgreSQL server at {PG_ADMIN_URL.split('@')[-1]} ({type(exc.orig).__name__}); "
                    "set CALF_TEST_PG_ADMIN or start PostgreSQL to run this test")
    yield PG_ADMIN_URL.rsplit("/", 1)[0] + "/" + name
    with admin.connect() as conn:
        conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
    admin.dispose()


def test_api_without_jobs_and_a_separate_worker_on_postgresql(tmp_path, postgres_url):
    port = free_port()
    shared = {"CALF_DATA_DIR": str(tmp_path / "data"), "CALF_DATABASE_URL": postgres_url}
    api = start(["serve", "--port", str(port)], {**shared, "CALF_RUN_JOBS": "false", "CALF_WORKERS": "1"})
    worker = None
    try:
        base = f"http://127.0.0.1:{port}"
        wait_ready(base, api)
        assert httpx.get(f"{base}/readyz").json()["database"] == "postgresql"
        data = (REAL / "bodyparts3d_right_leg.stl").read_bytes()
        response = httpx.post(f"{base}/api/v1/scans", content=data, headers={"Content-Type": "model/stl"}, timeout=60)
        assert response.status_code == 202
        time.sleep(1.0)
        assert httpx.get(base + response.headers["location"]).json()["status"] == "queued"  # the API fits nothing
        worker = start(["worker"], {**shared, "CALF_WORKERS": "1"})
        deadline = time.monotonic() + 120
        job = {}
        while time.monotonic() < deadline:
            job = httpx.get(base + response.headers["location"]).json()
            if job["status"] in ("succeeded", "failed"):
                break
            time.sleep(0.2)
        assert job["status"] == "succeeded", job
        record = httpx.get(f"{base}/api/v1/records/{job['record_id']}").json()
        assert record["fit"]["points_per_layer"] == 15 and record["source"] == "fit"
    finally:
        stop(*(p for p in (api, worker) if p is not None))

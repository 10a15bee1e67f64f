"""Scale-out on real servers: the API sends fits through Dramatiq on Redis to two
`calf-nurbs worker` processes, jobs and records in PostgreSQL, scans in a shared
directory.  A worker SIGKILLed mid-fit: its job completes on the other worker, once.
Skipped, saying why, where no Redis or PostgreSQL server runs (.ci/run starts both)."""

from __future__ import annotations

import os
import signal
import time
import uuid

import httpx
import pytest
import redis
from sqlalchemy import create_engine, text

from tests.api.test_processes import free_port, postgres_url, start, stop, wait_ready  # noqa: F401 - a fixture
from tests.conftest import REAL

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

REDIS_URL = os.environ.get("CALF_TEST_REDIS", "redis://127.0.0.1:6379/0")
LEG = (REAL / "bodyparts3d_right_leg.stl").read_bytes()
BODY = (REAL / "vh_male_skin.glb").read_bytes()


@pytest.fixture
def redis_url():
    try:
        redis.Redis.from_url(REDIS_URL, socket_connect_timeout=2).ping()
    except redis.exceptions.RedisError as exc:
        pytest.skip(f"no Redis server at {REDIS_URL.split('@')[-1]} ({type(exc).__name__}); "
                    "set CALF_TEST_REDIS or start Redis to run this test")
    return REDIS_URL


@pytest.fixture
def cluster(tmp_path, postgres_url, redis_url):  # noqa: F811 - the imported fixture
    """(base URL, database URL, API process, two worker processes)."""
    namespace = f"calf-test-{uuid.uuid4().hex[:8]}"  # this test's own queues
    shared = {"CALF_DATA_DIR": str(tmp_path / "data"), "CALF_DATABASE_URL": postgres_url, "CALF_BROKER_URL": redis_url,
              "CALF_BROKER_NAMESPACE": namespace, "CALF_BROKER_HEARTBEAT_S": "3", "CALF_JOB_LEASE_S": "3",
              "CALF_WORKERS": "1", "CALF_LOG_LEVEL": "WARNING"}
    port = free_port()
    api = start(["serve", "--port", str(port)], shared)
    base = f"http://127.0.0.1:{port}"
    workers = []
    try:
        wait_ready(base, api)
        workers = [start(["worker"], shared) for _ in range(2)]
        yield base, postgres_url, api, workers
    finally:
        stop(api, *workers)
        client = redis.Redis.from_url(redis_url)
        for key in client.scan_iter(f"{namespace}*"):
            client.delete(key)


def _upload(base: str, data: bytes, media: str, **params) -> str:
    response = httpx.post(f"{base}/api/v1/scans", content=data, params=params, headers={"Content-Type": media}, timeout=120)
    assert response.status_code == 202, response.text
    return base + response.headers["location"]


def _wait(url: str, statuses=("succeeded", "failed"), timeout=240.0) -> dict:
    deadline = time.monotonic() + timeout
    job = {}
    while time.monotonic() < deadline:
        job = httpx.get(url, timeout=10).json()
        if job["status"] in statuses:
            return job
        time.sleep(0.1)
    raise AssertionError(f"job still {job.get('status')}")


def _records(database_url: str) -> int:
    engine = create_engine(database_url)
    with engine.connect() as connection:
        count = connection.execute(text("SELECT count(*) FROM records")).scalar_one()
    engine.dispose()
    return count


def test_fits_go_through_dramatiq_workers_and_end_once(cluster):
    base, database_url, _, _ = cluster
    jobs = [_upload(base, LEG, "model/stl", points=points) for points in (8, 15)]
    finished = [_wait(url) for url in jobs]
    assert all(job["status"] == "succeeded" and job["attempts"] == 1 for job in finished)
    assert _records(database_url) == 2


def test_a_worker_killed_mid_fit_hands_its_job_to_the_other_once(cluster):
    base, database_url, _, workers = cluster
    url = _upload(base, BODY, "model/gltf-binary", side="left")
    _wait(url, statuses=("running",))
    engine = create_engine(database_url)
    with engine.connect() as connection:
        owner = connection.execute(text("SELECT lease_owner FROM jobs WHERE id = :id"),
                                   {"id": url.rsplit("/", 1)[1]}).scalar_one()
    engine.dispose()
    os.kill(int(owner.split(":")[1]), signal.SIGKILL)  # the Dramatiq worker process fitting it
    job = _wait(url)
    assert job["status"] == "succeeded" and job["attempts"] >= 2
    assert _records(database_url) == 1
    assert sum(w.poll() is None for w in workers) >= 1

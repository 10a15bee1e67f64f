"""The real ASGI app on a temporary SQLite database migrated with Alembic."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.db.migrate import upgrade_to_head
from app.main import create_app
from app.settings import Settings


def make_settings(data_dir: Path, **overrides) -> Settings:
    """Settings on a temporary SQLite file.  The upload rate limit is off unless a test
    sets it (suites upload dozens of scans back to back; test_observability tests it)."""
    overrides = {"upload_rate_limit": 0.0, **overrides}
    return Settings(data_dir=data_dir, database_url=f"sqlite:///{data_dir / 'calf.db'}", workers=2, **overrides)


@contextlib.contextmanager
def serve(data_dir: Path, **overrides) -> Iterator[TestClient]:
    """The real app on ``data_dir``'s SQLite database, migrated with Alembic first, for
    the with-block (its lifespan - runner, pools - starts and stops with it).  The one
    way the tests build a service: ``overrides`` are Settings fields."""
    with serve_settings(make_settings(data_dir, **overrides)) as client:
        yield client


@contextlib.contextmanager
def serve_settings(settings: Settings) -> Iterator[TestClient]:
    """:func:`serve` for settings already made (a test that writes to the database -
    keys, jobs - before the service starts)."""
    upgrade_to_head(settings.resolved_database_url)
    with TestClient(create_app(settings)) as client:
        yield client


@pytest.fixture
def service_client(tmp_path):
    """Factory: ``service_client(**settings)`` gives a client of a fresh service in the
    test's own temporary folder (``data_dir=`` to share one), shut at the test's end."""
    with contextlib.ExitStack() as stack:
        def make(data_dir: Path | None = None, **overrides) -> TestClient:
            return stack.enter_context(serve(data_dir or tmp_path, **overrides))

        yield make


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("calf-data")


@pytest.fixture(scope="module")
def client(data_dir):
    with serve(data_dir) as test_client:
        yield test_client


#: the case reference of the session's fitted record (tests/api: fitted_record)
SHARED_CASE = "CASE-SHARED-1"


@pytest.fixture(scope="session")
def shared_client(tmp_path_factory):
    """One service for the whole session, holding :func:`fitted_record`: the tests that
    read a record (its measurements, exports, designs, orders, size decisions) use it
    rather than each module starting a service and uploading and fitting the same leg.
    Tests that erase, count or list must not use it (other modules add designs and
    charts to it)."""
    with serve(tmp_path_factory.mktemp("calf-shared")) as test_client:
        yield test_client


@pytest.fixture(scope="session")
def fitted_record(shared_client) -> dict:
    """The record (its JSON body) of the BodyParts3D right leg (foot to knee, the floor in
    the scan) uploaded to :func:`shared_client` with case ``SHARED_CASE`` and fitted once
    per session (paper mode, 8 points a layer)."""
    from tests.conftest import REAL

    upload = shared_client.post("/api/v1/scans", content=(REAL / "bodyparts3d_right_leg.stl").read_bytes(),
                                params={"case_ref": SHARED_CASE, "points": 8}, headers={"Content-Type": "model/stl"})
    assert upload.status_code == 202, upload.text
    job = wait_for_job(shared_client, upload.headers["location"])
    assert job["status"] == "succeeded", job
    return shared_client.get(f"/api/v1/records/{job['record_id']}").json()


def wait_for_job(client: TestClient, location: str, timeout: float = 120.0) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = client.get(location).json()
        if job["status"] in ("succeeded", "failed"):
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {location} did not finish in {timeout} s")

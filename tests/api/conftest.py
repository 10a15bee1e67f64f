"""The real ASGI app on a temporary SQLite database migrated with Alembic."""

from __future__ import annotations

import time
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


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("calf-data")


@pytest.fixture(scope="module")
def client(data_dir):
    settings = make_settings(data_dir)
    upgrade_to_head(settings.resolved_database_url)
    with TestClient(create_app(settings)) as test_client:
        yield test_client


def wait_for_job(client: TestClient, location: str, timeout: float = 120.0) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = client.get(location).json()
        if job["status"] in ("succeeded", "failed"):
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {location} did not finish in {timeout} s")

"""Request dependencies: settings, the database session, the scan store, the runner."""

from __future__ import annotations

from collections.abc import Iterator

from fastapi import Request
from sqlalchemy.orm import Session

from app.jobs.runner import EmbeddedRunner
from app.services.storage import ScanStore
from app.settings import Settings


def get_app_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_session(request: Request) -> Iterator[Session]:
    """One session per request.  Services commit their unit of work before the response
    is built (FastAPI runs this exit code only after the response has been sent); here
    whatever was not committed is rolled back and the session closed."""
    session = request.app.state.sessions()
    try:
        yield session
    finally:
        session.rollback()
        session.close()


def get_store(request: Request) -> ScanStore:
    return request.app.state.store


def get_runner(request: Request) -> EmbeddedRunner:
    return request.app.state.runner

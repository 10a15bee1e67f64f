"""Waiting at start for the database (app.services.health.wait_for_database): a real
SQLite file that appears late, and a PostgreSQL URL whose host does not resolve."""

from __future__ import annotations

import threading

import pytest
from sqlalchemy.exc import OperationalError

from app.db.session import session_factory
from app.services.health import wait_for_database


def test_a_database_that_never_answers_is_given_up_on_after_the_wait(caplog):
    """A database whose host does not resolve (as a container's database before its
    name is registered) is tried again through the wait, then its error comes through."""
    sessions = session_factory("postgresql+psycopg://calf:calf@calf-no-such-host.invalid:5432/calf")
    with caplog.at_level("WARNING", logger="calf_nurbs.health"), pytest.raises(OperationalError):
        wait_for_database(sessions, timeout_s=1.5, poll_s=0.5)
    assert sum("does not answer yet" in r.message for r in caplog.records) >= 2


def test_a_database_that_answers_late_is_waited_for(tmp_path):
    """SQLite in a folder that does not exist yet fails to open; made while the service
    waits, the wait ends as soon as the database opens."""
    folder = tmp_path / "late"
    sessions = session_factory(f"sqlite:///{folder / 'calf.db'}")
    threading.Timer(1.0, folder.mkdir).start()
    wait_for_database(sessions, timeout_s=20.0, poll_s=0.2)
    assert (folder / "calf.db").exists()

"""Job views: a failed job names its reason with a title, whatever the reason."""

from __future__ import annotations

import pytest

from app.db.models import Job, Scan
from app.errors import FAILURE_TITLES, PROBLEM_TYPE_PREFIX
from app.geometry.errors import FailureReason
from app.services.jobs import JOB_FAILED_TITLE, job_view


def _failed(code: str) -> dict:
    scan = Scan(id="s1", sha256="0" * 64)
    job = Job(id="j1", status="failed", options={}, attempts=1, error_code=code, error_detail="why")
    return job_view(job, scan)


def test_every_failure_reason_has_a_title():
    """A reason without a title answered 500 on its job's view (no_calf, several_legs)."""
    assert [reason.value for reason in FailureReason if reason not in FAILURE_TITLES] == []


@pytest.mark.parametrize("reason", list(FailureReason))
def test_a_failed_job_names_its_reason_and_title(reason):
    error = _failed(reason.value)["error"]
    assert error["code"] == reason.value
    assert error["title"] == FAILURE_TITLES[reason]
    assert error["type"] == PROBLEM_TYPE_PREFIX + reason.value


def test_a_code_this_release_does_not_know_still_has_a_title():
    """A job failed by another release (a rolling upgrade shares the database)."""
    assert _failed("a_reason_from_the_future")["error"]["title"] == JOB_FAILED_TITLE

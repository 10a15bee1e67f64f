"""The repositories on a migrated temporary database: the fair claim order of jobs."""

from __future__ import annotations

from datetime import timedelta

import pytest

from app.db.migrate import upgrade_to_head
from app.db.models import Scan, Tenant, utcnow
from app.db.repositories import JOB_RUNNING, JobRepository
from app.db.session import session_factory


@pytest.fixture()
def sessions(tmp_path):
    url = f"sqlite:///{tmp_path / 'calf.db'}"
    upgrade_to_head(url)
    return session_factory(url)


def _queue(session, tenant: str, n: int) -> list[str]:
    if session.get(Tenant, tenant) is None:
        session.add(Tenant(id=tenant, name=tenant))
        session.flush()
    scan = Scan(tenant_id=tenant, sha256=tenant.ljust(64, "0"), size_bytes=1, file_format="stl", media_type="model/stl")
    session.add(scan)
    session.flush()
    return [JobRepository(session, tenant).add(scan.id, {"points": 15 + i}).id for i in range(n)]


def test_the_clinic_with_the_fewest_fits_running_is_served_first(sessions):
    """Clinic A queued 5 jobs first and has one running; clinic B queues one later: the
    next free worker takes B's, then A's in their order (app.services.fair_share)."""
    with sessions() as session:
        a_jobs = _queue(session, "clinic-a", 5)
        session.commit()
        b_jobs = _queue(session, "clinic-b", 1)
        session.commit()
        system = JobRepository(session)
        first = system.claim_next("runner", utcnow() + timedelta(seconds=60))
        assert first.id == a_jobs[0]  # nobody runs anything yet: the oldest
        second = system.claim_next("runner", utcnow() + timedelta(seconds=60))
        assert second.id == b_jobs[0]  # A has a fit running, B none: B's goes before A's queue
        third = system.claim_next("runner", utcnow() + timedelta(seconds=60))
        assert third.id == a_jobs[1]
        session.commit()
        assert JobRepository(session, "clinic-a").count_active() == 5
        assert JobRepository(session, "clinic-b").count_active() == 1
        assert {j.status for j in (first, second, third)} == {JOB_RUNNING}


def test_a_dead_runners_fit_does_not_count_against_its_clinic(sessions):
    with sessions() as session:
        a_jobs = _queue(session, "clinic-a", 2)
        session.commit()
        b_jobs = _queue(session, "clinic-b", 1)
        session.commit()
        system = JobRepository(session)
        system.claim_next("dead-runner", utcnow() - timedelta(seconds=1))  # its lease has already lapsed
        session.commit()
        # A's lapsed fit is claimable again and counts as not running: A's oldest job first
        assert system.claim_next("runner", utcnow() + timedelta(seconds=60)).id == a_jobs[0]
        assert system.claim_next("runner", utcnow() + timedelta(seconds=60)).id == b_jobs[0]


def test_a_clinic_at_its_running_bound_leaves_the_worker_to_others(sessions):
    with sessions() as session:
        a_jobs = _queue(session, "clinic-a", 3)
        session.commit()
        system = JobRepository(session)
        assert system.claim_next("runner", utcnow() + timedelta(seconds=60), per_tenant=1).id == a_jobs[0]
        # A runs its one fit: its next job waits although a worker is free
        assert system.claim_next("runner", utcnow() + timedelta(seconds=60), per_tenant=1) is None
        b_jobs = _queue(session, "clinic-b", 1)
        session.commit()
        assert system.claim_next("runner", utcnow() + timedelta(seconds=60), per_tenant=1).id == b_jobs[0]


def test_records_are_owned_paged_newest_first_and_deleted_with_their_designs(sessions):
    """A clinic sees only its records, newest first in pages whose cursor continues
    where the last ended (ties of created_at broken by id); deleting a record deletes
    the designs made from it and keeps the other clinic's."""
    from app.db.models import Design
    from app.db.repositories import DesignRepository, RecordRepository

    with sessions() as session:
        for tenant in ("clinic-a", "clinic-b"):
            session.add(Tenant(id=tenant, name=tenant))
        session.flush()
        mine = RecordRepository(session, "clinic-a")
        made = [mine.add({"side": "left" if i % 2 else "right", "fit": {"error_index": 0.01 * i}}, f"etag{i}", "fit", None)
                for i in range(5)]
        other = RecordRepository(session, "clinic-b").add({"side": "left"}, "etag-b", "fit", None)
        DesignRepository(session, "clinic-a").add(made[0].id, {}, {}, "d0")
        DesignRepository(session, "clinic-b").add(other.id, {}, {}, "d1")
        session.commit()
        assert mine.get(other.id) is None and RecordRepository(session, "clinic-b").get(other.id) is not None
        first = mine.page(3, None)
        rest = mine.page(3, (first[-1].created_at, first[-1].id))
        order = [r.id for r in first + rest]
        assert sorted(order) == sorted(r.id for r in made) and len(set(order)) == 5
        keys = [(r.created_at, r.id) for r in first + rest]
        assert keys == sorted(keys, reverse=True)
        assert {r.side for r in mine.page(10, None, side="left")} == {"left"}
        mine.delete(made[0])
        session.commit()
        assert mine.count() == 4 + 1  # count is the whole table: clinic b's record stays
        assert session.query(Design).count() == 1

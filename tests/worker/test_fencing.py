"""Fenced jobs (issue 26): every write of a job's state, progress and result is guarded by its attempt
and host, so a stale worker (cut off, then healed) can neither finish, move nor overwrite a job another
worker runs now; its late writes are refused and logged, and a ride keeps exactly one result."""

from __future__ import annotations

import datetime as dt
import logging
import threading

import integration_services
import pytest
from sqlalchemy import func, select, update

from saddlescope.db.enums import JobStatus
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job, Result, utcnow
from saddlescope.db.repositories import JobRepository
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.services.jobs import runner
from saddlescope.services.jobs.runner import run_job
from saddlescope.services.jobs.stages import JobFenced
from saddlescope.services.results.documents import commit_result
from saddlescope.settings import load_settings
from saddlescope.storage import FileStorage

pg_database_url = integration_services.pg_database_url

ENGINES = ["sqlite", pytest.param("postgresql", marks=pytest.mark.integration)]


@pytest.fixture(params=ENGINES)
def setup(request, tmp_path):
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path / 'db.sqlite'}"
    else:
        url = request.getfixturevalue("pg_database_url")
    settings = load_settings(database_url=url, storage_dir=str(tmp_path / "storage"))
    upgrade_to_head(url)
    return settings, session_factory_for(url)


def _age(sessions, job_id: int, seconds: float) -> None:
    """Make a job's heartbeat `seconds` old: its worker went silent (cut off from the database)."""
    with session_scope(sessions) as s:
        s.execute(update(Job).where(Job.id == job_id).values(updated_at=utcnow() - dt.timedelta(seconds=seconds)))


def _taken_over(sessions, *, stale: str = "worker-a:1", fresh: str = "worker-b:2", **job) -> tuple[int, int, int]:
    """A job run by `stale` (attempt 1), silent too long, then taken over by `fresh` (attempt 2)."""
    with session_scope(sessions) as s:
        job_id = JobRepository(s).add(kind="selftest", **job).id
        first = JobRepository(s).mark_running(job_id, host=stale, code_version="t")
    _age(sessions, job_id, runner.STALE_AFTER_S + 60)
    with session_scope(sessions) as s:
        second = JobRepository(s).mark_running(job_id, host=fresh, code_version="t",
                                                stale_after_s=runner.STALE_AFTER_S)
    return job_id, first, second


def test_a_running_job_with_a_live_worker_is_not_taken_by_another(setup):
    _, sessions = setup
    with session_scope(sessions) as s:
        jobs = JobRepository(s)
        job_id = jobs.add(kind="selftest").id
        assert jobs.mark_running(job_id, host="worker-a:1", code_version="t") == 1
        assert jobs.mark_running(job_id, host="worker-b:2", code_version="t") is None  # default: fresh beat
        assert jobs.mark_running(job_id, host="worker-a:1", code_version="t") == 2  # its own retry


def test_a_stale_attempts_finish_progress_touch_and_timings_are_refused(setup):
    _, sessions = setup
    job_id, first, second = _taken_over(sessions)
    assert (first, second) == (1, 2)
    stale = {"attempt": first, "host": "worker-a:1"}
    with session_scope(sessions) as s:
        jobs = JobRepository(s)
        assert not jobs.set_progress(job_id, 0.9, "analyze", **stale)
        assert not jobs.touch(job_id, **stale)
        assert not jobs.set_timings(job_id, {"analyze": 1.0}, **stale)
        assert not jobs.finish(job_id, JobStatus.FAILED, error="late", **stale)
        assert not jobs.hold(job_id, **stale)
        # The same attempt number from another host is no better.
        assert not jobs.finish(job_id, JobStatus.DONE, attempt=second, host="worker-a:1")
    with session_scope(sessions) as s:
        job = s.get(Job, job_id)
        assert (job.status, job.host, job.attempts, job.progress, job.error) == (
            "running", "worker-b:2", 2, 0.0, None)
        assert job.timings == {}
    current = {"attempt": second, "host": "worker-b:2"}
    with session_scope(sessions) as s:
        jobs = JobRepository(s)
        assert jobs.set_progress(job_id, 0.5, "analyze", **current) and jobs.touch(job_id, **current)
        assert jobs.finish(job_id, JobStatus.DONE, **current)
        assert not jobs.finish(job_id, JobStatus.FAILED, **current)  # once


def test_a_stale_workers_run_stops_at_its_next_report_and_leaves_the_job_alone(setup, caplog):
    settings, sessions = setup
    with session_scope(sessions) as s:
        job_id = JobRepository(s).add(kind="selftest", payload={"steps": 40, "delay_s": 0.05}).id
    outcome: list[str] = []
    worker = threading.Thread(target=lambda: outcome.append(run_job(job_id, settings=settings)))
    with caplog.at_level(logging.WARNING, logger="saddlescope.services.jobs.runner"):
        worker.start()
        for _ in range(200):  # until the run has started
            with session_scope(sessions) as s:
                if s.get(Job, job_id).progress > 0:
                    break
            threading.Event().wait(0.02)
        # The worker is cut off for longer than the stale limit; another takes the job over.
        _age(sessions, job_id, runner.STALE_AFTER_S + 60)
        with session_scope(sessions) as s:
            assert JobRepository(s).mark_running(job_id, host="worker-b:2", code_version="t") == 2
        worker.join(timeout=30)
    assert outcome == [runner.FENCED]
    with session_scope(sessions) as s:
        job = s.get(Job, job_id)
        assert (job.status, job.host, job.attempts, job.finished_at) == ("running", "worker-b:2", 2, None)
    assert any("refused" in r.getMessage() and f"job {job_id}" in r.getMessage() for r in caplog.records)


def _ride(sessions) -> tuple[int, int]:
    from saddlescope.db.models import Club, Horse, Ride, Rider

    with session_scope(sessions) as s:
        club = Club(name="Fenced club")
        s.add(club)
        s.flush()
        horse, rider = Horse(club_id=club.id, name="H"), Rider(club_id=club.id, name="R")
        s.add_all([horse, rider])
        s.flush()
        ride = Ride(club_id=club.id, horse_id=horse.id, rider_id=rider.id, gait="walk", direction="CW")
        s.add(ride)
        s.flush()
        return club.id, ride.id


def test_two_workers_racing_to_store_one_jobs_result_leave_one_result(setup, caplog):
    settings, sessions = setup
    storage = FileStorage(settings.storage_dir)
    club_id, ride_id = _ride(sessions)
    job_id, first, second = _taken_over(sessions, ride_id=ride_id, club_id=club_id)
    workers = {"worker-a:1": first, "worker-b:2": second}
    outcomes: dict[str, object] = {}
    start = threading.Barrier(len(workers))

    def store(host: str) -> None:
        document = {"indicators": {"acc_y_wb_rms": 1.0 if host == "worker-a:1" else 2.0}}
        start.wait()
        try:
            outcomes[host] = commit_result(sessions, storage, club_id=club_id, ride_id=ride_id, job_id=job_id,
                                           document=document, code_version="t", attempt=workers[host], host=host)
        except JobFenced as exc:
            outcomes[host] = exc

    with caplog.at_level(logging.WARNING, logger="saddlescope.services.results.documents"):
        threads = [threading.Thread(target=store, args=(host,)) for host in workers]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(timeout=30)
    assert isinstance(outcomes["worker-a:1"], JobFenced)
    key = outcomes["worker-b:2"]
    assert isinstance(key, str) and f"/{job_id}-{second}-" in key
    with session_scope(sessions) as s:
        assert s.scalar(select(func.count()).select_from(Result).where(Result.ride_id == ride_id)) == 1
        result = s.scalars(select(Result).where(Result.ride_id == ride_id)).one()
        assert (result.result_key, result.acc_y_wb_rms, result.job_attempt) == (key, 2.0, second)
    # The stale attempt's document was removed again: only the stored result's remains.
    # the one stored result: its document, and the series and page derived from it beside it
    stem = key.removesuffix(".json")
    assert sorted(storage.iter_keys(f"rides/{ride_id}/results")) == sorted(
        [key, f"{stem}.page.json", f"{stem}.series.json"])
    assert any("refused" in r.getMessage() for r in caplog.records)


def test_two_workers_claiming_one_queued_job_at_once_get_one_attempt(setup):
    _, sessions = setup
    with session_scope(sessions) as s:
        job_id = JobRepository(s).add(kind="selftest").id
    claims: dict[str, int | None] = {}
    start = threading.Barrier(2)

    def claim(host: str) -> None:
        start.wait()
        for _ in range(50):  # SQLite answers "database is locked" to the loser now and then: ask again
            try:
                with session_scope(sessions) as s:
                    claims[host] = JobRepository(s).mark_running(job_id, host=host, code_version="t")
                return
            except Exception as exc:  # noqa: BLE001 (only the lock error is expected)
                if "locked" not in str(exc):
                    raise
                threading.Event().wait(0.05)

    threads = [threading.Thread(target=claim, args=(host,)) for host in ("worker-a:1", "worker-b:2")]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=30)
    assert sorted(claims.values(), key=lambda v: v or 0) == [None, 1]
    with session_scope(sessions) as s:
        assert s.get(Job, job_id).attempts == 1

"""A file store that does not answer is a passing failure (issue 26): the job goes back to the queue with
the reason, runs again after a pause and succeeds; after `STORE_ATTEMPTS` attempts it fails with the reason."""

from __future__ import annotations

import dataclasses

import integration_services
import pytest

from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job
from saddlescope.db.repositories import JobRepository
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.services.jobs import queue, runner
from saddlescope.services.jobs.runner import run_job
from saddlescope.settings import load_settings
from saddlescope.storage import StoreUnavailable

pg_database_url = integration_services.pg_database_url

ENGINES = ["sqlite", pytest.param("postgresql", marks=pytest.mark.integration)]
OUTAGE = "the file store is not answering (connection refused); try again in a moment"


@pytest.fixture(params=ENGINES)
def setup(request, tmp_path):
    url = f"sqlite:///{tmp_path / 'db.sqlite'}" if request.param == "sqlite" else request.getfixturevalue(
        "pg_database_url")
    upgrade_to_head(url)
    return load_settings(database_url=url, storage_dir=str(tmp_path / "storage")), session_factory_for(url)


def _store_down_for(monkeypatch, failures: int) -> dict:
    """The selftest stage meets a file store that does not answer `failures` times, then works."""
    real = runner.STAGES["selftest"]
    calls = {"n": 0}

    def flaky(ctx):
        calls["n"] += 1
        if calls["n"] <= failures:
            raise StoreUnavailable(OUTAGE)
        return real.run(ctx)

    monkeypatch.setitem(runner.STAGES, "selftest", dataclasses.replace(real, run=flaky))
    return calls


def _job(sessions) -> int:
    with session_scope(sessions) as s:
        return JobRepository(s).add(kind="selftest", payload={"steps": 2, "delay_s": 0.0}).id


def test_a_store_outage_queues_the_job_again_with_the_reason_then_it_succeeds(setup, monkeypatch):
    settings, sessions = setup
    _store_down_for(monkeypatch, failures=2)
    job_id = _job(sessions)
    assert run_job(job_id, settings=settings) == runner.RETRY
    with session_scope(sessions) as s:
        job = s.get(Job, job_id)
        assert (job.status, job.attempts, job.finished_at) == ("queued", 1, None)
        assert job.error == f"waiting to try again: selftest: {OUTAGE}"
    assert run_job(job_id, settings=settings) == runner.RETRY
    assert run_job(job_id, settings=settings) == "done"
    with session_scope(sessions) as s:
        job = s.get(Job, job_id)
        assert (job.status, job.attempts, job.error) == ("done", 3, None)


def test_a_store_that_stays_down_fails_the_job_with_the_reason(setup, monkeypatch):
    settings, sessions = setup
    _store_down_for(monkeypatch, failures=100)
    job_id = _job(sessions)
    outcomes = [run_job(job_id, settings=settings) for _ in range(runner.STORE_ATTEMPTS)]
    assert outcomes == [runner.RETRY] * (runner.STORE_ATTEMPTS - 1) + ["failed"]
    with session_scope(sessions) as s:
        job = s.get(Job, job_id)
        assert job.status == "failed" and OUTAGE in job.error and f"after {runner.STORE_ATTEMPTS} attempts" in job.error
    assert run_job(job_id, settings=settings) == "failed"  # a failed job is left alone


def test_the_inline_queue_runs_the_job_again_after_the_pause(setup, monkeypatch):
    settings, sessions = setup
    calls = _store_down_for(monkeypatch, failures=1)
    monkeypatch.setattr(runner, "STORE_RETRY_S", 0.01)
    job_id = _job(sessions)
    queue.InlineQueue(settings).submit(job_id)
    assert calls["n"] == 2
    with session_scope(sessions) as s:
        assert s.get(Job, job_id).status == "done"

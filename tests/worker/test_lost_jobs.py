"""Jobs whose worker died are found (a dead process on this machine, or no heartbeat for long) and queued
again; a running job writes a heartbeat while its stages run."""

from __future__ import annotations

import datetime as dt
import socket
import subprocess
import sys

import pytest

from saddlescope.db.enums import JobStatus
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job
from saddlescope.db.repositories import JobRepository
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.services import runner
from saddlescope.services.runner import job_is_lost, recover_lost_jobs, run_job
from saddlescope.settings import load_settings

NOW = dt.datetime(2026, 5, 1, 12, 0, tzinfo=dt.UTC)


@pytest.fixture
def dead_pid():
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


@pytest.fixture
def live_pid():
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    yield proc.pid
    proc.kill()
    proc.wait()


def test_lost_means_a_dead_local_process_or_a_silent_worker(dead_pid, live_pid):
    here = socket.gethostname()
    fresh, stale = NOW - dt.timedelta(seconds=5), NOW - dt.timedelta(seconds=runner.STALE_AFTER_S + 1)
    assert job_is_lost(f"{here}:{dead_pid}", fresh, now=NOW)
    assert not job_is_lost(f"{here}:{live_pid}", fresh, now=NOW)
    assert job_is_lost(f"{here}:{live_pid}", stale, now=NOW)  # alive but silent for too long (hung)
    assert not job_is_lost(f"other-machine:{dead_pid}", fresh, now=NOW)  # cannot see its processes
    assert job_is_lost("other-machine:1", stale, now=NOW)
    assert job_is_lost(None, None, now=NOW)


@pytest.fixture
def setup(tmp_path):
    settings = load_settings(
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "s")
    )
    upgrade_to_head(settings.database_url)
    return settings, session_factory_for(settings.database_url)


def test_recovery_queues_lost_jobs_again_and_leaves_the_others(setup, dead_pid, live_pid):
    _, sessions = setup
    here = socket.gethostname()
    with session_scope(sessions) as s:
        jobs = JobRepository(s)
        lost = jobs.add(kind="selftest").id
        alive = jobs.add(kind="selftest").id
        done = jobs.add(kind="selftest").id
        jobs.mark_running(lost, host=f"{here}:{dead_pid}", code_version="t")
        jobs.mark_running(alive, host=f"{here}:{live_pid}", code_version="t")
        jobs.mark_running(done, host=f"{here}:{dead_pid}", code_version="t")
        jobs.finish(done, JobStatus.DONE)
    submitted: list[int] = []
    assert recover_lost_jobs(sessions, submitted.append) == [lost] == submitted
    with session_scope(sessions) as s:
        assert s.get(Job, lost).status == "queued" and s.get(Job, lost).attempts == 1
        assert s.get(Job, alive).status == "running" and s.get(Job, done).status == "done"
    assert recover_lost_jobs(sessions, submitted.append) == []  # queued now: nothing more to do


def test_a_running_job_writes_a_heartbeat(setup, monkeypatch):
    settings, sessions = setup
    monkeypatch.setattr(runner, "HEARTBEAT_S", 0.1)
    monkeypatch.setattr(runner._Heartbeat.__init__, "__defaults__", (0.1,))
    beats = []
    real_touch = JobRepository.touch

    def touch(self, job_id):
        beats.append(job_id)
        real_touch(self, job_id)

    monkeypatch.setattr(JobRepository, "touch", touch)
    with session_scope(sessions) as s:
        # few progress reports over a long step: only the heartbeat says the worker is alive
        job_id = JobRepository(s).add(kind="selftest", payload={"steps": 1, "delay_s": 0.6}).id
    assert run_job(job_id, settings=settings) == "done"
    assert len(beats) >= 3 and set(beats) == {job_id}

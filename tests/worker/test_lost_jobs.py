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
from saddlescope.services.jobs import runner
from saddlescope.services.jobs.runner import job_is_lost, recover_lost_jobs, run_job
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
    settings = settings.model_copy(update={"heartbeat_s": 0.1})  # SADDLESCOPE_HEARTBEAT_S
    beats = []
    real_touch = JobRepository.touch

    def touch(self, job_id, **fence):
        beats.append(job_id)
        return real_touch(self, job_id, **fence)

    monkeypatch.setattr(JobRepository, "touch", touch)
    with session_scope(sessions) as s:
        # few progress reports over a long step: only the heartbeat says the worker is alive
        job_id = JobRepository(s).add(kind="selftest", payload={"steps": 1, "delay_s": 0.6}).id
    assert run_job(job_id, settings=settings) == "done"
    assert len(beats) >= 3 and set(beats) == {job_id}


def _age(sessions, job_id, seconds):
    """Make a job's last heartbeat `seconds` old (by the database's clock, which the test shares)."""
    from sqlalchemy import update

    from saddlescope.db.models import utcnow

    with session_scope(sessions) as s:
        s.execute(update(Job).where(Job.id == job_id).values(updated_at=utcnow() - dt.timedelta(seconds=seconds)))


def test_heartbeats_are_judged_by_the_database_clock_not_this_hosts(setup, monkeypatch):
    # Issue 25 item 6: a host whose clock runs an hour ahead took every live job for lost.
    from saddlescope.db.repositories import jobs as jobs_module

    _, sessions = setup
    with session_scope(sessions) as s:
        job_id = JobRepository(s).add(kind="selftest").id
        JobRepository(s).mark_running(job_id, host="other-machine:1", code_version="t")
    ahead = dt.datetime.now(dt.UTC) + dt.timedelta(hours=1)
    monkeypatch.setattr(runner, "utcnow", lambda: ahead)
    monkeypatch.setattr(jobs_module, "utcnow", lambda: ahead)
    assert recover_lost_jobs(sessions, lambda _: None) == []
    with session_scope(sessions) as s:
        assert s.get(Job, job_id).status == "running"


def test_a_job_that_keeps_losing_its_worker_is_failed_with_the_reason(setup):
    _, sessions = setup
    with session_scope(sessions) as s:
        jobs = JobRepository(s)
        job_id = jobs.add(kind="selftest").id
        for _ in range(runner.MAX_ATTEMPTS):
            jobs.mark_running(job_id, host="other-machine:1", code_version="t")
    _age(sessions, job_id, runner.STALE_AFTER_S + 60)
    submitted: list[int] = []
    assert recover_lost_jobs(sessions, submitted.append) == [] == submitted
    with session_scope(sessions) as s:
        job = s.get(Job, job_id)
        assert job.status == "failed" and "stopped (last heartbeat" in job.error
        assert f"attempt {runner.MAX_ATTEMPTS} of {runner.MAX_ATTEMPTS}" in job.error


def test_queued_jobs_the_broker_forgot_are_sent_again_once(setup):
    from saddlescope.services.jobs.runner import resend_queued_jobs

    settings, sessions = setup
    with session_scope(sessions) as s:
        jobs = JobRepository(s)
        held, forgotten, fresh, running = (jobs.add(kind="selftest", payload={"steps": 1, "delay_s": 0.0}).id
                                           for _ in range(4))
        jobs.mark_running(running, host="other-machine:1", code_version="t")
    for job_id in (held, forgotten, running):
        _age(sessions, job_id, 600)
    sent: list[int] = []
    assert resend_queued_jobs(sessions, sent.append, older_than_s=60, known={held}) == [forgotten] == sent
    assert resend_queued_jobs(sessions, sent.append, older_than_s=60, known={held}) == []  # its wait starts over
    # Sent twice anyway (two sweeps, a duplicate message): the job runs once.
    assert run_job(forgotten, settings=settings) == "done"
    assert run_job(forgotten, settings=settings) == "done"
    with session_scope(sessions) as s:
        assert s.get(Job, forgotten).attempts == 1


def test_a_copy_of_a_job_running_on_a_live_worker_does_not_run_it_again(setup):
    settings, sessions = setup
    with session_scope(sessions) as s:
        job_id = JobRepository(s).add(kind="selftest", payload={"steps": 1, "delay_s": 0.0}).id
        JobRepository(s).mark_running(job_id, host="other-machine:1", code_version="t")
    assert run_job(job_id, settings=settings) == "running"
    with session_scope(sessions) as s:
        job = s.get(Job, job_id)
        assert (job.status, job.host, job.attempts) == ("running", "other-machine:1", 1)


def test_each_host_has_its_own_name_and_only_its_own_pids_are_looked_up(dead_pid):
    # Hosts that share a host name but not their processes (network namespaces, cloned machines) are
    # told apart by SADDLESCOPE_HOST_NAME; another host's dead-looking pid says nothing here.
    w1 = load_settings(host_name="w1")
    assert runner.worker_host(w1).rpartition(":")[0] == "w1"
    fresh = NOW - dt.timedelta(seconds=5)
    assert job_is_lost(f"w1:{dead_pid}", fresh, now=NOW, here="w1")
    assert not job_is_lost(f"w1:{dead_pid}", fresh, now=NOW, here="w2")
    assert not job_is_lost(f"{socket.gethostname()}:{dead_pid}", fresh, now=NOW, here="w2")
    assert load_settings().resolved_host_name == socket.gethostname()


def test_the_stale_time_is_a_setting_and_recovery_uses_it(setup):
    _, sessions = setup
    quick = load_settings(stale_after_s=3)
    assert quick.stale_after_s == 3 and quick.resolved_heartbeat_s == 0.75  # a quarter of it
    assert load_settings().resolved_heartbeat_s == runner.HEARTBEAT_S
    with session_scope(sessions) as s:
        job_id = JobRepository(s).add(kind="selftest").id
        JobRepository(s).mark_running(job_id, host="other-machine:1", code_version="t")
    _age(sessions, job_id, 10)
    assert recover_lost_jobs(sessions, lambda _: None) == []  # 10 s is nothing against the default 180 s
    assert recover_lost_jobs(sessions, lambda _: None, stale_after_s=quick.stale_after_s) == [job_id]


def test_a_heartbeat_too_slow_for_the_stale_time_is_refused():
    from saddlescope.settings import ConfigurationError

    with pytest.raises(ConfigurationError, match="HEARTBEAT_S .* at most half of SADDLESCOPE_STALE_AFTER_S"):
        load_settings(stale_after_s=10, heartbeat_s=8)
    with pytest.raises(ConfigurationError, match="host_name"):
        load_settings(host_name="w1:7")

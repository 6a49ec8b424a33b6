"""The broker drill (issue 25, item 6): Redis restarted with nothing persisted loses no job.

The test starts its OWN redis-server on a free port (never the shared one), a real Celery worker
and the API, queues selftest jobs, restarts that Redis empty while jobs are queued and running,
and checks every job ends done or failed with a reason once the worker is back on the broker.
"""

from __future__ import annotations

import contextlib
import shutil
import socket
import subprocess
import time

import integration_services
import pytest
from fastapi.testclient import TestClient
from integration_services import new_club, require_service, run_celery_worker, stop_process

from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.settings import load_settings

pg_database_url = integration_services.pg_database_url

pytestmark = [pytest.mark.integration, pytest.mark.slow]

JOBS = 8
DEADLINE_S = 120.0  # the Done-when: every job ends within 2 minutes of a worker being available


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _start_redis(port: int, log_path) -> subprocess.Popen:
    binary = shutil.which("redis-server")
    if binary is None:
        require_service("redis-server", "no redis-server program on PATH to start a private Redis")
    with log_path.open("ab") as log:
        proc = subprocess.Popen([binary, "--port", str(port), "--bind", "127.0.0.1", "--save", "",
                                 "--appendonly", "no"], stdout=log, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), timeout=1) as s:
            s.sendall(b"PING\r\n")
            if s.recv(16).startswith(b"+PONG"):
                return proc
        if proc.poll() is not None:
            pytest.fail(f"redis-server exited with {proc.returncode}: {log_path.read_text()[-2000:]}")
        time.sleep(0.1)
    stop_process(proc)
    pytest.fail(f"redis-server on port {port} did not answer PING in 30 s")


def _statuses(api, job_ids) -> dict[int, dict]:
    return {job_id: api.ok("GET", f"/jobs/{job_id}") for job_id in job_ids}


def test_a_redis_restarted_empty_loses_no_job(pg_database_url, tmp_path):
    upgrade_to_head(pg_database_url)
    port = _free_port()
    broker_url = f"redis://127.0.0.1:{port}/0"
    redis_log = tmp_path / "redis.log"
    redis = _start_redis(port, redis_log)
    settings = load_settings(database_url=pg_database_url, broker_url=broker_url,
                             storage_dir=str(tmp_path / "storage"), secret_key=integration_services.TEST_SECRET)
    # Short sweeps so the drill is quick; production defaults are 60 s and 120 s.
    fast_sweeps = {"SADDLESCOPE_RECOVERY_INTERVAL_S": "2", "SADDLESCOPE_REQUEUE_AFTER_S": "4"}
    try:
        with run_celery_worker(database_url=pg_database_url, broker_url=broker_url,
                               storage_dir=tmp_path / "storage", log_path=tmp_path / "worker.log",
                               extra_env=fast_sweeps), \
                TestClient(create_app(settings, open_registration=True)) as client:
            api, _ = new_club(client)
            job_ids = []
            for i in range(JOBS):
                payload = {"steps": 10, "delay_s": 0.2, "fail": i == JOBS - 1}  # one fails on purpose
                job_ids.append(api.ok("POST", "/jobs", 201, json={"kind": "selftest", "payload": payload})["id"])
            started = time.monotonic()
            while _statuses(api, job_ids[:1])[job_ids[0]]["status"] == "queued":
                if time.monotonic() - started > 60:
                    pytest.fail(f"the worker did not take job {job_ids[0]} in 60 s")
                time.sleep(0.1)  # the worker has taken the first job; the others wait in Redis
            before = _statuses(api, job_ids)
            redis.kill()  # SIGKILL: nothing persisted (--save "" --appendonly no)
            redis.wait(timeout=10)
            redis = _start_redis(port, redis_log)  # same port, empty
            back = time.monotonic()
            while time.monotonic() - back < DEADLINE_S:
                after = _statuses(api, job_ids)
                if all(job["status"] in ("done", "failed") for job in after.values()):
                    break
                time.sleep(0.5)
            elapsed_s = time.monotonic() - back
    finally:
        stop_process(redis)
    counts = {status: sum(job["status"] == status for job in after.values())
              for status in ("done", "failed", "queued", "running", "cancelled")}
    at_restart = {status: sum(job["status"] == status for job in before.values()) for status in ("queued", "running")}
    print(f"\nbroker drill: {JOBS} jobs; at the Redis restart {at_restart}; "
          f"{elapsed_s:.0f} s after it: {counts}")
    lost = {job_id: job["status"] for job_id, job in after.items() if job["status"] not in ("done", "failed")}
    assert not lost, f"jobs lost with the broker's data (still queued or running): {lost}"
    assert at_restart["queued"] >= 1, before  # the drill did restart Redis under queued jobs
    failed = {job_id: job["error"] for job_id, job in after.items() if job["status"] == "failed"}
    assert all(failed.values()), failed  # failed, always with a reason
    assert list(failed) == [job_ids[-1]] and "failed on request" in failed[job_ids[-1]]
    assert counts["done"] == JOBS - 1


def test_the_sweep_sees_which_jobs_a_redis_broker_holds(tmp_path):
    from saddlescope.services.jobs.queue import CeleryQueue, broker_job_ids

    port = _free_port()
    redis = _start_redis(port, tmp_path / "redis.log")
    try:
        settings = load_settings(database_url=f"sqlite:///{tmp_path / 'db.sqlite'}",
                                 broker_url=f"redis://127.0.0.1:{port}/0", storage_dir=str(tmp_path / "s"),
                                 secret_key=integration_services.TEST_SECRET)
        queue = CeleryQueue(settings)
        try:
            assert broker_job_ids(queue.app) == set()
            queue.submit(41)
            queue.submit(42)
            assert broker_job_ids(queue.app) == {41, 42}
        finally:
            queue.close()
    finally:
        stop_process(redis)
    assert broker_job_ids(queue.app) is None  # broker gone: unknown, never "holds nothing"

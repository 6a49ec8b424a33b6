"""`saddlescope serve` as a real process: health over HTTP, and jobs in both modes.

Embedded mode needs nothing but a free port. Celery mode (integration) runs the production shape:
`saddlescope serve` with `saddlescope worker` on PostgreSQL and Redis.
"""

from __future__ import annotations

import socket
import subprocess
import time
from pathlib import Path

import httpx
import integration_services
import pytest

from conftest import PROJECT_ROOT
from saddlescope.db.migrate import upgrade_to_head

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url

SADDLESCOPE = str(integration_services.VENV_BIN / "saddlescope")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start(args: list[str], env: dict, log_path: Path, cwd: Path) -> subprocess.Popen:
    with log_path.open("wb") as log:
        return subprocess.Popen([SADDLESCOPE, *args], cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT)


def wait_healthy(base: str, proc: subprocess.Popen, log_path: Path, timeout_s: float = 60.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"saddlescope serve exited with {proc.returncode}:\n{log_path.read_text()[-3000:]}")
        try:
            response = httpx.get(f"{base}/api/health", timeout=5)
        except httpx.TransportError:
            time.sleep(0.2)
            continue
        return response.json() | {"http_status": response.status_code}
    pytest.fail(f"saddlescope serve did not answer within {timeout_s} s:\n{log_path.read_text()[-3000:]}")


def sign_up(base: str) -> dict[str, str]:
    """Register a club (open: embedded mode, or the first club of a deployment) and sign in; headers."""
    account = {"club_name": "E2E riding club", "email": "admin@e2e.example", "password": "e2e password"}
    created = httpx.post(f"{base}/api/clubs", json=account, timeout=10)
    assert created.status_code == 201, created.text
    credentials = {"username": account["email"], "password": account["password"]}
    login = httpx.post(f"{base}/api/auth/login", data=credentials, timeout=10)
    assert login.status_code == 200, login.text
    return {"Authorization": f"Bearer {login.json()['access_token']}"}


def health_details(base: str, headers: dict[str, str]) -> dict:
    """The admins' health answer (paths, versions, mode); the public one says only ok or degraded."""
    response = httpx.get(f"{base}/api/health/details", headers=headers, timeout=10)
    assert response.status_code == 200, response.text
    return response.json()


def run_job_over_http(base: str, body: dict, timeout_s: float = 60.0, headers: dict | None = None) -> dict:
    headers = headers or sign_up(base)
    assert httpx.post(f"{base}/api/jobs", json=body, timeout=10).status_code == 401  # not signed in
    created = httpx.post(f"{base}/api/jobs", json=body, headers=headers, timeout=10)
    assert created.status_code == 201, created.text
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = httpx.get(f"{base}/api/jobs/{created.json()['id']}", headers=headers, timeout=10).json()
        if job["status"] in ("done", "failed", "cancelled"):
            return job
        time.sleep(0.1)
    pytest.fail(f"job not finished after {timeout_s} s: {job}")


@pytest.mark.slow
def test_serve_answers_health_with_every_part_ok_and_runs_a_job(tmp_path):
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    env = integration_services.service_env(
        database_url=f"sqlite:///{tmp_path / 'var' / 'db.sqlite'}", storage_dir=tmp_path / "var" / "storage"
    )
    env.pop("SADDLESCOPE_SECRET_KEY")  # embedded mode works with the development default
    log_path = tmp_path / "serve.log"
    proc = start(["serve", "--host", "127.0.0.1", "--port", str(port)], env, log_path, tmp_path)
    try:
        health = wait_healthy(base, proc, log_path)
        assert health["http_status"] == 200, health
        assert {name: part["status"] for name, part in health["parts"].items()} == {
            "database": "ok",
            "broker": "ok",
            "storage": "ok",
        }
        assert health["summary"] == "Service OK" and "mode" not in health
        headers = sign_up(base)
        details = health_details(base, headers)
        assert details["mode"] == "embedded" and details["parts"]["broker"]["detail"].startswith("embedded")
        job = run_job_over_http(base, {"kind": "selftest", "payload": {"steps": 4, "delay_s": 0.05}},
                                headers=headers)
        assert job["status"] == "done" and job["progress"] == 1.0 and job["timings_s"]["selftest"] >= 0.2
        page = httpx.get(f"{base}/", timeout=10)
        assert page.status_code == 200 and "<title>SaddleScope</title>" in page.text
    finally:
        integration_services.stop_process(proc)
    # a clean shutdown on SIGTERM (uvicorn re-raises the signal after shutting down gracefully)
    assert proc.returncode in (0, -15) and "Finished server process" in log_path.read_text()


@pytest.mark.slow
@pytest.mark.integration
def test_serve_with_saddlescope_workers_on_postgresql_and_redis(
    request, tmp_path, pg_database_url, redis_url
):
    upgrade_to_head(pg_database_url)  # the compose file's one-shot `migrate` service
    env = integration_services.service_env(
        database_url=pg_database_url, storage_dir=tmp_path / "storage", broker_url=redis_url
    )
    worker_log, serve_log = tmp_path / "worker.log", tmp_path / "serve.log"
    worker = start(["worker"], env, worker_log, PROJECT_ROOT)
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    server = start(["serve", "--host", "127.0.0.1", "--port", str(port)], env, serve_log, tmp_path)
    try:
        deadline = time.monotonic() + 90
        while b" ready." not in worker_log.read_bytes():
            assert worker.poll() is None, worker_log.read_text()[-3000:]
            assert time.monotonic() < deadline, worker_log.read_text()[-3000:]
            time.sleep(0.2)
        health = wait_healthy(base, server, serve_log)
        assert health["http_status"] == 200 and health["summary"] == "Service OK", health
        headers = sign_up(base)
        assert health_details(base, headers)["mode"] == "celery"
        integration_services.report_service(
            request.config,
            f"`saddlescope serve` + `saddlescope worker` processes (pids {server.pid}, {worker.pid})",
        )
        job = run_job_over_http(base, {"kind": "selftest", "payload": {"steps": 3, "delay_s": 0.05}},
                                headers=headers)
        assert job["status"] == "done" and set(job["timings_s"]) == {"selftest", "total"}, job
    finally:
        integration_services.stop_process(server)
        integration_services.stop_process(worker, timeout_s=30)

"""Celery mode end to end: the API on PostgreSQL queues jobs over Redis to a real worker process."""

from __future__ import annotations

import time

import integration_services
import pytest
from fastapi.testclient import TestClient
from integration_services import new_club, poll_job

from saddlescope.api import create_app
from saddlescope.db.session import session_factory_for
from saddlescope.services.jobs.queue import CeleryQueue
from saddlescope.services.rides.registration import register_bundle
from saddlescope.settings import load_settings
from saddlescope.storage import open_storage

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url
celery_worker = integration_services.celery_worker

pytestmark = [pytest.mark.integration, pytest.mark.slow]


@pytest.fixture(scope="module")
def api(celery_worker, tmp_path_factory):
    settings = load_settings(
        database_url=celery_worker["database_url"],
        broker_url=celery_worker["broker_url"],
        storage_dir=str(celery_worker["storage_dir"]),
        secret_key=integration_services.TEST_SECRET,
    )
    bundle = integration_services.write_tiny_bundle(tmp_path_factory.mktemp("bundle") / "ride")
    with TestClient(create_app(settings, open_registration=True)) as client:
        api, account = new_club(client)
        ride_id = register_bundle(
            session_factory_for(settings.database_url), open_storage(settings), bundle,
            club_id=account["club"]["id"],
        )
        yield api, ride_id, celery_worker


def wait_done(client, job_id, timeout_s=60.0):
    return poll_job(lambda: client.get(f"/jobs/{job_id}").json(), job_id, timeout_s=timeout_s)


def test_health_is_ok_with_postgresql_redis_and_storage(api):
    client, _, _ = api
    assert client.client.get("/api/health").json()["summary"] == "Service OK"
    health = client.ok("GET", "/health/details")  # the details: admins only
    assert health["status"] == "ok" and health["mode"] == "celery", health
    assert health["parts"]["database"]["detail"].startswith("postgresql")
    assert "redis" in health["parts"]["broker"]["detail"]


def test_probe_job_runs_on_the_celery_worker(api):
    client, ride_id, worker = api
    response = client.post("/jobs", json={"kind": "probe", "ride_id": ride_id})
    assert response.status_code == 201, response.text
    job, _ = wait_done(client, response.json()["id"])
    assert job["status"] == "done", job["error"]
    assert job["progress"] == 1.0 and set(job["timings_s"]) == {"probe", "total"}
    # run by the worker process, not by this test process
    assert job["host"].endswith(f":{worker['process'].pid}")


def test_selftest_progress_is_readable_through_the_api(api):
    client, _, _ = api
    job_id = client.post(
        "/jobs", json={"kind": "selftest", "payload": {"steps": 10, "delay_s": 0.15}}
    ).json()["id"]
    job, seen = wait_done(client, job_id)
    assert job["status"] == "done" and job["timings_s"]["selftest"] >= 1.0
    assert any(v["status"] == "running" and 0 < v["progress"] < 1 for v in seen), seen


def test_a_job_delivered_twice_runs_once(api):
    client, _, worker = api
    job_id = client.post(
        "/jobs", json={"kind": "selftest", "payload": {"steps": 2, "delay_s": 0.05}}
    ).json()["id"]
    wait_done(client, job_id)
    queue = CeleryQueue(client.client.app.state.settings)
    try:
        queue.submit(job_id)  # as if the broker redelivered it
    finally:
        queue.close()
    time.sleep(1.0)
    job = client.get(f"/jobs/{job_id}").json()
    assert job["status"] == "done" and job["attempts"] == 1

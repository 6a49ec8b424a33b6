"""The API in embedded mode: jobs run in the real local process pool; progress is read back over HTTP."""

from __future__ import annotations

import datetime as dt
import time

import integration_services
import pytest
from api_helpers import Api, new_club
from fastapi.testclient import TestClient
from integration_services import poll_job

from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.repositories import JobRepository
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.services.rides.registration import register_bundle
from saddlescope.settings import load_settings
from saddlescope.storage import open_storage


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    """One app (and one pool process) for the module; SQLite and storage in a temporary folder."""
    root = tmp_path_factory.mktemp("api")
    settings = load_settings(
        database_url=f"sqlite:///{root / 'db.sqlite'}", storage_dir=str(root / "storage")
    )
    with TestClient(create_app(settings)) as client:  # the lifespan migrates (embedded mode)
        api, account = new_club(client)
        ride_id = register_bundle(
            session_factory_for(settings.database_url),
            open_storage(settings),
            integration_services.write_tiny_bundle(root / "bundle"),
            club_id=account["club"]["id"],
        )
        yield api, ride_id


def wait_done(client: Api, job_id: int, timeout_s: float = 60.0) -> tuple[dict, list[dict]]:
    """Poll GET /api/jobs/{id} until finished; returns the last view and every view seen."""
    def view() -> dict:
        response = client.get(f"/jobs/{job_id}")
        assert response.status_code == 200
        return response.json()

    return poll_job(view, job_id, timeout_s=timeout_s)


def test_health_reports_each_part_ok_and_the_embedded_broker(env):
    client, _ = env
    response = client.client.get("/api/health")
    assert response.status_code == 200 and response.json()["summary"] == "Service OK"
    health = client.ok("GET", "/health/details")  # the details: admins only
    assert health["status"] == "ok" and health["mode"] == "embedded"
    assert {name: part["status"] for name, part in health["parts"].items()} == {
        "database": "ok",
        "broker": "ok",
        "storage": "ok",
    }
    assert health["parts"]["broker"]["detail"].startswith("embedded")
    assert "schema at revision" in health["parts"]["database"]["detail"]


def test_probe_job_runs_in_the_pool_with_progress_and_timings(env):
    client, ride_id = env
    response = client.post("/jobs", json={"kind": "probe", "ride_id": ride_id})
    assert response.status_code == 201, response.text
    created = response.json()
    assert created["status"] == "queued" and created["ride_id"] == ride_id
    job, _ = wait_done(client, created["id"])
    assert job["status"] == "done", job["error"]
    assert job["progress"] == 1.0 and job["attempts"] == 1
    assert set(job["timings_s"]) == {"probe", "total"} and job["timings_s"]["probe"] > 0
    assert job["host"] and job["started_at"] and job["finished_at"]


def test_selftest_progress_is_visible_while_running(env):
    client, _ = env
    job_id = client.post(
        "/jobs", json={"kind": "selftest", "payload": {"steps": 12, "delay_s": 0.15}}
    ).json()["id"]
    job, seen = wait_done(client, job_id)
    assert job["status"] == "done"
    running = [v["progress"] for v in seen if v["status"] == "running"]
    assert any(0 < p < 1 for p in running), seen  # intermediate progress was readable
    assert running == sorted(running)
    assert any((v["stage"] or "").startswith("selftest: step") for v in seen)


def test_a_failing_job_reports_its_error(env):
    client, _ = env
    job_id = client.post(
        "/jobs", json={"kind": "selftest", "payload": {"steps": 1, "fail": True}}
    ).json()["id"]
    job, _ = wait_done(client, job_id)
    assert job["status"] == "failed" and "failed on request" in job["error"]


def test_cancel_a_queued_job(env):
    client, _ = env
    # a long job occupies the single pool process, so the second one is still queued when cancelled
    blocker = client.post(
        "/jobs", json={"kind": "selftest", "payload": {"steps": 20, "delay_s": 0.05}}
    ).json()
    queued = client.post("/jobs", json={"kind": "selftest", "payload": {"steps": 1}}).json()
    cancelled = client.post(f"/jobs/{queued['id']}/cancel")
    assert cancelled.status_code == 200 and cancelled.json()["status"] == "cancelled"
    wait_done(client, blocker["id"])
    assert client.get(f"/jobs/{queued['id']}").json()["status"] == "cancelled"  # never started
    assert client.get(f"/jobs/{queued['id']}").json()["attempts"] == 0


@pytest.mark.parametrize(
    ("body", "status", "message"),
    [
        ({"kind": "fly"}, 422, "unknown job kind 'fly'"),
        ({"kind": "probe", "ride_id": 999}, 404, "ride 999 not found"),
        ({"kind": "selftest", "payload": {"steps": 0}}, 422, "steps must be an integer from 1 to 1000"),
        ({"kind": "selftest", "surprise": 1}, 422, "surprise"),
    ],
)
def test_bad_job_requests_are_refused_with_a_reason(env, body, status, message):
    client, _ = env
    response = client.post("/jobs", json=body)
    assert response.status_code == status
    assert message in response.text


def test_unknown_job_is_404(env):
    client, _ = env
    response = client.get("/jobs/987654")
    assert response.status_code == 404 and response.json() == {"detail": "job 987654 not found"}


def test_job_kinds_are_listed(env):
    client, _ = env
    kinds = {k["name"]: k["stages"] for k in client.get("/jobs/kinds").json()}
    assert kinds["analyze"] == ["probe", "assemble", "calibrate", "analyze"] and kinds["probe"] == ["probe"]
    assert kinds["calibrate_rig"] == ["probe", "calibrate_rig"]


def test_openapi_docs_and_dashboard_are_served(env):
    api, _ = env
    client = api.client
    assert client.get("/docs").status_code == 200
    paths = client.get("/openapi.json").json()["paths"]
    assert {"/api/health", "/api/jobs", "/api/jobs/{job_id}", "/api/rides/{ride_id}/result",
            "/api/leaderboard", "/api/uploads/{upload_id}"} <= set(paths)
    page = client.get("/")
    assert page.status_code == 200 and "<title>SaddleScope</title>" in page.text


def test_an_embedded_server_resumes_jobs_a_stopped_server_left_unfinished(tmp_path):
    settings = load_settings(
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "s")
    )
    upgrade_to_head(settings.database_url)
    with session_scope(session_factory_for(settings.database_url)) as s:
        jobs = JobRepository(s)
        queued = jobs.add(kind="selftest", payload={"steps": 1, "delay_s": 0.0}).id
        running = jobs.add(kind="selftest", payload={"steps": 1, "delay_s": 0.0}).id
        jobs.mark_running(running, host="old-server:1", code_version="old")
    sessions = session_factory_for(settings.database_url)
    with TestClient(create_app(settings)):
        # system jobs (no club) are not visible through the API: read them from the database
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            with session_scope(sessions) as s:
                jobs = JobRepository(s)
                first, second = jobs.get(queued), jobs.get(running)
                if first.status == second.status == "done":
                    break
            time.sleep(0.1)
    assert first.status == second.status == "done"
    assert (first.attempts, second.attempts) == (1, 2) and second.host != "old-server:1"


class _NoWorkers:
    """A Celery-like queue that takes jobs but has no worker alive (pings answered by nobody)."""

    mode = "celery"

    def submit(self, job_id: int) -> None:
        pass

    def health(self) -> tuple[bool, str]:
        return True, "test: no workers"

    def workers_alive(self) -> int:
        return 0

    def close(self) -> None:
        pass


def test_a_job_says_it_waits_for_a_worker_when_none_is_alive(tmp_path):
    # Issue 25 item 6: with no worker alive a job said "queued" (or "running") forever.
    from sqlalchemy import update

    from saddlescope.db.models import Job
    from saddlescope.db.models import utcnow as now
    from saddlescope.services.jobs.runner import STALE_AFTER_S

    settings = load_settings(
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "s"))
    with TestClient(create_app(settings, queue=_NoWorkers())) as client:
        api, _ = new_club(client)
        queued = api.ok("POST", "/jobs", 201, json={"kind": "selftest"})["id"]
        stopped = api.ok("POST", "/jobs", 201, json={"kind": "selftest"})["id"]
        view = api.ok("GET", f"/jobs/{queued}")
        assert view["status"] == "queued" and view["note"].startswith("waiting for a worker: no worker")
        sessions = session_factory_for(settings.database_url)
        with session_scope(sessions) as s:
            JobRepository(s).mark_running(stopped, host="gone-machine:7", code_version="t")
        # a worker beating on a job is alive even when it cannot answer a ping (solo pool)
        assert api.ok("GET", f"/jobs/{queued}")["note"] is None
        assert api.ok("GET", f"/jobs/{stopped}")["note"] is None
        with session_scope(sessions) as s:
            s.execute(update(Job).where(Job.id == stopped).values(
                updated_at=now() - dt.timedelta(seconds=STALE_AFTER_S + 30)))
        view = api.ok("GET", f"/jobs/{stopped}")
        assert view["status"] == "running" and "gone-machine:7 sent no heartbeat for" in view["note"]
        assert api.ok("GET", f"/jobs/{queued}")["note"].startswith("waiting for a worker")

"""/api/health says in one line which part is broken (no paths or versions: those are in
/api/health/details, for admins only); a dead broker refuses jobs with 503 (no services needed)."""

from __future__ import annotations

import integration_services
import pytest
from api_helpers import add_member, new_club, settings_for
from fastapi.testclient import TestClient

from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job
from saddlescope.db.session import engine_for, session_factory_for
from saddlescope.services.health import check_database

DEAD_BROKER = "redis://127.0.0.1:1/0"  # port 1: nothing listens there


def test_unreachable_broker_is_reported_and_refuses_jobs(tmp_path):
    settings = settings_for(tmp_path, broker_url=DEAD_BROKER)
    upgrade_to_head(settings.database_url)  # with a broker the server does not migrate by itself
    with TestClient(create_app(settings)) as client:
        response = client.get("/api/health")
        assert response.status_code == 503
        public = response.json()
        assert public["summary"] == ("Service degraded: the job queue does not answer, so new analyses "
                                     "cannot start")
        assert {name: part["ok"] for name, part in public["parts"].items()} == {
            "database": True, "broker": False, "storage": True}
        assert "redis://" not in response.text and str(tmp_path) not in response.text
        api, _ = new_club(client)  # the first club of a deployment may register
        parts = api.ok("GET", "/health/details")["parts"]
        assert parts["database"]["ok"] and parts["storage"]["ok"]
        assert (
            not parts["broker"]["ok"]
            and "broker unreachable at redis://127.0.0.1:1/0" in parts["broker"]["detail"]
        )
        refused = api.post("/jobs", json={"kind": "selftest"})
        assert refused.status_code == 503 and "broker is unreachable" in refused.json()["detail"]
    with session_factory_for(settings.database_url)() as s:
        assert s.query(Job).count() == 0  # a job the broker refused is not kept (issue 39 item 8)


def test_database_behind_the_migrations_is_reported(tmp_path):
    settings = settings_for(tmp_path, auto_migrate=False)
    with TestClient(create_app(settings)) as client:
        response = client.get("/api/health")
    assert response.status_code == 503
    assert response.json()["summary"].startswith("Service degraded: the database does not answer or is not up")
    assert "alembic" not in response.text  # the operator's fix is a detail, for admins
    ok, detail = check_database(engine_for(settings.database_url))
    assert not ok and "run `alembic upgrade head`" in detail


def test_unwritable_storage_is_reported_to_admins_only(tmp_path):
    (tmp_path / "a-file").write_text("not a folder")
    settings = settings_for(tmp_path, storage_dir=str(tmp_path / "a-file"))
    with TestClient(create_app(settings)) as client:
        response = client.get("/api/health")
        assert response.status_code == 503 and "a-file" not in response.text
        assert "the file storage cannot be written" in response.json()["summary"]
        admin, _ = new_club(client)
        member, _ = add_member(admin)
        refused = member.get("/health/details")
        assert refused.status_code == 403 and "a-file" not in refused.text
        assert client.get("/api/health/details").status_code == 401
        storage = admin.ok("GET", "/health/details")["parts"]["storage"]
    assert not storage["ok"] and "a-file" in storage["detail"]


def test_the_public_answer_never_names_the_storage_folder_or_the_versions(tmp_path):
    settings = settings_for(tmp_path)
    with TestClient(create_app(settings)) as client:
        public = client.get("/api/health")
        admin, _ = new_club(client)
        details = admin.ok("GET", "/health/details")
    assert public.status_code == 200
    answer = public.json()
    assert answer["parts"]["storage"].pop("free_bytes") > 0  # the folder's free space, not its path
    assert answer == {"status": "ok", "summary": "Service OK", "parts": {
        name: {"ok": True, "status": "ok"} for name in ("database", "broker", "storage")}}
    assert str(tmp_path) not in public.text and "sqlite" not in public.text
    assert details["summary"] == "Service OK" and details["mode"] == "embedded" and details["version"]
    assert str(tmp_path / "storage") in details["parts"]["storage"]["detail"]


def test_missing_services_skip_or_fail_by_ci(monkeypatch):
    monkeypatch.setattr(integration_services, "IN_CI", False)
    with pytest.raises(pytest.skip.Exception, match="set CI=true to make this a failure"):
        integration_services.require_service("Redis", "connection refused")
    monkeypatch.setattr(integration_services, "IN_CI", True)
    with pytest.raises(pytest.fail.Exception, match="CI=true requires it"):
        integration_services.require_service("Redis", "connection refused")


def test_concurrent_health_probes_never_fail_on_a_healthy_service(tmp_path):
    # Issue 25 item 7: 50 probes at once used to share one probe file (".health-<pid>"), so one
    # probe deleted the file another was reading and /api/health answered a false 503.
    from concurrent.futures import ThreadPoolExecutor

    settings = settings_for(tmp_path)
    with TestClient(create_app(settings)) as client, ThreadPoolExecutor(max_workers=16) as pool:
        answers = list(pool.map(lambda _: client.get("/api/health"), range(50)))
    failed = [(r.status_code, r.json()["parts"]) for r in answers if r.status_code != 200]
    assert not failed, failed
    leftovers = [p.name for p in (tmp_path / "storage").iterdir() if p.name.startswith(".health")]
    assert not leftovers, leftovers

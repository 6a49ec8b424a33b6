"""/api/health names the part that is broken; a dead broker refuses jobs with 503 (no services needed)."""

from __future__ import annotations

import integration_services
import pytest
from api_helpers import new_club
from fastapi.testclient import TestClient

from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job
from saddlescope.db.session import session_factory_for
from saddlescope.settings import load_settings

DEAD_BROKER = "redis://127.0.0.1:1/0"  # port 1: nothing listens there


def settings_for(tmp_path, **overrides):
    values = {
        "database_url": f"sqlite:///{tmp_path / 'db.sqlite'}",
        "storage_dir": str(tmp_path / "storage"),
        "secret_key": "a-test-secret-of-enough-length",
    }
    values.update(overrides)
    return load_settings(**values)


def test_unreachable_broker_is_reported_and_refuses_jobs(tmp_path):
    settings = settings_for(tmp_path, broker_url=DEAD_BROKER)
    upgrade_to_head(settings.database_url)  # with a broker the server does not migrate by itself
    with TestClient(create_app(settings)) as client:
        response = client.get("/api/health")
        assert response.status_code == 503
        parts = response.json()["parts"]
        assert parts["database"]["ok"] and parts["storage"]["ok"]
        assert (
            not parts["broker"]["ok"]
            and "broker unreachable at redis://127.0.0.1:1/0" in parts["broker"]["detail"]
        )
        api, _ = new_club(client)  # the first club of a deployment may register
        refused = api.post("/jobs", json={"kind": "selftest"})
        assert refused.status_code == 503 and "broker is unreachable" in refused.json()["detail"]
    with session_factory_for(settings.database_url)() as s:
        job = s.query(Job).one()  # committed first, then marked failed with the reason
        assert job.status == "failed" and "broker is unreachable" in job.error


def test_database_behind_the_migrations_is_reported(tmp_path):
    settings = settings_for(tmp_path, auto_migrate=False)
    with TestClient(create_app(settings)) as client:
        response = client.get("/api/health")
    assert response.status_code == 503
    database = response.json()["parts"]["database"]
    assert not database["ok"] and "run `alembic upgrade head`" in database["detail"]


def test_unwritable_storage_is_reported(tmp_path):
    (tmp_path / "a-file").write_text("not a folder")
    settings = settings_for(tmp_path, storage_dir=str(tmp_path / "a-file"))
    with TestClient(create_app(settings)) as client:
        response = client.get("/api/health")
    storage = response.json()["parts"]["storage"]
    assert response.status_code == 503 and not storage["ok"] and "a-file" in storage["detail"]


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

"""Schemathesis against the OpenAPI schema of the app (in-process ASGI), signed in: no answer is a 5xx.

Every operation gets a bounded number of generated requests (`MAX_EXAMPLES`), so the whole run stays
well under two minutes. Ids of real rows exist (a ride, a horse, ...) so some requests get past the
lookups, and the signed-in admin is not user 1 (generated ids like 1 would otherwise let a request
deactivate the caller half-way).
"""

from __future__ import annotations

import integration_services
import pytest
import schemathesis
from hypothesis import HealthCheck, given, settings
from integration_services import add_member, new_club

from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.settings import load_settings

MAX_EXAMPLES = 20
# The body of a resumable-upload chunk is raw bytes, as application/octet-stream.
schemathesis.serializer.alias("application/offset+octet-stream", "application/octet-stream")

pytestmark = pytest.mark.slow
pg_database_url = integration_services.pg_database_url


@pytest.fixture(scope="module", params=["sqlite", pytest.param("postgresql", marks=pytest.mark.integration)])
def app_and_token(request, tmp_path_factory):
    from api_helpers import ThreadQueue, standin_installed
    from fastapi.testclient import TestClient

    root = tmp_path_factory.mktemp("schemathesis")
    database_url = (
        f"sqlite:///{root / 'db.sqlite'}"
        if request.param == "sqlite"
        else request.getfixturevalue("pg_database_url")
    )  # PostgreSQL refuses what SQLite takes
    app_settings = load_settings(
        database_url=database_url, storage_dir=str(root / "storage"), max_upload_bytes=4 * 1024**2
    )
    upgrade_to_head(app_settings.database_url)
    with standin_installed():
        app = create_app(app_settings, queue=ThreadQueue(app_settings), open_registration=True)
        with TestClient(app) as client:
            for _ in range(3):
                other, _ = new_club(client)
                add_member(other)
            admin, _ = new_club(client)
            horse = admin.ok("POST", "/horses", 201, json={"name": "Fuzzy"})
            rider = admin.ok("POST", "/riders", 201, json={"name": "Fuzzer"})
            admin.ok(
                "POST",
                "/rides",
                201,
                json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk", "direction": "CW"},
            )
            admin.ok("POST", "/rigs", 201, json={"name": "Fuzz rig"})
            yield app, admin.headers


def test_no_request_makes_the_server_fail(app_and_token):
    # Driven by hand (one Hypothesis run per operation) rather than with schemathesis.pytest, whose lazy
    # schema fixture does not work with this pytest version.
    app, headers = app_and_token
    schema = schemathesis.openapi.from_asgi("/openapi.json", app)
    failures, operations = [], 0
    # Routes that end the admin's sessions (logout everywhere, password change or reset) run last, so
    # the others are fuzzed signed in.
    ending = ("/api/auth/logout-everywhere", "/api/auth/password", "/api/users/{user_id}/password-reset")
    for operation in sorted((r.ok() for r in schema.get_all_operations()), key=lambda op: op.path in ending):
        operations += 1

        @given(case=operation.as_strategy())
        @settings(
            max_examples=MAX_EXAMPLES,
            deadline=None,
            derandomize=True,
            database=None,
            suppress_health_check=list(HealthCheck),
        )
        def run(case) -> None:
            response = case.call(headers={**(case.headers or {}), **headers})
            if response.status_code >= 500:
                failures.append(
                    f"{case.method} {case.formatted_path} -> {response.status_code}: {response.text[:300]}"
                )
            assert response.status_code < 500

        try:
            run()
        except AssertionError:
            pass  # recorded above, with the request; go on with the other operations
    assert operations > 40
    assert not failures, "\n".join(failures)

"""Schemathesis against the SERVED API: a real ``saddlescope serve`` process over HTTP, signed in, with the
server-error, status-code and response-schema checks on (issue 25).

The server is `saddlescope.bench.service.bench_server` (embedded mode, a throw-away folder). The fuzzing
admin registers a club of their own (not user 1, whom generated ids would otherwise deactivate half-way);
routes that end the admin's sessions run last. `MAX_EXAMPLES` per operation keeps the run near 2 minutes.
"""

from __future__ import annotations

import httpx
import pytest
import schemathesis
from hypothesis import HealthCheck, given, settings
from schemathesis.checks import not_a_server_error
from schemathesis.specs.openapi.checks import response_schema_conformance, status_code_conformance

from saddlescope.bench.service import bench_server, prepare_database

MAX_EXAMPLES = 20
CHECKS = [not_a_server_error, status_code_conformance, response_schema_conformance]
ENDING = ("/api/auth/logout-everywhere", "/api/auth/password", "/api/users/{user_id}/password-reset")
schemathesis.serializer.alias("application/offset+octet-stream", "application/octet-stream")

pytestmark = [pytest.mark.slow]


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    root = tmp_path_factory.mktemp("schemathesis-http")
    with bench_server(root, prepare_database(root), max_upload_bytes=4 * 1024**2) as server:
        base = server.base_url
        account = {"club_name": "Fuzz club", "email": "fuzz@club.example", "password": "fuzz password 1"}
        httpx.post(f"{base}/api/clubs", json=account, timeout=60).raise_for_status()
        token = httpx.post(f"{base}/api/auth/login", timeout=60,
                           data={"username": account["email"], "password": account["password"]}).json()
        headers = {"Authorization": f"Bearer {token['access_token']}"}
        with httpx.Client(base_url=f"{base}/api", headers=headers, timeout=60) as api:
            horse = api.post("/horses", json={"name": "Fuzzy"}).json()
            rider = api.post("/riders", json={"name": "Fuzzer"}).json()
            api.post("/rides", json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                     "direction": "CW"}).raise_for_status()
            api.post("/rigs", json={"name": "Fuzz rig"}).raise_for_status()
        yield base, headers


def test_the_served_api_keeps_its_schema_and_status_codes(served):
    base, headers = served
    schema = schemathesis.openapi.from_url(f"{base}/openapi.json")
    failures, operations = [], 0
    for operation in sorted((r.ok() for r in schema.get_all_operations()), key=lambda op: op.path in ENDING):
        operations += 1

        @given(case=operation.as_strategy())
        @settings(max_examples=MAX_EXAMPLES, deadline=None, derandomize=True, database=None,
                  suppress_health_check=list(HealthCheck))
        def run(case) -> None:
            try:
                case.call_and_validate(base_url=base, headers={**(case.headers or {}), **headers}, checks=CHECKS)
            except AssertionError as exc:
                failures.append(f"{case.method} {case.formatted_path}: {str(exc)[:400]}")
                raise

        try:
            run()
        except AssertionError:
            pass  # recorded above, with the request; go on with the other operations
        except Exception as exc:  # noqa: BLE001  schemathesis groups its failures in its own exceptions
            failures.append(f"{operation.method.upper()} {operation.path}: {type(exc).__name__}: {str(exc)[:400]}")
    assert operations > 40
    assert not failures, f"{len(failures)} operations failed:\n" + "\n\n".join(failures)

"""A part that does not answer is 503 with Retry-After and a sentence on every route; a full disk is 507.

No services needed: the database is a PostgreSQL address nobody listens on, the disk is full at the OS
call (the writer's file is /dev/full, so `write` fails with ENOSPC in the kernel), the broker and store
errors are their drivers' own exception types. The fault drill against real services that are stopped
is tests/api/test_api_fault_drill.py.
"""

from __future__ import annotations

import errno
import hashlib
import io
import os
import socket
import zipfile
from pathlib import Path

import botocore.exceptions
import kombu.exceptions
import pytest
import redis.exceptions
import sqlalchemy.exc
from api_helpers import FullDisk, new_club, settings_for
from fastapi.testclient import TestClient

from saddlescope.api import create_app
from saddlescope.api.outages import BROKER_DOWN, DATABASE_DOWN, DISK_FULL, STORE_DOWN, outage_of
from saddlescope.db.session import make_engine, make_session_factory


def dead_port() -> int:
    with socket.socket() as sock:  # a port nobody listens on once closed
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture
def app_client(tmp_path):
    with TestClient(create_app(settings_for(tmp_path)), raise_server_exceptions=False) as client:
        api, _ = new_club(client)
        yield client, api


@pytest.fixture
def full_disk(monkeypatch):
    return FullDisk().install(monkeypatch)


def new_ride(api, name: str) -> dict:
    horse = api.ok("POST", "/horses", 201, json={"name": name})
    rider = api.ok("POST", "/riders", 201, json={"name": name})
    return api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                               "direction": "CCW"})


def assert_outage(response, outage) -> None:
    assert response.status_code == outage.status_code, (response.status_code, response.text)
    assert response.json()["detail"] == outage.detail
    if outage.retry_after_s:
        assert response.headers["Retry-After"] == str(outage.retry_after_s)


def part_files(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if p.name.startswith(".part-")]


def stored_files(root: Path) -> dict[str, str]:
    """Each stored file's sha256 by its path in the store (empty folders are no data)."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in root.rglob("*") if p.is_file()}


def test_a_database_that_does_not_answer_is_503_on_every_kind_of_route(app_client):
    client, api = app_client
    app = client.app
    dead = make_engine(f"postgresql+psycopg://nobody@127.0.0.1:{dead_port()}/gone?connect_timeout=2")
    saved = app.state.engine, app.state.sessions
    app.state.engine, app.state.sessions = dead, make_session_factory(dead)
    try:
        for method, path, kwargs in [("GET", "/rides", {}), ("GET", "/horses", {}),
                                     ("POST", "/horses", {"json": {"name": "Down"}}), ("GET", "/auth/me", {})]:
            assert_outage(api.request(method, path, **kwargs), DATABASE_DOWN)
        signing_in = client.post("/api/auth/login", data={"username": "a@b.example", "password": "x" * 12})
        assert_outage(signing_in, DATABASE_DOWN)
    finally:
        app.state.engine, app.state.sessions = saved
        dead.dispose()
    assert api.ok("GET", "/horses")["items"] == []  # back: the same server answers again


def test_broker_and_store_errors_escaping_a_route_are_503(app_client, monkeypatch):
    client, api = app_client
    storage = client.app.state.storage
    raised = {
        "broker": redis.exceptions.ConnectionError("Error 111 connecting to redis:6379. Connection refused."),
        "kombu": kombu.exceptions.OperationalError("[Errno 111] Connection refused"),
        "store": botocore.exceptions.EndpointConnectionError(endpoint_url="http://seaweedfs:8333/bucket"),
    }
    expected = {"broker": BROKER_DOWN, "kombu": BROKER_DOWN, "store": STORE_DOWN}
    ride = new_ride(api, "Stored")
    for name, error in raised.items():
        def fail(*args, _error=error, **kwargs):
            raise _error

        monkeypatch.setattr(storage, "writer", fail)
        response = api.put(f"/rides/{ride['id']}/clips/motion/left", content=b"x" * 100,
                            headers={"Content-Type": "application/octet-stream", "X-Filename": "left.avi"})
        assert_outage(response, expected[name])
        assert "seaweedfs" not in response.text and "redis:6379" not in response.text
    monkeypatch.undo()


@pytest.mark.parametrize(("error", "outage"), [
    (sqlalchemy.exc.OperationalError("SELECT 1", {}, Exception("connection refused")), DATABASE_DOWN),
    (sqlalchemy.exc.OperationalError("INSERT", {}, Exception("database or disk is full")), DISK_FULL),
    (sqlalchemy.exc.TimeoutError("QueuePool limit of size 5 overflow 10 reached"), DATABASE_DOWN),
    (OSError(errno.EDQUOT, "Disk quota exceeded"), DISK_FULL),
    (OSError(errno.EACCES, "Permission denied"), None),
    (ValueError("not an outage"), None),
])
def test_what_each_driver_error_means(error, outage):
    assert outage_of(error) is outage


def upload_clip(api, ride_id: int, data: bytes):
    return api.put(f"/rides/{ride_id}/clips/motion/left", content=data,
                    headers={"Content-Type": "application/octet-stream", "X-Filename": "left.avi"})


def test_a_full_disk_refuses_uploads_with_507_and_leaves_nothing_half_written(app_client, full_disk, tmp_path):
    client, api = app_client
    ride = new_ride(api, "Full")
    storage_root = client.app.state.storage.root
    before = stored_files(storage_root)
    bundle = io.BytesIO()
    with zipfile.ZipFile(bundle, "w") as zf:
        zf.writestr("ride.json", "{}")
    resumable, small = (api.ok("POST", "/uploads", 201, json={
        "target": "ride_clip", "ride_id": ride["id"], "clip_kind": "motion", "camera": camera,
        "length_bytes": 300_000, "filename": f"{camera}.avi"}) for camera in ("left", "right"))
    full_disk.full = True
    refused = {
        "clip": upload_clip(api, ride["id"], os.urandom(300_000)),
        "bundle": api.post("/rides/bundle", files={"file": ("ride.zip", bundle.getvalue(), "application/zip")}),
        "chunk": api.patch(f"/uploads/{resumable['id']}", content=os.urandom(300_000),
                           headers={"Upload-Offset": "0", "Content-Type": "application/offset+octet-stream"}),
        # Small enough to stay in the file's buffer: the disk says no only when it is closed.
        "small chunk": api.patch(f"/uploads/{small['id']}", content=b"0123456789",
                                 headers={"Upload-Offset": "0", "Content-Type": "application/offset+octet-stream"}),
    }
    full_disk.full = False
    for what, response in refused.items():
        assert response.status_code == 507, (what, response.text)
        assert response.json()["detail"] == DISK_FULL.detail
    assert part_files(storage_root) == []
    assert stored_files(storage_root) == before
    assert api.ok("GET", f"/uploads/{resumable['id']}")["offset_bytes"] == 0
    assert api.ok("GET", f"/rides/{ride['id']}")["recordings"] == []
    # Room again: the same requests succeed.
    data = os.urandom(300_000)
    sent = api.patch(f"/uploads/{resumable['id']}", content=data,
                     headers={"Upload-Offset": "0", "Content-Type": "application/offset+octet-stream"})
    assert sent.status_code == 204, sent.text
    assert sent.headers["Upload-Offset"] == str(len(data))
    stored = upload_clip(api, ride["id"], data)
    assert stored.status_code in (200, 201, 422), stored.text  # random bytes are no video: refused as such
    assert stored.status_code != 507


def test_health_says_storage_is_degraded_below_the_free_space_threshold(tmp_path):
    settings = settings_for(tmp_path, storage_min_free_bytes=2**62)  # more than any disk has free
    with TestClient(create_app(settings)) as client:
        response = client.get("/api/health")
        assert response.status_code == 200, response.text  # reading still works: no 503 for the balancer
        health = response.json()
        assert health["status"] == "degraded"
        assert "the file storage is nearly full" in health["summary"]
        storage = health["parts"]["storage"]
        assert storage["status"] == "degraded" and not storage["ok"]
        free = os.statvfs(settings.storage_dir)
        assert 0 < storage["free_bytes"] <= 2 * free.f_bavail * free.f_frsize
        assert health["parts"]["database"]["status"] == "ok"
    with TestClient(create_app(settings_for(tmp_path))) as client:  # the default threshold: 1 GiB
        storage = client.get("/api/health").json()["parts"]["storage"]
        assert storage["status"] == "ok" and storage["free_bytes"] > 2**30


SECURITY_HEADERS = ("content-security-policy", "x-frame-options", "x-content-type-options", "referrer-policy",
                    "permissions-policy")


def test_every_kind_of_answer_carries_the_browser_security_headers(app_client, tmp_path):
    client, api = app_client
    answers = {"dashboard": client.get("/"), "script": client.get("/app.js"), "api": api.get("/horses"),
               "not found": api.get("/horses/999999"), "signed out": client.get("/api/rides"),
               "invalid": api.post("/horses", json={}), "docs": client.get("/docs")}
    for what, answer in answers.items():
        assert not [h for h in SECURITY_HEADERS if h not in answer.headers], (what, answer.headers)
        assert answer.headers["x-frame-options"] == "DENY" and answer.headers["x-content-type-options"] == "nosniff"
        assert "frame-ancestors 'none'" in answer.headers["content-security-policy"], what
    assert "script-src 'self';" in answers["dashboard"].headers["content-security-policy"]
    assert "cdn.jsdelivr.net" in answers["docs"].headers["content-security-policy"]  # FastAPI's Swagger UI
    bucket = settings_for(tmp_path, storage_url="s3://club/data", s3_endpoint_url="http://seaweedfs:8333",
                          s3_public_endpoint_url="https://files.club.example")
    from saddlescope.api.security_headers import headers_for

    policy = dict(headers_for(bucket))[b"content-security-policy"].decode()
    assert "connect-src 'self' https://files.club.example;" in policy  # direct uploads PUT parts there

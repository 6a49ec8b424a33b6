"""Fault drill: PostgreSQL stopped, Redis stopped, the object store stopped, the disk full.

During each fault every API route is called (with a request that would succeed: tests/api/route_walk.py)
and answers 503 (with Retry-After) or 507 with a reason, or what it answers without that part, never 500;
after each fault the data stored before it is intact (the same rows, the same bytes: sha256) and new
requests succeed.

The shared services are not stopped: the app reaches PostgreSQL and the SeaweedFS store through TCP relays
of its own (tests/tcp_proxy.py), closed for the fault, and a redis-server of its own, killed and started
again on the same port. A full disk is the kernel's ENOSPC on every write of the folder store (the
writer's file is /dev/full: `api_helpers.FullDisk`).
"""

from __future__ import annotations

import contextlib
import hashlib
import struct
import subprocess
import uuid
from urllib.parse import urlsplit

import integration_services
import pytest
import s3_server as s3_server_module
from api_helpers import FullDisk, add_member, new_club
from fastapi.testclient import TestClient
from route_walk import api_routes, call_kwargs, fill
from tcp_proxy import TcpRelay

from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.settings import load_settings
from saddlescope.storage import storage_for_url

pytestmark = pytest.mark.integration

s3_server = s3_server_module.s3_server
pg_database_url = integration_services.pg_database_url

# Routes that end the caller's own sign-in: the walk would sign itself out.
ENDS_OWN_SIGN_IN = {("POST", "/api/auth/logout"), ("POST", "/api/auth/logout-everywhere"),
                    ("POST", "/api/auth/password")}


def relayed(url: str, relay: TcpRelay) -> str:
    """`url` with its host and port replaced by the relay's."""
    parts = urlsplit(url)
    return parts._replace(netloc=parts.netloc.replace(f"{parts.hostname}:{parts.port}",
                                                      f"127.0.0.1:{relay.port}")).geturl()


@contextlib.contextmanager
def restartable_redis(folder):
    """A redis-server of our own; ``down()`` kills it, ``up()`` starts it again on the same port."""
    stack = contextlib.ExitStack()
    proc, url = stack.enter_context(integration_services.own_redis_server(folder))
    port = urlsplit(url).port

    class Control:
        def down(self) -> None:
            nonlocal proc
            proc.kill()
            proc.wait(timeout=10)

        def up(self) -> None:
            nonlocal proc
            proc = subprocess.Popen(["redis-server", "--port", str(port), "--bind", "127.0.0.1", "--save", "",
                                     "--appendonly", "no", "--dir", str(folder)],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
            import redis

            client = redis.Redis.from_url(url, socket_connect_timeout=1)
            for _ in range(200):
                with contextlib.suppress(redis.ConnectionError):
                    client.ping()
                    break
                import time

                time.sleep(0.05)
            client.close()

    control = Control()
    try:
        yield url, control
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=10)
        stack.close()


def distinct_clip(avi: bytes, tag: str) -> bytes:
    """The clip with a RIFF JUNK chunk naming `tag` after it (players skip it): the same clips make one ride
    (issue 37), so each ride of the drill needs bytes of its own."""
    payload = tag.encode()
    payload += b"\0" * (len(payload) % 2)
    return avi + b"JUNK" + struct.pack("<I", len(payload)) + payload


def make_things(api, tiny, tag: str) -> dict:
    """A horse, a rider, a rig, a ride with a clip, a grade, a job and an upload; their ids for `fill`."""
    member, user = add_member(api)
    horse = api.ok("POST", "/horses", 201, json={"name": f"Horse {tag}"})
    rider = api.ok("POST", "/riders", 201, json={"name": f"Rider {tag}"})
    rig = api.ok("POST", "/rigs", 201, json={"name": f"Rig {tag}", "board": {"inner_corners": [9, 6],
                                                                            "square_mm": 50}})
    ride = api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"],
                                               "rig_id": rig["id"], "gait": "walk", "direction": "CW",
                                               "notes": f"notes {tag}"})
    clip = distinct_clip((tiny / "motion" / "left.avi").read_bytes(), tag)
    api.ok("PUT", f"/rides/{ride['id']}/clips/motion/left", 200,
           files={"file": ("left.avi", clip, "video/x-msvideo")})
    grade = api.ok("POST", "/grades", 201, json={"ride_id": ride["id"], "rider_id": rider["id"], "grade": 3})
    saddle = api.ok("POST", "/saddles", 201, json={"name": f"Saddle {tag}"})
    link = api.ok("POST", "/share-links", 201, json={"horse_id": horse["id"]})
    job = api.ok("POST", "/jobs", 201, json={"kind": "selftest", "payload": {"steps": 1, "delay_s": 0}})
    upload = api.ok("POST", "/uploads", 201, json={"target": "ride_clip", "ride_id": ride["id"],
                                                   "clip_kind": "motion", "camera": "right", "length_bytes": 10})
    return {"horse_id": horse["id"], "rider_id": rider["id"], "rig_id": rig["id"], "ride_id": ride["id"],
            "other_id": ride["id"], "grade_id": grade["id"], "job_id": job["id"], "upload_id": upload["id"],
            "user_id": user["id"], "fmt": "json", "clip_kind": "motion", "camera": "left",
            "saddle_id": saddle["id"], "link_id": link["id"]}


def snapshot(api, storage, ids: dict) -> dict:
    """What is stored about `ids`: the rows as the API shows them and the sha256 of each stored file."""
    ride_id = ids["ride_id"]
    files = {key: hashlib.sha256(storage.read_bytes(key)).hexdigest() for key in storage.iter_keys(f"rides/{ride_id}")}
    ride = api.ok("GET", f"/rides/{ride_id}")
    ride.pop("latest_job_id", None)  # the walk may start jobs on it
    return {"ride": ride, "horse": api.ok("GET", f"/horses/{ids['horse_id']}"),
            "grade": api.ok("GET", f"/grades/{ids['grade_id']}"), "files": files}


def walk_every_route(api, ids: dict, tiny) -> dict[tuple[str, str], int]:
    """Call every route once; assert none answers 500 and every 5xx is 503/507 with a reason."""
    answers = {}
    routes = sorted(api_routes(api.client.app), key=lambda route: route[0] == "DELETE")  # deletions last
    for method, path in routes:
        if (method, path) in ENDS_OWN_SIGN_IN:
            continue
        response = api.request(method, fill(path, ids), **call_kwargs(method, path, ids, tiny))
        where = f"{method} {path} -> {response.status_code} {response.text[:300]}"
        assert response.status_code < 500 or response.status_code in (503, 507), where
        if response.status_code in (503, 507) and method != "HEAD":
            body = response.json()
            detail = body["summary"] if path == "/api/health" else body["detail"]  # health: its one line
            assert isinstance(detail, str) and len(detail) > 20 and "Traceback" not in detail, where
        if response.status_code == 503 and path != "/api/health":
            assert int(response.headers.get("Retry-After", 0)) > 0, where
        answers[(method, path)] = response.status_code
    return answers


def still_works(api, tiny, fault: str) -> None:
    """New requests succeed once the part is back: rows, a clip's bytes, a job on the broker."""
    horse = api.ok("POST", "/horses", 201, json={"name": f"After the {fault} fault"})
    rider = api.ok("POST", "/riders", 201, json={"name": f"After the {fault} fault"})
    ride = api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                               "direction": "CW"})
    clip = distinct_clip((tiny / "motion" / "middle.avi").read_bytes(), f"{fault} {uuid.uuid4()}")
    api.ok("PUT", f"/rides/{ride['id']}/clips/motion/middle", 200,
           files={"file": ("middle.avi", clip, "video/x-msvideo")})
    api.ok("POST", "/jobs", 201, json={"kind": "selftest", "payload": {"steps": 1, "delay_s": 0}})
    assert api.client.get("/api/health").status_code == 200


@pytest.fixture
def tiny(tmp_path_factory):
    return integration_services.write_tiny_bundle(tmp_path_factory.mktemp("drill") / "ride")


def test_database_broker_and_store_stopped_in_turn(tmp_path, pg_database_url, s3_server, tiny, monkeypatch):
    for name, value in s3_server.environ().items():
        monkeypatch.setenv(name, value)
    upgrade_to_head(pg_database_url)
    pg_host = urlsplit(pg_database_url)
    store = urlsplit(s3_server.endpoint_url)
    bucket_url = f"s3://{s3_server.new_bucket('drill')}/club-data"
    direct = storage_for_url(bucket_url, endpoint_url=s3_server.endpoint_url)  # bypasses the relay
    with (TcpRelay(pg_host.hostname, pg_host.port) as pg, TcpRelay(store.hostname, store.port) as s3,
          restartable_redis(tmp_path) as (broker_url, broker)):
        settings = load_settings(database_url=relayed(pg_database_url, pg), broker_url=broker_url,
                                 storage_url=bucket_url, s3_endpoint_url=relayed(s3_server.endpoint_url, s3),
                                 storage_dir=str(tmp_path / "storage"), secret_key=integration_services.TEST_SECRET,
                                 direct_uploads=False)
        with TestClient(create_app(settings, open_registration=True), raise_server_exceptions=False) as client:
            api, _ = new_club(client)
            kept = make_things(api, tiny, "kept")
            before = snapshot(api, direct, kept)
            faults = {"database": (pg.stop, pg.start), "broker": (broker.down, broker.up),
                      "store": (s3.stop, s3.start)}
            seen = {}
            for fault, (stop, start) in faults.items():
                walked = make_things(api, tiny, fault)
                stop()
                try:
                    seen[fault] = walk_every_route(api, walked, tiny)
                finally:
                    start()
                assert snapshot(api, direct, kept) == before, fault
                still_works(api, tiny, fault)
    refused = {fault: sum(code in (503, 507) for code in answers.values()) for fault, answers in seen.items()}
    routes = len(seen["database"])
    # The database is behind nearly every route; the broker behind starting jobs; the store behind clips.
    assert refused["database"] >= routes - 10, seen["database"]
    assert seen["broker"][("POST", "/api/jobs")] == 503
    assert seen["store"][("PUT", "/api/rides/{ride_id}/clips/{clip_kind}/{camera}")] == 503
    assert all(seen[fault][("GET", "/api/health")] == 503 for fault in faults)


def test_a_full_disk(tmp_path, pg_database_url, tiny, monkeypatch):
    upgrade_to_head(pg_database_url)
    with integration_services.own_redis_server(tmp_path) as (_, broker_url):
        settings = load_settings(database_url=pg_database_url, broker_url=broker_url,
                                 storage_dir=str(tmp_path / "storage"), secret_key=integration_services.TEST_SECRET)
        disk = FullDisk().install(monkeypatch)
        with TestClient(create_app(settings, open_registration=True), raise_server_exceptions=False) as client:
            api, _ = new_club(client)
            storage = client.app.state.storage
            kept = make_things(api, tiny, "kept")
            before = snapshot(api, storage, kept)
            walked = make_things(api, tiny, "walked")
            disk.full = True
            try:
                answers = walk_every_route(api, walked, tiny)
            finally:
                disk.full = False
            assert snapshot(api, storage, kept) == before
            assert not [p for p in storage.root.rglob(".part-*")]  # nothing half-written
            still_works(api, tiny, "disk")
    full = {route for route, code in answers.items() if code == 507}
    assert {("PUT", "/api/rides/{ride_id}/clips/{clip_kind}/{camera}"), ("POST", "/api/rides/bundle"),
            ("PATCH", "/api/uploads/{upload_id}")} <= full, answers

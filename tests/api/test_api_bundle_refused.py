"""A bundle whose analysis the job queue refuses (503) leaves nothing behind, and a resumable one can be finalised
again without sending its bytes again (issue 26: "a refused upload leaves nothing behind").

The refusing queues are real: the embedded pool after it was shut down (a server closing), and Celery with a
broker nobody listens at. On both storage back ends; in a bucket the resumable upload goes the direct way
(parts PUT to pre-signed URLs). No services but SeaweedFS are needed (SQLite database).
"""

from __future__ import annotations

import contextlib
from concurrent.futures import ProcessPoolExecutor
from types import SimpleNamespace

import httpx
import pytest
import s3_server as s3_server_module
from api_helpers import new_club, zip_folder
from disk_watch import HeldQueue, queue_of
from engines import s3_storage_env
from fastapi.testclient import TestClient
from integration_services import write_tiny_bundle

from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job
from saddlescope.db.session import session_factory_for
from saddlescope.services.jobs.queue import EmbeddedQueue
from saddlescope.services.uploads import direct as direct_uploads
from saddlescope.settings import load_settings
from saddlescope.storage import open_storage

s3_server = s3_server_module.s3_server  # one SeaweedFS for the session (tests/s3_server.py)

DEAD_BROKER = "redis://127.0.0.1:1/0"  # port 1: nothing listens there
REFUSALS = {"embedded": "the local job pool cannot take job", "celery": "the job broker is unreachable"}


def closed_embedded_queue(settings) -> EmbeddedQueue:
    """The embedded queue of a server that is closing: its pool was shut down, it takes no job."""
    queue = EmbeddedQueue(settings)
    pool = ProcessPoolExecutor(max_workers=1)
    pool.shutdown()
    queue._executor = lambda: pool  # the pool `submit` hands the job to
    return queue


@pytest.fixture(params=["embedded-file", *(pytest.param(p, marks=pytest.mark.integration)
                                           for p in ("embedded-s3", "celery-file", "celery-s3"))])
def refusing(request, tmp_path, monkeypatch):
    engine, store = request.param.split("-")
    overrides = {"database_url": f"sqlite:///{tmp_path / 'db.sqlite'}", "storage_dir": str(tmp_path / "storage"),
                 "secret_key": "a-test-secret-of-enough-length"}
    with contextlib.ExitStack() as stack:
        if store == "s3":
            stack.enter_context(s3_storage_env(request, overrides))
            monkeypatch.setattr(direct_uploads, "DIRECT_PART_BYTES", 5 * 1024**2)
        if engine == "celery":
            overrides["broker_url"] = DEAD_BROKER
        settings = load_settings(**overrides)
        upgrade_to_head(settings.database_url)  # with a broker the server does not migrate by itself
        queue = closed_embedded_queue(settings) if engine == "embedded" else None
        client = stack.enter_context(TestClient(create_app(settings, queue=queue, open_registration=True)))
        api, _ = new_club(client)
        yield SimpleNamespace(engine=engine, store=store, settings=settings, client=client, api=api,
                              folder=write_tiny_bundle(tmp_path / "bundle"))


def assert_nothing_left(env) -> None:
    """No ride, horse, rider or job in the database; no ride's file and no staged zip in storage."""
    api = env.api
    assert api.ok("GET", "/rides")["total"] == 0
    assert api.ok("GET", "/horses")["total"] == api.ok("GET", "/riders")["total"] == 0
    with session_factory_for(env.settings.database_url)() as session:
        assert session.query(Job).count() == 0  # the refused job went with its ride
    store = open_storage(env.settings)
    for prefix in ("rides", "incoming"):
        assert not store.exists(prefix) or not list(store.iter_keys(prefix)), prefix


def send_upload(env, data: bytes) -> dict:
    """A complete resumable bundle upload: chunks PATCHed to the API, or parts PUT straight to the bucket."""
    api = env.api
    upload = api.ok("POST", "/uploads", 201, json={"target": "bundle", "length_bytes": len(data),
                                                   "filename": "ride.zip"})
    if env.store == "s3":
        assert (upload["transport"], upload["parts_total"]) == ("s3-parts", 1)
        url = api.ok("POST", f"/uploads/{upload['id']}/parts", json={"numbers": [1]})["urls"]["1"]
        assert httpx.put(url, content=data, timeout=60).status_code == 200
    else:
        sent = api.patch(f"/uploads/{upload['id']}", content=data,
                         headers={"Upload-Offset": "0", "Content-Type": "application/offset+octet-stream"})
        assert sent.status_code == 204, sent.text
    return upload


def test_a_bundle_the_queue_refuses_is_a_503_that_leaves_no_ride(refusing):
    data = zip_folder(refusing.folder)
    refused = refusing.api.post("/rides/bundle", files={"file": ("ride.zip", data, "application/zip")})
    assert refused.status_code == 503, refused.text
    assert refused.headers["Retry-After"] == "10"  # issue 39 item 8: when to ask again
    detail = refused.json()["detail"]
    assert detail.startswith("ride.zip: ") and REFUSALS[refusing.engine] in detail
    assert detail.endswith("no ride was made from it, send the bundle again in a moment")
    assert_nothing_left(refusing)


def test_a_refused_resumable_bundle_keeps_its_upload_to_finalise_again(refusing):
    api, data = refusing.api, zip_folder(refusing.folder)
    upload = send_upload(refusing, data)
    refused = api.post(f"/uploads/{upload['id']}/finalize", json={"notes": "first canter"})
    assert refused.status_code == 503, refused.text
    detail = refused.json()["detail"]
    assert REFUSALS[refusing.engine] in detail
    assert detail.endswith("no ride was made from it, your upload is kept: finalise it again in a moment")
    kept = api.ok("GET", f"/uploads/{upload['id']}")
    assert (kept["status"], kept["offset_bytes"]) == ("open", len(data))
    assert_nothing_left(refusing)

    with queue_of(refusing.client.app, HeldQueue()) as held:  # the queue answers again
        outcome = api.ok("POST", f"/uploads/{upload['id']}/finalize", json={"notes": "first canter"})
    assert held.jobs == [outcome["job_id"]]
    ride = api.ok("GET", f"/rides/{outcome['ride_id']}")
    assert (len(ride["recordings"]), ride["notes"], ride["latest_job_id"]) == (12, "first canter", outcome["job_id"])
    assert api.ok("GET", f"/uploads/{upload['id']}")["status"] == "finalised"
    store = open_storage(refusing.settings)
    assert not [k for prefix in ("uploads", "incoming") if store.exists(prefix) for k in store.iter_keys(prefix)]


def test_a_job_the_queue_refuses_is_a_503_with_retry_after_and_leaves_no_job_row(refusing):
    # Issue 39 item 8: the refused job stayed as a row "failed" with 0 attempts, and no Retry-After.
    api = refusing.api
    horse = api.ok("POST", "/horses", 201, json={"name": "Waiting"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Patient"})
    ride = api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                                "direction": "CW"})
    refused = api.post("/jobs", json={"kind": "probe", "ride_id": ride["id"]})
    assert refused.status_code == 503, refused.text
    assert refused.headers["Retry-After"] == "10" and REFUSALS[refusing.engine] in refused.json()["detail"]
    with session_factory_for(refusing.settings.database_url)() as session:
        assert session.query(Job).count() == 0
    assert api.ok("GET", "/jobs")["total"] == 0
    assert api.ok("GET", f"/rides/{ride['id']}")["latest_job_id"] is None

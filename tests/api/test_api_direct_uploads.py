"""Direct uploads on object storage (issue 26 part 2): the client PUTs a resumable upload's parts straight
to the bucket (a real SeaweedFS) with URLs the API pre-signs, asks which parts arrived to resume, and
the API joins them at finalise; no byte of the file passes through the API."""

from __future__ import annotations

import hashlib
import os
import tempfile

import httpx
import pytest
import s3_server as s3_server_module
from api_helpers import new_club, zip_folder
from disk_watch import HeldQueue, bundle_clip_digests, queue_of, watching_local_writes
from engines import EMBEDDED_S3, open_env
from integration_services import write_tiny_bundle, write_tiny_clip

from saddlescope.services.uploads import direct as direct_uploads
from saddlescope.storage import direct_upload_key, open_storage

s3_server = s3_server_module.s3_server  # one SeaweedFS for the session (tests/s3_server.py)

PART_BYTES = 5 * 1024**2  # S3's smallest part but the last: three parts for the test's 12 MiB


@pytest.fixture(scope="module", params=[EMBEDDED_S3])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture(autouse=True)
def small_parts(monkeypatch):
    monkeypatch.setattr(direct_uploads, "DIRECT_PART_BYTES", PART_BYTES)


@pytest.fixture(scope="module")
def club(env, tmp_path_factory):
    api, _ = new_club(env.client)
    horse = api.ok("POST", "/horses", 201, json={"name": "Direct"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Direct"})
    ride = api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                              "direction": "CW"})
    return {"api": api, "ride": ride, "folder": tmp_path_factory.mktemp("direct")}


def start(api, ride_id: int, size: int, camera: str) -> dict:
    return api.ok("POST", "/uploads", 201, json=_upload_request(ride_id, size, camera))


def start_raw(api, ride_id: int, size: int, camera: str):
    return api.post("/uploads", json=_upload_request(ride_id, size, camera))


def _upload_request(ride_id: int, size: int, camera: str) -> dict:
    return {"target": "ride_clip", "ride_id": ride_id, "clip_kind": "motion", "camera": camera,
            "length_bytes": size, "filename": f"{camera}.avi"}


def put_part(api, upload_id: str, number: int, data: bytes) -> int:
    url = api.ok("POST", f"/uploads/{upload_id}/parts", json={"numbers": [number]})["urls"][str(number)]
    assert url.startswith("http://127.0.0.1:")  # the bucket's address, not the API's
    return httpx.put(url, content=data[(number - 1) * PART_BYTES:number * PART_BYTES], timeout=60).status_code


def test_parts_go_to_the_bucket_resume_and_finalise_into_a_recording(env, club, monkeypatch):
    api, ride = club["api"], club["ride"]
    data = bytes(range(256)) * (12 * 1024**2 // 256)  # 12 MiB: parts of 5, 5 and 2 MiB
    local: list[str] = []
    for name in ("mkstemp", "mkdtemp", "NamedTemporaryFile", "TemporaryFile", "SpooledTemporaryFile"):
        real = getattr(tempfile, name)
        monkeypatch.setattr(tempfile, name, lambda *a, _r=real, _n=name, **k: (local.append(_n), _r(*a, **k))[1])
    upload = start(api, ride["id"], len(data), "left")
    assert (upload["transport"], upload["part_bytes"], upload["parts_total"]) == ("s3-parts", PART_BYTES, 3)
    streamed = api.patch(f"/uploads/{upload['id']}", content=b"x",
                         headers={"Upload-Offset": "0", "Content-Type": "application/offset+octet-stream"})
    assert streamed.status_code == 409 and "PUT its parts" in streamed.json()["detail"]

    assert put_part(api, upload["id"], 1, data) == 200
    assert put_part(api, upload["id"], 3, data) == 200  # out of order is fine
    state = api.ok("GET", f"/uploads/{upload['id']}/parts")  # the connection dropped: what arrived?
    assert [p["number"] for p in state["parts"]] == [1, 3] and state["offset_bytes"] == PART_BYTES
    early = api.post(f"/uploads/{upload['id']}/finalize")
    assert early.status_code == 409 and "send part(s) 2 first" in early.json()["detail"]
    assert put_part(api, upload["id"], 1, data) == 200  # a retried part: the same bytes again
    assert put_part(api, upload["id"], 2, data) == 200
    bad = api.post(f"/uploads/{upload['id']}/parts", json={"numbers": [4]})
    assert bad.status_code == 422 and "has parts 1 to 3" in bad.json()["detail"]

    outcome = api.ok("POST", f"/uploads/{upload['id']}/finalize")
    clip = next(r for r in api.ok("GET", f"/rides/{ride['id']}/clips") if r["id"] == outcome["recording_id"])
    assert clip["sha256"] == hashlib.sha256(data).hexdigest() and clip["size_bytes"] == len(data)
    assert local == []  # nothing on the API's disk
    storage = open_storage(env.settings)
    assert storage.direct_id(direct_upload_key(upload["id"])) is None
    assert not list(storage.iter_keys("uploads"))


def test_a_wrong_sized_part_is_asked_for_again_and_an_abandoned_upload_leaves_nothing(env, club):
    api, ride = club["api"], club["ride"]
    data = b"z" * (PART_BYTES + 100)
    upload = start(api, ride["id"], len(data), "middle")
    url = api.ok("POST", f"/uploads/{upload['id']}/parts", json={"numbers": [1]})["urls"]["1"]
    assert httpx.put(url, content=data[:1000], timeout=60).status_code == 200  # a cut-off part
    assert api.ok("GET", f"/uploads/{upload['id']}/parts")["parts"] == []  # counted as missing
    assert api.delete(f"/uploads/{upload['id']}").status_code == 204
    storage = open_storage(env.settings)
    assert storage.direct_id(direct_upload_key(upload["id"])) is None  # its parts are gone from the bucket


def test_a_real_clip_sent_directly_is_probed_by_the_worker(env, club):
    api, first = club["api"], club["ride"]
    ride = api.ok("POST", "/rides", 201, json={"horse_id": first["horse_id"], "rider_id": first["rider_id"],
                                              "gait": "walk", "direction": "CCW"})
    data = write_tiny_clip(club["folder"] / "right.avi", frames=9).read_bytes()
    upload = start(api, ride["id"], len(data), "right")
    assert upload["parts_total"] == 1 and put_part(api, upload["id"], 1, data) == 200
    outcome = api.ok("POST", f"/uploads/{upload['id']}/finalize")
    clip = next(r for r in api.ok("GET", f"/rides/{ride['id']}/clips") if r["id"] == outcome["recording_id"])
    assert clip["fps"] is None  # the API never read it
    job = api.ok("POST", "/jobs", 201, json={"kind": "probe", "ride_id": ride["id"]})
    done, _ = api.wait_job(job["id"])
    assert done["status"] == "done", done["error"]
    clip = next(r for r in api.ok("GET", f"/rides/{ride['id']}/clips") if r["id"] == outcome["recording_id"])
    assert (clip["frame_count"], clip["fps"], clip["sha256"]) == (9, 30.0, hashlib.sha256(data).hexdigest())


def test_health_checks_the_bucket(env, club):
    storage = club["api"].ok("GET", "/health/details")["parts"]["storage"]
    bucket = env.settings.storage_url.removeprefix("s3://").split("/")[0]
    assert storage["ok"] and storage["detail"].startswith(f"s3://{bucket}/club-data")
    assert "writable" in storage["detail"]


def _dead_endpoint() -> str:
    import socket

    with socket.socket() as sock:  # a port nobody listens on once closed
        sock.bind(("127.0.0.1", 0))
        return f"http://127.0.0.1:{sock.getsockname()[1]}"


def test_a_store_that_does_not_answer_is_a_503_with_the_reason(env, club):
    from saddlescope.storage import S3Storage

    bucket = env.settings.storage_url.removeprefix("s3://").split("/")[0]
    state = env.client.app.state
    # Swapped by hand: pytest's monkeypatch does not put a starlette `State` attribute back (it deletes it).
    saved, state.storage = state.storage, S3Storage(bucket, "club-data", endpoint_url=_dead_endpoint())
    try:
        response = start_raw(club["api"], club["ride"]["id"], 1000, "left")
    finally:
        state.storage = saved
    assert response.status_code == 503, response.text
    detail = response.json()["detail"]
    assert detail.startswith("the file store is not answering") and "try again" in detail
    assert response.headers.get("Retry-After") == "10"


def test_part_urls_carry_the_public_endpoint(env, club):
    from saddlescope.storage import S3Storage

    bucket = env.settings.storage_url.removeprefix("s3://").split("/")[0]
    inside = env.settings.s3_endpoint_url
    storage = S3Storage(bucket, "club-data", endpoint_url=inside, public_endpoint_url="https://files.example.org")
    key = direct_upload_key("public-endpoint-check")
    direct_id = storage.start_direct(key)  # over the inside address
    try:
        url = storage.part_url(key, direct_id, 1, expires_s=60)
        assert url.startswith(f"https://files.example.org/{bucket}/club-data/") and "Signature=" in url
        same = S3Storage(bucket, "club-data", endpoint_url=inside).part_url(key, direct_id, 1, expires_s=60)
        assert same.startswith(f"{inside}/{bucket}/")  # unset: the servers' own address
    finally:
        storage.abort_direct(key)


def test_a_bundle_sent_directly_is_read_in_the_bucket_never_on_the_apis_disk(env, club):
    api = club["api"]
    folder = write_tiny_bundle(club["folder"] / "bundle", gait="canter")
    (folder / "extra").mkdir()
    (folder / "extra" / "noise.bin").write_bytes(os.urandom(11 * 1024**2))  # the zip spans three parts
    data = zip_folder(folder)
    with queue_of(env.client.app, HeldQueue()) as held, watching_local_writes() as writes:
        upload = api.ok("POST", "/uploads", 201, json={"target": "bundle", "length_bytes": len(data),
                                                       "filename": "canter.zip"})
        assert (upload["transport"], upload["parts_total"]) == ("s3-parts", 3)
        assert [put_part(api, upload["id"], number, data) for number in (1, 2, 3)] == [200] * 3
        meta = api.ok("GET", f"/uploads/{upload['id']}/bundle-meta")  # the dashboard pre-fills its form
        outcome = api.ok("POST", f"/uploads/{upload['id']}/finalize", json={"gait": "walk"})
    assert writes == []  # not one local file opened for writing, not one folder made
    assert (meta["gait"], meta["horse"]["name"]) == ("canter", "Horse 2")
    assert held.jobs == [outcome["job_id"]]
    ride = api.ok("GET", f"/rides/{outcome['ride_id']}")
    assert ride["gait"] == "walk"  # chosen in the form, over ride.json
    assert {(r["clip_kind"], r["camera_role"]): (r["size_bytes"], r["sha256"])
            for r in ride["recordings"]} == bundle_clip_digests(folder)
    storage = open_storage(env.settings)
    stored = {k.removeprefix(f"rides/{ride['id']}/bundle/") for k in storage.iter_keys(f"rides/{ride['id']}/bundle")}
    # every file ride.json names, and not the padding it does not (issue 39 item 9)
    assert stored == {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()} - {"extra/noise.bin"}
    assert storage.direct_id(direct_upload_key(upload["id"])) is None
    assert not list(storage.iter_keys("uploads")) and not list(storage.iter_keys("incoming"))

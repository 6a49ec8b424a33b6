"""Resumable uploads (tus-like) and the streamed upload path: offsets, resuming, finalising, refusals.

On both storage back ends: the folder tree, and a bucket of a real SeaweedFS ("embedded-s3"), where the
API keeps no byte of a video on its own disk (a clip, or a bundle zip read in place) and the worker's probe
stage reads the clips. A broken bundle gets the same reason on both back ends and leaves nothing.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import io
import json
import tempfile
import zipfile

import integration_services
import pytest
import s3_server as s3_server_module
from api_helpers import job_outcome, new_club, zip_folder
from disk_watch import HeldQueue, bundle_clip_digests, in_a_job_thread, queue_of, watching_local_writes
from engines import EMBEDDED_S3, ENGINES, open_env
from integration_services import write_tiny_bundle, write_tiny_clip, zip_with_a_flipped_byte

from saddlescope.storage import FileStorage, open_storage, upload_key

s3_server = s3_server_module.s3_server  # one SeaweedFS for the session (tests/s3_server.py)

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url


@pytest.fixture(scope="module", params=[*ENGINES, EMBEDDED_S3])
def env(request, tmp_path_factory):
    # The streamed transport on every back end (direct uploads to the bucket: test_api_direct_uploads.py).
    yield from open_env(request, tmp_path_factory, worker=False, direct_uploads=False)


def on_s3(env) -> bool:
    return env.settings.storage_url is not None and env.settings.storage_url.startswith("s3://")


@pytest.fixture(scope="module")
def club(env, tmp_path_factory):
    api, _ = new_club(env.client)
    horse = api.ok("POST", "/horses", 201, json={"name": "Phone"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Filmed"})
    ride = api.ok(
        "POST",
        "/rides",
        201,
        json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk", "direction": "CCW"},
    )
    folder = tmp_path_factory.mktemp("uploads")
    return {"api": api, "ride": ride, "folder": folder}


def start(api, ride_id: int, data: bytes, camera: str = "left", **extra) -> dict:
    return api.ok(
        "POST",
        "/uploads",
        201,
        json={
            "target": "ride_clip",
            "ride_id": ride_id,
            "clip_kind": "motion",
            "camera": camera,
            "length_bytes": len(data),
            "filename": f"{camera}.avi",
            **extra,
        },
    )


def send(api, upload_id: str, offset: int, chunk: bytes):
    return api.patch(
        f"/uploads/{upload_id}",
        content=chunk,
        headers={"Upload-Offset": str(offset), "Content-Type": "application/offset+octet-stream"},
    )


def test_chunks_at_offsets_resume_and_finalise_into_a_probed_recording(env, club):
    api, ride = club["api"], club["ride"]
    data = write_tiny_clip(club["folder"] / "phone.avi", frames=12).read_bytes()
    upload = start(api, ride["id"], data)
    assert upload["offset_bytes"] == 0 and upload["status"] == "open" and len(upload["id"]) == 32
    third = len(data) // 3
    first = send(api, upload["id"], 0, data[:third])
    assert first.status_code == 204 and first.headers["Upload-Offset"] == str(third)

    # the connection dropped: the client asks where to resume
    head = api.request("HEAD", f"/uploads/{upload['id']}")
    assert head.status_code == 200 and head.headers["Upload-Offset"] == str(third)
    assert head.headers["Upload-Length"] == str(len(data))
    stale = send(api, upload["id"], 0, data[:third])  # a retry of the first chunk: the same bytes
    assert stale.status_code == 204 and stale.headers["Upload-Offset"] == str(third)
    other = send(api, upload["id"], 0, b"\xff" * third)  # other bytes where some were acknowledged
    assert other.status_code == 409 and f"resume from {third}" in other.json()["detail"]
    # The 409 says where to resume as the client reads it (uploader.js): the header and `offset_bytes`.
    assert (other.headers["Upload-Offset"], other.json()["offset_bytes"]) == (str(third), third)
    ahead = send(api, upload["id"], 2 * third, data[2 * third :])  # past the server's offset (a lost chunk)
    assert ahead.status_code == 409 and (ahead.headers["Upload-Offset"], ahead.json()["offset_bytes"]) == (
        str(third), third)
    early = api.post(f"/uploads/{upload['id']}/finalize")
    assert early.status_code == 409 and f"has {third} of its {len(data)} bytes" in early.json()["detail"]

    assert send(api, upload["id"], third, data[third : 2 * third]).status_code == 204
    too_much = send(api, upload["id"], 2 * third, data[2 * third :] + b"extra")
    assert too_much.status_code == 413 and "more bytes than the" in too_much.json()["detail"]
    part_way = api.ok("GET", f"/uploads/{upload['id']}")
    assert part_way["offset_bytes"] == 2 * third  # the bad chunk did not count
    assert part_way["outcome"] is None  # nothing made yet (the row keeps {}: not an answer)
    assert send(api, upload["id"], 2 * third, data[2 * third :]).status_code == 204

    outcome = api.ok("POST", f"/uploads/{upload['id']}/finalize")
    assert outcome["job_id"] is None  # one camera of three: nothing to start yet
    clip = next(r for r in api.ok("GET", f"/rides/{ride['id']}/clips") if r["id"] == outcome["recording_id"])
    assert clip["sha256"] == hashlib.sha256(data).hexdigest() and clip["size_bytes"] == len(data)
    if on_s3(env):  # probed by the worker, not by the API: its probe job fills these in
        assert (clip["frame_count"], clip["fps"], clip["width"], clip["height"]) == (None, None, None, None)
        job = api.ok("POST", "/jobs", 201, json={"kind": "probe", "ride_id": ride["id"]})
        assert job_outcome(api, job["id"])["status"] == "done"
        clip = next(r for r in api.ok("GET", f"/rides/{ride['id']}/clips") if r["id"] == outcome["recording_id"])
        assert clip["sha256"] == hashlib.sha256(data).hexdigest()
    assert (clip["frame_count"], clip["fps"], clip["width"], clip["height"]) == (12, 30.0, 64, 48)
    assert clip["original_filename"] == "left.avi"
    done = api.ok("GET", f"/uploads/{upload['id']}")
    assert done["status"] == "finalised" and done["outcome"] == outcome
    closed = send(api, upload["id"], len(data), b"more")
    # no offset to resume from: the upload takes no more bytes
    assert closed.status_code == 409 and "Upload-Offset" not in closed.headers and "offset_bytes" not in closed.json()
    assert not open_storage(env.settings).exists(upload_key(upload["id"]))


def test_a_refused_file_marks_the_upload_failed_with_the_reason(env, club):
    api, ride = club["api"], club["ride"]
    data = b"not a video at all " * 50
    upload = start(api, ride["id"], data, camera="middle")
    assert send(api, upload["id"], 0, data).status_code == 204
    response = api.post(f"/uploads/{upload['id']}/finalize")
    if on_s3(env):  # the API cannot read it without keeping it: the worker's probe refuses it, with the reason
        assert response.status_code == 200
        job = api.ok("POST", "/jobs", 201, json={"kind": "probe", "ride_id": ride["id"]})
        failed = job_outcome(api, job["id"])
        assert failed["status"] == "failed" and "middle camera (middle-" in failed["error"]
        assert "is not a usable video" in failed["error"]
        return
    assert response.status_code == 422 and "(middle.avi) is not a usable video" in response.json()["detail"]
    failed = api.ok("GET", f"/uploads/{upload['id']}")
    assert failed["status"] == "failed" and "not a usable video" in failed["error"]
    assert all(r["camera_role"] != "middle" for r in api.ok("GET", f"/rides/{ride['id']}/clips"))


def test_abandon_and_bad_requests(env, club):
    api, ride = club["api"], club["ride"]
    upload = start(api, ride["id"], b"0123456789", camera="right")
    assert send(api, upload["id"], 0, b"01234").status_code == 204
    assert api.delete(f"/uploads/{upload['id']}").status_code == 204
    assert api.get(f"/uploads/{upload['id']}").status_code == 404
    assert not open_storage(env.settings).exists(upload_key(upload["id"]))
    assert api.get("/uploads/not-an-upload-id").status_code == 422
    missing_offset = api.patch(f"/uploads/{'0' * 32}", content=b"x")
    assert missing_offset.status_code == 422 and "Upload-Offset" in missing_offset.json()["detail"]
    wrong = api.post(
        "/uploads",
        json={
            "target": "rig_clip",
            "rig_id": 999,
            "clip_kind": "motion",
            "camera": "left",
            "length_bytes": 5,
        },
    )
    assert wrong.status_code == 404 and "rig 999 not found" in wrong.json()["detail"]
    rig = api.ok("POST", "/rigs", 201, json={"name": "Resumable rig"})
    motion_for_rig = api.post(
        "/uploads",
        json={
            "target": "rig_clip",
            "rig_id": rig["id"],
            "clip_kind": "motion",
            "camera": "left",
            "length_bytes": 5,
        },
    )
    assert (
        motion_for_rig.status_code == 422 and "a rig has no 'motion' clips" in motion_for_rig.json()["detail"]
    )


def test_a_bundle_as_a_resumable_upload_becomes_a_ride_with_a_job(env, club):
    api = club["api"]
    folder = write_tiny_bundle(club["folder"] / "bundle")
    data = zip_folder(folder)
    upload = api.ok(
        "POST", "/uploads", 201, json={"target": "bundle", "length_bytes": len(data), "filename": "ride.zip"}
    )
    step = 7000
    for offset in range(0, len(data), step):
        assert send(api, upload["id"], offset, data[offset : offset + step]).status_code == 204
    # The form's suggestions come from ride.json inside the zip (on S3: read by ranges from its parts).
    meta = api.ok("GET", f"/uploads/{upload['id']}/bundle-meta")
    ride_json = json.loads((folder / "ride.json").read_text())
    assert (meta["gait"], meta["horse"]["name"]) == (ride_json["gait"], ride_json["horse"]["name"])
    outcome = api.ok("POST", f"/uploads/{upload['id']}/finalize")
    ride = api.ok("GET", f"/rides/{outcome['ride_id']}")
    assert (
        ride["from_bundle"] and len(ride["recordings"]) == 12 and ride["latest_job_id"] == outcome["job_id"]
    )
    if env.engine == "embedded":  # its job runs in a thread here: to its end, before a later test watches the disk
        assert job_outcome(api, outcome["job_id"], timeout_s=300)["status"] in ("done", "failed")


def test_raw_and_multipart_uploads_store_the_same_bytes(env, club):
    api, ride = club["api"], club["ride"]
    data = write_tiny_clip(club["folder"] / "raw.avi", frames=9).read_bytes()
    raw = api.ok(
        "PUT",
        f"/rides/{ride['id']}/clips/static/left",
        content=data,
        headers={"Content-Type": "video/x-msvideo", "X-Filename": "raw.avi"},
    )
    form = api.ok(
        "PUT",
        f"/rides/{ride['id']}/clips/static/middle",
        files={"file": ("form.avi", data)},
        data={"note": "a form field next to the file is ignored"},
    )
    assert raw["recording"]["sha256"] == form["recording"]["sha256"] == hashlib.sha256(data).hexdigest()
    assert (
        raw["recording"]["original_filename"] == "raw.avi"
        and form["recording"]["original_filename"] == "form.avi"
    )
    no_file = api.put(f"/rides/{ride['id']}/clips/static/right", files={"other": ("x.avi", data)})
    assert no_file.status_code == 422 and "no 'file' field" in no_file.json()["detail"]


def test_on_object_storage_the_api_keeps_no_video_byte_on_its_disk(env, club, monkeypatch):
    if not on_s3(env):
        pytest.skip("a check of the object-storage back end (the folder tree keeps clips on disk by design)")
    api, ride = club["api"], club["ride"]
    data = write_tiny_clip(club["folder"] / "private.avi", frames=10).read_bytes()
    local_files: list[str] = []  # every temporary file or folder, or local store, the API opens meanwhile
    for name in ("mkstemp", "mkdtemp", "NamedTemporaryFile", "TemporaryFile", "SpooledTemporaryFile"):
        real = getattr(tempfile, name)
        monkeypatch.setattr(tempfile, name, lambda *a, _real=real, _name=name, **k: (
            local_files.extend([] if in_a_job_thread() else [_name]), _real(*a, **k))[1])
    monkeypatch.setattr(FileStorage, "__init__", lambda self, root: local_files.append(f"FileStorage({root})"))
    upload = start(api, ride["id"], data, camera="right", clip_kind="plumb")
    half = len(data) // 2
    assert send(api, upload["id"], 0, data[:half]).status_code == 204
    assert send(api, upload["id"], 0, data[:half]).status_code == 204  # a retried chunk: idempotent
    assert send(api, upload["id"], half, data[half:]).status_code == 204
    resumable = api.ok("POST", f"/uploads/{upload['id']}/finalize")
    direct = api.ok("PUT", f"/rides/{ride['id']}/clips/static/right", content=data,
                    headers={"Content-Type": "video/x-msvideo", "X-Filename": "direct.avi"})
    assert local_files == []
    # The API's own data folder holds the database and its secret, never a clip; the bucket has both clips.
    stored = [p for p in env.settings.storage_dir.parent.rglob("*") if p.is_file()]
    assert all(p.name.startswith(("db.sqlite", "secret_key")) for p in stored), stored
    assert not env.settings.storage_dir.exists()
    bucket = open_storage(env.settings)
    keys = [k for k in bucket.iter_keys(f"rides/{ride['id']}/clips")]
    assert any(k.startswith(f"rides/{ride['id']}/clips/plumb/right-") for k in keys)
    assert any(k.startswith(f"rides/{ride['id']}/clips/static/right-") for k in keys)
    sha = hashlib.sha256(data).hexdigest()
    clips = {r["id"]: r for r in api.ok("GET", f"/rides/{ride['id']}/clips")}
    assert clips[resumable["recording_id"]]["sha256"] == clips[direct["recording"]["id"]]["sha256"] == sha
    assert not list(bucket.iter_keys("uploads"))  # the parts and chunks are gone


def bundle_recordings(api, ride_id: int) -> dict[tuple[str, str], tuple[int, str]]:
    ride = api.ok("GET", f"/rides/{ride_id}")
    return {(r["clip_kind"], r["camera_role"]): (r["size_bytes"], r["sha256"]) for r in ride["recordings"]}


def test_on_object_storage_a_bundle_never_touches_the_apis_disk(env, club):
    if not on_s3(env):
        pytest.skip("a check of the object-storage back end (the folder tree unpacks bundles on disk by design)")
    api = club["api"]
    folders = {gait: write_tiny_bundle(club["folder"] / f"watched-{gait}", gait=gait)
               for gait in ("rising_trot", "canter")}
    zips = {gait: zip_folder(folder) for gait, folder in folders.items()}
    # No job runs (the worker has a disk of its own): what the API alone writes.
    with queue_of(env.client.app, HeldQueue()) as held, watching_local_writes() as writes:
        upload = api.ok("POST", "/uploads", 201, json={"target": "bundle", "length_bytes": len(zips["rising_trot"]),
                                                       "filename": "trot.zip"})
        for offset in range(0, len(zips["rising_trot"]), 50_000):
            assert send(api, upload["id"], offset, zips["rising_trot"][offset:offset + 50_000]).status_code == 204
        resumable = api.ok("POST", f"/uploads/{upload['id']}/finalize")
        oneshot = api.ok("POST", "/rides/bundle", 201,
                         files={"file": ("canter.zip", zips["canter"], "application/zip")})
    # Not one file opened for writing, not one folder made: the zips were read in place in the bucket.
    assert writes == []
    assert held.jobs == [resumable["job_id"], oneshot["job_id"]]
    bucket = open_storage(env.settings)
    for gait, ride_id in (("rising_trot", resumable["ride_id"]), ("canter", oneshot["ride"]["id"])):
        assert bundle_recordings(api, ride_id) == bundle_clip_digests(folders[gait])
        stored = {k.removeprefix(f"rides/{ride_id}/bundle/") for k in bucket.iter_keys(f"rides/{ride_id}/bundle")}
        assert stored == {p.relative_to(folders[gait]).as_posix() for p in folders[gait].rglob("*") if p.is_file()}
    assert not list(bucket.iter_keys("incoming")) and not list(bucket.iter_keys("uploads"))


def _zip_without(data: bytes, name: str) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(data)) as source, zipfile.ZipFile(out, "w") as target:
        for info in source.infolist():
            if info.filename != name:
                target.writestr(info, source.read(info))
    return out.getvalue()


def bad_bundle_zips(folder) -> dict[str, tuple[bytes, str]]:
    """Broken bundles and the exact reason each gets, the same on both storage back ends."""
    ride_json = json.loads((folder / "ride.json").read_text())
    good = zip_folder(folder)
    # A new horse: registered before the broken member is met on object storage, and taken back with the ride.
    new_horse = zip_folder(folder, rewrite={"ride.json": json.dumps({**ride_json, "horse": {"name": "Only in a zip"}})})
    return {
        "not a zip": (b"this is a video, honest\n" * 500, "ride.zip: a ride bundle must be a folder or a .zip archive"),
        "no ride.json": (_zip_without(good, "ride.json"), "ride.zip: no ride.json (is this a ride bundle?)"),
        "escaping member": (zip_folder(folder, extra={"../../escape.avi": b"x" * 100}),
                            "ride.zip: member '../../escape.avi' has a '..' component (it would be written "
                            "outside the bundle)"),
        "truncated": (good[:len(good) * 2 // 3], "ride.zip: a ride bundle must be a folder or a .zip archive"),
        "corrupt member": (zip_with_a_flipped_byte(new_horse, "motion/left.avi"),
                           "ride.zip: corrupt or unsupported zip archive (Bad CRC-32 for file 'motion/left.avi')"),
    }


def test_a_broken_bundle_gets_the_same_reason_on_both_back_ends_and_leaves_nothing(env, club):
    api = club["api"]
    cases = bad_bundle_zips(write_tiny_bundle(club["folder"] / "broken", gait="sitting_trot"))
    rides_before = {r["id"] for r in api.ok("GET", "/rides", params={"limit": 500})["items"]}
    horses_before = {h["name"] for h in api.ok("GET", "/horses", params={"limit": 500})["items"]}
    upload_ids = []
    for what, (data, reason) in cases.items():
        oneshot = api.post("/rides/bundle", files={"file": ("ride.zip", data, "application/zip")})
        assert (oneshot.status_code, oneshot.json()["detail"]) == (422, reason), what
        upload = api.ok("POST", "/uploads", 201, json={"target": "bundle", "length_bytes": len(data),
                                                       "filename": "ride.zip"})
        upload_ids.append(upload["id"])
        assert send(api, upload["id"], 0, data).status_code == 204
        finalised = api.post(f"/uploads/{upload['id']}/finalize")
        assert (finalised.status_code, finalised.json()["detail"]) == (422, reason), what
        assert (api.ok("GET", f"/uploads/{upload['id']}")["status"], what) == ("failed", what)
    assert {r["id"] for r in api.ok("GET", "/rides", params={"limit": 500})["items"]} == rides_before
    assert {h["name"] for h in api.ok("GET", "/horses", params={"limit": 500})["items"]} == horses_before
    # Nothing in the store: no staged zip, no upload's bytes, no file of a ride taken back.
    store = open_storage(env.settings)
    keys = [k for prefix in ("incoming", "uploads", "rides") if store.exists(prefix) for k in store.iter_keys(prefix)]
    assert not [k for k in keys if k.startswith(("incoming/", *(f"uploads/{u}" for u in upload_ids)))]
    assert not [k for k in keys if k.startswith("rides/") and int(k.split("/")[1]) > max(rides_before, default=0)]


def _wind_back(env, upload_id: str, hours: float) -> None:
    """Make an upload look untouched for `hours` (its row's last move)."""
    from sqlalchemy import create_engine, text

    engine = create_engine(env.settings.database_url)
    with engine.begin() as connection:
        connection.execute(text("UPDATE uploads SET updated_at = updated_at - :age WHERE id = :id")
                           if engine.dialect.name == "postgresql" else
                           text("UPDATE uploads SET updated_at = datetime(updated_at, :age) WHERE id = :id"),
                           {"age": dt.timedelta(hours=hours) if engine.dialect.name == "postgresql"
                            else f"-{hours} hours", "id": upload_id})
    engine.dispose()


def test_the_sweep_removes_an_abandoned_upload_and_keeps_a_live_one(env, club):
    """What a club gave up on goes with its bytes after `upload_expiry_s`; an upload still moving stays.
    The sweep is what every worker runs hourly and `saddlescope sweep` runs by hand."""
    from saddlescope.db.session import session_factory_for
    from saddlescope.services.uploads.intake import sweep_abandoned

    api, ride = club["api"], club["ride"]
    data = write_tiny_clip(club["folder"] / "sweep.avi", frames=8).read_bytes()
    given_up, live = start(api, ride["id"], data, camera="middle"), start(api, ride["id"], data, camera="right")
    for upload in (given_up, live):
        assert send(api, upload["id"], 0, data[:1000]).status_code == 204
    storage = open_storage(env.settings)
    _wind_back(env, given_up["id"], hours=25)
    swept = sweep_abandoned(session_factory_for(env.settings.database_url), storage,
                            max_age_s=env.settings.upload_expiry_s)
    assert swept["expired uploads"] == 1, swept
    assert api.get(f"/uploads/{given_up['id']}").status_code == 404
    assert not any(key.startswith(f"uploads/{given_up['id']}") for key in storage.iter_keys("uploads"))
    assert api.ok("GET", f"/uploads/{live['id']}")["offset_bytes"] == 1000  # still resumable
    assert send(api, live["id"], 1000, data[1000:]).status_code == 204


def _finalise_at_once(api, upload_id: str, times: int = 12) -> list:
    """`times` finalises of one upload sent together (a client retrying a slow finalise, several tabs)."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=times) as pool:
        return list(pool.map(lambda _: api.post(f"/uploads/{upload_id}/finalize"), range(times)))


def test_concurrent_finalises_of_a_clip_answer_one_outcome_never_500(env, club):
    # Issue 39 item 3: the "still open" check and the move were not atomic: [200, 500, 500, 500].
    api, ride = club["api"], club["ride"]
    data = write_tiny_clip(club["folder"] / "twelve.avi", frames=10).read_bytes()
    upload = start(api, ride["id"], data, camera="left")
    assert send(api, upload["id"], 0, data).status_code == 204
    answers = _finalise_at_once(api, upload["id"])
    codes = sorted(r.status_code for r in answers)
    assert set(codes) <= {200, 409} and codes.count(200) >= 1, [(r.status_code, r.text) for r in answers]
    outcomes = [r.json() for r in answers if r.status_code == 200]
    assert all(o == outcomes[0] for o in outcomes), outcomes
    assert all(str(ride["id"]) in r.json()["detail"] or "being finalised" in r.json()["detail"]
               for r in answers if r.status_code == 409)
    # A retry after the end answers the same outcome; one clip stored, with the right bytes.
    assert api.ok("POST", f"/uploads/{upload['id']}/finalize") == outcomes[0]
    assert api.ok("GET", f"/uploads/{upload['id']}")["status"] == "finalised"
    clips = [c for c in api.ok("GET", f"/rides/{ride['id']}/clips") if c["id"] == outcomes[0]["recording_id"]]
    assert len(clips) == 1 and clips[0]["sha256"] == hashlib.sha256(data).hexdigest()


def test_concurrent_finalises_of_a_bundle_make_one_ride(env, club):
    api = club["api"]
    data = zip_folder(write_tiny_bundle(club["folder"] / "bundle-twelve", gait="canter", frames=6))
    upload = api.ok("POST", "/uploads", 201,
                    json={"target": "bundle", "length_bytes": len(data), "filename": "twelve.zip"})
    assert send(api, upload["id"], 0, data).status_code == 204
    rides_before = api.ok("GET", "/rides")["total"]
    answers = _finalise_at_once(api, upload["id"])
    assert {r.status_code for r in answers} <= {200, 409}, [(r.status_code, r.text) for r in answers]
    outcomes = [r.json() for r in answers if r.status_code == 200]
    assert outcomes and all(o == outcomes[0] for o in outcomes), outcomes
    assert api.ok("GET", "/rides")["total"] == rides_before + 1  # one ride made, whoever answered
    assert api.ok("GET", f"/rides/{outcomes[0]['ride_id']}")["from_bundle"]
    assert api.ok("POST", f"/uploads/{upload['id']}/finalize") == outcomes[0]
    if env.engine == "embedded":
        assert job_outcome(api, outcomes[0]["job_id"], timeout_s=300)["status"] in ("done", "failed")


def test_a_finalise_still_running_after_the_wait_answers_409_and_a_dead_one_is_swept(env, club, monkeypatch):
    """Another request holds the upload (its row says finalising): after `FINALISE_WAIT_S` the answer is 409
    with Retry-After, never 500; a finalise whose process died leaves the claim to the sweep."""
    from sqlalchemy import create_engine, text

    from saddlescope.db.session import session_factory_for
    from saddlescope.services.uploads import intake as uploads_service

    api, ride = club["api"], club["ride"]
    data = write_tiny_clip(club["folder"] / "held.avi", frames=8).read_bytes()
    upload = start(api, ride["id"], data, camera="middle")
    assert send(api, upload["id"], 0, data).status_code == 204
    engine = create_engine(env.settings.database_url)
    with engine.begin() as connection:  # what a finalise in another process did first
        connection.execute(text("UPDATE uploads SET status = 'finalising' WHERE id = :id"), {"id": upload["id"]})
    engine.dispose()
    monkeypatch.setattr(uploads_service, "FINALISE_WAIT_S", 0.3)
    held = api.post(f"/uploads/{upload['id']}/finalize")
    assert held.status_code == 409 and held.headers["Retry-After"] == "5", held.text
    assert "is being finalised by an earlier request" in held.json()["detail"]
    assert api.ok("GET", f"/uploads/{upload['id']}")["status"] == "finalising"
    _wind_back(env, upload["id"], hours=25)
    swept = uploads_service.sweep_abandoned(session_factory_for(env.settings.database_url),
                                            open_storage(env.settings), max_age_s=env.settings.upload_expiry_s)
    assert swept["expired uploads"] >= 1 and api.get(f"/uploads/{upload['id']}").status_code == 404

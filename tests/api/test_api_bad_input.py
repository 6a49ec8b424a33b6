"""The bad-input corpus: every refusal is a 4xx with a specific reason, and nothing stored before is lost."""

from __future__ import annotations

import json

import integration_services
import pytest
from api_helpers import new_club, zip_bomb, zip_folder, zip_members
from engines import ENGINES, MAX_UPLOAD_BYTES, open_env
from integration_services import write_tiny_bundle, write_tiny_clip

from saddlescope.storage import open_storage

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture(scope="module")
def setup(env, tmp_path_factory):
    """A club with a ride whose left motion clip is uploaded (the thing that must survive every refusal)."""
    api, _ = new_club(env.client)
    horse = api.ok("POST", "/horses", 201, json={"name": "Steady"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Careful"})
    ride = api.ok(
        "POST",
        "/rides",
        201,
        json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk", "direction": "CW"},
    )
    folder = tmp_path_factory.mktemp("corpus")
    good = write_tiny_clip(folder / "good.avi", frames=6)
    first = api.ok(
        "PUT", f"/rides/{ride['id']}/clips/motion/left", files={"file": ("good.avi", good.read_bytes())}
    )
    return {
        "api": api,
        "ride": ride,
        "folder": folder,
        "good": first["recording"],
        "bundle": write_tiny_bundle(folder / "bundle"),
    }


def state(env, setup) -> tuple:
    """What must not change: the ride's recordings, the club's rides, and leftovers in storage."""
    api, ride = setup["api"], setup["ride"]
    clips = api.ok("GET", f"/rides/{ride['id']}/clips")
    recordings = sorted((r["clip_kind"], r["camera_role"], r["sha256"]) for r in clips)
    storage = open_storage(env.settings)
    files = [k for k in storage.iter_keys("rides") if "/clips/" in k]
    leftovers = [k for k in storage.iter_keys("incoming")] if storage.exists("incoming") else []
    return recordings, api.ok("GET", "/rides")["total"], sorted(files), leftovers


def refused(env, setup, response, status: int, *reasons: str) -> None:
    body = response.json()
    assert response.status_code == status, body
    assert str(env.settings.storage_dir) not in body["detail"]  # where storage lives is nobody's business
    for reason in reasons:
        assert reason in body["detail"], body["detail"]


def clip(setup, name: str, **kwargs) -> bytes:
    return write_tiny_clip(setup["folder"] / name, **kwargs).read_bytes()


@pytest.mark.parametrize(
    ("name", "make", "reasons"),
    [
        ("empty.mp4", lambda s: b"", ["motion clip of the middle camera", "empty file"]),
        (
            "notes.mp4",
            lambda s: b"these are my notes, not a video\n" * 100,
            ["motion clip of the middle camera (notes.mp4) is not a usable video"],
        ),
        (
            "cut.avi",
            lambda s: clip(s, "whole.avi", frames=20)[:3000],
            ["motion clip of the middle camera (cut.avi) is not a usable video"],
        ),
        (
            "slow.avi",
            lambda s: clip(s, "slow.avi", frames=6, fps=25.0),
            ["runs at 25.000 fps but the left camera's at 30.000 fps", "same frame rate"],
        ),
        (
            "big.avi",
            lambda s: clip(s, "big.avi", frames=6, size=(80, 60)),
            ["is 80x60 px but the left camera's is 64x48 px"],
        ),
    ],
)
def test_an_unusable_clip_is_refused_with_the_reason_and_the_earlier_clip_stays(
    env, setup, name, make, reasons
):
    before = state(env, setup)
    response = setup["api"].put(
        f"/rides/{setup['ride']['id']}/clips/motion/middle", files={"file": (name, make(setup), "video/mp4")}
    )
    refused(env, setup, response, 422, *reasons)
    assert state(env, setup) == before


def test_a_bad_replacement_keeps_the_good_clip(env, setup):
    before = state(env, setup)
    response = setup["api"].put(
        f"/rides/{setup['ride']['id']}/clips/motion/left", files={"file": ("junk.mp4", b"\x00" * 5000)}
    )
    refused(env, setup, response, 422, "motion clip of the left camera (junk.mp4) is not a usable video")
    assert state(env, setup) == before
    assert before[0] == [("motion", "left", setup["good"]["sha256"])]


def test_unknown_clip_kind_or_camera(env, setup):
    api, ride = setup["api"], setup["ride"]
    refused(
        env,
        setup,
        api.put(f"/rides/{ride['id']}/clips/warmup/left", content=b"x"),
        422,
        "a ride has no 'warmup' clips",
    )
    response = api.put(f"/rides/{ride['id']}/clips/motion/top", content=b"x")
    assert response.status_code == 422 and "camera" in response.json()["detail"]


def test_a_file_over_the_size_limit_is_refused_while_streaming(env, setup):
    before = state(env, setup)
    body = (b"\x00" * (1 << 20) for _ in range(MAX_UPLOAD_BYTES // (1 << 20) + 1))  # a generator: streamed
    response = setup["api"].put(
        f"/rides/{setup['ride']['id']}/clips/motion/middle",
        content=body,
        headers={"Content-Type": "application/octet-stream"},
    )
    refused(env, setup, response, 413, "larger than the upload limit of 16777216 bytes")
    assert state(env, setup) == before
    multipart = setup["api"].put(
        f"/rides/{setup['ride']['id']}/clips/motion/middle",
        files={"file": ("huge.mp4", b"\x00" * (MAX_UPLOAD_BYTES + 1))},
    )
    refused(env, setup, multipart, 413, "larger than the upload limit")
    resumable = setup["api"].post(
        "/uploads",
        json={
            "target": "ride_clip",
            "ride_id": setup["ride"]["id"],
            "clip_kind": "motion",
            "camera": "right",
            "length_bytes": MAX_UPLOAD_BYTES + 1,
        },
    )
    refused(env, setup, resumable, 413, "larger than the upload limit")
    assert state(env, setup) == before


def bundle_with(setup, **changes) -> bytes:
    folder = setup["bundle"]
    meta = json.loads((folder / "ride.json").read_text())
    meta.update(changes)
    return zip_folder(folder, rewrite={"ride.json": json.dumps(meta).encode()})


@pytest.mark.parametrize(
    ("make", "reasons"),
    [
        (lambda s: zip_folder(s["bundle"], extra={"../../evil.txt": b"owned"}), ["'..' component"]),
        (lambda s: zip_bomb(), ["compresses", "zip bomb"]),
        (lambda s: bundle_with(s, gait="gallop"), ["ride.json", "gait", "gallop"]),
        (lambda s: bundle_with(s, cameras=["left", "middle", "top"]), ["ride.json", "top"]),
        (
            lambda s: bundle_with(
                s,
                clips={
                    **json.loads((s["bundle"] / "ride.json").read_text())["clips"],
                    "motion": {
                        "left": "motion/left.avi",
                        "middle": "motion/middle.avi",
                        "right": "motion/missing.avi",
                    },
                },
            ),
            ["clips.motion.right 'motion/missing.avi' does not exist in the bundle"],
        ),
        (
            lambda s: b"PK\x03\x04 this is not really a zip",
            ["a ride bundle must be a folder or a .zip archive"],
        ),
        (lambda s: zip_members({"notes.txt": b"hello"}), ["no ride.json"]),
    ],
)
def test_a_bad_bundle_is_refused_with_the_reason_and_nothing_is_registered(env, setup, make, reasons):
    before = state(env, setup)
    response = setup["api"].post(
        "/rides/bundle", files={"file": ("ride.zip", make(setup), "application/zip")}
    )
    refused(env, setup, response, 422, *reasons)
    assert state(env, setup) == before


def test_unknown_gait_and_other_bad_json_fields_name_the_field(env, setup):
    api = setup["api"]
    ride = setup["ride"]
    response = api.post(
        "/rides",
        json={
            "horse_id": ride["horse_id"],
            "rider_id": ride["rider_id"],
            "gait": "gallop",
            "direction": "CW",
        },
    )
    refused(env, setup, response, 422, "body.gait", "'walk', 'sitting_trot', 'rising_trot' or 'canter'")
    refused(
        env,
        setup,
        api.post("/horses", json={"name": "Tall", "height_withers_m": 3.5}),
        422,
        "body.height_withers_m",
    )
    refused(env, setup, api.post("/horses", json={"name": "Nul\x00l"}), 422, "NUL")
    # The sort values are an enum (the OpenAPI lists them); the refusal names the allowed ones.
    refused(env, setup, api.get("/rides", params={"sort": "-price"}), 422, "sort", "'-ridden_on'")
    refused(
        env,
        setup,
        api.get("/leaderboard", params={"gait": "canter", "indicator": "beauty"}),
        422,
        "unknown indicator 'beauty'",
    )
    refused(
        env,
        setup,
        api.post("/grades", json={"ride_id": ride["id"], "rider_id": ride["rider_id"], "grade": 6}),
        422,
        "body.grade",
    )
    horse = api.ok("POST", "/horses", 201, json={"name": "Twice"})
    refused(env, setup, api.post("/horses", json={"name": "Twice"}), 409, "already has a horse named 'Twice'")
    refused(env, setup, api.delete(f"/horses/{ride['horse_id']}"), 409, "still has 1 ride", "delete those rides first")
    assert api.ok("GET", f"/horses/{horse['id']}")["name"] == "Twice"

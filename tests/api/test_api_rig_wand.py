"""A rig calibrated with a wand (issue 35, item 3): its wand and close-up clips are uploaded like its
calibration clips, its wand length is set on the rig, and its calibration job takes the wand way.

The wand calibration itself is a stand-in here (tests/core and tests/services run the real one): what is
checked is which clips and which length the rig's job hands it, and the refusals in words before that.
"""

from __future__ import annotations

import pytest
from api_helpers import ThreadQueue, job_outcome, new_club, standin_calibrate_clips, standin_calibration
from fastapi.testclient import TestClient
from integration_services import write_tiny_clip

from saddlescope.api import create_app
from saddlescope.core.types import CAMERA_ROLES
from saddlescope.settings import load_settings

SMALL = {"kind": "checkerboard", "inner_corners": [5, 4], "square_mm": 20.0}


@pytest.fixture
def env(tmp_path, monkeypatch):
    import saddlescope.services.rigs.calibration as calibration

    calls: list[dict] = []

    def standin_wand(wand_paths, close_up_paths, *, board, wand_length_m, sync=None, params=None, on_progress=None):
        calls.append({"wand": sorted(wand_paths), "close_up": sorted(close_up_paths), "board": dict(board),
                      "wand_length_m": wand_length_m,
                      "wand_files": sorted(p.name.split("-")[0] for p in wand_paths.values())})
        return {**standin_calibration((64, 48)), "wand": {"length_m": wand_length_m}}

    def standin_board_and_wand(paths, wand_paths, *, board, wand_length_m, sync=None, params=None, on_progress=None):
        calls.append({"way": "board+wand", "calibration": sorted(paths), "wand": sorted(wand_paths),
                      "wand_length_m": wand_length_m,
                      "kinds": [_kind_of(p) for p in [*paths.values(), *wand_paths.values()]]})
        return {**standin_calibration((64, 48)), "wand": {"length_m": wand_length_m},
                "wand_refinement": {"kept": True, "reason": "no worse", "sentence": "Refined by the wand: the middle "
                                    "camera's lens is now known to 700 px from the centre of its image, was 240 px.",
                                    "board": {}, "refined": {}}}

    monkeypatch.setattr(calibration, "calibrate_clips", standin_calibrate_clips)
    monkeypatch.setattr(calibration, "calibrate_wand_clips", standin_wand)
    monkeypatch.setattr(calibration, "calibrate_board_and_wand_clips", standin_board_and_wand)
    settings = load_settings(database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "storage"))
    queue = ThreadQueue(settings)
    with TestClient(create_app(settings, queue=queue)) as client:
        api, _account = new_club(client)
        yield api, tmp_path, calls
    queue.close()


def _kind_of(path) -> str:
    """The clip kind of a clip the job fetched: the kind `_tagged` appended to its bytes."""
    return path.read_bytes()[-16:].decode().strip("#")


def _tagged(clip: bytes, kind: str) -> bytes:
    """A clip with its kind appended (after the container's end: decoders ignore it)."""
    return clip + kind.rjust(16, "#").encode()


def _upload(api, rig_id: int, kind: str, camera: str, clip: bytes) -> None:
    api.ok("PUT", f"/rigs/{rig_id}/clips/{kind}/{camera}", files={"file": (f"{kind}-{camera}.avi", clip)})


def test_a_wand_length_in_centimetres_is_refused_in_words(env):
    api, _, _ = env
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena", "board": SMALL})
    assert rig["wand_length_m"] is None
    refused = api.client.patch(f"/api/rigs/{rig['id']}", json={"wand_length_m": 100}, headers=api.headers)
    assert refused.status_code == 422
    assert "100 cm is 1.00 m" in refused.text
    assert api.ok("PATCH", f"/rigs/{rig['id']}", json={"wand_length_m": 1.2})["wand_length_m"] == 1.2
    assert api.ok("PATCH", f"/rigs/{rig['id']}", json={"wand_length_m": None})["wand_length_m"] is None


def test_the_wand_way_without_its_length_or_clips_is_refused_in_words(env):
    api, tmp_path, calls = env
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena", "board": SMALL})
    url = f"/api/rigs/{rig['id']}/calibrate"
    no_length = api.client.post(url, json={"method": "wand"}, headers=api.headers)
    assert no_length.status_code == 422
    assert "give the wand's length first" in no_length.json()["detail"]
    no_clips = api.client.post(url, json={"method": "wand", "wand_length_m": 1.0}, headers=api.headers)
    assert no_clips.status_code == 409
    assert no_clips.json()["detail"].endswith(
        "cannot be calibrated with a wand yet: upload the wand clip of the left, middle, right cameras and "
        "the close-up clip of the left, middle, right cameras first")
    # the board walk without its clips, asked for by name, is refused the same way
    board = api.client.post(url, json={"method": "board"}, headers=api.headers)
    assert board.status_code == 409 and "upload the calibration clip of the left, middle, right cameras" in board.text
    assert calls == []


def test_a_rigs_wand_and_close_up_clips_and_length_calibrate_it_the_wand_way(env):
    api, tmp_path, calls = env
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena", "board": SMALL, "wand_length_m": 0.9})
    clip = write_tiny_clip(tmp_path / "clip.avi", frames=6).read_bytes()
    for camera in CAMERA_ROLES:
        _upload(api, rig["id"], "close_up", camera, clip)
    for camera in CAMERA_ROLES[:2]:
        _upload(api, rig["id"], "wand", camera, clip)
    part = api.client.post(f"/api/rigs/{rig['id']}/calibrate", json={"method": "wand"}, headers=api.headers)
    assert part.status_code == 409 and "upload the wand clip of the right camera first" in part.text
    assert {r["clip_kind"] for r in api.ok("GET", f"/rigs/{rig['id']}/clips")} == {"wand", "close_up"}
    _upload(api, rig["id"], "wand", "right", clip)  # the last clip of the wand way starts the calibration
    jobs = api.ok("GET", "/jobs", params={"rig_id": rig["id"]})["items"]
    job = next(j for j in jobs if j["kind"] == "calibrate_rig")
    assert job_outcome(api, job["id"])["status"] == "done"
    assert calls == [{"wand": list(CAMERA_ROLES), "close_up": list(CAMERA_ROLES), "board": SMALL,
                      "wand_length_m": 0.9, "wand_files": sorted(CAMERA_ROLES)}]
    detail = api.ok("GET", f"/rigs/{rig['id']}")
    assert detail["calibrated"] and detail["calibration"]["wand"] == {"length_m": 0.9}
    # a new wand length makes the wand's calibration stale; calibrating again takes the new length
    assert api.ok("PATCH", f"/rigs/{rig['id']}", json={"wand_length_m": 1.0})["calibrated"] is False
    again = api.ok("POST", f"/rigs/{rig['id']}/calibrate", 201, json={})
    assert job_outcome(api, again["id"])["status"] == "done"
    assert [c["wand_length_m"] for c in calls] == [0.9, 1.0]


def test_a_ride_takes_no_wand_clips(env):
    api, tmp_path, _ = env
    horse = api.ok("POST", "/horses", 201, json={"name": "Bay"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Ann"})
    ride = api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                               "direction": "CW"})
    clip = write_tiny_clip(tmp_path / "clip.avi", frames=6).read_bytes()
    refused = api.client.put(f"/api/rides/{ride['id']}/clips/wand/left", files={"file": ("w.avi", clip)},
                             headers=api.headers)
    assert refused.status_code == 422 and "a ride has no 'wand' clips" in refused.text


def test_a_wand_clip_is_checked_on_upload_and_shown_beside_the_boards_check(env):
    """Issue 35 item 4: the wand's clips are checked before anyone rides, like the board's (the rig page shows
    the check's `wand`); without the wand's length there is nothing to look for, and the check waits for it."""
    api, tmp_path, _ = env
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena", "board": SMALL})
    clip = write_tiny_clip(tmp_path / "clip.avi", frames=12).read_bytes()
    _upload(api, rig["id"], "wand", "left", clip)
    assert [j for j in api.ok("GET", "/jobs", params={"rig_id": rig["id"]})["items"]
            if j["kind"] == "check_calibration"] == []  # no wand length yet: nothing to check against
    refused = api.client.post(f"/api/rigs/{rig['id']}/calibration-check", headers=api.headers)
    assert refused.status_code == 409 and "no wand length for its wand clips" in refused.json()["detail"]
    api.ok("PATCH", f"/rigs/{rig['id']}", json={"wand_length_m": 1.0})
    _upload(api, rig["id"], "wand", "middle", clip)  # a clip of a rig with its wand's length: checked at once
    job = next(j for j in api.ok("GET", "/jobs", params={"rig_id": rig["id"]})["items"]
               if j["kind"] == "check_calibration")
    assert job_outcome(api, job["id"])["status"] == "done"
    check = api.ok("GET", f"/rigs/{rig['id']}/calibration-check")
    assert check["checked"] is False  # the board's clips: none uploaded
    wand = check["wand"]
    assert sorted(wand["cameras"]) == ["left", "middle"] and wand["film_again"] is True  # no wand in these clips
    assert wand["verdict"].startswith("Film again: the left and middle cameras' wand clips")


def test_a_rig_with_its_board_walk_and_wand_clips_is_calibrated_by_both(env):
    """Issue 35: the board walk refined by the wand is the way once the rig has both clip sets and the wand's
    length; the rig page says whether the wand refined it."""
    api, tmp_path, calls = env
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena", "board": SMALL, "wand_length_m": 1.0})
    url = f"/api/rigs/{rig['id']}/calibrate"
    clip = write_tiny_clip(tmp_path / "clip.avi", frames=6).read_bytes()
    for camera in CAMERA_ROLES:
        # the third starts the board walk's calibration
        _upload(api, rig["id"], "calibration", camera, _tagged(clip, "calibration"))
    jobs = api.ok("GET", "/jobs", params={"rig_id": rig["id"]})["items"]
    assert job_outcome(api, next(j for j in jobs if j["kind"] == "calibrate_rig")["id"])["status"] == "done"
    no_wand = api.client.post(url, json={"method": "board+wand"}, headers=api.headers)
    assert no_wand.status_code == 409 and no_wand.json()["detail"].endswith(
        "cannot be calibrated with the board walk refined by the wand yet: upload the wand clip of the left, "
        "middle, right cameras first")
    for camera in CAMERA_ROLES:  # each new clip makes the calibration stale; the third wand clip completes both
        _upload(api, rig["id"], "wand", camera, _tagged(clip, "wand"))
        # Each clip's board-walk job ends before the next clip comes, so that the wand's way is taken once
        # (a clip arriving while a job runs: test_a_wand_clip_uploaded_while_the_board_walk_is_calibrated_is_used).
        for job in api.ok("GET", "/jobs", params={"rig_id": rig["id"]})["items"]:
            if job["kind"] == "calibrate_rig":
                assert job_outcome(api, job["id"])["status"] == "done"
    jobs = api.ok("GET", "/jobs", params={"rig_id": rig["id"]})["items"]
    assert job_outcome(api, max(j["id"] for j in jobs if j["kind"] == "calibrate_rig"))["status"] == "done"
    call = {"way": "board+wand", "calibration": sorted(CAMERA_ROLES), "wand": sorted(CAMERA_ROLES),
            "wand_length_m": 1.0, "kinds": ["calibration"] * 3 + ["wand"] * 3}
    assert calls == [call]
    again = api.ok("POST", f"/rigs/{rig['id']}/calibrate", 201, json={})  # the page's "Calibrate again"
    assert job_outcome(api, again["id"])["status"] == "done"
    assert calls == [call, call]
    report = api.ok("GET", f"/rigs/{rig['id']}/calibration-report")
    assert report["quality"]["refined_by_wand"] is True
    assert "Refined by the wand: the middle camera's lens is now known to 700 px" in " ".join(
        report["quality"]["sentences"])
    # asked for by name, the board walk alone is still a way
    board = api.ok("POST", f"/rigs/{rig['id']}/calibrate", 201, json={"method": "board"})
    assert job_outcome(api, board["id"])["status"] == "done" and len(calls) == 2


def test_a_wand_clip_uploaded_while_the_board_walk_is_calibrated_is_used(env, monkeypatch):
    """A clip that arrives while the rig's calibration job runs: that job keeps nothing (its clips changed), and
    the job queued behind it calibrates from the clips as they are, the wand's among them."""
    import threading

    from api_helpers import standin_calibrate_clips

    import saddlescope.services.rigs.calibration as calibration

    api, tmp_path, calls = env
    release = threading.Event()
    started = threading.Semaphore(0)

    def slow_board_walk(paths, **kwargs):
        started.release()
        assert release.wait(60), "the test never let the board walk's calibration finish"
        return standin_calibrate_clips(paths, **kwargs)

    monkeypatch.setattr(calibration, "calibrate_clips", slow_board_walk)
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena", "board": SMALL, "wand_length_m": 1.0})
    clip = write_tiny_clip(tmp_path / "clip.avi", frames=6).read_bytes()
    for camera in CAMERA_ROLES:
        _upload(api, rig["id"], "calibration", camera, _tagged(clip, "calibration"))
    assert started.acquire(timeout=60)  # the board walk's job is calibrating
    for camera in CAMERA_ROLES:
        _upload(api, rig["id"], "wand", camera, _tagged(clip, "wand"))
    jobs = api.ok("GET", "/jobs", params={"rig_id": rig["id"]})["items"]
    newest = max(j["id"] for j in jobs if j["kind"] == "calibrate_rig")
    assert job_outcome(api, newest)["status"] == "done"  # the wand's clips completed, while the first still runs
    assert [c["way"] for c in calls] == ["board+wand"]
    release.set()
    first = min(j["id"] for j in jobs if j["kind"] == "calibrate_rig")
    ended = job_outcome(api, first)
    assert ended["status"] == "failed" and "its clips changed while this job calibrated it" in ended["error"]
    report = api.ok("GET", f"/rigs/{rig['id']}/calibration-report")
    assert report["quality"]["refined_by_wand"] is True  # the wand's calibration stayed: the board walk's did not

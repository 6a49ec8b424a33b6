"""Rigs and uploads as a club uses them: readiness before analysis, bundle pre-fill confirmed by the form,
nothing left behind by a refused bundle, the printable board at true scale and the calibration report."""

from __future__ import annotations

import json
import re

import pytest
from api_helpers import add_member, job_outcome, new_club, zip_folder
from engines import open_env
from integration_services import write_tiny_bundle, write_tiny_clip

from saddlescope.db.repositories import RigRepository
from saddlescope.db.session import make_engine, make_session_factory, session_scope
from saddlescope.storage import open_storage


@pytest.fixture(scope="module", params=["embedded"])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture
def club(env, tmp_path):
    api, info = new_club(env.client)
    horse = api.ok("POST", "/horses", 201, json={"name": "Bella"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Anna"})
    return {"api": api, "info": info, "horse": horse, "rider": rider, "folder": tmp_path}


BOARD = {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0}


def upload(api, data: bytes, *, finalize: bool = True, body: dict | None = None, **target) -> dict:
    """A resumable upload in one chunk; the finalize answer (or, unfinalised, the upload)."""
    created = api.ok("POST", "/uploads", 201, json={**target, "length_bytes": len(data)})
    sent = api.patch(f"/uploads/{created['id']}", content=data,
                     headers={"Upload-Offset": "0", "Content-Type": "application/offset+octet-stream"})
    assert sent.status_code == 204, sent.text
    if not finalize:
        return created
    return api.ok("POST", f"/uploads/{created['id']}/finalize", json=body or {})


def clip(folder, name: str) -> bytes:
    return write_tiny_clip(folder / f"{name}.avi", frames=6).read_bytes()


def new_ride(club, **extra) -> dict:
    return club["api"].ok("POST", "/rides", 201, json={
        "horse_id": club["horse"]["id"], "rider_id": club["rider"]["id"], "gait": "walk", "direction": "CW", **extra})


def test_a_ride_is_refused_with_what_is_missing_until_its_clips_and_rig_are_complete(club):
    api, folder = club["api"], club["folder"]
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena"})  # no board yet
    ride = new_ride(club, rig_id=rig["id"])
    answer = api.ok("GET", f"/rides/{ride['id']}/readiness")
    assert answer["ready"] is False
    text = " ".join(answer["missing"])
    assert "no calibration board described" in text
    assert "calibration clips" in text and "motion clip" in text and "static clip" in text

    api.ok("PATCH", f"/rigs/{rig['id']}", json={"board": BOARD})  # the club's admin sets the board
    for camera in ("left", "middle"):
        rig_clip = upload(api, clip(folder, f"cal-{camera}"), target="rig_clip", rig_id=rig["id"],
                          clip_kind="calibration", camera=camera)
        assert set(rig_clip) == {"recording_id", "job_id"}  # a rig's clip: no `missing` (absent, not null)
    for kind in ("static", "motion"):
        for camera in ("left", "middle", "right"):
            last = upload(api, clip(folder, f"{kind}-{camera}"), target="ride_clip", ride_id=ride["id"],
                          clip_kind=kind, camera=camera)
    # The last clip is stored, but nothing is queued: the answer says why.
    assert last["job_id"] is None
    assert any("only 2 cameras (left and middle)" in m and "right camera's calibration clip" in m
               for m in last["missing"]), last
    missing = api.ok("GET", f"/rides/{ride['id']}/readiness")["missing"]
    assert missing == last["missing"] and len(missing) == 1

    refused = api.post(f"/rides/{ride['id']}/analyze")
    assert refused.status_code == 422
    assert missing[0] in refused.json()["detail"] and "cannot be analysed yet" in refused.json()["detail"]
    assert api.ok("GET", "/jobs", params={"ride_id": ride["id"]})["total"] == 0

    upload(api, clip(folder, "cal-right"), target="rig_clip", rig_id=rig["id"], clip_kind="calibration",
           camera="right")
    assert api.ok("GET", f"/rides/{ride['id']}/readiness") == {"ready": True, "missing": []}
    job = api.ok("POST", f"/rides/{ride['id']}/analyze", 201)
    assert job["kind"] == "analyze"


def test_a_ride_without_a_rig_is_told_to_choose_one_and_an_incomplete_ride_can_be_deleted(club):
    api, folder = club["api"], club["folder"]
    ride = new_ride(club)
    upload(api, clip(folder, "m-left"), target="ride_clip", ride_id=ride["id"], clip_kind="motion", camera="left")
    missing = api.ok("GET", f"/rides/{ride['id']}/readiness")["missing"]
    assert missing[0].startswith("No camera rig is chosen")
    assert any("motion clips (the ride) of the middle and right cameras are missing" in m for m in missing)
    assert api.delete(f"/rides/{ride['id']}").status_code == 204  # an incomplete ride is deletable
    assert api.get(f"/rides/{ride['id']}/readiness").status_code == 404


def test_a_bundle_only_prefills_and_the_ride_takes_the_forms_choices(env, club, tmp_path):
    api = club["api"]
    data = zip_folder(write_tiny_bundle(tmp_path / "bundle"))
    staged = upload(api, data, finalize=False, target="bundle", filename="sunday.zip")
    meta = api.ok("GET", f"/uploads/{staged['id']}/bundle-meta")
    assert meta["horse"] == {"name": "Horse 2", "id": None} and meta["rider"] == {"name": "Rider B", "id": None}
    assert (meta["gait"], meta["direction"]) == ("walk", "CCW")
    assert api.ok("GET", "/rides")["total"] == 0  # reading the meta creates nothing

    rig = api.ok("POST", "/rigs", 201, json={"name": "Sunday rig", "board": BOARD})
    chosen = {"horse_id": club["horse"]["id"], "rider_id": club["rider"]["id"], "gait": "canter",
              "direction": "CW", "ridden_on": "2026-05-03", "notes": "new saddle", "rig_id": rig["id"]}
    done = api.ok("POST", f"/uploads/{staged['id']}/finalize", json=chosen)
    ride = api.ok("GET", f"/rides/{done['ride_id']}")
    assert {k: ride[k] for k in chosen} == chosen
    horses = [h["name"] for h in api.ok("GET", "/horses")["items"]]
    riders = [r["name"] for r in api.ok("GET", "/riders")["items"]]
    assert horses == ["Bella"] and riders == ["Anna"]  # the zip's horse and rider were not added


def test_a_bundle_kept_as_the_zip_says_adds_its_horse_only_when_the_form_leaves_it(club, tmp_path):
    api = club["api"]
    data = zip_folder(write_tiny_bundle(tmp_path / "bundle", gait="canter"))
    done = upload(api, data, target="bundle", filename="b.zip", body={"direction": "CW"})
    ride = api.ok("GET", f"/rides/{done['ride_id']}")
    assert (ride["gait"], ride["direction"]) == ("canter", "CW")
    assert "Horse 2" in [h["name"] for h in api.ok("GET", "/horses")["items"]]


def test_a_refused_bundle_leaves_nothing_behind(env, club, tmp_path):
    api = club["api"]
    folder = write_tiny_bundle(tmp_path / "bundle")
    meta = json.loads((folder / "ride.json").read_text())
    meta["clips"]["motion"]["right"] = "motion/missing.avi"
    data = zip_folder(folder, rewrite={"ride.json": json.dumps(meta).encode()})
    storage = open_storage(env.settings)

    def stored() -> set[str]:
        return {k for top in ("rides", "incoming", "uploads") if storage.exists(top) for k in storage.iter_keys(top)}

    for job in api.ok("GET", "/jobs")["items"]:  # the earlier tests' analyses write their results meanwhile
        job_outcome(api, job["id"])
    before = stored()
    staged = upload(api, data, finalize=False, target="bundle", filename="broken.zip")
    assert api.ok("GET", f"/uploads/{staged['id']}/bundle-meta")["gait"] == "walk"  # ride.json itself reads
    refused = api.post(f"/uploads/{staged['id']}/finalize",
                       json={"horse_id": club["horse"]["id"], "rider_id": club["rider"]["id"]})
    assert refused.status_code == 422 and "missing.avi" in refused.text
    assert api.ok("GET", "/rides")["total"] == 0
    assert api.delete(f"/uploads/{staged['id']}").status_code == 204  # as the dashboard does after a 4xx
    assert stored() - before == set()  # no ride folder, staged copy or upload bytes left

    not_zip = upload(api, b"not a zip at all", finalize=False, target="bundle", filename="notes.txt")
    answer = api.get(f"/uploads/{not_zip['id']}/bundle-meta")
    assert answer.status_code == 422
    assert answer.json()["detail"] == "notes.txt: a ride bundle must be a folder or a .zip archive"


@pytest.mark.parametrize("board,size_mm", [
    (BOARD, (600, 450)),  # 9 x 6 inner corners: 10 x 7 squares and a one-square margin each side
    ({"kind": "charuco", "inner_corners": [5, 3], "square_mm": 30.0, "marker_mm": 22.0,
      "dictionary": "DICT_4X4_50"}, (240, 180)),
])
def test_the_board_prints_at_true_scale(club, board, size_mm):
    api = club["api"]
    rig = api.ok("POST", "/rigs", 201, json={"name": f"rig {board['kind']}", "board": board})
    svg = api.get(f"/rigs/{rig['id']}/board.svg")
    assert svg.status_code == 200 and svg.headers["content-type"].startswith("image/svg+xml")
    width = re.search(r'width="([0-9.]+)mm"', svg.text)
    height = re.search(r'height="([0-9.]+)mm"', svg.text)
    assert (float(width.group(1)), float(height.group(1))) == pytest.approx(size_mm)
    cols, rows = board["inner_corners"]
    assert float(width.group(1)) == pytest.approx((cols + 1 + 2) * board["square_mm"])
    assert f'viewBox="0 0 {size_mm[0]:g} {size_mm[1]:g}"' in svg.text and "data:image/png;base64," in svg.text
    bare = api.ok("POST", "/rigs", 201, json={"name": "no board"})
    assert api.get(f"/rigs/{bare['id']}/board.svg").status_code == 404


def test_a_member_cannot_change_the_board(env, club):
    api = club["api"]
    rig = api.ok("POST", "/rigs", 201, json={"name": "shared", "board": BOARD})
    member, _ = add_member(api)
    refused = member.patch(f"/rigs/{rig['id']}", json={"board": {**BOARD, "square_mm": 40.0}})
    assert refused.status_code == 403 and "rig.change_board" in refused.text


def test_the_calibration_report_says_quality_and_where_the_board_never_was(env, club):
    api = club["api"]
    rig = api.ok("POST", "/rigs", 201, json={"name": "measured", "board": BOARD})
    # not calibrated: the quality is one sentence, without the numbers' keys (CalibrationReportOut)
    assert api.ok("GET", f"/rigs/{rig['id']}/calibration-report") == {
        "quality": {"calibrated": False, "sentences": ["Not calibrated yet."]}, "coverage": {}, "calibrating": False}
    cams = {c: {"K": [[800, 0, 320], [0, 800, 240], [0, 0, 1]], "dist": [0] * 5, "image_size": [640, 480],
                "rms_px": rms} for c, rms in (("left", 0.21), ("middle", 0.3), ("right", 1.6))}
    left_third = [[x, y] for x in (20.0, 100.0, 200.0) for y in (20.0, 240.0, 460.0)]
    everywhere = [[x, y] for x in (20.0, 320.0, 620.0) for y in (20.0, 240.0, 460.0)]
    calibration = {"cameras": cams, "extrinsics": {}, "checks": {"board_square_error_mm": 0.3}, "flags": [],
                   "pairs": {}, "board_corners_px": {"left": left_third, "middle": everywhere},
                   "board_coverage": {"left": {"hull_px": [[20, 20], [200, 20], [200, 460], [20, 460]],
                                               "area_fraction": 0.26}}}
    engine = make_engine(env.settings.database_url)
    try:
        with session_scope(make_session_factory(engine)) as session:
            RigRepository(session).set_calibration(rig["id"], calibration, {"flags": []})
    finally:
        engine.dispose()
    report = api.ok("GET", f"/rigs/{rig['id']}/calibration-report")
    quality = report["quality"]
    assert quality["reprojection_px"] == pytest.approx(1.6) and quality["reprojection_grade"] == "poor"
    assert quality["square_grade"] == "good" and "0.30 mm" in " ".join(quality["sentences"])
    left = report["coverage"]["left"]
    assert left["missed"] == ["top edge", "top-right corner", "centre", "right edge", "bottom edge",
                              "bottom-right corner"]
    assert left["sentence"].startswith("The board never reached the top edge, top-right corner")
    assert left["corners_px"] == left_third and left["area_fraction"] == pytest.approx(0.26)
    assert report["coverage"]["middle"]["missed"] == []
    right = report["coverage"]["right"]
    assert right["missed"] is None and "calibrate again" in right["sentence"]

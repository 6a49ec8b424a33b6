"""The rig's board as a club prints it, and its calibration clips checked before anyone rides (issue 35):
the board's size and the papers it fits with the square each camera distance needs, the print page with
its own page size and policy, and the check that runs by itself on every calibration clip uploaded."""

from __future__ import annotations

import re

import pytest
from api_helpers import new_club
from engines import open_env
from integration_services import write_tiny_clip

BIG = {"kind": "checkerboard", "inner_corners": [12, 11], "square_mm": 50.0}  # 750 x 700 mm
SMALL = {"kind": "checkerboard", "inner_corners": [5, 4], "square_mm": 20.0}  # 160 x 140 mm


@pytest.fixture(scope="module", params=["embedded"])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture
def api(env):
    return new_club(env.client)[0]


def test_the_board_sizes_state_the_print_and_the_square_each_distance_needs(api):
    rig = api.ok("POST", "/rigs", 201, json={"name": "Outdoor", "board": BIG})
    sizes = api.ok("GET", f"/rigs/{rig['id']}/board-sizes")
    assert (sizes["width_mm"], sizes["height_mm"], sizes["square_mm"]) == (750, 700, 50)
    # no clip, no calibration: a 1080p phone with a 70 degree view; 8 px a square
    assert (sizes["image_width_px"], sizes["hfov_deg"], sizes["camera_source"]) == (1920, 70.0, "assumed")
    needed = {row["distance_m"]: row["square_mm"] for row in sizes["squares_needed"]}
    assert needed[8.0] == pytest.approx(8 * 2 * 8000 * 0.7002 / 1920, abs=0.1)  # 47 mm at 8 m
    assert needed[4.0] == pytest.approx(needed[8.0] / 2, abs=0.1)
    assert "47 mm at 8 m" in " ".join(sizes["sentences"])
    assert sizes["reach_m"] == pytest.approx(50 / needed[8.0] * 8, rel=0.01)
    layouts = {lay["layout"]: lay for lay in sizes["layouts"]}
    assert [k for k, lay in layouts.items() if lay["fits"]] == ["a0", "a4-tiles"]
    assert layouts["a4-tiles"]["sheets"] == 12
    # on one A3 sheet this pattern's squares could be at most (420 - 20) / 15 mm, found up to about 4.4 m
    assert layouts["a3"]["largest_square_mm"] == pytest.approx(min(400 / 15, 259 / 14), abs=0.1)
    assert layouts["a3"]["reach_m"] < layouts["a0"]["reach_m"]

    small = api.ok("POST", "/rigs", 201, json={"name": "Indoor", "board": SMALL})
    small_sizes = api.ok("GET", f"/rigs/{small['id']}/board-sizes")
    assert next(lay for lay in small_sizes["layouts"] if lay["layout"] == "a4")["fits"]
    assert "it fits one A4 sheet" in small_sizes["sentences"][0]


def test_the_print_page_has_its_page_size_its_own_policy_and_refuses_a_paper_too_small(api):
    rig = api.ok("POST", "/rigs", 201, json={"name": "Outdoor", "board": BIG})
    page = api.get(f"/rigs/{rig['id']}/board-print", params={"layout": "a4-tiles"})
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert re.search(r"@page\{size:(210mm 297mm|297mm 210mm);margin:0\}", page.text)
    assert page.text.count('<section class="sheet">') == 12
    assert "'sha256-" in page.headers["content-security-policy"] and "script-src" not in page.headers[
        "content-security-policy"]
    assert page.text.count("This bar must measure exactly 100 mm") == 12
    refused = api.get(f"/rigs/{rig['id']}/board-print", params={"layout": "a3"})
    assert refused.status_code == 422
    assert refused.json()["detail"].startswith("the board is 750 \u00d7 700 mm and does not fit on one A3 sheet")
    assert api.get(f"/rigs/{rig['id']}/board-print", params={"layout": "letter"}).status_code == 422
    bare = api.ok("POST", "/rigs", 201, json={"name": "no board"})
    assert api.get(f"/rigs/{bare['id']}/board-print").status_code == 404
    assert api.get(f"/rigs/{bare['id']}/board-sizes").status_code == 404


def test_a_calibration_clip_is_checked_as_soon_as_it_is_uploaded(api, tmp_path):
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena", "board": BIG})
    before = api.ok("GET", f"/rigs/{rig['id']}/calibration-check")
    assert before["checked"] is False and before["cameras"] == {} and "Not checked yet" in before["verdict"]
    assert api.post(f"/rigs/{rig['id']}/calibration-check").status_code == 409  # nothing to check yet

    clip = write_tiny_clip(tmp_path / "left.avi", frames=6).read_bytes()  # no board in it
    api.ok("PUT", f"/rigs/{rig['id']}/clips/calibration/left", files={"file": ("left.avi", clip)})
    jobs = api.ok("GET", "/jobs", params={"rig_id": rig["id"]})["items"]
    check_job = next(job for job in jobs if job["kind"] == "check_calibration")
    done, _ = api.wait_job(check_job["id"], timeout_s=120)
    assert done["status"] == "done", done
    check = api.ok("GET", f"/rigs/{rig['id']}/calibration-check")
    assert check["checked"] and check["film_again"] and check["verdict"].startswith("Film again: the left camera")
    left = check["cameras"]["left"]
    assert left["views"] == 0 and left["frames_sampled"] == 6
    assert [f["code"] for f in left["findings"]] == ["calibration_check.board_not_seen"]
    assert left["findings"][0]["severity"] == "problem" and left["findings"][0]["advice"].startswith("Film")
    assert set(check["clips"]) == {"left"}  # the recording checked

    again = api.ok("POST", f"/rigs/{rig['id']}/calibration-check", 201)
    assert again["kind"] == "check_calibration"
    assert api.wait_job(again["id"], timeout_s=120)[0]["status"] == "done"


def test_a_clip_checked_before_keeps_its_answer_and_only_new_or_changed_clips_are_searched(api, tmp_path,
                                                                                            monkeypatch):
    import saddlescope.services.rigs.calibration_check as calibration_check

    searched: list[list[str]] = []
    real = calibration_check.check_calibration_clips

    def spy(paths, board, **kwargs):
        searched.append(sorted(paths))
        return real(paths, board, **kwargs)

    monkeypatch.setattr(calibration_check, "check_calibration_clips", spy)
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena, clip by clip", "board": BIG})

    def upload_and_check(camera: str, shade: int) -> dict:
        clip = write_tiny_clip(tmp_path / f"{camera}-{shade}.avi", frames=6, shade=shade).read_bytes()
        api.ok("PUT", f"/rigs/{rig['id']}/clips/calibration/{camera}", files={"file": (f"{camera}.avi", clip)})
        return wait_checks()

    def wait_checks() -> dict:
        for job in api.ok("GET", "/jobs", params={"rig_id": rig["id"], "kind": "check_calibration"})["items"]:
            assert api.wait_job(job["id"], timeout_s=120)[0]["status"] == "done"
        return api.ok("GET", f"/rigs/{rig['id']}/calibration-check")

    upload_and_check("left", 0)
    check = upload_and_check("middle", 40)
    assert searched == [["left"], ["middle"]]  # the left clip was not searched again
    assert list(check["cameras"]) == ["left", "middle"] and set(check["clips"]) == {"left", "middle"}
    assert check["verdict"].startswith("Film again: the left and middle cameras' board clips")
    assert check["cameras"]["left"]["frames_sampled"] == 6 and check["cameras"]["middle"]["views"] == 0

    retaken = upload_and_check("left", 80)  # another take for the left camera (same recording id): searched again
    assert searched[-1] == ["left"] and retaken["clips"] == check["clips"]
    api.ok("PATCH", f"/rigs/{rig['id']}", json={"board": SMALL})  # another board: every clip searched again
    api.ok("POST", f"/rigs/{rig['id']}/calibration-check", 201)
    again = wait_checks()
    assert searched[-1] == ["left", "middle"] and list(again["cameras"]) == ["left", "middle"]
    assert again["film_again"] and again["verdict"] == check["verdict"]

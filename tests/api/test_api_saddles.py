"""Saddles and riders' weight (issue 37, item 3) and honest data (item 4) from a client's side.

Saddles: CRUD, club scoping and plain reasons for bad input; a horse's saddles compared; the leaderboard and the
comparison filtered by saddle. Honest data: the same motion clips never make two rides (clip by clip then as a
bundle, and the other way round: 409 naming the ride they already are); rides too uncertain for a decision are
never ranked or averaged unless asked, on every path.
"""

from __future__ import annotations

import numpy as np
import pytest
from api_helpers import ride_json_with, zip_folder
from engines import open_env
from integration_services import add_member, new_club, write_tiny_bundle

from saddlescope.db.repositories import ResultRepository
from saddlescope.db.session import session_factory_for, session_scope

REASON = "the W_b r.m.s. is known only to ±19 % (95 % interval 3.4-5.0 m/s²; a decision needs ±10 %)"


@pytest.fixture(scope="module", params=["embedded"])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


def _result(env, club_id: int, ride_id: int, wb: float, *, reason: str | None = None) -> None:
    """A stored result (as the one writer stores it), without rendering a ride."""
    with session_scope(session_factory_for(env.settings.database_url)) as session:
        ResultRepository(session).replace_for_ride(
            club_id=club_id, ride_id=ride_id, job_id=None, result_key=None, code_version="test",
            indicators={"acc_y_wb_rms": wb, "vdv_y_wb": wb * 2.5, "acc_y_wk_rms": wb * 1.1, "vdv_y_wk": wb * 2.7},
            uncertain_reason=reason)


def test_saddles_crud_scoping_and_bad_input(env):
    api, created = new_club(env.client)
    saddle = api.ok("POST", "/saddles", 201, json={"name": "Wintec 500", "maker": "Wintec", "saddle_type": "gp",
                                                   "tree_width": "medium", "notes": "changeable gullet"})
    assert (saddle["name"], saddle["saddle_type"], saddle["rides"]) == ("Wintec 500", "gp", 0)
    assert api.ok("GET", "/saddles")["total"] == 1
    changed = api.ok("PATCH", f"/saddles/{saddle['id']}", json={"tree_width": None, "saddle_type": "dressage"})
    assert (changed["tree_width"], changed["saddle_type"]) == (None, "dressage")
    # a name in use, an unknown type
    assert "already has a saddle named" in api.ok("POST", "/saddles", 409, json={"name": "Wintec 500"})["detail"]
    bad_type = api.ok("POST", "/saddles", 422, json={"name": "X", "saddle_type": "racing"})["detail"]
    assert "saddle_type" in bad_type
    # another club sees nothing of it, nor can use it on a ride
    other, _ = new_club(env.client)
    other.ok("GET", f"/saddles/{saddle['id']}", 404)
    horse = other.ok("POST", "/horses", 201, json={"name": "Other horse"})
    rider = other.ok("POST", "/riders", 201, json={"name": "Other rider"})
    refused = other.ok("POST", "/rides", 404, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                                    "direction": "CW", "saddle_id": saddle["id"]})
    assert "saddle" in refused["detail"]
    other.ok("GET", "/leaderboard", 404, params={"gait": "walk", "saddle_id": saddle["id"]})
    # unknown saddle on a ride of its own club
    horse = api.ok("POST", "/horses", 201, json={"name": "Bramble"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Ann", "weight_kg": 64.5})
    body = {"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk", "direction": "CW"}
    assert "saddle 99999 not found" in api.ok("POST", "/rides", 404, json={**body, "saddle_id": 99999})["detail"]
    # weights: out of range and pounds named
    too_heavy = api.ok("POST", "/riders", 422, json={"name": "Bob", "weight_kg": 250})["detail"]
    assert "between 20 and 200" in too_heavy and "pounds" in too_heavy
    assert "between 20 and 200" in api.ok("POST", "/rides", 422, json={**body, "rider_weight_kg": 12})["detail"]
    # a ride takes the rider's weight by default, and its saddle and pad
    ride = api.ok("POST", "/rides", 201, json={**body, "saddle_id": saddle["id"], "pad": "sheepskin half pad"})
    assert (ride["saddle_id"], ride["pad"], ride["rider_weight_kg"]) == (saddle["id"], "sheepskin half pad", 64.5)
    edited = api.ok("PATCH", f"/rides/{ride['id']}", json={"rider_weight_kg": 66, "pad": None})
    assert (edited["rider_weight_kg"], edited["pad"]) == (66, None)
    assert api.ok("GET", "/rides", params={"saddle_id": saddle["id"]})["total"] == 1
    # deleting a saddle in use: refused with the reason; a member may not delete at all
    member, _ = add_member(api)
    member.ok("DELETE", f"/saddles/{saddle['id']}", 403)
    assert "still has 1 ride" in api.ok("DELETE", f"/saddles/{saddle['id']}", 409)["detail"]
    api.ok("PATCH", f"/rides/{ride['id']}", json={"saddle_id": None})
    api.ok("DELETE", f"/saddles/{saddle['id']}", 204)


def _club_with_two_saddles(env):
    api, created = new_club(env.client)
    club_id = created["club"]["id"]
    horse = api.ok("POST", "/horses", 201, json={"name": "Pippin"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Cara", "weight_kg": 70})
    saddles = {name: api.ok("POST", "/saddles", 201, json={"name": name, "saddle_type": kind})["id"]
               for name, kind in (("Old GP", "gp"), ("New treeless", "treeless"))}
    rides = []
    for name, wb, reason in (("Old GP", 1.0, None), ("Old GP", 1.1, None), ("Old GP", 0.9, None),
                             ("New treeless", 0.6, None), ("New treeless", 0.65, None), ("New treeless", 0.55, None),
                             ("New treeless", 0.1, REASON)):
        ride = api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "canter",
                                                   "direction": "CW", "saddle_id": saddles[name]})
        _result(env, club_id, ride["id"], wb, reason=reason)
        rides.append(ride["id"])
    return api, horse["id"], saddles, rides


def test_a_horses_saddles_compared_beyond_the_uncertainty(env):
    api, horse_id, saddles, rides = _club_with_two_saddles(env)
    answer = api.ok("GET", f"/horses/{horse_id}/saddles", params={"gait": "canter"})
    by_name = {s["saddle"]: s for s in answer["saddles"]}
    assert by_name["New treeless"]["rides"] == 3 and answer["uncertain_left_out"] == 1  # the 0.1 is not counted
    wb = by_name["Old GP"]["indicators"]["acc_y_wb_rms"]
    assert wb["n"] == 3 and wb["mean"] == pytest.approx(1.0) and wb["low"] < 1.0 < wb["high"]
    diff = next(d for d in answer["differences"] if d["indicator"] == "acc_y_wb_rms")
    # saddles in name order: b = Old GP against a = New treeless, 0.4 m/s² higher
    assert (diff["saddle_a"], diff["saddle_b"]) == ("New treeless", "Old GP")
    assert diff["exceeds_uncertainty"] is True and 0 < diff["low"] < diff["difference"] < diff["high"]
    assert diff["difference"] == pytest.approx(0.4) and diff["p_value"] < 0.01
    assert "more than the uncertainty" in diff["sentence"]
    assert "New treeless is the more comfortable" in diff["sentence"]
    assert "Welch" in answer["method"]
    # asked for, the uncertain ride counts
    included = api.ok("GET", f"/horses/{horse_id}/saddles", params={"gait": "canter", "include_uncertain": True})
    assert {s["saddle"]: s["rides"] for s in included["saddles"]}["New treeless"] == 4
    # one saddle across horses
    across = api.ok("GET", f"/saddles/{saddles['New treeless']}/across-horses")
    assert across["saddle"]["rides"] == 4 and len(across["rides"]) == 4
    assert [h["rides"] for h in across["horses"]] == [3]
    api.ok("GET", f"/horses/{horse_id}/saddles", 422, params={"gait": "gallop"})


def test_uncertain_rides_are_never_ranked_or_averaged_unless_asked(env):
    api, horse_id, saddles, rides = _club_with_two_saddles(env)
    board = api.ok("GET", "/leaderboard", params={"gait": "canter"})
    assert board["rides"] == 6 and board["entries"][0]["uncertain_rides"] == 0
    assert [u["ride_id"] for u in board["uncertain"]] == [rides[-1]]
    assert api.ok("GET", "/leaderboard", params={"gait": "canter", "include_uncertain": True})["rides"] == 7
    filtered = api.ok("GET", "/leaderboard", params={"gait": "canter", "saddle_id": saddles["Old GP"]})
    assert filtered["rides"] == 3 and filtered["entries"][0]["mean"] == pytest.approx(1.0)
    compare = api.ok("GET", "/comparison", params={"gait": "canter", "saddle_id": saddles["New treeless"]})
    horses = compare["indicators"]["acc_y_wb_rms"]["horses"]
    assert compare["uncertain_left_out"] == 1 and horses[0]["n"] == 3 and horses[0]["min"] == pytest.approx(0.55)
    gaits = api.ok("GET", f"/horses/{horse_id}/comparison")
    assert gaits["rides"] == 6 and gaits["uncertain_left_out"] == 1
    trend = api.ok("GET", f"/horses/{horse_id}/trend", params={"gait": "canter"})
    assert len(trend["points"]) == 6 and trend["uncertain_left_out"] == 1
    shown = api.ok("GET", f"/horses/{horse_id}/trend", params={"gait": "canter", "include_uncertain": True})
    assert shown["points"][-1]["uncertain_reason"] == REASON
    assert shown["points"][-1]["band"]["n"] == 6  # the band never holds an uncertain ride


def _clip_by_clip_ride(api, folder):
    horse = api.ok("POST", "/horses", 201, json={"name": f"Horse {folder.name}"})
    rider = api.ok("POST", "/riders", 201, json={"name": f"Rider {folder.name}"})
    ride = api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                               "direction": "CW"})
    return ride


def _put_motion(api, ride_id, folder, camera):
    return api.put(f"/rides/{ride_id}/clips/motion/{camera}", content=(folder / f"motion/{camera}.avi").read_bytes(),
                   headers={"Content-Type": "video/x-msvideo", "X-Filename": f"{camera}.avi"})


def test_clips_one_by_one_then_the_same_as_a_bundle_make_one_ride(env, tmp_path):
    api, _ = new_club(env.client)
    folder = write_tiny_bundle(tmp_path / "first")
    ride = _clip_by_clip_ride(api, folder)
    for camera in ("left", "middle", "right"):
        assert _put_motion(api, ride["id"], folder, camera).status_code == 200
    answer = api.post("/rides/bundle", files={"file": ("ride.zip", zip_folder(folder), "application/zip")})
    assert answer.status_code == 409, answer.text
    assert answer.json()["ride_id"] == ride["id"] and f"ride {ride['id']}" in answer.json()["detail"]
    assert api.ok("GET", "/rides")["total"] == 1
    # another club may hold the same clips: the rule is per club
    other, _ = new_club(env.client)
    other.ok("POST", "/rides/bundle", 201, files={"file": ("ride.zip", zip_folder(folder), "application/zip")})


def test_a_bundle_then_the_same_clips_one_by_one_make_one_ride(env, tmp_path):
    api, _ = new_club(env.client)
    folder = write_tiny_bundle(tmp_path / "second")
    first = api.ok("POST", "/rides/bundle", 201, files={"file": ("ride.zip", zip_folder(folder), "application/zip")})
    again = _clip_by_clip_ride(api, folder)
    answer = _put_motion(api, again["id"], folder, "middle")
    assert answer.status_code == 409, answer.text
    assert answer.json()["ride_id"] == first["ride"]["id"]
    assert f"it was not stored with ride {again['id']}" in answer.json()["detail"]
    assert api.ok("GET", f"/rides/{again['id']}")["recordings"] == []  # nothing stored on the second ride
    # the same zip again: the same answer
    same = api.post("/rides/bundle", files={"file": ("ride.zip", zip_folder(folder), "application/zip")})
    assert same.status_code == 409 and same.json()["ride_id"] == first["ride"]["id"]


def _cantering_trc(path, *, noise_m: float):
    """Three markers on a body cantering at 3 m/s (0.7 s strides) for 3 s, with Gaussian noise of `noise_m`."""
    from saddlescope.io.mocap import write_trc

    t = np.arange(300) / 100.0
    w = 2 * np.pi / 0.7
    body = np.array([[0.25, 0.0, 0.1], [-0.25, 0.02, 0.1], [0.0, -0.08, -0.12]])
    centre = np.stack([3.0 * t, 1.2 + 0.03 * np.cos(w * t) + 0.01 * np.cos(2 * w * t), 0.01 * np.sin(w * t)], axis=1)
    points = centre[:, None, :] + body[None] + np.random.default_rng(3).normal(0, noise_m, (len(t), 3, 3))
    return write_trc(path, ["A", "B", "C"], points, 100.0, units="m")


def test_a_too_uncertain_motion_capture_ride_is_not_ranked_anywhere(env, tmp_path):
    api, _ = new_club(env.client)
    rider = api.ok("POST", "/riders", 201, json={"name": "Lab rider", "weight_kg": 72})["id"]
    saddle = api.ok("POST", "/saddles", 201, json={"name": "Lab saddle"})["id"]
    rides = {}
    for name, noise_m in (("Noisy", 0.01), ("Clean", 0.0003)):
        horse = api.ok("POST", "/horses", 201, json={"name": name})["id"]
        trc = _cantering_trc(tmp_path / f"{name}.trc", noise_m=noise_m)
        created = api.ok("POST", "/mocap", 201, content=trc.read_bytes(),
                         headers={"Content-Type": "application/octet-stream"},
                         params={"horse_id": horse, "rider_id": rider, "markers": "A,B,C", "gait": "canter",
                                 "offset_mm": "0,50,0", "filename": trc.name, "saddle_id": saddle})
        rides[name] = (horse, created["ride"])
    noisy_horse, noisy_ride = rides["Noisy"]
    assert (noisy_ride["saddle_id"], noisy_ride["rider_weight_kg"]) == (saddle, 72)
    board = api.ok("GET", "/leaderboard", params={"gait": "canter"})
    assert [e["horse"] for e in board["entries"]] == ["Clean"]
    assert [u["ride_id"] for u in board["uncertain"]] == [noisy_ride["id"]]
    assert [e["horse"] for e in api.ok("GET", "/leaderboard", params={"gait": "canter", "saddle_id": saddle})[
        "entries"]] == ["Clean"]
    compare = api.ok("GET", "/comparison", params={"gait": "canter"})
    assert [h["horse"] for h in compare["indicators"]["acc_y_wb_rms"]["horses"]] == ["Clean"]
    assert api.ok("GET", f"/horses/{noisy_horse}/comparison")["rides"] == 0
    assert api.ok("GET", f"/horses/{noisy_horse}/trend", params={"gait": "canter"})["points"] == []
    across = api.ok("GET", f"/saddles/{saddle}/across-horses")
    assert [h["horse"] for h in across["horses"]] == ["Clean"] and len(across["rides"]) == 2  # listed, marked
    refused = api.ok("POST", "/mocap", 422, content=b"x", headers={"Content-Type": "application/octet-stream"},
                     params={"horse_id": noisy_horse, "rider_id": rider, "markers": "A,B,C", "filename": "x.trc",
                             "rider_weight_kg": 500})
    assert "between 20 and 200" in refused["detail"]


def test_a_bundles_ride_json_names_the_saddle_pad_and_weight(env, tmp_path):
    api, _ = new_club(env.client)
    known = api.ok("POST", "/saddles", 201, json={"name": "Club GP"})["id"]
    folder = write_tiny_bundle(tmp_path / "with-saddle")
    meta = {"saddle": {"name": "Club GP"}, "pad": "gel pad", "rider": {"name": "Dora", "weight_kg": 58.5}}
    data = zip_folder(folder, rewrite={"ride.json": ride_json_with(folder, **meta)})
    ride = api.ok("POST", "/rides/bundle", 201, files={"file": ("ride.zip", data, "application/zip")})["ride"]
    assert (ride["saddle_id"], ride["pad"], ride["rider_weight_kg"]) == (known, "gel pad", 58.5)
    # a saddle new to the club is added with its details; a weight out of range is refused naming the field
    other = write_tiny_bundle(tmp_path / "new-saddle")
    data = zip_folder(other, rewrite={"ride.json": ride_json_with(
        other, saddle={"name": "Borrowed treeless", "type": "treeless", "tree_width": "wide"})})
    ride = api.ok("POST", "/rides/bundle", 201, files={"file": ("ride.zip", data, "application/zip")})["ride"]
    added = api.ok("GET", f"/saddles/{ride['saddle_id']}")
    assert (added["name"], added["saddle_type"], added["tree_width"], added["rides"]) == (
        "Borrowed treeless", "treeless", "wide", 1)
    third = write_tiny_bundle(tmp_path / "heavy")
    data = zip_folder(third, rewrite={"ride.json": ride_json_with(third, rider={"name": "X", "weight_kg": 400})})
    refused = api.ok("POST", "/rides/bundle", 422, files={"file": ("ride.zip", data, "application/zip")})
    assert "weight_kg" in refused["detail"]
    bad_type = write_tiny_bundle(tmp_path / "bad-type")
    data = zip_folder(bad_type, rewrite={"ride.json": ride_json_with(bad_type, saddle={"name": "Y", "type": "racing"})})
    refused = api.ok("POST", "/rides/bundle", 422, files={"file": ("ride.zip", data, "application/zip")})
    assert "saddle.type 'racing' is not one of" in refused["detail"]
    assert api.ok("GET", "/saddles")["total"] == 2  # nothing left of the refused bundles


def test_an_indicator_added_in_the_core_is_ranked_with_no_other_change(env):
    """The newcomer's table, row (c): an indicator added in core/vibration (its key, its computation, its
    interval) is a leaderboard choice at once; here ISO 2631-1's VDV ratio, lower is better."""
    from saddlescope.core.vibration import INDICATORS

    assert INDICATORS["vdv_ratio_y_wb"].better == "lower"
    api, created = new_club(env.client)
    horses = {name: api.ok("POST", "/horses", 201, json={"name": name})["id"] for name in ("Jolty", "Smooth")}
    rider = api.ok("POST", "/riders", 201, json={"name": "Cara"})["id"]
    for name, ratio in (("Jolty", 1.9), ("Jolty", 1.8), ("Smooth", 1.2)):
        ride = api.ok("POST", "/rides", 201, json={"horse_id": horses[name], "rider_id": rider, "gait": "canter",
                                                   "direction": "CW"})
        with session_scope(session_factory_for(env.settings.database_url)) as session:
            ResultRepository(session).replace_for_ride(
                club_id=created["club"]["id"], ride_id=ride["id"], job_id=None, result_key=None, code_version="t",
                indicators={"acc_y_wb_rms": 1.0, "vdv_ratio_y_wb": ratio}, uncertain_reason=None)
    board = api.ok("GET", "/leaderboard", params={"gait": "canter", "indicator": "vdv_ratio_y_wb"})
    assert [e["horse"] for e in board["entries"]] == ["Smooth", "Jolty"]
    assert board["entries"][1]["mean"] == pytest.approx(1.85)
    glossary = {e["code"]: e for e in api.ok("GET", "/glossary") if e["kind"] == "indicator"}
    assert "ISO 2631-1 6.3.3" in glossary["vdv_ratio_y_wb"]["label"]

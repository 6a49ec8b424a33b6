"""Resources as JSON: create, read, change, delete; lists paginated (limit/offset + total), filtered
and sorted."""

from __future__ import annotations

import integration_services
import pytest
from api_helpers import new_club
from engines import ENGINES, open_env

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture(scope="module")
def stable(env):
    """A club with 5 horses, 2 riders, a rig and 12 rides over three months."""
    api, _ = new_club(env.client)
    horses = [
        api.ok("POST", "/horses", 201, json={"name": name, "birth_year": year, "breed": breed})
        for name, year, breed in [
            ("Bravo", 2005, "Dutch"),
            ("alpha", 2010, None),
            ("Charlie", 1999, "Arab"),
            ("Delta_1", 2012, "Dutch"),
            ("Echo%", 2001, None),
        ]
    ]
    riders = [api.ok("POST", "/riders", 201, json={"name": n}) for n in ("Rider A", "Rider B")]
    rig = api.ok(
        "POST",
        "/rigs",
        201,
        json={
            "name": "Arena",
            "recorded_on": "2026-03-02",
            "board": {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50},
        },
    )
    rides = []
    gaits = ["walk", "sitting_trot", "rising_trot", "canter"]
    for i in range(12):
        rides.append(
            api.ok(
                "POST",
                "/rides",
                201,
                json={
                    "horse_id": horses[i % 3]["id"],
                    "rider_id": riders[i % 2]["id"],
                    "rig_id": rig["id"] if i < 6 else None,
                    "gait": gaits[i % 4],
                    "direction": "CW" if i % 2 else "CCW",
                    "ridden_on": f"2026-0{1 + i // 4}-{10 + i:02d}",
                },
            )
        )
    return {"api": api, "horses": horses, "riders": riders, "rig": rig, "rides": rides}


def test_pages_add_up_to_the_whole_list(stable):
    api = stable["api"]
    first = api.ok("GET", "/rides", params={"limit": 5, "sort": "ridden_on"})
    second = api.ok("GET", "/rides", params={"limit": 5, "offset": 5, "sort": "ridden_on"})
    third = api.ok("GET", "/rides", params={"limit": 5, "offset": 10, "sort": "ridden_on"})
    assert first["total"] == second["total"] == third["total"] == 12
    assert (len(first["items"]), len(second["items"]), len(third["items"])) == (5, 5, 2)
    ids = [r["id"] for page in (first, second, third) for r in page["items"]]
    assert sorted(ids) == sorted(r["id"] for r in stable["rides"])
    dates = [r["ridden_on"] for page in (first, second, third) for r in page["items"]]
    assert dates == sorted(dates)
    newest = api.ok("GET", "/rides", params={"limit": 1})["items"][0]  # default: newest ride first
    assert newest["ridden_on"] == max(dates)
    assert api.ok("GET", "/rides", params={"offset": 100})["items"] == []
    assert api.get("/rides", params={"limit": 0}).status_code == 422
    assert api.get("/rides", params={"limit": 501}).status_code == 422


def test_ride_filters(stable):
    api, horses, riders = stable["api"], stable["horses"], stable["riders"]
    by_horse = api.ok("GET", "/rides", params={"horse_id": horses[0]["id"]})
    assert by_horse["total"] == 4 and {r["horse_id"] for r in by_horse["items"]} == {horses[0]["id"]}
    combined = api.ok("GET", "/rides", params={"horse_id": horses[0]["id"], "rider_id": riders[0]["id"]})
    assert {(r["horse_id"], r["rider_id"]) for r in combined["items"]} == {(horses[0]["id"], riders[0]["id"])}
    assert combined["total"] == 2
    canter = api.ok("GET", "/rides", params={"gait": "canter"})
    assert canter["total"] == 3 and {r["gait"] for r in canter["items"]} == {"canter"}
    february = api.ok("GET", "/rides", params={"date_from": "2026-02-01", "date_to": "2026-02-28"})
    assert february["total"] == 4 and all(r["ridden_on"].startswith("2026-02") for r in february["items"])
    assert api.ok("GET", "/rides", params={"rig_id": stable["rig"]["id"]})["total"] == 6
    assert api.ok("GET", "/rides", params={"status": "new"})["total"] == 12
    assert api.ok("GET", "/rides", params={"status": "analysed"})["total"] == 0
    assert api.get("/rides", params={"gait": "gallop"}).status_code == 422
    assert api.get("/rides", params={"date_from": "yesterday"}).status_code == 422


def test_horse_search_and_sort(stable):
    api = stable["api"]
    names = [h["name"] for h in api.ok("GET", "/horses")["items"]]
    assert names == sorted(names)
    by_year = [h["birth_year"] for h in api.ok("GET", "/horses", params={"sort": "-birth_year"})["items"]]
    assert by_year == sorted(by_year, reverse=True)
    assert [h["name"] for h in api.ok("GET", "/horses", params={"q": "LPH"})["items"]] == ["alpha"]
    # LIKE wildcards in the search are taken literally
    assert [h["name"] for h in api.ok("GET", "/horses", params={"q": "%"})["items"]] == ["Echo%"]
    assert [h["name"] for h in api.ok("GET", "/horses", params={"q": "_"})["items"]] == ["Delta_1"]
    breeds = [h["breed"] for h in api.ok("GET", "/horses", params={"sort": "breed"})["items"]]
    assert breeds[-2:] == [None, None]  # missing values last
    bad = api.get("/horses", params={"sort": "weight"})
    assert bad.status_code == 422 and "'birth_year', '-birth_year'" in bad.json()["detail"]


def test_change_and_delete(stable):
    api, horse = stable["api"], stable["horses"][4]
    changed = api.ok("PATCH", f"/horses/{horse['id']}", json={"breed": "Pony", "height_withers_m": 1.2})
    assert (changed["name"], changed["breed"], changed["height_withers_m"]) == (horse["name"], "Pony", 1.2)
    cleared = api.ok("PATCH", f"/horses/{horse['id']}", json={"breed": None, "name": None})
    assert cleared["breed"] is None and cleared["name"] == horse["name"]  # a name cannot be cleared
    clash = api.patch(f"/horses/{horse['id']}", json={"name": "Bravo"})
    assert clash.status_code == 409
    assert api.delete(f"/horses/{horse['id']}").status_code == 204
    assert api.get(f"/horses/{horse['id']}").status_code == 404
    assert api.delete(f"/rigs/{stable['rig']['id']}").status_code == 409  # rides use it
    ride = stable["rides"][-1]
    moved = api.ok(
        "PATCH", f"/rides/{ride['id']}", json={"gait": "walk", "notes": "windy", "ridden_on": None}
    )
    assert (moved["gait"], moved["notes"], moved["ridden_on"]) == ("walk", "windy", None)
    assert api.patch(f"/rides/{ride['id']}", json={"horse_id": 999999}).status_code == 404
    detail = api.ok("GET", f"/rides/{ride['id']}")
    assert detail["recordings"] == [] and detail["latest_job_id"] is None and detail["meta"] == {}
    assert api.delete(f"/rides/{ride['id']}").status_code == 204
    assert api.ok("GET", "/rides")["total"] == 11


def test_rigs_and_riders(stable):
    api = stable["api"]
    rig = api.ok("GET", f"/rigs/{stable['rig']['id']}")
    assert rig["board"] == {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0}
    assert rig["calibrated"] is False and rig["calibration"] is None
    assert api.ok("PATCH", f"/rigs/{rig['id']}", json={"name": "Indoor arena"})["name"] == "Indoor arena"
    charuco = api.post(
        "/rigs",
        json={
            "name": "Charuco",
            "board": {
                "kind": "charuco",
                "inner_corners": [4, 6],
                "square_mm": 40,
                "dictionary": "DICT_4X4_50",
                "marker_mm": 30,
            },
        },
    )
    assert charuco.status_code == 201
    bad_board = api.post("/rigs", json={"name": "Bad", "board": {"inner_corners": [1, 6], "square_mm": 40}})
    assert bad_board.status_code == 422 and "inner_corners" in bad_board.json()["detail"]
    me = api.ok("GET", "/auth/me")["user"]
    rider = api.ok("PATCH", f"/riders/{stable['riders'][1]['id']}", json={"user_id": me["id"]})
    assert rider["user_id"] == me["id"]
    assert [r["name"] for r in api.ok("GET", "/riders", params={"q": "b"})["items"]] == ["Rider B"]

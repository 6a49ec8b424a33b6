"""The similarity routes: a ride's most-alike rides (cached, else a `similarity` job), two rides compared,
a horse's consistency; another club's ids (404), a ride without a result (409), bad options (422).

Both ways SaddleScope runs: embedded (SQLite, jobs in threads) and celery (PostgreSQL, Redis and a real
Celery worker process running the similarity job; required under CI=true).
"""

from __future__ import annotations

import integration_services
import pytest
from api_helpers import new_club
from engines import ENGINES, open_env
from similarity_docs import motion_document, store_document

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url

HORSES = ("Ash", "Birch", "Cedar")


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory)


@pytest.fixture(scope="module")
def world(env):
    """Club A: three horses with two canter rides each, one walk ride, one ride never analysed; club B."""
    a, _ = new_club(env.client)
    rider = a.ok("POST", "/riders", 201, json={"name": "Rider"})["id"]
    horses = {name: a.ok("POST", "/horses", 201, json={"name": name})["id"] for name in HORSES}
    rides: dict[tuple[str, str, int], int] = {}

    def add(name: str, gait: str, recording: int, day: str, *, analysed: bool = True) -> int:
        ride = a.ok("POST", "/rides", 201, json={"horse_id": horses[name], "rider_id": rider, "gait": gait,
                                                  "direction": "CCW", "ridden_on": day})["id"]
        if analysed:
            store_document(env.settings.database_url, env.settings.storage_dir, ride,
                           motion_document(name, gait, recording=recording))
        rides[(name, gait, recording)] = ride
        return ride

    for name in HORSES:
        for recording in range(2):
            add(name, "canter", recording, f"2026-0{recording + 3}-0{HORSES.index(name) + 1}")
    add("Ash", "walk", 0, "2026-05-01")
    unanalysed = add("Birch", "walk", 9, "2026-05-02", analysed=False)
    b, _ = new_club(env.client)
    return {"a": a, "b": b, "horses": horses, "rides": rides, "unanalysed": unanalysed}


def similar(api, ride_id: int, **params):
    """GET the most-alike list; a 202 is followed through its job to the 200."""
    response = api.get(f"/rides/{ride_id}/similar", params=params)
    if response.status_code == 202:
        pending = response.json()
        assert pending["job"]["kind"] == "similarity" and pending["missing"] >= 1, pending
        job, _ = api.wait_job(pending["job"]["id"], timeout_s=120)
        assert job["status"] == "done", job
        response = api.get(f"/rides/{ride_id}/similar", params=params)
    assert response.status_code == 200, response.text
    return response.json()


def test_most_alike_is_queued_as_a_job_then_served_from_the_cache(world):
    a, rides = world["a"], world["rides"]
    query = rides[("Ash", "canter", 0)]
    first = a.get(f"/rides/{query}/similar")
    assert first.status_code == 202, first.text
    pending = first.json()
    assert pending["ride_id"] == query and pending["cached"] == 0 and pending["pairs"] == 5
    assert pending["job"]["payload"]["markers"] == "saddle" and len(pending["job"]["payload"]["pairs"]) == 5
    again = a.get(f"/rides/{query}/similar")  # polling does not queue a second job
    if again.status_code == 202:
        assert again.json()["job"]["id"] == pending["job"]["id"]
    job, _ = a.wait_job(pending["job"]["id"], timeout_s=120)
    assert job["status"] == "done", job
    assert job["ride_id"] is None and "similarity" in job["timings_s"]

    answer = a.ok("GET", f"/rides/{query}/similar")
    assert answer["ride"]["ride_id"] == query and answer["gait"] == "same" and answer["candidates"] == 5
    items = answer["items"]
    assert [item["rank"] for item in items] == [1, 2, 3, 4, 5]
    sims = [item["similarity"] for item in items]
    assert sims == sorted(sims, reverse=True) and all(0 <= s <= 1 for s in sims)
    assert {item["ride"]["gait"] for item in items} == {"canter"}
    # the other recording of the same horse and gait moves most alike
    assert items[0]["ride"]["ride_id"] == rides[("Ash", "canter", 1)]
    assert items[0]["ride"]["horse"] == "Ash" and items[0]["measure"] and items[0]["measures"]
    assert answer["not_comparable"] == []
    assert len(a.ok("GET", f"/rides/{query}/similar", params={"limit": 2})["items"]) == 2

    # any gait: the walk ride joins (its pair computed by another job)
    every = similar(a, query, gait="any")
    assert every["candidates"] == 6 and {i["ride"]["gait"] for i in every["items"]} == {"canter", "walk"}


@pytest.mark.parametrize("markers", ["M2", "all"])
def test_marker_sets_and_the_window_span(world, markers):
    a, rides = world["a"], world["rides"]
    answer = similar(a, rides[("Birch", "canter", 1)], markers=markers, span="window", limit=3)
    assert answer["markers"] == markers and answer["span"] == "window" and len(answer["items"]) == 3
    assert answer["items"][0]["ride"]["horse"] == "Birch"


def test_two_rides_compared_with_the_paths_and_the_aligned_strides(world):
    a, rides = world["a"], world["rides"]
    one, two = rides[("Cedar", "canter", 0)], rides[("Cedar", "canter", 1)]
    pair = a.ok("GET", f"/rides/{two}/similar/{one}", params={"markers": "M1"})
    assert [r["ride_id"] for r in pair["rides"]] == [two, one] and pair["markers"] == "M1"
    assert 0 <= pair["similarity"] <= 1 and pair["comparison"]["similarity"] == pytest.approx(pair["similarity"])
    assert pair["reason"] is None and pair["measures"]
    view = pair["view"]
    assert len(view["paths_mm"]) == 2 and all(len(p) > 100 and len(p[0]) == 3 for p in view["paths_mm"])
    strides = view["strides"]
    assert len(strides["phase"]) == len(strides["first_mm"]) == len(strides["second_mm"]) == 100
    assert 0 <= strides["shift_phase"] < 1
    assert a.ok("GET", f"/rides/{one}/similar/{two}", params={"markers": "M1"})["cached"] is True
    # the list reads the pair the pair view cached (same number)
    listed = similar(a, one, markers="M1")
    assert listed["items"][0]["ride"]["ride_id"] == two
    assert listed["items"][0]["similarity"] == pytest.approx(pair["similarity"])


def test_the_pair_answer_says_which_marker_and_which_stretch_of_the_stride_differ(world):
    a, rides = world["a"], world["rides"]
    one, two = rides[("Cedar", "canter", 0)], rides[("Birch", "canter", 1)]
    pair = a.ok("GET", f"/rides/{one}/similar/{two}", params={"markers": "all"})
    diff = pair["differences"]
    assert diff["time_base"] == "stride phase" and diff["stretches"] == 10
    assert [m["marker"] for m in diff["per_marker"]] == ["M1", "M2", "M3"]
    assert all(len(m["per_stretch_mm"]) == 10 and m["rms_mm"] > 0 for m in diff["per_marker"])
    assert diff["most_different_marker"] in {"M1", "M2", "M3"} and 0 <= diff["most_different_stretch"] < 10
    assert pair["comparison"]["differences"] == diff


def test_a_horses_consistency_per_gait(world):
    a, horses, rides = world["a"], world["horses"], world["rides"]
    answer = a.ok("GET", f"/horses/{horses['Ash']}/consistency")
    assert answer["horse"] == "Ash"
    gaits = {g["gait"]: g for g in answer["gaits"]}
    assert set(gaits) == {"walk", "canter"}
    canter = gaits["canter"]["rides"]
    assert [r["ride"]["ride_id"] for r in canter] == [rides[("Ash", "canter", 0)], rides[("Ash", "canter", 1)]]
    assert canter[0]["earlier"] == 0 and canter[0]["vs_previous"] is None
    assert canter[1]["earlier"] == 1 and 0 < canter[1]["vs_previous"] <= 1
    assert canter[1]["mean_vs_earlier"] == canter[1]["vs_previous"] == gaits["canter"]["mean_vs_previous"]
    assert gaits["walk"]["rides"][0]["vs_previous"] is None


def test_a_reanalysed_rides_cached_pairs_are_invalidated(env, world):
    a, rides = world["a"], world["rides"]
    query, other = rides[("Ash", "canter", 0)], rides[("Birch", "canter", 0)]
    similar(a, query)  # everything cached
    assert a.get(f"/rides/{query}/similar").status_code == 200
    store_document(env.settings.database_url, env.settings.storage_dir, other,
                   motion_document("Birch", "canter", recording=5), code_version="test-2")
    again = a.get(f"/rides/{query}/similar")
    assert again.status_code == 202, again.text
    assert again.json()["missing"] == 1 and again.json()["cached"] == 4
    assert similar(a, query)["candidates"] == 5


def test_another_clubs_rides_and_horses_are_not_found(world):
    a, b, rides, horses = world["a"], world["b"], world["rides"], world["horses"]
    ride, other = rides[("Ash", "canter", 0)], rides[("Ash", "canter", 1)]
    for path in (f"/rides/{ride}/similar", f"/rides/{ride}/similar/{other}", f"/horses/{horses['Ash']}/consistency"):
        response = b.get(path)
        assert response.status_code == 404, f"{path}: {response.text}"
        assert "Ash" not in response.text
    # one of the two rides is another club's
    b_rider = b.ok("POST", "/riders", 201, json={"name": "B rider"})["id"]
    b_horse = b.ok("POST", "/horses", 201, json={"name": "B horse"})["id"]
    b_ride = b.ok("POST", "/rides", 201, json={"horse_id": b_horse, "rider_id": b_rider, "gait": "canter",
                                                "direction": "CW"})["id"]
    for caller, path in ((b, f"/rides/{b_ride}/similar/{ride}"), (a, f"/rides/{ride}/similar/{b_ride}")):
        response = caller.get(path)
        assert response.status_code == 404 and "not found" in response.json()["detail"], response.text


def test_a_ride_without_a_result_is_409_with_the_reason(world):
    a, rides, unanalysed = world["a"], world["rides"], world["unanalysed"]
    for path in (f"/rides/{unanalysed}/similar", f"/rides/{rides[('Ash', 'canter', 0)]}/similar/{unanalysed}"):
        response = a.get(path)
        assert response.status_code == 409, response.text
        detail = response.json()["detail"]
        assert f"ride {unanalysed} has no result to compare" in detail and "clips are not all uploaded" in detail


@pytest.mark.parametrize(("params", "field"), [({"markers": "M7"}, "markers"), ({"span": "lap"}, "span"),
                                               ({"gait": "trot"}, "gait"), ({"limit": 0}, "limit")])
def test_bad_options_are_422_naming_the_field(world, params, field):
    a, ride = world["a"], world["rides"][("Ash", "canter", 0)]
    for path in (f"/rides/{ride}/similar", f"/rides/{ride}/similar/{world['rides'][('Ash', 'canter', 1)]}"):
        if field in ("gait", "limit") and path.count("/") > 3:
            continue
        response = a.get(path, params=params)
        assert response.status_code == 422, response.text
        assert f"query.{field}" in response.json()["detail"]


def test_a_ride_compared_with_itself_is_422(world):
    ride = world["rides"][("Ash", "canter", 0)]
    response = world["a"].get(f"/rides/{ride}/similar/{ride}")
    assert response.status_code == 422 and "other_id" in response.json()["detail"]


def test_the_similarity_job_refuses_a_bad_payload(world):
    response = world["a"].post("/jobs", json={"kind": "similarity", "payload": {"pairs": [[1, 1]]}})
    assert response.status_code == 422 and "two different ride ids" in response.json()["detail"]
    response = world["a"].post("/jobs", json={"kind": "similarity", "payload": {"markers": "M9", "pairs": [[1, 2]]}})
    assert response.status_code == 422 and "markers" in response.json()["detail"]

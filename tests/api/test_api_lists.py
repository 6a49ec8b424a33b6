"""Lists that scale and ride details after upload: every sort value pages without overlap, the sort and
indicator parameters are enums in the OpenAPI, ride edits are validated and mark the result outdated
until re-analysed, deleting a ride removes its files and rows, and a horse or rider with rides says
how many and what to do."""

from __future__ import annotations

from pathlib import Path

import pytest
from api_helpers import add_member, new_club, zip_folder
from engines import open_env
from integration_services import write_tiny_bundle

from saddlescope.api.routers.horses import HorseSort
from saddlescope.api.routers.jobs import JobSort
from saddlescope.api.routers.riders import RiderSort
from saddlescope.api.routers.rides import RideSort
from saddlescope.core.vibration import INDICATORS
from saddlescope.services.jobs.stage_labels import progress_percent, stage_label


@pytest.fixture(scope="module", params=["embedded"])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory)


@pytest.fixture(scope="module")
def club(env):
    """A club with 3 horses, 2 riders and 9 rides (no clips) over three months, and a few jobs."""
    api, who = new_club(env.client)
    horses = [api.ok("POST", "/horses", 201, json={"name": n, "birth_year": 2000 + i})
              for i, n in enumerate(("Bravo", "Alpha", "Charlie"))]
    riders = [api.ok("POST", "/riders", 201, json={"name": n}) for n in ("Rider B", "Rider A")]
    gaits = ["walk", "sitting_trot", "rising_trot", "canter"]
    rides = [api.ok("POST", "/rides", 201, json={
        "horse_id": horses[i % 3]["id"], "rider_id": riders[i % 2]["id"], "gait": gaits[i % 4],
        "direction": "CW" if i % 2 else "CCW", "ridden_on": f"2026-0{1 + i // 3}-1{i % 3}",
    }) for i in range(9)]
    jobs = [api.ok("POST", "/jobs", 201, json={"kind": "selftest", "payload": {"steps": 1, "delay_s": 0}})
            for _ in range(3)]
    return {"api": api, "who": who, "horses": horses, "riders": riders, "rides": rides, "jobs": jobs}


def _all_pages(api, path: str, **params) -> tuple[list[dict], int]:
    """Every row of a list read 4 at a time, and the total the pages reported."""
    rows, totals, offset = [], set(), 0
    while True:
        page = api.ok("GET", path, params={**params, "limit": 4, "offset": offset})
        totals.add(page["total"])
        rows += page["items"]
        offset += 4
        if offset >= page["total"]:
            break
    assert len(totals) == 1, f"{path} {params}: the total changed between pages: {totals}"
    return rows, totals.pop()


@pytest.mark.parametrize(("path", "sorts", "key"), [
    ("/rides", RideSort, "rides"), ("/horses", HorseSort, "horses"), ("/riders", RiderSort, "riders"),
    ("/jobs", JobSort, None),
])
def test_every_sort_value_pages_through_every_row_once(club, path, sorts, key):
    api = club["api"]
    expected = {row["id"] for row in club[key]} if key else None
    for sort in sorts:
        rows, total = _all_pages(api, path, sort=sort.value)
        ids = [row["id"] for row in rows]
        assert len(ids) == len(set(ids)) == total, f"{path}?sort={sort.value}: pages overlap or miss rows"
        if expected is not None:
            assert set(ids) == expected
        field = sort.value.removeprefix("-")
        values = [row.get(field) for row in rows if row.get(field) is not None] if field in rows[0] else []
        assert values == sorted(values, reverse=sort.value.startswith("-")), f"{path}?sort={sort.value}"


def test_ride_filters_combine_and_count(club):
    api, horses = club["api"], club["horses"]
    rows, total = _all_pages(api, "/rides", horse_id=horses[0]["id"], sort="ridden_on")
    assert total == 3 and {r["horse_id"] for r in rows} == {horses[0]["id"]}
    february = api.ok("GET", "/rides", params={"date_from": "2026-02-01", "date_to": "2026-02-28",
                                               "gait": "walk"})
    assert february["total"] == 1 and february["items"][0]["ridden_on"].startswith("2026-02")
    assert api.ok("GET", "/rides", params={"status": "new", "limit": 1})["total"] == 9
    kinds = api.ok("GET", "/jobs", params={"kind": "selftest"})
    assert kinds["total"] == 3
    assert api.get("/jobs", params={"kind": "nonsense"}).status_code == 422
    assert api.get("/rides", params={"sort": "weight"}).status_code == 422


def test_sort_and_indicator_parameters_are_enums_in_the_openapi(env):
    spec = env.client.get("/openapi.json").json()

    def param(path: str, name: str) -> dict:
        found = [p for p in spec["paths"][path]["get"]["parameters"] if p["name"] == name]
        assert found, f"{path} has no parameter {name}"
        schema = found[0]["schema"]
        options = schema.get("anyOf", [schema])
        refs = [o for o in options if "$ref" in o or "enum" in o or o.get("type") == "array"]
        target = refs[0]
        if target.get("type") == "array":
            target = target["items"]
        if "$ref" in target:
            target = spec["components"]["schemas"][target["$ref"].rsplit("/", 1)[1]]
        return target

    rides = param("/api/rides", "sort")["enum"]
    assert {"ridden_on", "-ridden_on", "acc_y_wb_rms", "-vdv_y_wb", "id", "-id"} <= set(rides)
    assert set(param("/api/horses", "sort")["enum"]) == {v.value for v in HorseSort}
    assert set(param("/api/riders", "sort")["enum"]) == {v.value for v in RiderSort}
    assert set(param("/api/jobs", "sort")["enum"]) == {v.value for v in JobSort}
    assert "analyze" in param("/api/jobs", "kind")["enum"]
    assert set(param("/api/horses/{horse_id}/comparison", "indicator")["enum"]) == set(INDICATORS)


def test_ride_edits_are_validated(club, env):
    api, ride = club["api"], club["rides"][0]
    other, _ = new_club(env.client)
    foreign_horse = other.ok("POST", "/horses", 201, json={"name": "Elsewhere"})
    for body, status in [({"gait": "gallop"}, 422), ({"direction": "up"}, 422), ({"ridden_on": "soon"}, 422),
                         ({"horse_id": foreign_horse["id"]}, 404), ({"colour": "bay"}, 422),
                         ({"notes": "x" * 100_000}, 422), ({"horse_id": 0}, 422)]:
        answer = api.patch(f"/rides/{ride['id']}", json=body)
        assert answer.status_code == status, (body, answer.text)
        assert isinstance(answer.json()["detail"], str) and answer.json()["detail"]
    moved = api.ok("PATCH", f"/rides/{ride['id']}", json={
        "horse_id": club["horses"][1]["id"], "rider_id": club["riders"][1]["id"], "gait": "canter",
        "direction": "CW", "ridden_on": "2026-03-30", "notes": "windy"})
    assert (moved["horse_id"], moved["gait"], moved["direction"], moved["ridden_on"], moved["notes"]) == (
        club["horses"][1]["id"], "canter", "CW", "2026-03-30", "windy")
    assert moved["result_outdated_by"] == []  # no result yet: nothing to be outdated


def test_deleting_a_horse_or_rider_with_rides_says_how_many_and_what_to_do(env):
    api, _ = new_club(env.client)
    horse = api.ok("POST", "/horses", 201, json={"name": "Busy"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Rider Busy"})
    for day in (1, 2):
        api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                            "direction": "CW", "ridden_on": f"2026-05-0{day}"})
    refused = api.delete(f"/horses/{horse['id']}")
    assert refused.status_code == 409
    assert refused.json()["detail"].startswith("horse 'Busy' still has 2 rides; delete those rides first")
    refused = api.delete(f"/riders/{rider['id']}")
    assert refused.status_code == 409 and "rider 'Rider Busy' still has 2 rides" in refused.json()["detail"]


def _files_under(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if p.is_file()] if root.exists() else []


def test_an_edited_ride_is_outdated_until_reanalysed_and_deleting_it_removes_everything(env, tmp_path):
    api, who = new_club(env.client)
    bundle = write_tiny_bundle(tmp_path / "bundle", gait="walk")
    created = api.ok("POST", "/rides/bundle", 201, files={"file": ("ride.zip", zip_folder(bundle),
                                                                   "application/zip")})
    ride_id = created["ride"]["id"]
    job, _ = api.wait_job(created["job_id"])
    assert job["status"] == "done", job["error"]
    assert (job["progress_percent"], job["stage_label"], job["owner_id"]) == (100, "Finished", who["user"]["id"])
    before = api.ok("GET", f"/rides/{ride_id}")
    assert before["status"] == "analysed" and before["result_outdated_by"] == []

    edited = api.ok("PATCH", f"/rides/{ride_id}", json={"gait": "canter", "notes": "really a canter"})
    assert edited["result_outdated_by"] == ["gait"]
    assert api.ok("PATCH", f"/rides/{ride_id}", json={"direction": "CW" if before["direction"] == "CCW"
                                                      else "CCW"})["result_outdated_by"] == ["gait", "direction"]
    assert api.ok("PATCH", f"/rides/{ride_id}", json={"direction": before["direction"]})[
        "result_outdated_by"] == ["gait"]  # changed back: only the gait differs now
    again, _ = api.wait_job(api.ok("POST", f"/rides/{ride_id}/analyze", 201)["id"])
    assert again["status"] == "done", again["error"]
    after = api.ok("GET", f"/rides/{ride_id}")
    assert after["result_outdated_by"] == [] and after["gait"] == "canter"
    # The bundle said walk: the new result was computed as a canter (the stand-in's numbers differ per gait).
    assert after["indicators"] != before["indicators"]

    rider = api.ok("GET", "/riders")["items"][0]
    api.ok("POST", "/grades", 201, json={"ride_id": ride_id, "rider_id": rider["id"], "grade": 4})
    storage = Path(env.settings.storage_dir)
    stored = _files_under(storage / "rides" / str(ride_id))
    assert any("results" in p.parts for p in stored) and any("bundle" in p.parts for p in stored)
    assert api.delete(f"/rides/{ride_id}").status_code == 204
    assert _files_under(storage / "rides" / str(ride_id)) == []
    assert api.get(f"/rides/{ride_id}").status_code == 404
    assert api.ok("GET", "/jobs", params={"ride_id": ride_id})["total"] == 0
    assert api.ok("GET", "/grades", params={"ride_id": ride_id})["total"] == 0
    # With its last ride gone, the rider can be deleted.
    assert api.delete(f"/riders/{rider['id']}").status_code == 204


def test_a_new_ride_is_deletable_by_its_maker_not_by_another_member(club):
    admin = club["api"]
    maker, maker_user = add_member(admin)
    other, _ = add_member(admin)
    ride = maker.ok("POST", "/rides", 201, json={"horse_id": club["horses"][0]["id"],
                                                  "rider_id": club["riders"][0]["id"], "gait": "walk",
                                                  "direction": "CW"})
    assert ride["status"] == "new" and ride["created_by"] == maker_user["id"]
    refused = other.delete(f"/rides/{ride['id']}")
    assert refused.status_code == 403 and "ride.delete" in refused.json()["detail"]
    assert maker.delete(f"/rides/{ride['id']}").status_code == 204


def test_stage_labels_say_what_a_job_does_in_plain_words():
    assert stage_label(None, "queued") == "Waiting to start"
    assert stage_label("calibrate: board views", "running") == "Calibrating the cameras: finding the calibration board"
    assert stage_label("analyze: detection", "running") == "Analysing the ride: finding the markers"
    assert stage_label("probe: motion/left", "running") == "Checking the clips: motion clip of the left camera"
    assert stage_label("selftest: step 1/5", "running") == "Testing the workers: step 1/5"
    assert stage_label("analyze", "failed") == "Stopped with an error"
    assert stage_label("something_new", "running") == "Something new"
    assert [progress_percent(p, s) for p, s in [(0.0, "queued"), (0.456, "running"), (0.9995, "running"),
                                                (1.0, "done"), (None, "failed")]] == [0, 45, 99, 100, 0]

"""The riding club's day through the API, on both engines (embedded: SQLite + threads; celery: PostgreSQL,
Redis and a real worker process) and both storage back ends (embedded-s3: a bucket of a real SeaweedFS):
upload a ride (a zip bundle, or clip by clip with a rig calibrated once), watch the job, read the result
and exports, compare horses, rank them, correlate grades."""

from __future__ import annotations

import csv
import io
import json

import integration_services
import numpy as np
import openpyxl
import pytest
import s3_server as s3_server_module
from api_helpers import Api, add_member, another_take, new_club, ride_json_with, standin_result, zip_folder
from engines import CELERY_S3, EMBEDDED_S3, ENGINES, open_env
from integration_services import mp4_with_a_free_box

from saddlescope.core.vibration import COMFORT_INDICATORS, leaderboard
from saddlescope.io.mocap import read_mocap

s3_server = s3_server_module.s3_server  # one SeaweedFS for the session (tests/s3_server.py)

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url
tiny_ride = integration_services.tiny_ride

STAGES = {"probe", "assemble", "calibrate", "analyze", "total"}


@pytest.fixture(scope="module", params=[
    *ENGINES, EMBEDDED_S3, CELERY_S3])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory)


@pytest.fixture(scope="module")
def admin(env) -> Api:
    api, _ = new_club(env.client)
    return api


def upload_zip(api: Api, data: bytes, **params) -> dict:
    return api.ok(
        "POST", "/rides/bundle", 201, files={"file": ("ride.zip", data, "application/zip")}, params=params
    )


def meta_of(folder, **changes) -> dict:
    return json.loads(ride_json_with(folder, **changes))


def test_a_bundle_upload_is_analysed_and_its_result_and_exports_are_served(env, admin, tiny_ride, tmp_path):
    created = upload_zip(admin, zip_folder(tiny_ride))
    ride_id = created["ride"]["id"]
    assert created["ride"]["from_bundle"] and created["ride"]["gait"] == "canter"
    job, seen = admin.wait_job(created["job_id"])
    assert job["status"] == "done", job["error"]
    assert set(job["timings_s"]) == STAGES and job["progress"] == 1.0
    progress = [v["progress"] for v in seen]
    assert progress == sorted(progress)  # the bar never goes back
    if env.engine == "celery":  # run by the worker process, not by this one
        assert job["host"].endswith(f":{env.worker.pid}")

    ride = admin.ok("GET", f"/rides/{ride_id}")
    assert ride["status"] == "analysed" and ride["latest_job_id"] == job["id"]
    assert len(ride["recordings"]) == 12
    assert {(r["fps"], r["width"], r["height"]) for r in ride["recordings"]} == {(30.0, 640, 480)}
    horse = admin.ok("GET", f"/horses/{ride['horse_id']}")
    assert horse["name"] == meta_of(tiny_ride)["horse"]["name"]  # created from ride.json

    expected = standin_result(meta_of(tiny_ride))
    result = admin.ok("GET", f"/rides/{ride_id}/result")
    assert result["indicators"] == pytest.approx(expected["indicators"])
    assert result["units"]["acc_y_wb_rms"] == "m/s^2" and result["units"]["t_a8_limit_wb_h"] == "h"
    n = len(expected["saddle"]["t_s"])
    assert result["decimation"] == {"step": 1, "samples": n, "max_points": 2000}
    assert len(result["series"]["acceleration_m_s2"]) == n
    small = admin.ok("GET", f"/rides/{ride_id}/result", params={"max_points": 10})
    step = small["decimation"]["step"]
    assert step == -(-n // 10) and len(small["series"]["t_s"]) <= 10
    assert small["series"]["t_s"] == expected["saddle"]["t_s"][::step]
    assert ride["indicators"] == pytest.approx({k: expected["indicators"][k] for k in COMFORT_INDICATORS})

    document = admin.ok("GET", f"/rides/{ride_id}/export/json")
    assert document["format"] == "saddlescope.result/1" and document["indicators"] == result["indicators"]

    table = admin.ok("GET", f"/rides/{ride_id}/export/csv")
    assert "attachment" in table.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(table.content.decode("utf-8-sig"))))
    assert len(rows) == 1 and rows[0]["Horse"] == horse["name"] and rows[0]["Gait"] == "canter"
    assert float(rows[0]["W_b r.m.s. (m/s²)"]) == pytest.approx(expected["indicators"]["acc_y_wb_rms"], rel=5e-3)

    book = openpyxl.load_workbook(io.BytesIO(admin.ok("GET", f"/rides/{ride_id}/export/xlsx").content))
    header = [c.value for c in next(book.worksheets[0].iter_rows(max_row=1))]
    assert "W_b r.m.s. (m/s²)" in header

    positions = (
        np.concatenate(
            [
                np.asarray(expected["markers"]["position_m"]),
                np.asarray(expected["saddle"]["position_m"])[:, None],
            ],
            axis=1,
        )
        * 1e3
    )
    for fmt in ("c3d", "trc"):
        path = tmp_path / f"ride.{fmt}"
        path.write_bytes(admin.ok("GET", f"/rides/{ride_id}/export/{fmt}").content)
        tracks = read_mocap(path)
        assert list(tracks.labels) == ["M1", "M2", "M3", "S"] and tracks.rate_hz == pytest.approx(30.0)
        scale = 1.0 if tracks.units == "mm" else 1e3
        np.testing.assert_allclose(tracks.points * scale, positions, atol=1e-2)

    many = admin.ok("GET", "/rides/export/csv", params={"gait": "canter"})
    assert str(ride_id) in many.content.decode("utf-8-sig")

    # the dashboard polls: an unchanged result is a 304 without a body; a re-analysis changes the tag
    first = admin.get(f"/rides/{ride_id}/result")
    unchanged = admin.get(f"/rides/{ride_id}/result", headers={"If-None-Match": first.headers["etag"]})
    assert unchanged.status_code == 304 and not unchanged.content
    again, _ = admin.wait_job(admin.ok("POST", f"/rides/{ride_id}/analyze", 201)["id"])
    assert again["status"] == "done"
    renewed = admin.get(f"/rides/{ride_id}/result", headers={"If-None-Match": first.headers["etag"]})
    assert renewed.status_code == 200 and renewed.headers["etag"] != first.headers["etag"]
    assert renewed.json()["job_id"] == again["id"]


def upload_clip(api: Api, owner: str, owner_id: int, kind: str, camera: str, path) -> dict:
    return api.ok(
        "PUT",
        f"/{owner}/{owner_id}/clips/{kind}/{camera}",
        files={"file": (path.name, path.read_bytes(), "video/mp4")},
    )


def test_clips_one_by_one_with_a_rig_calibrated_once_for_all_its_rides(env, admin, tiny_ride, tmp_path):
    board = json.loads((tiny_ride / "ride.json").read_text())["board"]
    rig = admin.ok(
        "POST", "/rigs", 201, json={"name": "Arena, Monday", "recorded_on": "2026-05-04", "board": board}
    )
    for camera in ("left", "middle"):
        assert (
            upload_clip(
                admin, "rigs", rig["id"], "calibration", camera, tiny_ride / f"calibration/{camera}.mp4"
            )["job_id"]
            is None
        )
    third = upload_clip(admin, "rigs", rig["id"], "calibration", "right", tiny_ride / "calibration/right.mp4")
    probed_by_api = env.settings.storage_url is None  # on object storage the worker's probe stage reads clips
    assert third["recording"]["fps"] == (30.0 if probed_by_api else None) and third["recording"]["sha256"]
    # the third camera completes the set: calibration starts, queued behind the three clips' calibration
    # checks (each 15-50 s on a loaded two-core runner): the wait allows for them
    job, _ = admin.wait_job(third["job_id"], timeout_s=240.0)
    assert job["kind"] == "calibrate_rig" and job["status"] == "done", job["error"]
    assert {clip["fps"] for clip in admin.ok("GET", f"/rigs/{rig['id']}/clips")} == {30.0}  # probed now
    rig_now = admin.ok("GET", f"/rigs/{rig['id']}")
    assert rig_now["calibrated"] and set(rig_now["calibration"]["cameras"]) == {"left", "middle", "right"}
    for kind in ("plumb", "static"):
        for camera in ("left", "middle", "right"):
            assert (
                upload_clip(admin, "rigs", rig["id"], kind, camera, tiny_ride / f"{kind}/{camera}.mp4")[
                    "job_id"
                ]
                is None
            )  # the rig is calibrated already: nothing to start
    assert len(admin.ok("GET", f"/rigs/{rig['id']}/clips")) == 9

    horse = admin.ok(
        "POST", "/horses", 201, json={"name": "Clip Horse", "breed": "Dutch", "birth_year": 2001}
    )
    rider = admin.ok("POST", "/riders", 201, json={"name": "Clip Rider"})
    results = []
    for direction in ("CCW", "CW"):
        ride = admin.ok(
            "POST",
            "/rides",
            201,
            json={
                "horse_id": horse["id"],
                "rider_id": rider["id"],
                "rig_id": rig["id"],
                "gait": "canter",
                "direction": direction,
            },
        )
        assert ride["status"] == "new"
        # The second ride's clips are another take's bytes (the same clips never make two rides).
        takes = {camera: mp4_with_a_free_box(tiny_ride / f"motion/{camera}.mp4",
                                             tmp_path / direction / f"{camera}.mp4", f"take {direction}")
                 for camera in ("left", "middle", "right")}
        jobs = [
            upload_clip(admin, "rides", ride["id"], "motion", camera, takes[camera])["job_id"]
            for camera in ("left", "middle", "right")
        ]
        assert jobs[:2] == [None, None] and jobs[2] is not None
        job, _ = admin.wait_job(jobs[2])
        assert job["kind"] == "analyze" and job["status"] == "done", job["error"]
        assert set(job["timings_s"]) == STAGES
        result = admin.ok("GET", f"/rides/{ride['id']}/result")
        assert result["quality"]["calibration_from_rig"]  # analyze_bundle got rig= the stored calibration
        meta = {
            "horse": {"name": "Clip Horse"},
            "rider": {"name": "Clip Rider"},
            "gait": "canter",
            "direction": direction,
        }
        assert result["indicators"] == pytest.approx(standin_result(meta)["indicators"])
        results.append(result)
    calibrations = admin.ok("GET", "/jobs", params={"rig_id": rig["id"], "kind": "calibrate_rig"})
    assert calibrations["total"] == 1  # once for the rig, reused by both rides


# Database logic over rides: on both engines, not again on each storage back end (the uploads' and results'
# storage paths are the other tests' own)
@pytest.mark.parametrize("env", ENGINES, indirect=True)
def test_comparisons_leaderboard_and_grades(env, tiny_ride):
    admin, _ = new_club(env.client)
    plan = [
        ("Ajax", "canter", "Rider A"),
        ("Ajax", "canter", "Rider B"),
        ("Bella", "canter", "Rider A"),
        ("Cosmo", "canter", "Rider A"),
        ("Ajax", "walk", "Rider A"),
    ]
    rides = []
    for number, (horse, gait, rider) in enumerate(plan):
        data = zip_folder(
            tiny_ride,
            rewrite={
                **another_take(tiny_ride, f"take {number}"),
                "ride.json": ride_json_with(
                    tiny_ride, horse={"name": horse}, rider={"name": rider}, gait=gait
                )
            },
        )
        created = upload_zip(admin, data)
        rides.append((created["ride"], created["job_id"], horse, gait, rider))
    for _, job_id, *_ in rides:
        job, _ = admin.wait_job(job_id)
        assert job["status"] == "done", job["error"]
    expected_rows = [
        {
            "ride_id": ride["id"],
            "horse": horse,
            "gait": gait,
            **standin_result(
                {"horse": {"name": horse}, "rider": {"name": rider}, "gait": gait, "direction": "CCW"}
            )["indicators"],
        }
        for ride, _, horse, gait, rider in rides
    ]

    board = admin.ok("GET", "/leaderboard", params={"gait": "canter", "indicator": "acc_y_wb_rms"})
    truth = leaderboard(expected_rows, "acc_y_wb_rms", gait="canter")
    assert [e["horse"] for e in board["entries"]] == [t["horse"] for t in truth]
    assert [e["n"] for e in board["entries"]] == [t["n"] for t in truth]
    assert board["rides"] == 4 and board["better"] == "lower" and board["unit"] == "m/s^2"
    ajax = next(e for e in board["entries"] if e["horse"] == "Ajax")
    assert ajax["n"] == 2 and ajax["spread"] == pytest.approx(
        next(t for t in truth if t["horse"] == "Ajax")["spread"]
    )
    assert ajax["spread"] > 0 and ajax["horse_id"] == rides[0][0]["horse_id"]
    longer = admin.ok("GET", "/leaderboard", params={"gait": "canter", "indicator": "t_a8_limit_wb_h"})
    assert longer["better"] == "higher"
    assert [e["mean"] for e in longer["entries"]] == sorted(
        (e["mean"] for e in longer["entries"]), reverse=True
    )
    refused = admin.get("/leaderboard", params={"gait": "canter", "indicator": "vel_x_avg_kmh"})
    assert refused.status_code == 422 and "lower_is_better" in refused.json()["detail"]

    ajax_id, bella_id = rides[0][0]["horse_id"], rides[2][0]["horse_id"]
    gaits = admin.ok(
        "GET", f"/horses/{ajax_id}/comparison", params={"indicator": ["acc_y_wb_rms", "vdv_y_wb"]}
    )
    assert [g["group"] for g in gaits["indicators"]["acc_y_wb_rms"]["gaits"]] == ["walk", "canter"]
    canter = gaits["indicators"]["acc_y_wb_rms"]["gaits"][1]
    assert canter["n"] == 2 and canter["mean"] == pytest.approx(
        np.mean([r["acc_y_wb_rms"] for r in expected_rows[:2]])
    )
    walk = gaits["indicators"]["vdv_y_wb"]["gaits"][0]
    assert walk["n"] == 1 and walk["std"] is None  # one ride: no spread (NaN in JSON is null)

    pair = admin.ok("GET", "/comparison", params={"gait": "canter", "horses": f"{ajax_id},{bella_id}"})
    assert {h["horse"] for h in pair["indicators"]["acc_y_wb_rms"]["horses"]} == {"Ajax", "Bella"}
    assert set(pair["indicators"]) == set(COMFORT_INDICATORS)

    riders = {r["name"]: r["id"] for r in admin.ok("GET", "/riders")["items"]}
    for (ride, _, _horse, gait, _), grade in zip(rides, (2, 2, 4, 5, 3), strict=True):
        if gait == "canter":
            admin.ok(
                "POST",
                "/grades",
                201,
                json={"ride_id": ride["id"], "rider_id": riders["Rider A"], "grade": grade},
            )
    again = admin.ok(
        "POST",
        "/grades",
        201,
        json={
            "ride_id": rides[0][0]["id"],
            "rider_id": riders["Rider A"],
            "grade": 1,
            "comment": "changed my mind",
        },
    )
    assert (
        again["grade"] == 1
        and admin.ok("GET", "/grades", params={"ride_id": rides[0][0]["id"]})["total"] == 1
    )
    corr = admin.ok("GET", "/grades/correlation", params={"gait": "canter", "indicator": "acc_y_wb_rms"})
    stats = corr["indicators"]["acc_y_wb_rms"]
    assert stats["n"] == 3 and len(stats["points"]) == 3 and stats["expected_sign"] == -1
    # three points: no r nor rho (noise), and the reason in words (issue 37)
    assert stats["pearson_r"] is None and stats["spearman_rho"] is None and stats["min_points"] == 5
    assert stats["withheld_reason"].startswith("needs at least 5 graded horse-gait pairs")


def test_cancel_retry_and_a_failed_stage_keeps_the_uploads(env, admin, tiny_ride):
    job = admin.ok("POST", "/jobs", 201, json={"kind": "selftest", "payload": {"steps": 40, "delay_s": 0.1}})
    for _ in range(200):
        if admin.ok("GET", f"/jobs/{job['id']}")["status"] == "running":
            break
    cancelled = admin.ok("POST", f"/jobs/{job['id']}/cancel")
    assert cancelled["status"] == "cancelled"
    again = admin.ok("POST", f"/jobs/{job['id']}/retry")
    assert again["status"] in ("queued", "running", "done")
    done, _ = admin.wait_job(job["id"])
    assert done["status"] == "done" and done["attempts"] >= 1
    refused = admin.post(f"/jobs/{job['id']}/retry")
    assert refused.status_code == 409 and "only a failed or cancelled job" in refused.json()["detail"]

    data = zip_folder(
        tiny_ride, rewrite={**another_take(tiny_ride, "failing take"),
                            "ride.json": ride_json_with(tiny_ride, horse={"name": "Failing Fox"})}
    )
    created = upload_zip(admin, data)
    failed, _ = admin.wait_job(created["job_id"])
    assert failed["status"] == "failed"
    assert failed["error"].startswith("analyze: motion clip of the left camera: no marker found")
    ride = admin.ok("GET", f"/rides/{created['ride']['id']}")
    assert ride["status"] == "failed" and len(ride["recordings"]) == 12  # the uploads are kept
    assert admin.get(f"/rides/{ride['id']}/result").status_code == 404
    retried = admin.ok("POST", f"/jobs/{failed['id']}/retry")
    assert retried["id"] == failed["id"] and retried["error"] is None
    failed_again, _ = admin.wait_job(failed["id"])
    assert failed_again["status"] == "failed" and failed_again["attempts"] == 2


def test_a_member_works_with_the_clubs_data_but_cannot_manage_users(env, admin):
    member, user = add_member(admin)
    assert user["role"] == "member"
    horse = member.ok("POST", "/horses", 201, json={"name": "Member's horse"})
    assert admin.ok("GET", f"/horses/{horse['id']}")["name"] == "Member's horse"
    assert member.get("/users").status_code == 403
    assert member.delete(f"/horses/{horse['id']}").status_code == 403
    assert admin.delete(f"/horses/{horse['id']}").status_code == 204


def test_a_bundle_whose_cameras_disagree_fails_at_probe_with_the_reason(env, admin, tmp_path):
    from integration_services import write_tiny_bundle, write_tiny_clip

    bundle = write_tiny_bundle(tmp_path / "bundle")
    odd = write_tiny_clip(tmp_path / "odd.avi", frames=5, size=(80, 60)).read_bytes()
    created = upload_zip(admin, zip_folder(bundle, rewrite={"motion/middle.avi": odd}))
    job, _ = admin.wait_job(created["job_id"])
    assert job["status"] == "failed" and set(job["timings_s"]) == {"probe", "total"}
    assert job["error"] == (
        f"probe: ride {created['ride']['id']}: the motion clips disagree: the left camera's is 64x48 px at "
        "30.000 fps, the middle camera's 80x60 px at 30.000 fps"
    )
    assert len(admin.ok("GET", f"/rides/{created['ride']['id']}")["recordings"]) == 12  # kept

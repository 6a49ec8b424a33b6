"""A failed ride says which clip of which camera failed and what to do; the clip is replaced and the ride runs.

The analysis is a stand-in (the pipeline's own failures are exercised in tests/services/test_failure_advice.py
and tests/core/pipeline/test_consistency.py): it fails, as the detector does, naming the left camera's
motion clip when that clip is not like the others (it has another frame count), and succeeds otherwise.
A bundle ride's clip replaced from the ride page takes the bundle clip's place; the other clips are kept.
"""

from __future__ import annotations

import sys
import types

import integration_services
import pytest
from api_helpers import ThreadQueue, job_outcome, new_club, standin_analyze_bundle, standin_calibrate_clips, zip_folder
from fastapi.testclient import TestClient

from saddlescope.api import create_app
from saddlescope.settings import load_settings


def _picky_analysis(path, on_progress=None, rig=None, params=None, meta_overrides=None, rig_report=None):
    """The stand-in analysis, failing like the detector when the left motion clip differs from the right one."""
    from saddlescope.core.errors import DetectionError
    from saddlescope.io.bundle import open_bundle
    from saddlescope.io.video import probe_video

    with open_bundle(path) as bundle:
        motion = bundle.clip_paths["motion"]
        left, right = probe_video(motion["left"]).frame_count, probe_video(motion["right"]).frame_count
    if left != right:
        raise DetectionError(f"camera 'left', clip 'motion': markers not found on any of the {left} frames "
                             "(brightest blob 12 of 255)")
    return standin_analyze_bundle(path, on_progress, rig, params, meta_overrides, rig_report)


@pytest.fixture
def env(tmp_path, monkeypatch):
    module = types.ModuleType("saddlescope.services.analysis.ride_bundle")
    module.analyze_bundle = _picky_analysis
    monkeypatch.setitem(sys.modules, "saddlescope.services.analysis.ride_bundle", module)
    import saddlescope.services.rigs.calibration as calibration

    monkeypatch.setattr(calibration, "calibrate_clips", standin_calibrate_clips)
    settings = load_settings(database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "storage"))
    queue = ThreadQueue(settings)
    with TestClient(create_app(settings, queue=queue)) as client:
        api, _account = new_club(client)
        yield api, tmp_path
    queue.close()


def _bundle_with_a_broken_left_clip(folder):
    bundle = integration_services.write_tiny_bundle(folder / "bundle", gait="canter", frames=5)
    integration_services.write_tiny_clip(bundle / "motion" / "left.avi", frames=9)  # not like the others
    return bundle


def _upload_bundle(api, folder) -> dict:
    response = api.client.post("/api/rides/bundle", content=zip_folder(folder),
                               headers={**api.headers, "content-type": "application/zip", "x-filename": "ride.zip"})
    assert response.status_code == 201, response.text
    return response.json()


def test_a_failed_ride_names_the_clip_and_runs_once_that_clip_is_replaced(env):
    api, root = env
    uploaded = _upload_bundle(api, _bundle_with_a_broken_left_clip(root))
    ride_id = uploaded["ride"]["id"]
    failed = job_outcome(api, uploaded["job_id"])
    assert failed["status"] == "failed"
    failure = failed["failure"]
    assert failure["action"] == "replace_clip"
    assert (failure["camera"], failure["clip_kind"]) == ("left", "motion")
    assert "the motion clip of the left camera" in failure["sentence"]
    assert "upload the motion clip of the left camera again" in failure["sentence"]
    assert "blob" not in failure["sentence"] and "'motion'" not in failure["sentence"]
    assert failed["ride_label"] == "Horse 2, canter"
    assert failed["duration_s"] is not None and failed["remaining_s"] is None
    assert api.ok("GET", f"/rides/{ride_id}")["status"] == "failed"

    # The jobs list names the ride as the club does, with the same advice.
    listed = api.ok("GET", "/jobs", params={"ride_id": ride_id})["items"][0]
    assert listed["ride_label"] == "Horse 2, canter" and listed["failure"] == failure

    # Replace the left camera's motion clip (the other clips of the bundle kept): the analysis runs again.
    good = integration_services.write_tiny_clip(root / "good-left.avi", frames=5)
    response = api.client.put(f"/api/rides/{ride_id}/clips/motion/left", content=good.read_bytes(),
                              headers={**api.headers, "content-type": "application/octet-stream",
                                       "x-filename": "good-left.avi"})
    assert response.status_code == 200, response.text
    job_id = response.json()["job_id"]
    assert job_id is not None and job_id != uploaded["job_id"]
    done = job_outcome(api, job_id)
    assert done["status"] == "done", done["error"]
    assert done["failure"] is None
    ride = api.ok("GET", f"/rides/{ride_id}")
    assert ride["status"] == "analysed"
    clips = {(r["clip_kind"], r["camera_role"]) for r in ride["recordings"]}
    assert {("motion", "left"), ("motion", "right"), ("static", "middle"), ("calibration", "left")} <= clips


def test_a_ride_without_a_rig_cannot_lend_its_calibration(env):
    api, root = env
    uploaded = _upload_bundle(api, integration_services.write_tiny_bundle(root / "plain", frames=5))
    response = api.client.post(f"/api/rides/{uploaded['ride']['id']}/calibrate-rig", headers=api.headers)
    assert response.status_code == 422
    assert "has no rig" in response.json()["detail"]


def test_a_rides_own_calibration_clips_calibrate_its_rig(env, monkeypatch):
    api, root = env
    import saddlescope.services.rigs.calibration as calibration

    calibrated_from = []

    def recording(paths, **kwargs):
        calibrated_from.append(sorted(paths))
        return standin_calibrate_clips(paths, **kwargs)

    monkeypatch.setattr(calibration, "calibrate_clips", recording)
    rig = api.ok("POST", "/rigs", 201, json={"name": "Arena", "board": {
        "kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0}})
    folder = integration_services.write_tiny_bundle(root / "with-calibration", frames=5)
    response = api.client.post(f"/api/rides/bundle?rig_id={rig['id']}", content=zip_folder(folder),
                               headers={**api.headers, "content-type": "application/zip", "x-filename": "r.zip"})
    assert response.status_code == 201, response.text
    ride_id = response.json()["ride"]["id"]
    job_outcome(api, response.json()["job_id"])
    calibrated_from.clear()  # the first analysis calibrated the uncalibrated rig from the bundle itself
    job = api.ok("POST", f"/rides/{ride_id}/calibrate-rig", 201)
    assert (job["kind"], job["ride_id"], job["rig_id"]) == ("calibrate_rig", ride_id, rig["id"])
    done = job_outcome(api, job["id"])
    assert done["status"] == "done", done["error"]
    assert calibrated_from == [["left", "middle", "right"]]  # from the ride's own three calibration clips
    assert api.ok("GET", f"/rigs/{rig['id']}")["calibrated"]
    assert "calibrate_rig" in done["timings_s"]
    # the analysis runs again with the rig's new calibration
    again = api.ok("POST", f"/rides/{ride_id}/analyze", 201)
    assert job_outcome(api, again["id"])["status"] == "done"


def test_a_ride_without_calibration_clips_cannot_lend_them(env):
    api, root = env
    rig = api.ok("POST", "/rigs", 201, json={"name": "Barn", "board": {
        "kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0}})
    ride = api.ok("POST", "/rides", 201, json={
        "horse_id": api.ok("POST", "/horses", 201, json={"name": "Bramble"})["id"],
        "rider_id": api.ok("POST", "/riders", 201, json={"name": "Robin"})["id"],
        "gait": "sitting_trot", "direction": "CW", "rig_id": rig["id"]})
    response = api.post(f"/rides/{ride['id']}/calibrate-rig")
    assert response.status_code == 422
    assert "no calibration clip of the left, middle, right cameras" in response.json()["detail"]

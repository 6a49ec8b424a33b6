"""A motion-capture file through the REST upload: BTK's Gait.trc analysed as a ride with the pelvis
markers standing for M1-M3; the period and speed against the heels' (as tests/core/kinematics/
test_real_gait.py measures them); BTK's bad files refused with one sentence and nothing stored."""

from __future__ import annotations

import integration_services
import numpy as np
import pytest
from api_helpers import new_club
from engines import open_env
from scipy.signal import find_peaks

from conftest import real_data_path
from saddlescope.io.mocap import read_mocap

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url
pytestmark = pytest.mark.realdata
PELVIS_TRC = "R.ASIS,L.ASIS,V.Sacral"  # RASI, LASI, VSAC of Gait.c3d, named in full in Gait.trc


@pytest.fixture(scope="module", params=["embedded"])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture(scope="module")
def club(env):
    api, _ = new_club(env.client)
    horse = api.ok("POST", "/horses", 201, json={"name": "Gait lab"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Walker"})
    return api, horse["id"], rider["id"]


def _heel_stride():
    """Stride time (s) and speed (m/s) from the left heel's two stance phases (test_real_gait's references)."""
    data = read_mocap(real_data_path("c3d", "Gait.c3d"))
    pelvis = np.stack([data.marker(n) for n in ("RASI", "LASI", "VSAC")], axis=1)
    seen = np.flatnonzero(np.isfinite(pelvis).all(axis=(1, 2)))
    t_s = seen / data.rate_hz
    heel_m = data.marker("LHEE")[seen] / 1000.0
    stance, _ = find_peaks(-heel_m[:, 2], prominence=0.03)
    stride_s = float(np.diff(t_s[stance])[0])
    return stride_s, float(np.linalg.norm(np.diff(heel_m[stance, :2], axis=0))) / stride_s


def _upload(api, horse_id, rider_id, name, **params):
    body = real_data_path("c3d", name).read_bytes()
    query = {"horse_id": horse_id, "rider_id": rider_id, "filename": name, **params}
    return api.post("/mocap", params=query, content=body, headers={"Content-Type": "application/octet-stream"})


def test_gait_trc_through_the_upload_gives_the_heels_period_and_speed(club):
    api, horse_id, rider_id = club
    response = _upload(api, horse_id, rider_id, "Gait.trc", markers=PELVIS_TRC, up="z", gait="walk")
    assert response.status_code == 201, response.text
    out = response.json()
    stride_s, speed_m_s = _heel_stride()  # 1.00 s, 1.43 m/s
    assert out["period_s"] == pytest.approx(stride_s, rel=0.03)  # measured: 0.977 s
    assert out["indicators"]["vel_x_avg_kmh"] / 3.6 == pytest.approx(speed_m_s, rel=0.03)  # measured: 1.450 m/s
    source = out["source"]
    assert source["kind"] == "mocap" and source["format"] == "trc" and source["up"] == "+z"
    assert source["markers"] == PELVIS_TRC.split(",")
    ride_id = out["ride"]["id"]
    ride = api.ok("GET", f"/rides/{ride_id}")
    assert ride["status"] == "analysed" and ride["meta"]["source"]["file"] == "Gait.trc"
    result = api.ok("GET", f"/rides/{ride_id}/result")
    assert result["period_s"] == pytest.approx(out["period_s"])
    assert any("+z up" in f for f in result["quality"]["flags"])


def test_a_multipart_c3d_with_a_point_label(club):
    api, horse_id, rider_id = club
    path = real_data_path("c3d", "Gait.c3d")
    response = api.post("/mocap", params={"horse_id": horse_id, "rider_id": rider_id, "markers": "RASI,LASI,VSAC",
                                          "point": "C7", "strides": 1},
                        files={"file": ("Gait.c3d", path.read_bytes(), "application/octet-stream")})
    assert response.status_code == 201, response.text
    source = response.json()["source"]
    assert source["up"] == "+z" and "POINT:Y_SCREEN" in source["up_reason"]
    assert source["point"] == "C7" and source["point_body_mm"][2] > 300  # C7 is well above the pelvis
    assert any("RKNE" in w for w in source["warnings"])


@pytest.mark.parametrize("name", ["Empty.c3d", "Empty.trc", "Truncated.trc", "badParameterOffset.c3d",
                                  "bad_parameter_section.c3d"])
def test_bad_files_are_refused_with_one_sentence_and_nothing_stored(club, name):
    api, horse_id, rider_id = club
    before = api.ok("GET", "/rides")["total"]
    response = _upload(api, horse_id, rider_id, name, markers="A,B,C")
    assert response.status_code == 422
    detail = response.json()["detail"]
    assert detail.startswith(name + ":") and "\n" not in detail and "Traceback" not in detail
    assert api.ok("GET", "/rides")["total"] == before


@pytest.mark.parametrize("params, words", [
    ({"markers": "RASI,LASI"}, "three labels"),
    ({"markers": "RASI,LASI,RKNE"}, "used by 2 markers"),
    ({"markers": "RASI,LASI,VSAC", "up": "w"}, "vertical axis"),
    ({"markers": "RASI,LASI,VSAC", "offset_mm": "1,2"}, "three numbers"),
])
def test_bad_choices_are_refused_with_the_reason(club, params, words):
    api, horse_id, rider_id = club
    response = _upload(api, horse_id, rider_id, "Gait.c3d", **params)
    assert response.status_code == 422 and words in response.json()["detail"]


def test_a_file_that_is_no_mocap_and_another_clubs_horse(club, env):
    api, horse_id, rider_id = club
    response = api.post("/mocap", params={"horse_id": horse_id, "rider_id": rider_id, "markers": "A,B,C",
                                          "filename": "ride.mp4"}, content=b"xx")
    assert response.status_code == 422 and ".c3d or .trc" in response.json()["detail"]
    other, _ = new_club(env.client)
    response = _upload(other, horse_id, rider_id, "Gait.trc", markers=PELVIS_TRC)
    assert response.status_code == 404

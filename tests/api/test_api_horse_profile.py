"""The horse page's routes: an indicator's trend with the horse's own normal band (mean ± 2 SD over
EARLIER rides in the gait, from the fifth ride on), two rides side by side with % differences, the
reasons for another club's horse, an unknown ride or a ride of another horse, and heights in hands.
"""

from __future__ import annotations

import statistics

import integration_services
import pytest
from api_helpers import add_member, new_club
from engines import ENGINES, open_env
from similarity_docs import store_document

# Tango's canter rides in the order they were ridden; they are uploaded out of order (UPLOAD_ORDER) so
# the trend must follow the dates, not the ids.
CANTER_WB_RMS = [1.0, 1.2, 0.9, 1.1, 1.05, 2.0]
CANTER_DATES = ["2026-01-05", "2026-01-12", "2026-01-19", "2026-01-26", "2026-02-02", "2026-02-09"]
UPLOAD_ORDER = [2, 0, 1, 3, 5, 4]

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url


def _doc(wb_rms: float, gait: str = "canter") -> dict:
    indicators = {"acc_y_wb_rms": wb_rms, "vdv_y_wb": 2 * wb_rms, "vel_x_avg_kmh": 18.0,
                  "amplitude_y_m": 0.0 if wb_rms == 1.0 else 0.1}
    return {"format": "saddlescope.result/1", "fps": 30.0, "gait": gait, "indicators": indicators,
            "quality": {"flags": []}}


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory)


@pytest.fixture(scope="module")
def world(env):
    a, _ = new_club(env.client)
    rider = a.ok("POST", "/riders", 201, json={"name": "Rider R"})["id"]
    tango = a.ok("POST", "/horses", 201, json={"name": "Tango", "height_withers_m": "15.2 hh"})
    other = a.ok("POST", "/horses", 201, json={"name": "Other"})["id"]

    def ride(horse: int, gait: str, day: str, wb_rms: float | None) -> int:
        ride_id = a.ok("POST", "/rides", 201, json={"horse_id": horse, "rider_id": rider, "gait": gait,
                                                     "direction": "CW", "ridden_on": day})["id"]
        if wb_rms is not None:
            store_document(env.settings.database_url, env.settings.storage_dir, ride_id, _doc(wb_rms, gait))
        return ride_id

    canter = {i: ride(tango["id"], "canter", CANTER_DATES[i], CANTER_WB_RMS[i]) for i in UPLOAD_ORDER}
    walk = ride(tango["id"], "walk", "2026-01-07", 0.5)
    unanalysed = ride(tango["id"], "canter", "2026-03-01", None)
    others = ride(other, "canter", "2026-01-06", 1.3)
    b, _ = new_club(env.client)
    return {"a": a, "b": b, "tango": tango, "canter": [canter[i] for i in range(6)], "walk": walk,
            "unanalysed": unanalysed, "others": others}


def test_the_trend_follows_the_dates_and_has_a_band_from_the_fifth_ride_on(world):
    trend = world["a"].ok("GET", f"/horses/{world['tango']['id']}/trend",
                          params={"gait": "canter", "indicator": "acc_y_wb_rms"})
    points = trend["points"]
    assert [p["ride_id"] for p in points] == world["canter"]  # by date; the walk ride is another gait
    assert [p["value"] for p in points] == CANTER_WB_RMS
    assert [p["date"] for p in points] == CANTER_DATES
    assert trend["unit"] == "m/s^2" and trend["min_rides_for_band"] == 4
    assert [p["band"] for p in points[:4]] == [None] * 4 and [p["outside"] for p in points[:4]] == [None] * 4
    for i in (4, 5):  # the band of ride i is the rides before it: mean ± 2 sample SD
        earlier = CANTER_WB_RMS[:i]
        band = points[i]["band"]
        mean, sd = statistics.mean(earlier), statistics.stdev(earlier)
        assert band["n"] == i
        assert band["mean"] == pytest.approx(mean, rel=1e-12) and band["sd"] == pytest.approx(sd, rel=1e-12)
        assert band["low"] == pytest.approx(mean - 2 * sd) and band["high"] == pytest.approx(mean + 2 * sd)
    assert points[4]["outside"] is False  # 1.05 lies within 1.05 ± 0.26
    assert points[5]["outside"] is True  # 2.0 is far above the first five


def test_the_pair_gives_both_values_and_the_percent_difference(world):
    first, last = world["canter"][0], world["canter"][5]
    pair = world["a"].ok("GET", f"/horses/{world['tango']['id']}/ride-pair", params={"a": first, "b": last})
    assert pair["a"]["ride_id"] == first and pair["b"]["ride_id"] == last and pair["b_is_later"] is True
    assert pair["a"]["date"] == CANTER_DATES[0] and pair["b"]["gait"] == "canter"
    rows = {row["key"]: row for row in pair["indicators"]}
    assert rows["acc_y_wb_rms"]["a"] == 1.0 and rows["acc_y_wb_rms"]["b"] == 2.0
    assert rows["acc_y_wb_rms"]["difference_percent"] == pytest.approx(100.0)
    assert rows["acc_y_wb_rms"]["unit"] == "m/s^2" and rows["acc_y_wb_rms"]["better"] == "lower"
    assert rows["vdv_y_wb"]["difference_percent"] == pytest.approx(100.0)
    assert rows["vel_x_avg_kmh"]["difference_percent"] == 0.0
    assert rows["amplitude_y_m"]["difference_percent"] is None  # from zero: no percentage
    back = world["a"].ok("GET", f"/horses/{world['tango']['id']}/ride-pair",
                         params={"a": last, "b": first, "indicator": ["acc_y_wb_rms"]})
    assert [r["key"] for r in back["indicators"]] == ["acc_y_wb_rms"]
    assert back["indicators"][0]["difference_percent"] == pytest.approx(-50.0)
    assert back["b_is_later"] is False
    # Any two rides of the horse, also across gaits
    mixed = world["a"].ok("GET", f"/horses/{world['tango']['id']}/ride-pair",
                          params={"a": world["walk"], "b": first})
    assert mixed["indicators"][0]["key"] == "acc_y_wb_rms"  # the main comfort measure first
    assert mixed["indicators"][0]["difference_percent"] == pytest.approx(100.0)


def _detail(response) -> str:
    return response.json()["detail"]


def test_another_clubs_horse_and_unknown_rides_are_not_found(world):
    horse = world["tango"]["id"]
    for path in (f"/horses/{horse}/trend?gait=canter", f"/horses/{horse}/ride-pair?a=1&b=2"):
        response = world["b"].get(path)
        assert response.status_code == 404 and "horse" in _detail(response)
    response = world["a"].get(f"/horses/{horse}/ride-pair", params={"a": world["canter"][0], "b": 999_999})
    assert response.status_code == 404 and "ride 999999" in _detail(response)
    assert world["a"].get("/horses/999999/trend", params={"gait": "walk"}).status_code == 404


def test_wrong_rides_and_options_get_their_reason(world):
    a, horse = world["a"], world["tango"]["id"]
    response = a.get(f"/horses/{horse}/ride-pair", params={"a": world["canter"][0], "b": world["others"]})
    assert response.status_code == 422 and "another horse" in _detail(response)
    response = a.get(f"/horses/{horse}/ride-pair", params={"a": world["canter"][0], "b": world["canter"][0]})
    assert response.status_code == 422 and "two different rides" in _detail(response)
    response = a.get(f"/horses/{horse}/ride-pair", params={"a": world["canter"][0], "b": world["unanalysed"]})
    assert response.status_code == 409 and "no analysis result yet" in _detail(response)
    response = a.get(f"/horses/{horse}/trend", params={"gait": "canter", "indicator": "comfort"})
    assert response.status_code == 422 and "indicator" in _detail(response)
    assert "unknown indicator 'comfort'" in _detail(response) and "/api/indicators" in _detail(response)
    response = a.get(f"/horses/{horse}/trend", params={"gait": "gallop"})
    assert response.status_code == 422 and "gait" in _detail(response)
    response = a.get(f"/horses/{horse}/ride-pair", params={"a": world["canter"][0]})
    assert response.status_code == 422 and "b" in _detail(response)


def test_a_height_in_hands_is_understood_and_a_bare_number_explains_the_unit(world):
    a, horse = world["a"], world["tango"]["id"]
    assert world["tango"]["height_withers_m"] == pytest.approx(62 * 0.0254)  # 15.2 hh = 62 inches
    assert a.ok("PATCH", f"/horses/{horse}", json={"height_withers_m": "163 cm"})["height_withers_m"] == 1.63
    response = a.patch(f"/horses/{horse}", json={"height_withers_m": 15.2})
    assert response.status_code == 422
    assert '"15.2 hh"' in _detail(response) and "metres" in _detail(response)
    response = a.patch(f"/horses/{horse}", json={"height_withers_m": "15.5 hh"})
    assert response.status_code == 422 and "inches (0-3)" in _detail(response)
    assert a.ok("GET", f"/horses/{horse}")["height_withers_m"] == 1.63  # refused changes keep the height
    member, _ = add_member(a)
    assert member.ok("PATCH", f"/horses/{horse}", json={"height_withers_m": "16 hh"})["height_withers_m"] == \
        pytest.approx(64 * 0.0254)


def test_grade_points_name_the_horse_riders_rides_and_dates(world):
    a = world["a"]
    rider = a.ok("GET", "/riders")["items"][0]
    a.ok("POST", "/grades", 201, json={"ride_id": world["canter"][0], "rider_id": rider["id"], "grade": 4})
    points = a.ok("GET", "/grades/correlation", params={"gait": "canter", "indicator": "acc_y_wb_rms"})[
        "indicators"]["acc_y_wb_rms"]["points"]
    assert points == [{"horse": "Tango", "gait": "canter", "grade": 4.0, "value": pytest.approx(
        statistics.mean(CANTER_WB_RMS)), "horse_id": world["tango"]["id"], "riders": ["Rider R"],
        "rides": len(CANTER_WB_RMS), "first_date": CANTER_DATES[0], "last_date": CANTER_DATES[-1]}]

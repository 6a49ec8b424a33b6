"""The ride page's new result fields (plain-language quality, fitted curves, weighted acceleration,
spectrum) and the one-page ride report (HTML and a one-page PDF) through the API.

Results are put in as the analyse stage would (tests/e2e/dashboard_helpers.py's seeded documents: exact
Fourier series with the core's own indicators), for a horse with five canter rides so the last one has
a normal band from four earlier rides and the first has none.
"""

from __future__ import annotations

import datetime as dt
import io
import sys

import numpy as np
import pytest
from api_helpers import new_club
from fastapi.testclient import TestClient

from conftest import PROJECT_ROOT
from saddlescope.api import create_app
from saddlescope.core.findings import Finding
from saddlescope.io.findings_document import findings_to_list
from saddlescope.services.results.report import duration_text
from saddlescope.settings import load_settings

sys.path.insert(0, str(PROJECT_ROOT / "tests" / "e2e"))
from dashboard_helpers import result_document, store_result  # noqa: E402

WEAK_AXIS = ("rotation about the markers' weakest axis (eigenvalue ratio 0.026) kept at 0% in ω and 0% in α: "
             "the rest is what skin motion predicts")


@pytest.fixture(scope="module")
def club(tmp_path_factory):
    root = tmp_path_factory.mktemp("report")
    database_url = f"sqlite:///{root / 'db.sqlite'}"
    settings = load_settings(database_url=database_url, storage_dir=str(root / "storage"))
    rng = np.random.default_rng(3)
    with TestClient(create_app(settings)) as client:
        api, _ = new_club(client)
        horse = api.ok("POST", "/horses", 201, json={"name": "Bella", "breed": "Dutch", "birth_year": 2012})
        rider = api.ok("POST", "/riders", 201, json={"name": "Anna"})
        rides = []
        for i, scale in enumerate((1.0, 1.05, 0.95, 1.02, 1.6)):  # the fifth ride is much rougher
            ride = api.ok("POST", "/rides", 201, json={
                "horse_id": horse["id"], "rider_id": rider["id"], "gait": "canter", "direction": "CCW",
                "ridden_on": (dt.date(2026, 3, 1) + dt.timedelta(days=7 * i)).isoformat()})
            doc = result_document(scale=scale, gait="canter", rng=rng)
            doc["quality"]["flags"].append(WEAK_AXIS)
            if i == 1:  # stored as this version writes it: the findings as data beside their sentences
                doc["quality"]["findings"] = findings_to_list(
                    [Finding("tracking.lost", doc["quality"]["flags"][0]), Finding("rotation.weak_axis", WEAK_AXIS)])
            store_result(database_url, root / "storage", ride["id"], doc)
            rides.append(ride["id"])
        unanalysed = api.ok("POST", "/rides", 201, json={
            "horse_id": horse["id"], "rider_id": rider["id"], "gait": "canter", "direction": "CW"})
        yield {"api": api, "rides": rides, "unanalysed": unanalysed["id"]}


def test_the_result_says_its_quality_in_plain_words_with_the_expert_detail(club):
    result = club["api"].ok("GET", f"/rides/{club['rides'][0]}/result")
    notes = {n["code"]: n for n in result["quality_notes"]}
    assert set(notes) == {"tracking.lost", "rotation.weak_axis"}
    assert notes["rotation.weak_axis"]["severity"] == "check"
    assert "10 cm below" in notes["rotation.weak_axis"]["message"]
    assert notes["rotation.weak_axis"]["detail"] == WEAK_AXIS
    assert result["quality_summary"]["severity"] == "check"
    assert result["strides_analysed"] == 2


def test_a_result_with_findings_as_data_gives_the_notes_of_one_with_sentences_only(club):
    old, new = (club["api"].ok("GET", f"/rides/{ride}/result") for ride in club["rides"][:2])
    assert "findings" not in old["quality"] and [f["code"] for f in new["quality"]["findings"]] == [
        "tracking.lost", "rotation.weak_axis"]
    assert new["quality_notes"] == old["quality_notes"] and new["quality_summary"] == old["quality_summary"]


def test_the_result_serves_fitted_curves_residuals_and_weighted_acceleration(club):
    result = club["api"].ok("GET", f"/rides/{club['rides'][0]}/result")
    series = result["series"]
    n = len(series["t_s"])
    for key in ("position_fitted_m", "position_residual_m", "velocity_measured_m_s", "velocity_residual_m_s",
                "acceleration_measured_m_s2", "acceleration_residual_m_s2"):
        assert len(series[key]) == n and len(series[key][0]) == 3, key
    measured = np.asarray(series["position_m"])
    fitted = np.asarray(series["position_fitted_m"])
    assert np.allclose(measured - fitted, series["position_residual_m"], atol=1e-6)
    assert np.abs(series["position_residual_m"])[:, 1].max() < 0.005  # the vertical fit follows the data
    wb = np.asarray(series["acc_y_wb_m_s2"], dtype=float)
    assert wb.shape == (n,) and len(series["acc_y_wk_m_s2"]) == n
    # the weighted r.m.s. over the window is the indicator (the window is about two whole strides)
    assert np.sqrt(np.mean(wb**2)) == pytest.approx(result["indicators"]["acc_y_wb_rms"], rel=0.03)
    spectrum = result["spectrum"]
    assert spectrum["frequency_hz"][:3] == pytest.approx([1.65, 3.3, 4.95])
    assert spectrum["amplitude_m_s2"][:3] == pytest.approx([4.0, 1.5, 0.5], rel=1e-6)
    # W_b damps the stride's fundamental (1.65 Hz) and lifts nothing much around 5 Hz, where it peaks
    assert spectrum["amplitude_wb_m_s2"][0] < 0.5 * spectrum["amplitude_m_s2"][0]
    assert spectrum["amplitude_wb_m_s2"][2] == pytest.approx(spectrum["amplitude_m_s2"][2], rel=0.1)


def test_a_decimated_result_keeps_every_series_aligned(club):
    result = club["api"].ok("GET", f"/rides/{club['rides'][0]}/result", params={"max_points": 10})
    n = len(result["series"]["t_s"])
    assert n <= 10
    assert len(result["series"]["position_fitted_m"]) == n and len(result["series"]["acc_y_wb_m_s2"]) == n


def test_the_report_names_the_ride_and_reads_the_last_ride_against_its_normal_band(club):
    response = club["api"].get(f"/rides/{club['rides'][-1]}/report")
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/html")
    page = response.text
    for text in ("Bella", "Anna", "canter", "2026-03-29", "<svg", "Analysis version test",
                 "n = 4", "above", "Move the middle marker", "has 4 earlier analysed rides"):
        assert text in page, text
    assert "eigenvalue" not in page.split("<main")[1].split("<footer")[0].replace("detail", "")


def test_the_first_ride_has_no_band_yet(club):
    page = club["api"].get(f"/rides/{club['rides'][0]}/report").text
    assert page.count("not enough earlier rides") == 10  # every indicator row
    assert "this horse has 0 earlier analysed rides in canter" in page


@pytest.mark.slow  # WeasyPrint loads its fonts: about 10 s the first time
def test_the_pdf_report_is_one_a4_page(club):
    pypdf = pytest.importorskip("pypdf")
    response = club["api"].get(f"/rides/{club['rides'][-1]}/report.pdf")
    assert response.status_code == 200, response.text
    assert response.headers["content-type"] == "application/pdf"
    reader = pypdf.PdfReader(io.BytesIO(response.content))
    assert len(reader.pages) == 1
    box = reader.pages[0].mediabox
    assert (round(float(box.width) / 72 * 25.4), round(float(box.height) / 72 * 25.4)) == (210, 297)
    assert "Bella" in reader.pages[0].extract_text()


def test_a_ride_without_a_result_has_no_report_yet(club):
    for path in ("report", "report.pdf"):
        response = club["api"].get(f"/rides/{club['unanalysed']}/{path}")
        assert response.status_code == 404
        assert "not been analysed" in response.json()["detail"]
    assert club["api"].get("/rides/999999/report").status_code == 404


@pytest.mark.parametrize(("hours", "text"), [
    (2 + 5 / 60, "2 h 05 min"), (0.2, "12 min"), (40 / 3600, "under a minute"), (0.000241, "under a minute"),
    (59.6 / 3600, "under a minute"), (61 / 3600, "1 min"), (None, "–"),
    (float("inf"), "no limit"), (1234.0, "1,234 h"),
])
def test_exposure_times_read_in_hours_minutes_and_seconds(hours, text):
    assert duration_text(hours) == text

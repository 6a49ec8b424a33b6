"""The per-horse export (issue 37): all of a horse's analysed rides, one row per ride, as CSV or xlsx with
named columns, units in the header and rounded values; reachable from the horse page (`/api/horses/{id}/export`).
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import re
import sys

import numpy as np
import openpyxl
import pytest
from api_helpers import new_club, settings_for
from fastapi.testclient import TestClient

from conftest import PROJECT_ROOT
from saddlescope.api import create_app

sys.path.insert(0, str(PROJECT_ROOT / "tests" / "e2e"))
from dashboard_helpers import result_document, store_result  # noqa: E402


@pytest.fixture(scope="module")
def club(tmp_path_factory):
    root = tmp_path_factory.mktemp("horse-export")
    settings = settings_for(root)
    rng = np.random.default_rng(8)
    with TestClient(create_app(settings)) as client:
        api, _ = new_club(client)
        rider = api.ok("POST", "/riders", 201, json={"name": "Anna", "weight_kg": 61.5})["id"]
        saddle = api.ok("POST", "/saddles", 201, json={"name": "Old GP"})["id"]
        bella = api.ok("POST", "/horses", 201, json={"name": "Bella Rosa"})["id"]
        cosmo = api.ok("POST", "/horses", 201, json={"name": "Cosmo"})["id"]
        docs = {}
        # the seeded documents know canter and walk; the sitting trot ride stores a canter-like result
        plan = [(bella, "canter"), (bella, "sitting_trot"), (bella, "walk"), (cosmo, "canter")]
        for i, (horse, gait) in enumerate(plan):
            # the first ride in the Old GP with the rider weighed that day; the others her usual weight, no saddle
            ride = api.ok("POST", "/rides", 201, json={"horse_id": horse, "rider_id": rider, "gait": gait,
                                                       "direction": "CW", "ridden_on": f"2026-05-0{i + 1}",
                                                       **({"saddle_id": saddle, "rider_weight_kg": 63.25}
                                                          if i == 0 else {})})
            docs[ride["id"]] = result_document(scale=1.0 + 0.1 * i, gait="walk" if gait == "walk" else "canter",
                                               rng=rng)
            store_result(settings.database_url, root / "storage", ride["id"], docs[ride["id"]])
        unanalysed = api.ok("POST", "/horses", 201, json={"name": "Dolly"})["id"]
        yield {"api": api, "bella": bella, "cosmo": cosmo, "dolly": unanalysed, "docs": docs}


def test_a_horses_csv_has_one_row_per_ride_with_named_columns_and_rounded_values(club):
    answer = club["api"].ok("GET", f"/horses/{club['bella']}/export")
    assert answer.headers["content-type"].startswith("text/csv")
    assert 'filename="bella-rosa-rides.csv"' in answer.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(answer.content.decode("utf-8-sig"))))
    assert [row["Gait"] for row in rows] == ["canter", "sitting trot", "walk"]
    assert {r["Horse"] for r in rows} == {"Bella Rosa"}
    header = list(rows[0])
    assert header[:7] == ["Ride", "Horse", "Rider", "Gait", "Ridden on", "Saddle", "Rider's weight (kg)"]
    assert [(row["Saddle"], row["Rider's weight (kg)"]) for row in rows] == [("Old GP", "63.2"), ("", "61.5"),
                                                                             ("", "61.5")]
    assert len(header) == len(set(header))  # each column once
    assert "W_b r.m.s. (m/s²)" in header and "Speed (km/h)" in header
    assert not [h for h in header if re.search(r"[a-z]_[a-z]|\[", h)]  # no code, no bracketed unit
    for row in rows:
        doc = club["docs"][int(row["Ride"])]
        assert float(row["W_b r.m.s. (m/s²)"]) == float(f"{doc['indicators']['acc_y_wb_rms']:.3g}")
        minutes = float(row["Time to the A(8) exposure limit value, W_b (min)"])
        assert minutes == pytest.approx(doc["indicators"]["t_a8_limit_wb_h"] * 60, rel=5e-3)
        for key, cell in row.items():
            if re.fullmatch(r"-?[0-9.]+", cell or "") and key != "Ride":
                assert len(cell.replace(".", "").replace("-", "").strip("0")) <= 3, (key, cell)
        assert "null" not in row.values() and "nan" not in {v.lower() for v in row.values()}


def test_a_horses_xlsx_holds_the_same_rows(club):
    answer = club["api"].ok("GET", f"/horses/{club['bella']}/export", params={"format": "xlsx"})
    sheet = openpyxl.load_workbook(io.BytesIO(answer.content))["Indicators"]
    header = [c.value for c in sheet[1]]
    assert header[:7] == ["Ride", "Horse", "Rider", "Gait", "Ridden on", "Saddle", "Rider's weight (kg)"]
    assert sheet.max_row == 4 and "Saddle id" not in header
    assert [(sheet.cell(row=r, column=6).value, sheet.cell(row=r, column=7).value) for r in (2, 3)] == [
        ("Old GP", 63.2), (None, 61.5)]
    speed = [row[header.index("Speed (km/h)")] for row in sheet.iter_rows(min_row=2, values_only=True)]
    assert all(isinstance(v, int | float) and v == float(f"{v:.3g}") for v in speed)
    assert sheet.cell(row=2, column=5).value.date() == dt.date(2026, 5, 1)


def test_a_horse_without_analysed_rides_or_of_another_club_has_no_export(club):
    empty = club["api"].get(f"/horses/{club['dolly']}/export")
    assert empty.status_code == 404 and "no analysed rides" in empty.json()["detail"]
    assert club["api"].get("/horses/999999/export").status_code == 404
    assert club["api"].get(f"/horses/{club['bella']}/export", params={"format": "pdf"}).status_code == 422


def test_a_rides_own_export_names_its_saddle_and_the_riders_weight(club):
    ride = min(club["docs"])  # the ride in the Old GP
    table = club["api"].ok("GET", f"/rides/{ride}/export/csv").content.decode("utf-8-sig")
    (row,) = list(csv.DictReader(io.StringIO(table)))
    assert (row["Saddle"], row["Rider's weight (kg)"]) == ("Old GP", "63.2")
    book = openpyxl.load_workbook(io.BytesIO(club["api"].ok("GET", f"/rides/{ride}/export/xlsx").content))
    header = [c.value for c in book["Indicators"][1]]
    assert book["Indicators"].cell(row=2, column=header.index("Rider's weight (kg)") + 1).value == 63.2
    assert ("Rider's weight (kg)", "rider_weight_kg", "kg") == next(
        r[:3] for r in book["Units"].iter_rows(min_row=2, values_only=True) if r[1] == "rider_weight_kg")

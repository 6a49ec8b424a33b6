"""The one-page report (issue 37): a ride with every note and flag is ONE A4 page, in the browser's print
layout and as the API's PDF, and its text shows no raw code, "null" or "NaN".

The ride's result is stored as the analyse stage would (tests/e2e/test_dashboard.py's seeded documents),
with every finding kind of `core.findings`, the too-uncertain verdict, a 95 % interval on every report
indicator and four earlier rides, so the normal band is shown too.
"""

from __future__ import annotations

import datetime as dt
import io
import re
import sys

import numpy as np
import pytest
from api_helpers import new_club, settings_for
from fastapi.testclient import TestClient

from conftest import PROJECT_ROOT
from saddlescope.api import create_app
from saddlescope.core.findings import FINDING_KINDS, Finding
from saddlescope.io.findings_document import findings_to_list
from saddlescope.services.results.report import REPORT_INDICATORS

sys.path.insert(0, str(PROJECT_ROOT / "tests" / "e2e"))
from dashboard_helpers import result_document, store_result  # noqa: E402

REASON = "the W_b r.m.s. is known only to ±14 % (95 % interval 3.52-4.63 m/s²; a decision needs ±10 %)"
RAW_TEXT = re.compile(r"\bnull\b|\bNaN\b|\bundefined\b|\bNone\b|\b[a-z]+_[a-z0-9_]+\b|\b[a-z]{2,}\.[a-z_]{2,}\b")


def every_flag_document(rng: np.random.Generator) -> dict:
    """A result with every finding kind (each with a long expert sentence), the verdict and intervals."""
    doc = result_document(scale=1.6, gait="canter", rng=rng)
    findings = [Finding(code, f"{code}: the expert's sentence for this finding, long enough to wrap over the "
                              f"width of the report's column at least once ({i}).")
                for i, code in enumerate(FINDING_KINDS)]
    doc["quality"]["flags"] = [f.detail for f in findings]
    doc["quality"]["findings"] = findings_to_list(findings)
    doc["quality"]["decision"] = {"too_uncertain": True, "reason": REASON}
    doc["indicators_interval_95"] = {key: [0.8 * doc["indicators"][key], 1.25 * doc["indicators"][key]]
                                     for key, _ in REPORT_INDICATORS if isinstance(doc["indicators"].get(key), float)}
    # the longest passes line: six passes, one of them left out (issue 38)
    doc["passes"] = [{"start_s": 8.0 * i, "end_s": 8.0 * i + 1.2, "start_frame": 240 * i, "frames": 36,
                      "strides": 0 if i == 5 else 2, "speed_m_s": 4.1, "indicators": {"acc_y_wb_rms": 4.0},
                      "used": i != 5, "reason": "too short" if i == 5 else None} for i in range(6)]
    doc["quality"]["pass_pooling"] = {"used": 5, "left_out": 1, "strides": 10, "reference_pass": 0,
                                      "spread_fraction": {"acc_y_wb_rms": 0.031}}
    return doc


@pytest.fixture(scope="module")
def worst_ride(tmp_path_factory):
    root = tmp_path_factory.mktemp("one-page")
    settings = settings_for(root)
    rng = np.random.default_rng(37)
    with TestClient(create_app(settings)) as client:
        api, _ = new_club(client)
        horse = api.ok("POST", "/horses", 201, json={
            "name": "Bellissima Wonderful Dancing Queen", "breed": "Royal Dutch Warmblood (KWPN)",
            "birth_year": 2012})
        rider = api.ok("POST", "/riders", 201, json={"name": "Annabelle van der Westhuizen-Oppenheimer"})
        for i in range(5):
            ride = api.ok("POST", "/rides", 201, json={
                "horse_id": horse["id"], "rider_id": rider["id"], "gait": "canter", "direction": "CCW",
                "ridden_on": (dt.date(2026, 3, 1) + dt.timedelta(days=7 * i)).isoformat()})
            doc = every_flag_document(rng) if i == 4 else result_document(scale=1.0 + 0.03 * i, gait="canter",
                                                                            rng=rng)
            store_result(settings.database_url, root / "storage", ride["id"], doc)
        yield api, ride["id"]


def test_the_report_of_a_ride_with_every_flag_has_no_raw_code_in_its_text(worst_ride):
    api, ride_id = worst_ride
    page = api.get(f"/rides/{ride_id}/report").text
    sheet = page.split("<main", 1)[1].split("</main>", 1)[0]
    text = re.sub(r"<[^>]+>", " ", sheet)
    assert "Too uncertain for a decision" in text and "more notes: the club sees every note on the ride page" in text
    assert "5 passes: 2, 2, 2, 2 and 2 strides (1 more left out: too short)" in text and "spread ±3.1 %" in text
    assert not RAW_TEXT.findall(text), RAW_TEXT.findall(text)


@pytest.mark.slow  # WeasyPrint loads its fonts: about 10 s the first time
def test_the_pdf_of_a_ride_with_every_note_and_flag_is_one_a4_page(worst_ride):
    pypdf = pytest.importorskip("pypdf")
    api, ride_id = worst_ride
    response = api.get(f"/rides/{ride_id}/report.pdf")
    assert response.status_code == 200, response.text
    reader = pypdf.PdfReader(io.BytesIO(response.content))
    text = reader.pages[0].extract_text()
    assert len(reader.pages) == 1, f"{len(reader.pages)} pages; page 2: {reader.pages[-1].extract_text()[:200]!r}"
    box = reader.pages[0].mediabox
    assert (round(float(box.width) / 72 * 25.4), round(float(box.height) / 72 * 25.4)) == (210, 297)
    for words in ("Bellissima", "Too uncertain", "Analysis version", "passive"):
        assert words in text, words
    assert not RAW_TEXT.findall(text), RAW_TEXT.findall(text)

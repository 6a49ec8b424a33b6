"""No page shows the words "null", "undefined" or "NaN" (issue #37): a value the page did not have
must read as nothing, or as words, never as JavaScript's name for "missing". Nor a raw code of the
glossary (GET /api/glossary: `lab_vertical`, `sitting_trot`, `acc_y_wb_rms`, `analyze`, `dtw`, ...):
every label comes from it. Nor a number with more than four significant digits (`long_numbers`: what
counts as one is defined and justified there).

A small club on a fresh server: one ride with an analysis job that is queued or running (a long
selftest job tied to the ride), two analysed rides of its horse (a result with 95 % intervals, one whose
speed interval is narrower than the last digit shown) and the main lists; each page's visible text is
scanned in Debian's chromium. The full page tour (test_page_audit.py) runs the null scan on every page.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from browser_harness import (
    VISIBLE_TEXT_JS,
    chromium_for_module,
    long_numbers,
    missing_words,
    new_club_admin,
    screenshot,
    serve_fresh,
    sign_in,
)
from dashboard_helpers import result_document, store_result

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ADMIN = ("secretary@nulls.example", "nulls admin password")
# Glossary codes that are not themselves words a page may use ("walk", "canter", "left" are both).
CODE_WORDS = ("analyze", "selftest", "dtw", "chaincode")


def raw_code_pattern(glossary: list[dict]) -> re.Pattern[str]:
    """The glossary's codes that must never show: those with an underscore, and `CODE_WORDS`."""
    codes = sorted({e["code"] for e in glossary if "_" in e["code"] or e["code"] in CODE_WORDS}, key=len, reverse=True)
    return re.compile(r"(?<![A-Za-z0-9_])(?:" + "|".join(map(re.escape, codes)) + r")(?![A-Za-z0-9_])")


def raw_codes(text: str, pattern: re.Pattern[str]) -> list[str]:
    """The lines of `text` that show a raw glossary code."""
    return [line.strip() for line in text.splitlines() if pattern.search(line)]


def test_raw_codes_are_found_as_words_only():
    pattern = raw_code_pattern([{"code": "lab_vertical"}, {"code": "analyze"}, {"code": "walk"},
                                {"code": "acc_y_wb_rms"}])
    text = "Gravity from lab_vertical\nRide analysis\nwalk\nanalyze\nacc_y_wb_rms_x is another\nanalyzed"
    assert raw_codes(text, pattern) == ["Gravity from lab_vertical", "analyze"]


def test_missing_words_are_found_alone_or_glued_but_not_inside_words():
    text = "Analysis job #3: queued\nnullnullnull\nHorse: Nullarbor, annulled\nspeed NaN km/h\nundefined"
    assert missing_words(text) == ["nullnullnull", "speed NaN km/h", "undefined"]


def test_long_numbers_are_found_but_not_dates_times_counts_ids_or_urls():
    text = ("speed 9.9712 km/h\n0.004163 km\n18.00–18.00 km/h\n18.000 km/h\nridden 2026-11-29 12:30\n"
            "1,234 rides\nride #12345\nhttp://127.0.0.1:54321/#/shared/abc123456789\n12346 m\n12300 m\n"
            "version 0.1.0+a16e38d\n1,234.5 m\n-0.0041634\n29.11.2026\n95 %: 1.10–1.41 m/s²")
    assert long_numbers(text) == ["speed 9.9712 km/h", "18.000 km/h", "12346 m", "1,234.5 m", "-0.0041634"]


def _analysed_rides(served, api, horse: int, rider: int) -> list[int]:
    """Two canters of the horse with results: intervals on the indicators, and one speed interval that
    both ends round alike at four digits (the page must not show "18.00–18.00 km/h")."""
    rides = []
    for i, day in enumerate(("2026-05-01", "2026-05-08")):
        created = api.post("/api/rides", json={"horse_id": horse, "rider_id": rider, "gait": "canter",
                                               "direction": "CW", "ridden_on": day, "rider_weight_kg": 61.35})
        assert created.status_code == 201, created.text
        doc = result_document(scale=1.0 + 0.1 * i, gait="canter", rng=np.random.default_rng(40 + i))
        speed = doc["indicators"]["vel_x_avg_kmh"]
        doc["indicators_interval_95"] = {key: [0.93 * value, 1.07 * value] for key, value in doc["indicators"].items()
                                         if isinstance(value, float) and value > 0}
        doc["indicators_interval_95"]["vel_x_avg_kmh"] = [speed - 0.0004, speed + 0.0004]
        store_result(served.database_url, served.storage_dir, created.json()["id"], doc)
        rides.append(created.json()["id"])
    return rides


@pytest.fixture(scope="module")
def club(tmp_path_factory):
    with serve_fresh(tmp_path_factory.mktemp("nulls")) as served:
        with new_club_admin(served.base, club_name="Null Check Club", email=ADMIN[0], password=ADMIN[1]) as api:
            horse = api.post("/api/horses", json={"name": "Bramble"}).json()["id"]
            rider = api.post("/api/riders", json={"name": "Anna"}).json()["id"]
            saddle = api.post("/api/saddles", json={"name": "Old GP"}).json()["id"]  # no maker, type or width
            ride = api.post("/api/rides", json={"horse_id": horse, "rider_id": rider, "gait": "sitting_trot",
                                                "direction": "CW", "saddle_id": saddle})
            assert ride.status_code == 201, ride.text
            ride_id = ride.json()["id"]
            # a job that stays queued (no worker) or running (1000 steps of 5 s) while the page is open
            job = api.post("/api/jobs", json={"kind": "selftest", "ride_id": ride_id,
                                              "payload": {"steps": 1000, "delay_s": 5}})
            assert job.status_code in (200, 201, 202), job.text
            analysed = _analysed_rides(served, api, horse, rider)
        yield {"base": served.base, "ride": ride_id, "horse": horse, "saddle": saddle, "analysed": analysed}


def test_no_page_shows_null_undefined_or_nan(club):
    paths = [f"/rides/{club['ride']}", "/", "/rides", "/horses", "/riders", "/jobs", "/rigs", "/grades",
             "/leaderboard", "/account", "/start", "/saddles", f"/saddles/{club['saddle']}", f"/horses/{club['horse']}",
             *[f"/rides/{ride}" for ride in club["analysed"]], f"/compare?horse={club['horse']}"]
    found, codes, long = [], [], []
    with chromium_for_module() as chromium:
        context = chromium.new_context(base_url=club["base"], viewport={"width": 1280, "height": 900})
        page = context.new_page()
        sign_in(page, *ADMIN)
        glossary = page.context.request.get(f"{club['base']}/api/glossary")
        assert glossary.ok, glossary.text()
        pattern = raw_code_pattern(glossary.json())
        for path in paths:
            page.goto(f"{club['base']}/#{path}")
            page.wait_for_function("() => { const v = document.querySelector('[data-view]');"
                                   " return v && !v.hasAttribute('aria-busy') && v.children.length > 0; }")
            if path == f"/rides/{club['ride']}":
                page.wait_for_selector("[data-job-progress]")
            elif path.startswith("/rides/"):
                page.locator("[data-result]").wait_for(state="visible")
            page.wait_for_load_state("networkidle")
            text = page.evaluate(VISIBLE_TEXT_JS)
            found += [f"{path}: {line!r}" for line in missing_words(text)]
            codes += [f"{path}: {line!r}" for line in raw_codes(text, pattern)]
            long += [f"{path}: {line!r}" for line in long_numbers(text)]
            screenshot(page, f"no-null{path.replace('/', '-') or '-overview'}")
        context.close()
    assert not found, "pages show JavaScript's words for a missing value:\n" + "\n".join(found)
    assert not codes, "pages show raw codes instead of the glossary's labels:\n" + "\n".join(codes)
    assert not long, "pages show numbers with more than four significant digits:\n" + "\n".join(long)

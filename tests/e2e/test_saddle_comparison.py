"""A saddle comparison on a horse page with two saddles, in a real browser (issue 37, item 3).

A real `saddlescope serve` (embedded) with one horse ridden in canter in two saddles, three rides each,
the old saddle clearly rougher; results are stored as the analyse stage stores them (test_dashboard's
`result_document`). The horse page shows both saddles with n and intervals and says in words that the
difference exceeds the uncertainty; the saddle page lists the horse; the leaderboard filters by saddle.
Screenshots at 1280 and 390 px wide go to var/test-artifacts/screenshots/.
"""

from __future__ import annotations

import numpy as np
import pytest
from browser_harness import axe_violations, missing_words, new_club_admin, serve_fresh, shoot_both_widths
from dashboard_helpers import (  # noqa: F401 (browser and sync_playwright_factory are fixtures used here)
    EMAIL,
    PASSWORD,
    Console,
    _ok,
    browser,
    result_document,
    sign_in,
    store_result,
    sync_playwright_factory,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow]

OLD_SCALES = [1.0, 1.06, 0.95]  # the old general-purpose saddle: rougher
NEW_SCALES = [0.62, 0.66, 0.6]  # the new treeless one


@pytest.fixture(scope="module")
def served(sync_playwright_factory, tmp_path_factory):  # noqa: F811 (the imported fixture)
    with serve_fresh(tmp_path_factory.mktemp("saddles")) as server:
        yield {"base": server.base, **_seed(server.base, server.database_url, server.storage_dir)}


def _seed(base: str, database_url: str, storage_dir) -> dict:
    rng = np.random.default_rng(5)
    with new_club_admin(base, club_name="Saddle Club", email=EMAIL, password=PASSWORD) as api:
        rider = _ok(api.post("/api/riders", json={"name": "Rider A", "weight_kg": 68}))["id"]
        horse = _ok(api.post("/api/horses", json={"name": "Tango"}))["id"]
        saddles = {name: _ok(api.post("/api/saddles", json={"name": name, "saddle_type": kind, "maker": "Maker"}))["id"]
                   for name, kind in (("Old GP", "gp"), ("New treeless", "treeless"))}
        rides = []
        for name, scales in (("Old GP", OLD_SCALES), ("New treeless", NEW_SCALES)):
            for i, scale in enumerate(scales):
                ride_id = _ok(api.post("/api/rides", json={
                    "horse_id": horse, "rider_id": rider, "gait": "canter", "direction": "CCW",
                    "ridden_on": f"2026-03-{1 + i + (10 if name == 'Old GP' else 0):02d}", "saddle_id": saddles[name],
                    "pad": "half pad"}))["id"]
                store_result(database_url, storage_dir, ride_id, result_document(scale=scale, gait="canter", rng=rng))
                rides.append(ride_id)
        answer = _ok(api.get(f"/api/horses/{horse}/saddles", params={"gait": "canter"}))
    return {"horse": horse, "saddles": saddles, "answer": answer, "rides": rides}


@pytest.fixture
def page(browser, served):  # noqa: F811 (the imported fixture)
    context = browser.new_context(base_url=served["base"], viewport={"width": 1280, "height": 900})
    tab = context.new_page()
    tab.console = Console()
    tab.console.attach(tab)
    tab.set_default_timeout(15_000)
    try:
        yield tab
    finally:
        context.close()


def test_a_horse_page_compares_its_two_saddles_beyond_the_uncertainty(page, served):
    answer = served["answer"]
    assert {s["saddle"]: s["rides"] for s in answer["saddles"]} == {"Old GP": 3, "New treeless": 3}
    sign_in(page)
    page.goto(f"/#/horses/{served['horse']}")
    page.get_by_role("heading", level=1, name="Tango").wait_for()
    rows = page.locator("[data-saddles-table] tbody tr")
    rows.nth(1).wait_for()
    assert rows.count() == 2
    new_row = page.locator(f"[data-saddles-table] tr[data-saddle-id='{served['saddles']['New treeless']}']")
    wb = next(s for s in answer["saddles"] if s["saddle"] == "New treeless")["indicators"]["acc_y_wb_rms"]
    cell = new_row.locator("td[data-key='acc_y_wb_rms']").inner_text()
    assert cell.startswith(f"{wb['mean']:.3g}".rstrip("0").rstrip(".")[:4]) and "(" in cell and "\u2013" in cell
    assert new_row.locator("td").first.inner_text() == "3"  # n rides
    verdict = page.locator("[data-saddles-verdicts] li[data-indicator='acc_y_wb_rms']")
    assert verdict.get_attribute("data-exceeds") == "true"
    text = verdict.inner_text()
    assert "more than the uncertainty" in text and "New treeless is the more comfortable" in text
    assert "Welch" in page.locator("[data-saddles-method]").inner_text()
    body = page.locator("main, body").first.inner_text()
    assert missing_words(body) == [], missing_words(body)
    assert axe_violations(page) == []
    shoot_both_widths(page, "horse-saddles")

    # The saddle's own page, across horses
    page.locator(f"[data-saddles-table] a[href='#/saddles/{served['saddles']['Old GP']}']").click()
    page.get_by_role("heading", level=1, name="Old GP").wait_for()
    page.locator("[data-saddle-horses] tbody tr").first.wait_for()
    assert page.locator("[data-saddle-horses] tbody tr").count() == 1
    assert page.locator("[data-saddle-rides] tbody tr").count() == 3
    assert axe_violations(page) == []
    shoot_both_widths(page, "saddle-page")

    # The leaderboard filtered by saddle
    page.goto(f"/#/leaderboard?gait=canter&saddle_id={served['saddles']['New treeless']}")
    page.locator("[data-leaderboard-table] tbody tr").first.wait_for()
    assert page.locator("#lb-saddle").input_value() == str(served["saddles"]["New treeless"])
    assert page.locator("[data-leaderboard-table] tbody tr td").nth(1).inner_text() == "3"

    # A ride names its saddle, pad and the rider's weight (copied from the rider), editable in its details
    page.goto(f"/#/rides/{served['rides'][0]}")
    saddle_line = page.locator("[data-ride-saddle]")
    saddle_line.wait_for()
    assert saddle_line.inner_text() == "Saddle Old GP, pad: half pad \u00b7 rider's weight 68 kg"
    page.locator(".ride-edit-box summary").click()
    assert page.locator("#ride-edit-saddle").input_value() == str(served["saddles"]["Old GP"])
    assert page.locator("#ride-edit-weight").input_value() == "68"
    page.select_option("#ride-edit-saddle", str(served["saddles"]["New treeless"]))
    page.fill("#ride-edit-weight", "250")
    page.locator("[data-ride-edit-save]").click()
    page.get_by_text("between 20 and 200").wait_for()  # the server's reason, in words
    assert page.console.unexpected(422) == []

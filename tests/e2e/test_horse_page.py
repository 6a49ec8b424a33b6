"""The horse page, compare, grades and leaderboard in a real browser (Debian's chromium via Playwright).

A real `saddlescope serve` (embedded: SQLite, temporary storage) with one horse ridden over eleven
dates (eight canter rides, the last one much rougher, and three walk rides) and two other horses with a
graded canter ride each; results are stored as the analyse stage stores them (test_dashboard's
`result_document`: indicators from the core's own formulas). Screenshots at 1280 and 390 px wide go to
var/test-artifacts/screenshots/.
"""

from __future__ import annotations

import numpy as np
import pytest
from browser_harness import new_club_admin, serve_fresh, wait_for_charts_drawn
from dashboard_helpers import (  # noqa: F401 (browser and sync_playwright_factory are fixtures used here)
    EMAIL,
    PASSWORD,
    Console,
    _ok,
    browser,
    js_fmt,
    result_document,
    sign_in,
    store_result,
    sync_playwright_factory,
)

from conftest import PROJECT_ROOT
from saddlescope.services.results.report import distance_text, duration_text

pytestmark = [pytest.mark.browser, pytest.mark.slow]

SCREENSHOTS = PROJECT_ROOT / "var" / "test-artifacts" / "screenshots"
# Tango's canter rides, weekly: the scale of its vertical acceleration; the last ride is far rougher.
CANTER_SCALES = [1.0, 1.05, 0.95, 1.02, 0.98, 1.04, 0.97, 1.6]
WALK_SCALES = [1.0, 1.1, 0.9]


@pytest.fixture(scope="module")
def served(sync_playwright_factory, tmp_path_factory):  # noqa: F811 (the imported fixture)
    with serve_fresh(tmp_path_factory.mktemp("horse-page")) as server:
        yield {"base": server.base, **_seed(server.base, server.database_url, server.storage_dir)}


def _seed(base: str, database_url: str, storage_dir) -> dict:
    rng = np.random.default_rng(11)
    with new_club_admin(base, club_name="Horse Page Club", email=EMAIL, password=PASSWORD) as api:
        rider = _ok(api.post("/api/riders", json={"name": "Rider A"}))["id"]
        horses = {name: _ok(api.post("/api/horses", json={"name": name, "breed": "KWPN"}))["id"]
                  for name in ("Tango", "Bella", "Comet")}

        def ride(horse: str, gait: str, day: str, scale: float) -> int:
            ride_id = _ok(api.post("/api/rides", json={"horse_id": horses[horse], "rider_id": rider, "gait": gait,
                                                       "direction": "CCW", "ridden_on": day}))["id"]
            store_result(database_url, storage_dir, ride_id, result_document(scale=scale, gait=gait, rng=rng))
            return ride_id

        canter = [ride("Tango", "canter", f"2026-0{1 + i // 4}-{5 + 7 * (i % 4):02d}", s)
                  for i, s in enumerate(CANTER_SCALES)]
        walk = [ride("Tango", "walk", f"2026-01-{6 + 7 * i:02d}", s) for i, s in enumerate(WALK_SCALES)]
        for name, scale, grade in (("Bella", 0.7, 5), ("Comet", 1.3, 2)):
            graded = ride(name, "canter", "2026-02-01", scale)
            _ok(api.post("/api/grades", json={"ride_id": graded, "rider_id": rider, "grade": grade}))
        _ok(api.post("/api/grades", json={"ride_id": canter[0], "rider_id": rider, "grade": 4}))
        # a fourth horse-gait point: pooled over the gaits the grades page has 4, one short of a correlation
        _ok(api.post("/api/grades", json={"ride_id": walk[0], "rider_id": rider, "grade": 3}))
        trend = _ok(api.get(f"/api/horses/{horses['Tango']}/trend",
                            params={"gait": "canter", "indicator": "acc_y_wb_rms"}))
        pair = _ok(api.get(f"/api/horses/{horses['Tango']}/ride-pair", params={"a": canter[-2], "b": canter[-1]}))
    return {"horses": horses, "canter": canter, "walk": walk, "trend": trend, "pair": pair}


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


def _drawn(page, name: str) -> None:
    wait_for_charts_drawn(page, [name])


def _fits_phone(page, name: str) -> None:
    """At 390 px wide nothing scrolls sideways; screenshots at both widths for a person to look at."""
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SCREENSHOTS / f"{name}-1280.png"), full_page=True)
    page.set_viewport_size({"width": 390, "height": 844})
    page.wait_for_timeout(400)  # Plotly's responsive relayout
    overflow = page.evaluate("document.documentElement.scrollWidth - window.innerWidth")
    page.screenshot(path=str(SCREENSHOTS / f"{name}-390.png"), full_page=True)
    assert overflow <= 0, f"{name}: the page scrolls {overflow} px sideways at 390 px"
    page.set_viewport_size({"width": 1280, "height": 900})


def test_the_horse_page_shows_trend_band_gait_counts_and_a_ride_pair(page, served):
    sign_in(page)
    tango = served["horses"]["Tango"]
    page.goto(f"/#/horses/{tango}")
    page.get_by_role("heading", level=1, name="Tango").wait_for()
    _drawn(page, "horse-trend")
    _drawn(page, "horse-gaits")

    # The trend opens in canter (most rides); the band is there from the fifth ride on, as the API says.
    assert page.locator("#hp-trend-gait").input_value() == "canter"
    traces = page.eval_on_selector('[data-chart="horse-trend"]',
                                   "el => el.data.map(t => ({name: t.name, y: t.y, fill: t.fill || null}))")
    by_name = {t["name"]: t for t in traces}
    band_high = next(t for t in traces if t["fill"] == "tonexty")
    want_high = [p["band"]["high"] if p["band"] else None for p in served["trend"]["points"]]
    assert band_high["y"][:4] == [None] * 4
    np.testing.assert_allclose(band_high["y"][4:], want_high[4:], rtol=1e-12)
    np.testing.assert_allclose(by_name["ride"]["y"], [p["value"] for p in served["trend"]["points"]], rtol=1e-12)
    assert served["trend"]["points"][-1]["outside"] is True  # the rough last ride
    assert by_name["outside its band"]["y"] == [served["trend"]["points"][-1]["value"]]
    note = page.locator("[data-trend-note]").inner_text()
    assert "1 of the 4 rides with enough earlier rides lie outside the band" in note
    # the page's band: Tango's own (8 canter rides), shaded across the chart, with its edges' intervals
    assert served["trend"]["band"]["source"] == "horse" and "this horse's own 8 rides" in note
    shapes = page.eval_on_selector('[data-chart="horse-trend"]',
                                   "el => el.layout.shapes.map(s => [s.type, s.y0, s.y1])")
    band = served["trend"]["band"]
    assert ["rect", pytest.approx(band["low"]), pytest.approx(band["high"])] in shapes

    # Gait bars: walk then canter, each saying how many rides stand behind it.
    bars = page.eval_on_selector('[data-chart="horse-gaits"]', "el => ({x: el.data[0].x, text: el.data[0].text, "
                                 "name: el.data[0].name})")
    assert bars["x"] == ["walk", "canter"]
    assert bars["text"] == [f"n = {len(WALK_SCALES)}", f"n = {len(CANTER_SCALES)}"]
    assert "n = rides" in bars["name"]

    # Two rides side by side: the newest against the one before, with % differences.
    table = page.locator("[data-pair-table]")
    table.wait_for(state="visible")
    assert page.locator("#hp-pair-a").input_value() == str(served["canter"][-2])
    assert page.locator("#hp-pair-b").input_value() == str(served["canter"][-1])
    row = table.locator('tr[data-key="acc_y_wb_rms"]')
    want = next(r for r in served["pair"]["indicators"] if r["key"] == "acc_y_wb_rms")
    assert row.locator("td").nth(0).inner_text() == js_fmt(want["a"])
    assert row.locator("[data-unit]").inner_text() == "m/s\u00b2"
    assert row.locator("[data-difference]").inner_text() == f"+{js_fmt(want['difference_percent'], 2)} %"
    assert "worse" in row.locator("[data-difference]").get_attribute("class")  # rougher is less comfortable
    assert table.locator("[data-difference]").count() == len(served["pair"]["indicators"])
    # issue #37: no "h" beside "12 min", no "0.00416" beside "km": times and distances say their own unit
    for key, words in (("t_a8_limit_wb_h", duration_text), ("d_a8_limit_wb_km", distance_text)):
        want = next(r for r in served["pair"]["indicators"] if r["key"] == key)
        timed = table.locator(f'tr[data-key="{key}"]')
        assert timed.locator("[data-unit]").count() == 0, key
        assert timed.locator("td").nth(0).inner_text() == words(want["a"]), key
    motion = page.locator("[data-pair-motion-link]")
    assert motion.get_attribute("href") == f"#/compare-rides/{served['canter'][-2]}/{served['canter'][-1]}"

    # Rides, ten to a page, newest first, each linking to its ride page.
    rides = page.locator("[data-horse-rides] tbody tr")
    assert rides.count() == 10
    assert rides.first.locator("a").get_attribute("href") == f"#/rides/{served['canter'][-1]}"
    page.locator("[data-page-next]").click()
    page.locator("[data-page-info]").filter(has_text="11\u201311 of 11").wait_for()
    _fits_phone(page, "horse")
    assert page.console.unexpected() == []


def test_the_profile_takes_a_height_in_hands_and_explains_a_bare_number(page, served):
    sign_in(page)
    page.goto(f"/#/horses/{served['horses']['Bella']}")
    form = page.locator("[data-horse-form]")
    form.wait_for(state="visible")
    assert form.get_attribute("data-permission") == "horse.create"
    page.locator("#hp-height").fill("15.2 hh")
    page.get_by_role("button", name="Save profile").click()
    page.locator('[data-profile="height"]').filter(has_text="15.2 hh").wait_for()
    assert page.locator('[data-profile="height"]').inner_text() == "1.57 m (15.2 hh)"
    page.locator("#hp-height").fill("15.2")
    page.get_by_role("button", name="Save profile").click()
    error = form.locator("[data-form-error]")
    error.wait_for(state="visible")
    assert '"15.2 hh"' in error.inner_text() and "metres" in error.inner_text()
    assert page.console.unexpected(422) == []


def test_a_horse_with_one_ride_shows_the_club_band_so_it_is_seen(page, served):
    sign_in(page)
    page.goto(f"/#/horses/{served['horses']['Bella']}")
    page.get_by_role("heading", level=1, name="Bella").wait_for()
    _drawn(page, "horse-trend")
    note = page.locator("[data-trend-note]")
    note.filter(has_text="Shaded").wait_for()
    text = note.inner_text()
    assert "1 ride in canter" in text and "from the club's 2 other horses in this gait" in text, text
    assert "this horse has 1 of the 5 rides its own band needs" in text
    # drawn: a shaded rectangle across the plot, of a real height on screen (not a line of one point)
    box = page.evaluate("""() => { const rects = [...document.querySelectorAll(
        '[data-chart="horse-trend"] .layer-below .shapelayer path, [data-chart="horse-trend"] .shapelayer path')];
        return rects.map(r => r.getBoundingClientRect()).map(b => [b.width, b.height]); }""")
    assert any(w > 200 and h > 10 for w, h in box), box
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SCREENSHOTS / "horse-one-ride-band-1280.png"), full_page=True)
    _fits_phone(page, "horse-one-ride-band")


def test_the_grades_page_shows_no_correlation_on_four_points(page, served):
    sign_in(page)
    page.goto("/#/grades")
    _drawn(page, "grades")
    page.select_option("#gr-gait", "")  # all gaits pooled: Tango canter and walk, Bella, Comet
    stats = page.locator("[data-grades-stats]")
    stats.locator('[data-stat="withheld"]').wait_for()
    assert stats.locator('[data-stat="n"]').inner_text() == "4"
    assert "needs at least 5 graded horse-gait pairs" in stats.inner_text()
    assert stats.locator('[data-stat="pearson"]').count() == 0 and "Pearson" not in stats.inner_text()


def test_compare_grades_and_leaderboard_say_how_many_rides_and_fit_a_phone(page, served):
    sign_in(page)
    page.goto(f"/#/compare?horse={served['horses']['Tango']}")
    _drawn(page, "compare-horse")
    page.select_option("#cmp-gait", "canter")
    page.wait_for_function("() => document.querySelector('[data-chart=\"compare-gait\"]')?.data?.[0]?.x?.length === 3")
    assert page.eval_on_selector('[data-chart="compare-horse"]', "el => el.data[0].text") == [
        f"n = {len(WALK_SCALES)}", f"n = {len(CANTER_SCALES)}"]
    horse_page = page.locator("[data-compare-horse-page] a")
    assert horse_page.get_attribute("href") == f"#/horses/{served['horses']['Tango']}"
    texts = page.eval_on_selector('[data-chart="compare-gait"]', "el => el.data[0].text")
    assert sorted(texts) == ["n = 1", "n = 1", f"n = {len(CANTER_SCALES)}"]
    _fits_phone(page, "compare")

    page.goto("/#/grades")
    _drawn(page, "grades")
    scatter = page.eval_on_selector('[data-chart="grades"]', "el => ({names: el.data.map(t => t.name), "
                                    "hover: el.data[0].hovertemplate, x: el.layout.xaxis.title.text, "
                                    "custom: el.data[0].customdata})")
    assert scatter["names"] == ["walk", "canter"]  # one trace (colour) per gait, in the legend
    assert "Rider A" in [c[1] for c in scatter["custom"]] and "graded by" in scatter["hover"]
    assert "(m/s\u00b2)" in scatter["x"]
    page.select_option("#gr-gait", "")  # all gaits pooled: still one colour per gait
    _drawn(page, "grades")
    _fits_phone(page, "grades")

    page.goto("/#/leaderboard?gait=canter&indicator=acc_y_wb_rms")
    first = page.locator("[data-leaderboard-table] tbody tr").first
    first.wait_for()
    assert first.locator("a").get_attribute("href") == f"#/horses/{served['horses']['Bella']}"
    _fits_phone(page, "leaderboard")
    first.locator("a").click()
    page.get_by_role("heading", level=1, name="Bella").wait_for()
    assert page.console.unexpected() == []

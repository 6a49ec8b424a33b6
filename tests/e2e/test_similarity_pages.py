"""The similarity views in a real browser: the "rides most alike" panel of the ride page and the pair view.

A real `saddlescope serve` (embedded mode: the similarity job runs in its local worker pool) with three
horses of two canter rides each, their results stored as the analyse stage stores them
(tests/api/similarity_docs.py). Debian's chromium driven by Playwright; skipped without it (fails under
CI=true), as tests/e2e/dashboard_helpers.py.
"""

from __future__ import annotations

import sys

import pytest
from browser_harness import chromium_for_module, new_club_admin, serve_fresh, wait_for_charts_drawn
from dashboard_helpers import EMAIL, PASSWORD, Console, _ok, _require_browser

from conftest import PROJECT_ROOT

sys.path.insert(0, str(PROJECT_ROOT / "tests" / "api"))
from similarity_docs import motion_document, store_document  # noqa: E402

pytestmark = [pytest.mark.browser, pytest.mark.slow]

HORSES = ("Ash", "Birch", "Cedar")
# WebGL (Plotly's scatter3d) in software: headless chromium has no GPU here.
WEBGL_ARGS = ["--enable-unsafe-swiftshader", "--use-angle=swiftshader"]


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """A seeded `saddlescope serve`: base URL and the rides by (horse, recording)."""
    sync_playwright = _require_browser()
    with serve_fresh(tmp_path_factory.mktemp("similarity-pages")) as server, new_club_admin(
            server.base, club_name="Similar Riding Club", email=EMAIL, password=PASSWORD,
            display_name="Coach") as api:
        rides = {}
        rider = _ok(api.post("/api/riders", json={"name": "Rider"}))["id"]
        for i, name in enumerate(HORSES):
            horse = _ok(api.post("/api/horses", json={"name": name}))["id"]
            for recording in range(2):
                ride = _ok(api.post("/api/rides", json={"horse_id": horse, "rider_id": rider, "gait": "canter",
                                                        "direction": "CCW",
                                                        "ridden_on": f"2026-0{recording + 3}-1{i}"}))["id"]
                doc = motion_document(name, "canter", recording=recording)
                store_document(server.database_url, server.storage_dir, ride, doc)
                rides[(name, recording)] = ride
        yield {"base": server.base, "rides": rides, "log": server.log, "playwright": sync_playwright}


@pytest.fixture(scope="module")
def browser(served):
    with chromium_for_module(served["playwright"], tuple(WEBGL_ARGS)) as chromium:
        yield chromium


@pytest.fixture
def page(browser, served):
    context = browser.new_context(base_url=served["base"], viewport={"width": 1280, "height": 900})
    tab = context.new_page()
    tab.console = Console()
    tab.console.attach(tab)
    tab.set_default_timeout(60_000)  # the first list waits for its similarity job
    answer = tab.context.request.post("/api/auth/login", data={"email": EMAIL, "password": PASSWORD})
    assert answer.ok, answer.text()
    try:
        yield tab
    finally:
        context.close()


def fits_the_width(page, selector: str = "main") -> bool:
    """No element inside `selector` reaches past the window's right edge (nothing to scroll sideways to)."""
    wide = page.eval_on_selector_all(
        f"{selector} *", "els => els.filter(e => e.getBoundingClientRect().right > window.innerWidth + 1)"
        ".map(e => e.tagName + '.' + e.getAttribute('class') + ' ' + Math.round(e.getBoundingClientRect().right))")
    assert wide == [], wide
    return True


def test_the_ride_page_lists_the_rides_most_alike(page, served):
    rides = served["rides"]
    query = rides[("Ash", 0)]
    page.goto(f"/#/rides/{query}")
    items = page.locator("[data-alike-list] li")
    items.first.wait_for()
    assert items.count() == 5
    assert items.first.get_attribute("data-ride-id") == str(rides[("Ash", 1)])  # same horse first
    first = items.first.inner_text()
    assert "Ash" in first and "canter" in first and "2026-04-10" in first
    sims = [float(v) for v in items.evaluate_all("els => els.map(e => e.dataset.similarity)")]
    assert sims == sorted(sims, reverse=True) and all(0 <= s <= 1 for s in sims)
    api = page.context.request.get(f"/api/rides/{query}/similar").json()
    assert [i["similarity"] for i in api["items"]] == pytest.approx(sims)
    href = items.first.locator("[data-pair-link]").get_attribute("href")
    assert href == f"#/compare-rides/{query}/{rides[('Ash', 1)]}?markers=saddle&span=stride"
    assert "5 of 5 analysed rides in canter" in page.locator("[data-alike-state]").inner_text()
    page.locator("[data-alike-panel]").screenshot(path="/tmp/sim_panel_1280.png")
    # another marker set: a new job, then the new list
    page.select_option("#alike-markers", "all")
    page.locator('[data-alike-list][data-markers="all"] li').first.wait_for()
    assert items.count() == 5
    assert "most like" in page.locator("[data-alike-state]").inner_text()
    page.set_viewport_size({"width": 390, "height": 844})
    page.locator("[data-alike-panel]").scroll_into_view_if_needed()
    assert fits_the_width(page, "[data-alike-panel]")
    page.locator("[data-alike-panel]").screenshot(path="/tmp/sim_panel_390.png")
    assert page.console.unexpected() == []


def test_the_pair_view_overlays_both_paths_in_3d_and_shows_the_alignment(page, served):
    rides = served["rides"]
    a, b = rides[("Birch", 0)], rides[("Cedar", 1)]
    page.goto(f"/#/compare-rides/{a}/{b}?markers=saddle&span=stride")
    wait_for_charts_drawn(page, ["pair-paths", "pair-alignment"])
    page.wait_for_function("() => document.querySelector('[data-chart=\"pair-paths\"]')?.data?.length === 4")
    page.wait_for_function("() => document.querySelector('[data-chart=\"pair-alignment\"]')?.data?.length === 3")
    api = page.context.request.get(f"/api/rides/{a}/similar/{b}").json()
    traces = page.eval_on_selector('[data-chart="pair-paths"]',
                                   "el => el.data.map(t => ({type: t.type, n: t.x.length, name: t.name}))")
    assert [t["type"] for t in traces] == ["scatter3d"] * 4
    assert [t["n"] for t in traces[:2]] == [len(p) for p in api["view"]["paths_mm"]]
    assert [t["n"] for t in traces[2:]] == [101, 101]  # closed mean-stride loops
    assert "Birch" in traces[0]["name"] and "Cedar" in traces[1]["name"]
    # the 3-D scene was drawn (a WebGL canvas), not only the div
    assert page.locator('[data-chart="pair-paths"] canvas').count() >= 1
    heights = page.eval_on_selector('[data-chart="pair-alignment"]', "el => el.data[1].y")
    assert heights == pytest.approx([-p[1] for p in api["view"]["strides"]["second_mm"]])
    assert page.locator("h1").inner_text() == "Birch and Cedar compared"
    shown = page.locator('[data-fact="Similarity"]').inner_text()
    assert abs(float(shown) - api["similarity"]) < 0.001
    # where they differ: a heat strip per track and tenth of the stride, the API's numbers
    page.wait_for_function("document.querySelector('[data-chart=\"pair-differences\"]')?.data?.length === 1")
    strip = page.eval_on_selector('[data-chart="pair-differences"]', "el => ({type: el.data[0].type, y: el.data[0].y,"
                                  " z: el.data[0].z})")
    assert strip["type"] == "heatmap" and strip["y"] == ["saddle"]
    assert strip["z"][0] == pytest.approx(api["differences"]["per_marker"][0]["per_stretch_mm"])
    assert page.locator('[data-fact="Differ most"]').inner_text().startswith("saddle, ")
    page.screenshot(path="/tmp/sim_pair_1280.png", full_page=True)
    page.set_viewport_size({"width": 390, "height": 844})
    page.wait_for_timeout(1000)  # Plotly redraws the charts for the narrow window
    page.screenshot(path="/tmp/sim_pair_390.png", full_page=True)
    assert fits_the_width(page)
    # another ride club B cannot see, or a ride that does not exist: the server's reason
    page.goto(f"/#/compare-rides/{a}/999999")
    page.locator("[data-pair-state] .form-error").wait_for()
    assert "ride 999999 not found" in page.locator("[data-pair-state]").inner_text()
    assert page.console.unexpected(404) == []

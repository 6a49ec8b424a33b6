"""The ride page and the one-page report in Debian's chromium: every chart drawn with Plotly data, the
quality in plain words, exposure times in h / min ("under a minute"), the job's progress in words, no horizontal
scrolling at 390 px, and the report printed by the browser as exactly one A4 page.

The seeded server and browser are tests/e2e/dashboard_helpers.py's (imported, not copied); this module adds
one ride whose result also holds the markers' tracks (for the 3-D view) and a rotation flag.
"""

from __future__ import annotations

import io

import dashboard_helpers
import numpy as np
import pytest
from dashboard_helpers import (
    _ok,
    api_client,
    charts_drawn,
    result_document,
    sign_in,
    store_result,
    wait_for_charts,
)

from conftest import PROJECT_ROOT
from saddlescope.services.jobs.stage_labels import progress_percent, stage_label
from saddlescope.services.results.report import duration_text

pytestmark = [pytest.mark.browser, pytest.mark.slow]

# dashboard_helpers' browser fixtures and its seeded server for the ride page, used by name
sync_playwright_factory = dashboard_helpers.sync_playwright_factory
browser = dashboard_helpers.browser
page = dashboard_helpers.page
dashboard = dashboard_helpers.ride_page_dashboard

SCREENSHOTS = PROJECT_ROOT / "var" / "test-artifacts" / "screenshots"
WEAK_AXIS = ("rotation about the markers' weakest axis (eigenvalue ratio 0.026) kept at 0% in ω and 0% in α: "
             "the rest is what skin motion predicts")
MARKERS_IN_LINE = ("the markers lie near a line (eigenvalue ratio 0.004 < 0.01): rotation about it (axis [1, 0, 0] "
                   "in the motion frame) is not observable, so its component of ω and α is left out (taken as zero)")


@pytest.fixture(scope="module")
def ride(dashboard):
    """A canter ride of Bella with marker tracks, roll read as zero and its reason among the flags."""
    doc = result_document(scale=1.0, gait="canter", rng=np.random.default_rng(11))
    position = np.asarray(doc["saddle"]["position_m"])
    layout = np.array([[0.0, -0.05, 0.1], [-0.2, -0.04, 0.1], [-0.4, -0.06, 0.1]])
    doc["markers"]["position_m"] = (position[:, None, :] + layout).tolist()
    doc["markers"]["names"] = ["M1", "M2", "M3"]
    omega = np.asarray(doc["angular"]["omega_rad_s"])
    omega[:, 0] = 0.0  # roll left out: the markers lie near a line
    doc["angular"]["omega_rad_s"] = omega.tolist()
    doc["quality"]["flags"] += [WEAK_AXIS, MARKERS_IN_LINE]
    with api_client(dashboard) as api:
        created = _ok(api.post("/api/rides", json={"horse_id": dashboard["horses"]["Bella"],
                                                   "rider_id": dashboard["riders"][0], "gait": "canter",
                                                   "direction": "CW", "ridden_on": "2026-05-02"}))
    store_result(dashboard["database_url"], dashboard["storage_dir"], created["id"], doc)
    return {"id": created["id"], "doc": doc}


def test_the_ride_page_draws_every_chart_and_says_its_quality_in_plain_words(page, dashboard, ride):
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    sign_in(page)
    page.goto(f"/#/rides/{ride['id']}")
    page.locator("[data-result]").wait_for(state="visible")
    wait_for_charts(page)
    drawn = charts_drawn(page)
    assert all(points > 0 for points in drawn.values()), drawn
    n = len(ride["doc"]["saddle"]["t_s"])
    assert page.eval_on_selector('[data-chart="tracks3d"]', "el => el.data.map(t => t.type)") == ["scatter3d"] * 4
    names = page.eval_on_selector('[data-chart="fit-y"]', "el => el.data.map(t => [t.name, t.y.length])")
    assert names == [["measured", n], ["fitted", n], ["residual", n]]
    page.select_option("[data-fit-quantity]", "acceleration")
    page.wait_for_function("() => document.querySelector('[data-chart=\"fit-y\"]').layout.title.text.startsWith('Acc')")
    fitted = page.eval_on_selector('[data-chart="fit-y"]', "el => el.data[1].y")
    np.testing.assert_allclose(fitted, np.asarray(ride["doc"]["saddle"]["acceleration_m_s2"])[:, 1], rtol=1e-12)

    # quality: the jargon becomes advice; the expert's sentence stays behind a toggle
    notes = page.locator("[data-quality-notes] li")
    assert notes.count() == 2  # the two rotation flags ask for the same thing: one line, two details
    assert "10 cm below" in page.locator('[data-quality-notes] [data-code="rotation.weak_axis"]').inner_text()
    assert not page.locator("[data-detail]").first.is_visible()  # folded away
    details = page.locator("[data-detail]").all_text_contents()
    assert sorted(details) == sorted(ride["doc"]["quality"]["flags"])
    assert "roll" in page.locator("[data-zero-rotation]").inner_text()
    assert "10 cm below" in page.locator("[data-zero-rotation]").inner_text()
    assert page.locator("[data-strides]").inner_text() == "2 whole strides analysed"

    # exposure times read as hours and minutes, the speed card has its 95 % interval
    ind = ride["doc"]["indicators"]
    for key in ("t_a8_action_wb_h", "t_vdv_limit_wk_h"):
        assert page.locator(f'[data-exposure-table] td[data-key="{key}"]').inner_text() == duration_text(ind[key])
    assert "95 % interval" in page.locator('[data-ci="vel_x_avg_kmh"]').inner_text()
    assert page.locator("[data-report-link]").get_attribute("href") == f"/api/rides/{ride['id']}/report"
    page.screenshot(path=str(SCREENSHOTS / "ride-1280.png"), full_page=True)

    page.set_viewport_size({"width": 390, "height": 844})
    page.reload()
    wait_for_charts(page)
    assert page.evaluate("document.documentElement.scrollWidth <= innerWidth"), page.evaluate(
        "document.documentElement.scrollWidth")
    page.screenshot(path=str(SCREENSHOTS / "ride-390.png"), full_page=True)
    assert page.console.unexpected() == []


def test_the_jobs_progress_reads_as_a_percentage_in_plain_words(page, dashboard):
    sign_in(page)
    page.goto("/#/rides")
    page.get_by_role("heading", level=1, name="Rides").wait_for()
    text = "(job) => import('/js/format.js').then(m => m.jobProgressText(job).text)"
    # the job as GET /api/jobs sends it: the page says the server's percentage and words, it guesses none
    running = {"progress": 0.42, "stage": "analyze", "status": "running"}
    running |= {"progress_percent": progress_percent(0.42, "running"), "stage_label": stage_label("analyze", "running")}
    assert page.evaluate(text, running) == f"42 % \u2013 {stage_label('analyze', 'running')}"
    assert page.evaluate(text, {"progress_percent": 63, "stage_label": "finding the markers",
                                "stage": "analyze"}) == "63 % \u2013 finding the markers"
    assert page.evaluate(text, {"progress": None, "stage": None, "progress_percent": None}) == "0 %"
    assert page.console.unexpected() == []


def test_the_report_prints_as_one_a4_page_in_the_browser(page, dashboard, ride):
    pypdf = pytest.importorskip("pypdf")
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    sign_in(page)
    page.goto(f"/api/rides/{ride['id']}/report")
    assert "Bella" in page.locator("h1").inner_text()
    page.screenshot(path=str(SCREENSHOTS / "report-1280.png"), full_page=True)
    pdf = page.pdf(format="A4", print_background=True)
    assert len(pypdf.PdfReader(io.BytesIO(pdf)).pages) == 1
    page.set_viewport_size({"width": 390, "height": 844})
    page.reload()
    assert page.evaluate("document.documentElement.scrollWidth <= innerWidth")
    page.screenshot(path=str(SCREENSHOTS / "report-390.png"), full_page=True)
    assert page.console.unexpected() == []

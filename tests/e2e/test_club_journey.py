"""A new club's whole journey in Debian's chromium (issue 23, "Done when"), from an EMPTY database on a
fresh `saddlescope serve` (embedded: SQLite and the in-process job runner), through the pages:

 1. create the club on the sign-in page;          2. add a member on #/account;
 3. add a rig with the tiny ride's board;         4. upload its calibration clips one by one (and its
    plumb and static clips) on the rig page; the calibration runs to done;
 5. add a horse and a rider on their pages;       6. upload the ride's motion clips one by one on #/upload;
 7. watch the analysis job reach done;            8. the ride page draws every chart (Plotly data, points);
 9. earlier canter rides seeded through the API / db: the horse page's trend has the horse's band;
10. the report prints (page.pdf, A4) on exactly one page, and so does the server's own PDF of it;
11. the ride's gait edited on the ride page and re-analysed (to done);
12. a ride deleted from the rides list after its confirmation dialog, and gone from the list.

On every page: no console errors, screenshots at 1280 and 390 px in
var/test-artifacts/screenshots/journey-<step>-<width>.png and no sideways scrolling at 390 px.
The clips are the real synthetic ones of `integration_services.tiny_ride`; the analyses are real.
"""

from __future__ import annotations

import io
import json
import time

import httpx
import integration_services
import numpy as np
import pytest
from browser_harness import SCREENSHOTS, chromium_for_module, serve_fresh, shoot_both_widths, wait_for_charts_drawn
from dashboard_helpers import (
    CHARTS,
    Console,
    _ok,
    _require_browser,
    charts_drawn,
    result_document,
    store_result,
    wait_for_charts,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow]

tiny_ride = integration_services.tiny_ride  # the session fixture: a 2.5 s canter bundle folder

PIPELINE_TIMEOUT_S = 900.0  # a calibration or an analysis on this loaded machine takes minutes
CLUB = {"club_name": "Meadow Riding Club", "display_name": "Sam Secretary", "email": "sam@meadow.example",
        "password": "sam's club password"}
MEMBER = {"email": "tess@meadow.example", "display_name": "Tess Trainer"}
HORSE, RIDER = "Juniper", "Robin Rider"
EARLIER = ["2026-10-01", "2026-10-08", "2026-10-15", "2026-10-22", "2026-10-29"]  # before the real ride


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """An empty club-less `saddlescope serve` and a chromium for the module."""
    sync_playwright = _require_browser()
    with serve_fresh(tmp_path_factory.mktemp("journey")) as server, chromium_for_module(sync_playwright) as chromium:
        yield {"base": server.base, "database_url": server.database_url, "storage_dir": server.storage_dir,
               "browser": chromium, "log": server.log}


def _api(served) -> httpx.Client:
    """A bearer-token client of the club's admin (used to watch jobs and, step 9, to seed rides)."""
    api = httpx.Client(base_url=served["base"], timeout=30)
    token = _ok(api.post("/api/auth/login", json={"email": CLUB["email"], "password": CLUB["password"]}))
    api.cookies.clear()
    api.headers["Authorization"] = f"Bearer {token['access_token']}"
    return api


def _wait_job(api: httpx.Client, served, *, statuses=("done",), **params) -> dict:
    """Poll /api/jobs (filtered by `params`) until the newest job is in `statuses`; fail on a failure."""
    deadline = time.monotonic() + PIPELINE_TIMEOUT_S
    job = None
    while time.monotonic() < deadline:
        jobs = _ok(api.get("/api/jobs", params={**params, "limit": 50}))["items"]
        job = max(jobs, key=lambda j: j["id"]) if jobs else None
        if job and job["status"] in statuses:
            return job
        if job and job["status"] in ("failed", "cancelled"):
            pytest.fail(f"job {job['id']} ({job['kind']}) {job['status']}: {job['error']}\n"
                        f"{served['log'].read_text()[-3000:]}")
        time.sleep(3)
    pytest.fail(f"no job of {params} reached {statuses} within {PIPELINE_TIMEOUT_S} s: {job}")


def _clip(path) -> dict:
    return {"name": path.name, "mimeType": "video/mp4", "buffer": path.read_bytes()}


def _loaded(tab, heading: str | None = None) -> None:
    if heading:
        tab.get_by_role("heading", level=1, name=heading).wait_for()
    tab.locator("main:not([aria-busy])").wait_for()


def _clean(tab, step: str, *allowed: int) -> None:
    """No console errors since the last check (`allowed`: HTTP statuses the step expects)."""
    errors = tab.console.unexpected(*allowed)
    tab.console.errors.clear()
    assert errors == [], f"{step}: console errors {errors}"


def _page_step(tab, step: str, *allowed: int) -> None:
    shoot_both_widths(tab, f"journey-{step}")
    _clean(tab, step, *allowed)


def test_a_new_club_from_its_cameras_to_a_report(served, tiny_ride):
    meta = json.loads((tiny_ride / "ride.json").read_text())
    context = served["browser"].new_context(base_url=served["base"], viewport={"width": 1280, "height": 900})
    tab = context.new_page()
    tab.console = Console()
    tab.console.attach(tab)
    tab.set_default_timeout(30_000)
    try:
        _journey(tab, served, meta, tiny_ride)
    finally:
        context.close()


def _journey(tab, served, meta, folder) -> None:
    # 1. The club is created on the sign-in page.
    tab.goto("/#/login")
    _loaded(tab, "Sign in")
    _page_step(tab, "01-sign-in")
    for field, value in (("#club-name", CLUB["club_name"]), ("#club-display", CLUB["display_name"]),
                         ("#club-email", CLUB["email"]), ("#club-password", CLUB["password"])):
        tab.locator(field).fill(value)
    tab.get_by_role("button", name="Create club and sign in").click()
    tab.wait_for_url("**/#/start")  # a new club lands on "Getting started"
    _loaded(tab)
    api = _api(served)

    # 2. A member is added on the account page (a one-time link to set a password is shown).
    tab.goto("/#/account")
    _loaded(tab, "Your account")
    tab.locator("#member-email").fill(MEMBER["email"])
    tab.locator("#member-name").fill(MEMBER["display_name"])
    tab.get_by_role("button", name="Add member").click()
    tab.locator("[data-reset-box]").wait_for(state="visible")
    tab.locator(f'[data-members-table] tr[data-email="{MEMBER["email"]}"]').wait_for()
    _page_step(tab, "02-account")

    # 3. The rig with its board: the board the tiny ride's clips were filmed with.
    board = meta["board"]
    assert board["kind"] == "checkerboard"
    tab.goto("/#/rigs")
    _loaded(tab, "Rigs")
    _page_step(tab, "03-rigs-empty")
    form = tab.locator("[data-rig-form]")
    form.get_by_label("Name").fill("Outdoor arena, three phones")
    form.get_by_label("Inner corners across").fill(str(board["inner_corners"][0]))
    form.get_by_label("Inner corners down").fill(str(board["inner_corners"][1]))
    form.get_by_label("Square size (mm)").fill(str(board["square_mm"]))
    form.get_by_role("button", name="Add the rig").click()
    tab.wait_for_url("**/#/rigs/*")
    rig_id = int(tab.url.rsplit("/", 1)[1])
    tab.locator("[data-board-image] svg").wait_for()
    stored = _ok(api.get(f"/api/rigs/{rig_id}"))["board"]
    assert {k: stored[k] for k in board} == board, stored

    # 4. Its calibration clips one by one; the third starts the calibration, which runs to done.
    for camera in ("left", "middle", "right"):
        path = folder / meta["clips"]["calibration"][camera]
        tab.locator(f'[data-rig-clip="calibration-{camera}"]').set_input_files(_clip(path))
        cell = tab.locator(f'.rig-clip[data-clip-kind="calibration"][data-camera="{camera}"]')
        cell.get_by_text(path.name).wait_for()
    status = tab.locator("[data-calibration-status]")
    calibrate = tab.locator("[data-calibrate]")
    if calibrate.is_visible() and not status.inner_text().startswith("Calibrat"):
        calibrate.click()  # not started by the upload: start it as the page offers
    job = _wait_job(api, served, rig_id=rig_id)
    assert job["kind"].startswith("calibrat"), job
    tab.wait_for_function(
        "() => document.querySelector('[data-calibration-status]').textContent.startsWith('Calibrated')",
        timeout=60_000)
    tab.locator("[data-calibration-words] li").first.wait_for()
    # The plumb and static clips belong to the rig too (the rides filmed with it reuse them).
    for kind in ("plumb", "static"):
        for camera in ("left", "middle", "right"):
            path = folder / meta["clips"][kind][camera]
            tab.locator(f'[data-rig-clip="{kind}-{camera}"]').set_input_files(_clip(path))
            tab.locator(f'.rig-clip[data-clip-kind="{kind}"][data-camera="{camera}"]').get_by_text(path.name).wait_for()
    tab.locator("[data-coverage] svg.coverage").first.wait_for()
    _page_step(tab, "04-rig")
    tab.goto("/#/rigs")
    tab.get_by_role("link", name="Outdoor arena, three phones").wait_for()
    assert "calibrated" in tab.locator("[data-rig-rows]").inner_text()
    _page_step(tab, "03-rigs")

    # 5. A horse and a rider on their pages.
    tab.goto("/#/horses")
    _loaded(tab, "Horses")
    tab.locator("#horse-name").fill(HORSE)
    tab.get_by_role("button", name="Add horse").click()
    tab.get_by_role("link", name=HORSE).first.wait_for()
    _page_step(tab, "05-horses")
    tab.goto("/#/riders")
    _loaded(tab, "Riders")
    tab.locator("#rider-name").fill(RIDER)
    tab.get_by_role("button", name="Add rider").click()
    tab.get_by_text(RIDER).first.wait_for()
    _page_step(tab, "05-riders")
    horse_id = next(h["id"] for h in _ok(api.get("/api/horses"))["items"] if h["name"] == HORSE)
    rider_id = next(r["id"] for r in _ok(api.get("/api/riders"))["items"] if r["name"] == RIDER)

    # 6. The ride's clips one by one on the upload page, with the rig, horse, rider and gait chosen.
    tab.goto("/#/upload")
    _loaded(tab, "Upload a ride")
    tab.get_by_label("Clips one by one").check()
    tab.select_option("#up-rig", str(rig_id))
    tab.select_option("#up-horse", label=HORSE)
    tab.select_option("#up-rider", label=RIDER)
    tab.select_option("#up-gait", meta["gait"])
    tab.select_option("#up-direction", meta["direction"])
    tab.wait_for_function("() => document.querySelector('[data-readiness-list]').textContent.includes('motion')")
    for camera in ("left", "middle", "right"):
        tab.locator(f"#clip-motion-{camera}").set_input_files(_clip(folder / meta["clips"]["motion"][camera]))
    tab.locator("[data-readiness]").wait_for(state="hidden")  # nothing missing: the rig has the rest
    _page_step(tab, "06-upload")
    tab.get_by_role("button", name="Upload and analyse").click()
    tab.wait_for_url("**/#/rides/*", timeout=120_000)
    ride_id = int(tab.url.rsplit("/", 1)[1])
    ride = _ok(api.get(f"/api/rides/{ride_id}"))
    assert (ride["horse_id"], ride["rider_id"], ride["rig_id"], ride["gait"]) == (horse_id, rider_id, rig_id, "canter")
    _clean(tab, "06-upload (sending)")

    # 7. The job on the jobs page, then to done.
    tab.goto("/#/jobs")
    _loaded(tab, "Jobs")
    _page_step(tab, "07-jobs-running")
    job = _wait_job(api, served, ride_id=ride_id)
    tab.reload()
    _loaded(tab, "Jobs")
    tab.locator("[data-jobs-table]").get_by_text("done", exact=True).first.wait_for()
    _page_step(tab, "07-jobs-done")

    # 8. The ride page: every chart drawn, with points.
    tab.goto(f"/#/rides/{ride_id}")
    tab.locator("[data-result]").wait_for(state="visible", timeout=60_000)
    wait_for_charts(tab)
    drawn = charts_drawn(tab)
    assert set(CHARTS) <= set(drawn) and all(points > 0 for points in drawn.values()), drawn
    on_page = tab.eval_on_selector_all("main [data-chart]", """els => els.map(el => [el.dataset.chart,
        (el.data || []).reduce((s, t) => s + Math.max(...[t.x, t.y, t.z].map(v => (v || []).length)), 0)])""")
    assert on_page and all(points > 0 for _, points in on_page), on_page  # no chart on the page left empty
    report_href = tab.locator("[data-report-link]").get_attribute("href")
    assert report_href == f"/api/rides/{ride_id}/report"
    _page_step(tab, "08-ride")

    # 9. Earlier canter rides of the horse (seeded through the API and the db); the trend has its band.
    rng = np.random.default_rng(23)
    earlier = []
    for day, scale in zip(EARLIER, (1.0, 1.05, 0.95, 1.02, 0.98), strict=True):
        seeded = _ok(api.post("/api/rides", json={"horse_id": horse_id, "rider_id": rider_id, "gait": "canter",
                                                  "direction": "CCW", "ridden_on": day}))["id"]
        store_result(served["database_url"], served["storage_dir"], seeded, result_document(
            scale=scale, gait="canter", rng=rng))
        earlier.append(seeded)
    tab.goto(f"/#/horses/{horse_id}")
    tab.get_by_role("heading", level=1, name=HORSE).wait_for()
    wait_for_charts_drawn(tab, ["horse-trend"])
    assert tab.locator("#hp-trend-gait").input_value() == "canter"
    traces = tab.eval_on_selector('[data-chart="horse-trend"]',
                                  "el => el.data.map(t => ({name: t.name, y: t.y, fill: t.fill || null}))")
    band = [t for t in traces if t["fill"] == "tonexty"]
    assert band and any(y is not None for y in band[0]["y"]), traces
    rides = next(t for t in traces if t["name"] == "ride")
    assert len(rides["y"]) == len(EARLIER) + 1
    _page_step(tab, "09-horse")

    # 10. The report, printed by the browser: one A4 page.
    pypdf = pytest.importorskip("pypdf")
    tab.goto(report_href)
    assert HORSE in tab.locator("h1").inner_text()
    pdf = tab.pdf(format="A4")
    (SCREENSHOTS / "journey-10-report.pdf").write_bytes(pdf)  # the printed report, kept with the screenshots
    (SCREENSHOTS / "journey-10-report.html").write_text(tab.content())
    assert len(pypdf.PdfReader(io.BytesIO(pdf)).pages) == 1
    served_pdf = api.get(f"/api/rides/{ride_id}/report.pdf", timeout=120)  # the server's own PDF (WeasyPrint)
    assert served_pdf.status_code == 200 and served_pdf.headers["content-type"].startswith("application/pdf")
    assert len(pypdf.PdfReader(io.BytesIO(served_pdf.content)).pages) == 1
    _page_step(tab, "10-report")

    # 11. The gait corrected on the ride page, then re-analysed.
    tab.goto(f"/#/rides/{ride_id}")
    tab.locator("[data-result]").wait_for(state="visible", timeout=60_000)
    tab.locator(".ride-edit-box > summary").click()  # the details form is folded under one line
    edit = tab.locator("[data-ride-edit-form]")
    edit.wait_for()
    edit.locator('select[name="gait"]').select_option("rising_trot")
    tab.get_by_role("button", name="Save details").click()
    outdated = tab.locator("[data-ride-edit-outdated]")
    outdated.wait_for(state="visible")
    assert "gait" in outdated.inner_text()
    assert _ok(api.get(f"/api/rides/{ride_id}"))["gait"] == "rising_trot"
    _page_step(tab, "11-ride-edited")
    jobs_before = _ok(api.get("/api/jobs", params={"ride_id": ride_id}))["total"]
    tab.locator("[data-ride-edit-reanalyse]").click()
    tab.locator("[data-ride-edit-outdated-text]").filter(has_text="Re-analysis queued").or_(
        tab.locator("main").get_by_text("%")).first.wait_for()
    # the page's "%" can be an interval's ("95 %") before the request lands: wait for the new job itself
    deadline = time.monotonic() + 60
    while (_ok(api.get("/api/jobs", params={"ride_id": ride_id}))["total"] == jobs_before
           and time.monotonic() < deadline):
        time.sleep(0.5)
    assert _ok(api.get("/api/jobs", params={"ride_id": ride_id}))["total"] == jobs_before + 1
    requeued = _wait_job(api, served, statuses=("queued", "running", "done"), ride_id=ride_id)
    _wait_job(api, served, ride_id=ride_id)
    assert _ok(api.get(f"/api/jobs/{requeued['id']}"))["status"] == "done"
    assert _ok(api.get(f"/api/rides/{ride_id}"))["result_outdated_by"] == []
    tab.reload()  # (the same address: goto would not load the page again)
    tab.locator("[data-result]").wait_for(state="visible", timeout=60_000)
    wait_for_charts(tab)
    tab.locator("[data-ride-edit-form]").wait_for(state="attached")  # folded again: nothing outdated
    tab.wait_for_function(
        "() => "
        "document.querySelector('[data-ride-edit-form] select[name=gait]').value === 'rising_trot'")
    assert tab.locator("[data-ride-edit-outdated]").is_hidden()  # the result is from the new details now
    assert "rising trot" in tab.locator("h1").inner_text()
    _page_step(tab, "11-ride-reanalysed")

    # 12. A ride deleted from the rides list, after its confirmation dialog; it is gone.
    gone = earlier[0]
    tab.goto("/#/rides")
    _loaded(tab, "Rides")
    row_button = tab.locator(f'[data-ride-delete="{gone}"]')
    row_button.wait_for()
    _page_step(tab, "12-rides")
    row_button.click()
    dialog = tab.locator("[data-ride-delete-dialog]")
    dialog.wait_for(state="visible")
    shoot_both_widths(tab, "journey-12-delete-dialog")
    dialog.locator("[data-ride-delete-confirm]").click()
    row_button.wait_for(state="detached")
    assert tab.locator(f'main a[href="#/rides/{gone}"]').count() == 0
    assert api.get(f"/api/rides/{gone}").status_code == 404
    remaining = {r["id"] for r in _ok(api.get("/api/rides", params={"limit": 100}))["items"]}
    assert gone not in remaining and ride_id in remaining
    _page_step(tab, "12-rides-after-delete")
    api.close()

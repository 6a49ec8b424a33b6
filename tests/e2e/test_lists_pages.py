"""The list pages in a real browser: rides, jobs, horses and riders paged, filtered and sorted by the
server with the state in the URL; a ride's details edited (gait, then "Re-analyse now") and a ride
deleted after a confirmation naming it; a member sees no control the API would refuse; no page scrolls
sideways at 390 px. Screenshots at 1280 and 390 px go to var/test-artifacts/screenshots/.

A real `saddlescope serve` (embedded mode, SQLite) seeded with 120 rides over the REST API; two of
them get a stored result as the analyse stage stores it (dashboard_helpers.store_result). Debian's
chromium driven by Playwright; skipped without it (fails under CI=true), as tests/e2e/dashboard_helpers.py.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import numpy as np
import pytest
from browser_harness import chromium_for_module, new_club_admin, serve_fresh, shoot_both_widths
from dashboard_helpers import (
    EMAIL,
    PASSWORD,
    Console,
    _ok,
    _require_browser,
    result_document,
    store_result,
)

pytestmark = [pytest.mark.browser, pytest.mark.slow]

MEMBER_EMAIL, MEMBER_PASSWORD = "member@example.org", "member password 1"
HORSES = ("Bella", "Comet", "Dancer", "Echo")
GAITS = ("walk", "sitting_trot", "rising_trot", "canter")
N_RIDES = 120


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    _require_browser()
    with serve_fresh(tmp_path_factory.mktemp("lists")) as server:
        yield {"base": server.base, **_seed(server.base, server.database_url, server.storage_dir)}


def _seed(base: str, database_url: str, storage_dir: Path) -> dict:
    with new_club_admin(base, club_name="Lists Club", email=EMAIL, password=PASSWORD) as api:
        member = _ok(api.post("/api/users", json={"email": MEMBER_EMAIL, "password": MEMBER_PASSWORD,
                                                  "role": "member"}))
        horses = [_ok(api.post("/api/horses", json={"name": name}))["id"] for name in HORSES]
        riders = [_ok(api.post("/api/riders", json={"name": name}))["id"] for name in ("Rider A", "Rider B", "Rider C")]
        rides = []
        for i in range(N_RIDES):
            rides.append(_ok(api.post("/api/rides", json={
                "horse_id": horses[i % 4], "rider_id": riders[i % 3], "gait": GAITS[(i // 4) % 4],
                "direction": "CW" if i % 2 else "CCW",
                "ridden_on": f"2026-{1 + i // 28:02d}-{1 + i % 28:02d}"})))
        rng = np.random.default_rng(3)
        analysed = [r for r in rides if r["gait"] == "canter"][:2]
        for ride in analysed:
            store_result(database_url, storage_dir, ride["id"],
                         result_document(scale=1.0, gait="canter", rng=rng))
        for _ in range(3):
            _ok(api.post("/api/jobs", json={"kind": "selftest", "payload": {"steps": 1, "delay_s": 0}}))
    return {"horses": horses, "riders": riders, "rides": rides, "analysed": analysed, "member": member}


@pytest.fixture(scope="module")
def browser():
    with chromium_for_module() as chromium:
        yield chromium


def _page(browser, server, *, email=EMAIL, password=PASSWORD, width=1280):
    context = browser.new_context(base_url=server["base"], viewport={"width": width, "height": 900})
    tab = context.new_page()
    tab.console = Console()
    tab.console.attach(tab)
    tab.set_default_timeout(30_000)
    tab.set_default_navigation_timeout(60_000)
    answer = context.request.post("/api/auth/login", data={"email": email, "password": password})
    assert answer.ok, answer.text()
    return tab


@pytest.fixture
def admin_page(browser, server):
    tab = _page(browser, server)
    yield tab
    tab.context.close()


@contextmanager
def api(server) -> Iterator[httpx.Client]:
    """A client of the server signed in as the admin with a bearer token (no cookies, so no CSRF)."""
    with httpx.Client(base_url=server["base"], timeout=30) as client:
        token = _ok(client.post("/api/auth/login", json={"email": EMAIL, "password": PASSWORD}))["access_token"]
        client.cookies.clear()
        client.headers["Authorization"] = f"Bearer {token}"
        yield client


def _range_text(page) -> str:
    return page.locator("[data-pager-range]").first.inner_text()


def _shoot(page, name: str) -> None:
    shoot_both_widths(page, f"lists-{name}")


def test_rides_list_pages_filters_sorts_and_keeps_its_state_in_the_url(admin_page, server):
    page = admin_page
    page.goto("/#/rides")
    page.locator("[data-rides-table] tbody tr").first.wait_for()
    assert _range_text(page).startswith(f"Rides 1\u201350 of {N_RIDES}")
    assert page.locator("[data-rides-table] tbody tr").count() == 50
    first_horse = page.locator("[data-rides-table] tbody tr").first.locator("td").nth(1).locator("a")
    assert first_horse.get_attribute("href").startswith("#/horses/")

    page.locator("[data-pager-next]").first.click()
    page.wait_for_url("**/#/rides?page=2")
    page.get_by_text(f"Rides 51\u2013100 of {N_RIDES}").wait_for()
    page.locator("[data-pager-size]").first.select_option("25")
    page.get_by_text(f"Rides 1\u201325 of {N_RIDES}").wait_for()

    page.locator("#rides-gait").select_option("canter")
    canter = sum(r["gait"] == "canter" for r in server["rides"])
    page.get_by_text(f"Rides 1\u201325 of {canter}").wait_for()
    assert "gait=canter" in page.url
    gaits = page.locator("[data-rides-table] tbody tr td:nth-child(4)").all_inner_texts()
    assert gaits and set(gaits) == {"canter"}

    page.locator("#rides-sort").select_option("ridden_on")
    page.wait_for_url("**sort=ridden_on**")
    page.locator("[data-rides-table] tbody tr").first.wait_for()
    dates = page.locator("[data-rides-table] tbody tr td:nth-child(6)").all_inner_texts()
    assert dates == sorted(dates) and dates[0] == min(r["ridden_on"] for r in server["rides"] if r["gait"] == "canter")

    page.reload()
    page.locator("[data-rides-table] tbody tr").first.wait_for()
    assert page.locator("#rides-gait").input_value() == "canter"
    assert page.locator("#rides-sort").input_value() == "ridden_on"
    assert page.locator("[data-rides-table] tbody tr td:nth-child(6)").all_inner_texts() == dates

    page.go_back()  # before the sort: newest first again, still canter
    page.wait_for_function("() => !location.hash.includes('sort=ridden_on')")
    page.locator("[data-rides-table] tbody tr").first.wait_for()
    newest = page.locator("[data-rides-table] tbody tr td:nth-child(6)").first.inner_text()
    assert newest == max(r["ridden_on"] for r in server["rides"] if r["gait"] == "canter")
    _shoot(page, "rides")
    assert page.console.unexpected() == []


def test_a_rides_gait_is_edited_and_reanalysis_offered(admin_page, server):
    page = admin_page
    ride = server["analysed"][0]
    page.goto("/#/rides?gait=canter")
    page.locator(f'[data-ride-edit="{ride["id"]}"]').click()
    form = page.locator("[data-ride-edit-form]")
    form.wait_for()
    page.wait_for_function("() => document.querySelector('#ride-edit-gait').value === 'canter'")
    page.locator("#ride-edit-gait").select_option("walk")
    page.locator("#ride-edit-notes").fill("it was a walk")
    page.locator("[data-ride-edit-save]").click()
    notice = page.locator("[data-ride-edit-outdated]")
    notice.wait_for()
    assert "computed with the old gait" in notice.inner_text()
    with api(server) as client:
        saved = _ok(client.get(f"/api/rides/{ride['id']}"))
    assert (saved["gait"], saved["notes"], saved["result_outdated_by"]) == ("walk", "it was a walk", ["gait"])
    _shoot(page, "ride-edit")
    # This seeded ride has a result but no clips: re-analysing it is refused with what is missing (the
    # club's journey test re-analyses a real ride to done), and nothing is queued that could not run.
    page.locator("[data-ride-edit-reanalyse]").click()
    refusal = page.locator("[data-ride-edit-form] [data-form-error]")
    refusal.wait_for()
    assert "missing" in refusal.inner_text()
    with api(server) as client:
        jobs = _ok(client.get("/api/jobs", params={"ride_id": ride["id"], "kind": "analyze"}))
    assert jobs["total"] == 0
    assert page.console.unexpected(422) == []


def test_a_ride_is_deleted_after_a_confirmation_naming_it(admin_page, server):
    page = admin_page
    ride = server["rides"][5]
    page.goto(f"/#/rides?sort=ridden_on&horse_id={ride['horse_id']}")
    row = page.locator(f'[data-rides-table] tr[data-ride-id="{ride["id"]}"]')
    row.locator("[data-ride-delete]").click()
    dialog = page.locator("[data-ride-delete-dialog]")
    dialog.wait_for()
    assert f"#{ride['id']}" in dialog.inner_text() and HORSES[5 % 4] in dialog.inner_text()
    _shoot(page, "ride-delete-dialog")
    page.locator("[data-ride-delete-cancel]").click()
    assert row.is_visible()
    row.locator("[data-ride-delete]").click()
    page.locator("[data-ride-delete-confirm]").click()
    row.wait_for(state="detached")
    with api(server) as client:
        assert client.get(f"/api/rides/{ride['id']}").status_code == 404
    assert page.console.unexpected() == []


def test_a_member_sees_no_control_that_would_be_refused(browser, server):
    page = _page(browser, server, email=MEMBER_EMAIL, password=MEMBER_PASSWORD)
    try:
        page.goto("/#/rides")
        page.locator("[data-rides-table] tbody tr").first.wait_for()
        assert page.locator('[data-permission="ride.delete"]').count() == 0  # the member made none of them
        assert page.locator("[data-ride-edit]").count() > 0
        page.goto(f"/#/rides?edit={server['rides'][0]['id']}")
        page.locator("[data-ride-edit-form]").wait_for()
        assert page.locator("[data-ride-edit-delete]").is_hidden()
        for path, name in (("/#/horses", "horses"), ("/#/riders", "riders")):
            page.goto(path)
            page.locator("[data-entity-table] tbody tr").first.wait_for()
            assert page.locator('[data-permission="horse.delete"]').count() == 0
            _shoot(page, f"{name}-member")
        page.goto("/#/jobs")
        page.locator("[data-jobs-table] tbody tr").first.wait_for()
        assert page.locator('[data-permission^="job."]').count() == 0  # selftest jobs: admins' only
        assert page.console.unexpected() == []
    finally:
        page.context.close()


def test_jobs_horses_and_riders_pages_page_and_filter(admin_page, server):
    page = admin_page
    page.goto("/#/jobs?size=25")
    page.locator("[data-jobs-table] tbody tr").first.wait_for()
    assert "of" in _range_text(page)
    done = page.locator('[data-jobs-table] tr[data-status="done"]').first
    done.wait_for()
    assert "100" in done.locator("[data-job-percent]").inner_text()
    assert done.locator("[data-job-stage]").inner_text() == "Finished"
    page.locator("#jobs-kind").select_option("selftest")
    page.wait_for_url("**kind=selftest**")
    page.wait_for_function(  # the filtered page has replaced the first one
        "() => [...document.querySelectorAll('[data-jobs-table] tbody tr td:nth-child(2)')]"
        ".some(td => td.innerText === 'Worker self-test')")
    kinds = page.locator("[data-jobs-table] tbody tr td:nth-child(2)").all_inner_texts()
    assert kinds and set(kinds) == {"Worker self-test"}  # the glossary's label, never the code
    _shoot(page, "jobs")

    page.goto("/#/horses")
    page.locator("[data-entity-table] tbody tr").first.wait_for()
    assert page.locator('[data-permission="horse.delete"]').count() == len(HORSES)  # an admin may
    link = page.locator("[data-entity-table] tbody tr th a").first
    assert link.get_attribute("href").startswith("#/horses/")
    page.locator("#horses-search").fill("om")
    page.locator("#horses-search").press("Enter")
    page.wait_for_url("**q=om**")
    page.get_by_text("Horses 1\u20131 of 1").wait_for()
    assert page.locator("[data-entity-table] tbody tr th").all_inner_texts() == ["Comet"]
    with api(server) as client:
        comets = _ok(client.get("/api/rides", params={"horse_id": server["horses"][1], "limit": 1}))["total"]
    page.once("dialog", lambda dialog: dialog.accept())
    page.locator('[data-permission="horse.delete"]').first.click()
    page.get_by_text(f"horse 'Comet' still has {comets} rides; delete those rides first").wait_for()
    _shoot(page, "horses")
    page.goto("/#/riders?size=25&sort=-name")
    page.locator("[data-entity-table] tbody tr").first.wait_for()
    assert page.locator("[data-entity-table] tbody tr th").all_inner_texts() == ["Rider C", "Rider B", "Rider A"]
    _shoot(page, "riders")
    assert page.console.unexpected(409) == []  # the refused horse deletion only

"""The vet's view in Debian's chromium (issue 37): a member makes a share link on the ride page; the link,
opened in a fresh browser context without signing in, shows the report as a clean page (no app, prints as
one A4 page); an admin withdraws it on the Account page and the link then says so in plain words, with no
sign-in redirect. The horse page shares the horse's page and offers its rides as CSV / Excel.

The seeded server is dashboard_helpers.ride_page_dashboard, the ride page tests' own.
"""

from __future__ import annotations

import io

import dashboard_helpers
import pytest
from browser_harness import assert_no_horizontal_scroll, axe_violations, require_axe, screenshot
from dashboard_helpers import Console, sign_in

pytestmark = [pytest.mark.browser, pytest.mark.slow]

sync_playwright_factory = dashboard_helpers.sync_playwright_factory
browser = dashboard_helpers.browser
page = dashboard_helpers.page
dashboard = dashboard_helpers.ride_page_dashboard


def _make_link(page) -> str:
    """Open the share control on the current page, make a link, and return it as shown."""
    page.locator("details[data-share] summary").click()
    page.locator("[data-share-make]").click()
    field = page.locator("[data-share-url]")
    field.wait_for(state="visible")
    return field.input_value()


def _fresh_tab(browser, dashboard, width: int = 1280):
    """A new browser context: no cookie, nobody signed in (as the vet's own browser)."""
    context = browser.new_context(base_url=dashboard["base"], viewport={"width": width, "height": 900})
    tab = context.new_page()
    tab.console = Console()
    tab.console.attach(tab)
    tab.set_default_timeout(15_000)
    return context, tab


def test_a_ride_link_opens_without_signing_in_and_is_refused_after_withdrawing(page, browser, dashboard):
    pypdf = pytest.importorskip("pypdf")
    sign_in(page)
    ride = next(r for r in dashboard["rides"] if r["horse"] == "Bella" and r["gait"] == "canter")
    page.goto(f"/#/rides/{ride['id']}")
    page.locator("[data-result]").wait_for(state="visible")
    link = _make_link(page)
    assert link.startswith(dashboard["base"] + "/shared/") and len(link.rsplit("/", 1)[1]) >= 43
    assert "until" in page.locator("[data-share-result]").inner_text()
    screenshot(page, "share-ride-control")

    context, vet = _fresh_tab(browser, dashboard)
    try:
        answer = vet.goto(link)
        assert answer.status == 200 and vet.url == link  # no redirect to a sign-in page
        assert vet.locator("h1").inner_text().startswith("Ride report: Bella")
        assert vet.locator("nav, [data-nav], #app").count() == 0  # the report alone, not the app
        assert vet.locator("a[href*='/api/'], a[href*='#/']").count() == 0
        pdf = vet.pdf(format="A4", print_background=True)
        assert len(pypdf.PdfReader(io.BytesIO(pdf)).pages) == 1
        require_axe()
        assert axe_violations(vet) == []
        screenshot(vet, "shared-report")
        vet.set_viewport_size({"width": 390, "height": 844})
        assert_no_horizontal_scroll(vet)
        screenshot(vet, "shared-report")
        assert vet.console.unexpected() == []

        # an admin withdraws it on the Account page
        page.goto("/#/account")
        row = page.locator("[data-share-links-table] tbody tr").filter(has_text="Report of Bella's canter")
        row.first.wait_for(state="visible")
        screenshot(page, "share-links-admin")
        row.first.locator("[data-revoke]").click()
        page.locator("[data-share-links-table] tbody tr").filter(has_text="withdrawn").first.wait_for(state="visible")

        refused = vet.goto(link)
        assert refused.status == 410 and vet.url == link
        assert vet.locator("h1").inner_text() == "This link was withdrawn by the club"
        assert "Bella" not in vet.locator("body").inner_text()
        screenshot(vet, "shared-withdrawn")
        assert vet.console.unexpected(410) == []
    finally:
        context.close()
    assert page.console.unexpected() == []


def test_a_horse_link_shows_the_horse_and_its_reports_and_the_page_exports_its_rides(page, browser, dashboard):
    sign_in(page)
    bella = dashboard["horses"]["Bella"]
    page.goto(f"/#/horses/{bella}")
    csv_link = page.locator('[data-horse-export="csv"]')
    csv_link.wait_for(state="visible")
    assert csv_link.get_attribute("href") == f"/api/horses/{bella}/export?format=csv"
    with page.expect_download() as download:
        csv_link.click()
    assert download.value.suggested_filename == "bella-rides.csv"
    link = _make_link(page)
    screenshot(page, "share-horse-control")
    page.set_viewport_size({"width": 390, "height": 844})
    assert_no_horizontal_scroll(page)
    screenshot(page, "share-horse-control")

    context, vet = _fresh_tab(browser, dashboard, width=390)
    try:
        assert vet.goto(link).status == 200
        assert vet.locator("h1").inner_text() == "Bella"
        assert vet.locator("section[data-gait] tbody tr").count() >= 1
        assert_no_horizontal_scroll(vet)
        assert axe_violations(vet) == []
        screenshot(vet, "shared-horse")
        vet.locator("section[data-gait] tbody tr a").first.click()
        vet.wait_for_load_state()
        assert vet.locator("h1").inner_text().startswith("Ride report: Bella")
        assert vet.locator("text=Back to the horse").count() == 1
        assert vet.console.unexpected() == []
    finally:
        context.close()
    assert page.console.unexpected() == []

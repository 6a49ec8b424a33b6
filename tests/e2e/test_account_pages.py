"""Accounts in a real browser: a club is created, its admin adds a member with a one-time link, the
member sets a password from it in a fresh browser, signs in and changes it; members see no members
section and no health details; the last admin cannot demote themselves; the overview and the sign-in
page fit a phone. Screenshots of each page at 1280 and 390 px go to var/test-artifacts/screenshots/.

A real `saddlescope serve` (embedded mode, an empty SQLite database) and Debian's chromium driven by
Playwright, started with the helpers of tests/e2e/dashboard_helpers.py; skipped without chromium.
"""

from __future__ import annotations

import httpx
import pytest
from browser_harness import chromium_for_module, serve_fresh
from dashboard_helpers import Console, _ok, _require_browser

from conftest import PROJECT_ROOT

pytestmark = [pytest.mark.browser, pytest.mark.slow]

SHOTS = PROJECT_ROOT / "var" / "test-artifacts" / "screenshots"
ADMIN = {"club_name": "Hoofbeat Riding Club", "display_name": "Anna Admin", "email": "anna@hoofbeat.example",
         "password": "anna's first password"}
MEMBER = {"email": "ben@hoofbeat.example", "display_name": "Ben Member"}
PHONE = {"width": 390, "height": 844}
DESKTOP = {"width": 1280, "height": 900}


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """An empty `saddlescope serve`: its base URL and storage folder."""
    sync_playwright = _require_browser()
    with serve_fresh(tmp_path_factory.mktemp("account-pages")) as server, \
            chromium_for_module(sync_playwright) as chromium:
        yield {"base": server.base, "storage": str(server.storage_dir), "browser": chromium}


def new_tab(served, viewport=DESKTOP):
    """A page in a fresh browser context (its own cookies), recording console errors."""
    context = served["browser"].new_context(base_url=served["base"], viewport=viewport)
    tab = context.new_page()
    tab.console = Console()
    tab.console.attach(tab)
    tab.set_default_timeout(15_000)
    tab.on("dialog", lambda dialog: dialog.accept())  # the confirmations of disable, reset, sign-out
    return tab


def loaded(tab, heading: str) -> None:
    tab.get_by_role("heading", level=1, name=heading).wait_for()
    tab.locator("main:not([aria-busy])").wait_for()


def shoot(tab, name: str) -> None:
    """Screenshots at 1280 and 390 px; at 390 px the page must not scroll sideways."""
    SHOTS.mkdir(parents=True, exist_ok=True)
    size = tab.viewport_size
    for width, viewport in (("1280", DESKTOP), ("390", PHONE)):
        tab.set_viewport_size(viewport)
        tab.wait_for_timeout(150)  # Plotly and the grid settle after a resize
        tab.screenshot(path=str(SHOTS / f"{name}-{width}.png"), full_page=True)
        if width == "390":
            widths = tab.evaluate("[document.documentElement.scrollWidth, innerWidth]")
            assert widths[0] <= widths[1], f"{name} scrolls sideways at 390 px: {widths}"
    tab.set_viewport_size(size)


def sign_in_page(tab, email: str, password: str) -> None:
    tab.goto("/#/login")
    loaded(tab, "Sign in")
    tab.locator("#login-email").fill(email)
    tab.locator("#login-password").fill(password)
    tab.get_by_role("button", name="Sign in", exact=True).click()
    tab.wait_for_url("**/#/")
    loaded(tab, "Overview")


def api_status(served, email: str, password: str) -> int:
    return httpx.post(f"{served['base']}/api/auth/login", json={"email": email, "password": password}).status_code


def test_a_club_admin_brings_in_a_member_who_sets_and_changes_a_password(served):
    admin = new_tab(served)
    admin.goto("/#/login")
    loaded(admin, "Sign in")
    shoot(admin, "login")
    for field, value in (("#club-name", ADMIN["club_name"]), ("#club-display", ADMIN["display_name"]),
                         ("#club-email", ADMIN["email"]), ("#club-password", ADMIN["password"])):
        admin.locator(field).fill(value)
    admin.get_by_role("button", name="Create club and sign in").click()
    admin.wait_for_url("**/#/start")  # a new club lands on "Getting started"
    loaded(admin, "Getting started")
    assert admin.locator(".layout-drawing").is_visible()  # the cameras and markers drawn
    shoot(admin, "getting-started")

    # A new club's overview says what to do first; the admin sees the health details.
    admin.goto("/#/")
    loaded(admin, "Overview")
    steps = admin.locator("[data-getting-started]")
    steps.wait_for(state="visible")
    assert [a.get_attribute("href") for a in steps.locator("a").all()] == [
        "#/start", "#/rigs", "#/horses", "#/riders", "#/upload"]
    admin.locator("[data-health-details]").wait_for(state="visible")
    assert admin.locator("[data-health-summary]").inner_text() == "Service OK"
    assert served["storage"] in admin.locator("[data-health-table]").inner_text()
    shoot(admin, "overview-admin")

    # Add a member with a one-time link; the link is shown with a copy button.
    admin.get_by_role("link", name=f"{ADMIN['display_name']} \u00b7 {ADMIN['club_name']}").click()
    loaded(admin, "Your account")
    admin.locator("#member-email").fill(MEMBER["email"])
    admin.locator("#member-name").fill(MEMBER["display_name"])
    admin.get_by_role("button", name="Add member").click()
    box = admin.locator("[data-reset-box]")
    box.wait_for(state="visible")
    link = admin.locator("[data-reset-link]").input_value()
    assert link.startswith(f"{served['base']}/#/reset-password?token=")
    assert MEMBER["display_name"] in box.inner_text()
    admin.get_by_role("button", name="Copy link").click()
    admin.get_by_role("button", name="Copied").or_(admin.get_by_role("button", name="Select and copy it")).wait_for()
    row = admin.locator(f'[data-members-table] tr[data-email="{MEMBER["email"]}"]')
    row.wait_for()
    assert "active" in row.inner_text()
    shoot(admin, "account-admin")

    # The member opens the link in a browser of their own and sets a password.
    member = new_tab(served)
    member.goto(link.removeprefix(served["base"]))
    loaded(member, "Set a new password")
    shoot(member, "reset-password")
    member.locator("#reset-new").fill("ben's own password")
    member.locator("#reset-repeat").fill("ben's other password")
    member.get_by_role("button", name="Set password").click()
    member.locator("[data-reset-form] [data-form-error]").filter(has_text="differ").wait_for()
    member.locator("#reset-repeat").fill("ben's own password")
    member.get_by_role("button", name="Set password").click()
    member.locator("[data-reset-done]").wait_for(state="visible")
    assert "token" not in member.url  # the spent link left the address bar
    member.goto(link.removeprefix(served["base"]))  # used once: refused with the reason
    loaded(member, "Set a new password")
    member.locator("#reset-new").fill("another password")
    member.locator("#reset-repeat").fill("another password")
    member.get_by_role("button", name="Set password").click()
    member.locator("[data-reset-form] [data-form-error]").filter(has_text="already used").wait_for()

    # Signed in, the member sees one health line, no details, and no members section or admin control.
    sign_in_page(member, MEMBER["email"], "ben's own password")
    summary = member.locator("[data-health-summary]")
    summary.filter(has_text="Service OK").wait_for()
    assert member.locator("[data-health-details]").is_hidden()
    assert served["storage"] not in member.content()
    shoot(member, "overview-member")
    member.goto("/#/account")
    loaded(member, "Your account")
    assert member.locator("[data-members]").count() == 0
    assert member.locator("[data-permission]").count() == 0
    assert "member of Hoofbeat Riding Club" in member.locator("[data-account-who]").inner_text()
    shoot(member, "account-member")

    # The member changes the password and stays signed in; the old one stops working.
    member.locator("#pw-current").fill("ben's own password")
    member.locator("#pw-new").fill("ben's newer password")
    member.locator("#pw-repeat").fill("ben's newer password")
    member.get_by_role("button", name="Change password").click()
    member.locator("[data-password-form] [data-form-ok]").wait_for(state="visible")
    member.reload()
    loaded(member, "Your account")  # still signed in (the guard would have sent us to sign in)
    assert api_status(served, MEMBER["email"], "ben's own password") == 401
    assert api_status(served, MEMBER["email"], "ben's newer password") == 200

    # The last admin cannot make themselves a member: the server's reason is shown, the role stays.
    admin.reload()
    loaded(admin, "Your account")
    mine = admin.locator(f'[data-members-table] tr[data-email="{ADMIN["email"]}"]')
    mine.get_by_label(f"Role of {ADMIN['display_name']}").select_option("member")
    error = admin.locator("[data-members-error]")
    error.wait_for(state="visible")
    assert "last active admin" in error.inner_text()
    assert mine.get_by_label(f"Role of {ADMIN['display_name']}").input_value() == "admin"

    # Disabling the member signs them out and refuses their sign-in; enabling lets them back.
    row.get_by_role("button", name="Disable").click()
    row.filter(has_text="disabled").wait_for()
    assert api_status(served, MEMBER["email"], "ben's newer password") == 401
    row.get_by_role("button", name="Enable").click()
    row.filter(has_text="active").wait_for()
    assert api_status(served, MEMBER["email"], "ben's newer password") == 200

    # With a second admin, an admin may step down: the members section goes at once.
    row.get_by_label(f"Role of {MEMBER['display_name']}").select_option("admin")
    admin.locator("[data-announcer]").filter(has_text=f"{MEMBER['display_name']} changed.").wait_for(state="attached")
    mine.get_by_label(f"Role of {ADMIN['display_name']}").select_option("member")
    admin.locator("[data-members]").wait_for(state="detached")
    loaded(admin, "Your account")
    assert admin.locator("[data-permission]").count() == 0
    with httpx.Client(base_url=served["base"], timeout=30) as api:  # Ben, now an admin, gives it back
        token = _ok(api.post("/api/auth/login", json={"email": MEMBER["email"], "password": "ben's newer password"}))
        api.cookies.clear()
        api.headers["Authorization"] = f"Bearer {token['access_token']}"
        anna = next(u for u in _ok(api.get("/api/users"))["items"] if u["email"] == ADMIN["email"])
        _ok(api.patch(f"/api/users/{anna['id']}", json={"role": "admin"}))

    assert admin.console.unexpected(409) == []
    assert member.console.unexpected(401) == []
    admin.context.close()
    member.context.close()


def test_members_are_paged_and_the_phone_menu_works_by_keyboard(served):
    with httpx.Client(base_url=served["base"], timeout=30) as api:
        token = _ok(api.post("/api/auth/login", json={"email": ADMIN["email"], "password": ADMIN["password"]}))
        api.cookies.clear()
        api.headers["Authorization"] = f"Bearer {token['access_token']}"
        total = _ok(api.get("/api/users"))["total"]
        for n in range(22 - total):
            _ok(api.post("/api/users", json={"email": f"rider{n:02d}@hoofbeat.example", "password": "a password 1"}))
    tab = new_tab(served, PHONE)
    sign_in_page(tab, ADMIN["email"], ADMIN["password"])

    # The phone header: a Menu button (nav folded away), opened and shut from the keyboard.
    toggle = tab.get_by_role("button", name="Menu")
    assert tab.locator("[data-nav]").is_hidden()
    toggle.focus()
    tab.keyboard.press("Enter")
    assert toggle.get_attribute("aria-expanded") == "true"
    tab.get_by_role("link", name="Rides", exact=True).wait_for(state="visible")
    tab.screenshot(path=str(SHOTS / "menu-open-390.png"), full_page=True)
    tab.keyboard.press("Escape")
    assert tab.locator("[data-nav]").is_hidden() and toggle.get_attribute("aria-expanded") == "false"
    tab.keyboard.press("Enter")
    tab.get_by_role("link", name=f"{ADMIN['display_name']} \u00b7 {ADMIN['club_name']}").click()
    loaded(tab, "Your account")
    assert tab.locator("[data-nav]").is_hidden()  # following a link shuts the menu

    info = tab.locator("[data-page-info]")
    info.filter(has_text="1\u201320 of 22").wait_for()
    assert tab.locator("[data-members-table] tbody tr").count() == 20
    assert tab.evaluate("document.documentElement.scrollWidth <= innerWidth")
    tab.get_by_role("button", name="Next").click()
    info.filter(has_text="21\u201322 of 22").wait_for()
    assert tab.locator("[data-members-table] tbody tr").count() == 2

    # With a horse, a rider and rides (no rig yet) the overview still shows the rig step, the rest
    # ticked, and its rides table scrolls inside its own box on a phone.
    with httpx.Client(base_url=served["base"], timeout=30, headers=api.headers) as api:
        horse = _ok(api.post("/api/horses", json={"name": "Comet"}))["id"]
        rider = _ok(api.post("/api/riders", json={"name": "Rider A"}))["id"]
        for gait in ("walk", "canter"):
            _ok(api.post("/api/rides", json={"horse_id": horse, "rider_id": rider, "gait": gait,
                                             "direction": "CW"}))
    tab.goto("/#/")
    loaded(tab, "Overview")
    tab.locator("[data-ride-table] tbody tr").first.wait_for()
    steps = tab.locator("[data-getting-started]")
    assert steps.is_visible()
    assert [s.get_attribute("data-step") for s in steps.locator("li.done").all()] == ["horse", "ride"]
    shoot(tab, "overview-with-rides")
    assert tab.console.unexpected() == []
    tab.context.close()


def test_the_sign_in_page_says_refusals_in_plain_sentences(served):
    tab = new_tab(served)
    try:
        tab.goto("/#/login")
        loaded(tab, "Sign in")
        for field, value in (("#club-name", "Short Password Club"), ("#club-email", "not-an-address"),
                             ("#club-password", "short")):
            tab.locator(field).fill(value)
        tab.get_by_role("button", name="Create club and sign in").click()
        error = tab.locator("[data-register-form] [data-form-error]")
        error.wait_for(state="visible")
        text = error.inner_text()
        assert text == "The password needs at least 8 characters.", text
        tab.locator("#club-password").fill("long enough password")
        tab.get_by_role("button", name="Create club and sign in").click()
        tab.wait_for_function("""() => {  // the next refusal, not the moment the old one is cleared
            const text = document.querySelector('[data-register-form] [data-form-error]').textContent;
            return text.trim() !== '' && !text.includes('password'); }""")
        text = error.inner_text()
        assert text == "'not-an-address' is not an e-mail address.", text
        assert not any(raw in text for raw in ("body.", "String should", "loc")), text

        tab.locator("#login-email").fill("nobody@club.example")
        tab.locator("#login-password").fill("a wrong password")
        tab.locator("[data-login-form]").get_by_role("button", name="Sign in").click()
        refused = tab.locator("[data-login-form] [data-form-error]")
        refused.wait_for(state="visible")
        sentence = refused.inner_text()
        assert sentence[0].isupper() and sentence.endswith("."), sentence
        assert tab.console.unexpected(401, 422) == []
    finally:
        tab.context.close()

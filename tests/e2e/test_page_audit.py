"""Every page of the dashboard, audited in Debian's chromium: as an admin and as a member, at 1280 and
390 px wide.

The pages are discovered, not listed: every `route("...")` registered in frontend/app.js is visited,
its `:params` filled with the ids of what was seeded (by the path segment before them: `rides`,
`horses`, `riders`, `rigs`, `jobs`, `users`, `compare-rides`). A route with a parameter this file
cannot fill fails the audit, naming it, so a new page is never skipped silently. Routes registered
with `auth: false` (sign-in, password reset) are audited signed out.

On every page: no console error, no "null" / "undefined" / "NaN" in its text, no sideways scroll at 390 px, no
serious or critical axe-core violation (WCAG 2 A/AA and best practice), a screenshot in
var/test-artifacts/screenshots/. For the member also: every visible `[data-permission]` control is one their
`/api/auth/me` permissions allow ("all", or "own" on a thing they made: the control's closest
`[data-owner-id]`, else the page's own thing), and, without relying on that attribute, no visible button
reading like delete / remove / disable / change role / cancel / retry / board unless the member holds such a
right.

All problems of all pages are collected and reported together, page by page.
"""

from __future__ import annotations

import re
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import numpy as np
import pytest
from browser_harness import (
    PHONE_WIDTH_PX,
    VISIBLE_TEXT_JS,
    assert_no_horizontal_scroll,
    axe_violations,
    console_errors,
    launch_chromium,
    missing_words,
    require_axe,
    require_browser,
    screenshot,
    serve_fresh,
    sign_in,
    visible_permission_controls,
)
from dashboard_helpers import _ok, result_document, store_result

from conftest import PROJECT_ROOT

pytestmark = [pytest.mark.browser, pytest.mark.slow]

APP_JS = PROJECT_ROOT / "frontend" / "app.js"
ADMIN = ("secretary@audit.example", "audit admin password", "Secretary")
MEMBER = ("rider@audit.example", "audit member password", "Young rider")
WIDTHS_PX = (1280, PHONE_WIDTH_PX)
# Words of buttons that need more than a member's rights, and the actions that could allow them.
RISKY_BUTTON = re.compile(r"delete|remove|disable|change role|cancel|retry|change (the )?board", re.I)
RISKY_ACTIONS = {
    "delete": ("ride.delete", "horse.delete", "rig.delete"), "remove": ("ride.delete", "horse.delete", "rig.delete"),
    "disable": ("user.manage",), "change role": ("user.manage",), "cancel": ("job.cancel",),
    "retry": ("job.retry",), "change board": ("rig.change_board",), "change the board": ("rig.change_board",),
}
# Query strings a page needs to show something (the token is refused on submit only).
ROUTE_QUERY = {"/reset-password": "?token=audit-not-a-real-token"}


# ----------------------------------------------------------------------------- routes, pure


@dataclass(frozen=True)
class Route:
    pattern: str
    auth: bool = True


def registered_routes(app_js: Path = APP_JS) -> list[Route]:
    """Every `route("pattern", mount, {...})` of the dashboard's app.js, in order."""
    text = app_js.read_text()
    routes = []
    for match in re.finditer(r'\broute\(\s*["\']([^"\']+)["\']\s*,(.*?)\)\s*;', text, re.S):
        options = match.group(2)
        routes.append(Route(match.group(1), auth=not re.search(r"\bauth\s*:\s*false\b", options)))
    return routes


def fill_route(pattern: str, ids: dict[str, list[int]]) -> str:
    """The pattern with each `:param` replaced by a seeded id: the path segment before the params
    names the kind (`/rides/:id`, `/compare-rides/:a/:b` take successive ride ids)."""
    segments = pattern.strip("/").split("/")
    kind, used = None, 0
    out = []
    for segment in segments:
        if not segment.startswith(":"):
            kind, used = segment, 0
            out.append(segment)
            continue
        choices = ids.get(kind or "", [])
        if used >= len(choices):
            raise LookupError(f"the audit cannot fill {segment} of route {pattern!r}: nothing seeded for "
                              f"{kind!r}; add it to the seeding of tests/e2e/test_page_audit.py")
        out.append(str(choices[used]))
        used += 1
    return "/" + "/".join(out)


def is_allowed(permissions: dict[str, str], action: str, owner_id: int | None, user_id: int) -> bool:
    """The dashboard's `can(action, ownerId)` (frontend/js/session.js) against /api/auth/me."""
    grant = permissions.get(action)
    return grant == "all" or (grant == "own" and owner_id is not None and owner_id == user_id)


def permission_problems(controls: list[dict], buttons: list[dict], permissions: dict[str, str], *,
                        user_id: int, page_owner_id: int | None) -> list[str]:
    """What a member must not see: `controls` from `visible_permission_controls`, `buttons` the visible
    risky-looking buttons without `data-permission` ({text})."""
    problems = []
    for control in controls:
        owner = int(control["owner_id"]) if control["owner_id"] not in (None, "") else page_owner_id
        if not is_allowed(permissions, control["action"], owner, user_id):
            problems.append(f"{control['tag']} {control['text']!r} needs {control['action']} "
                            f"(member has {permissions.get(control['action'], 'none')!r}, owner {owner})")
    for button in buttons:
        words = [w for w in RISKY_ACTIONS if re.search(w, button["text"], re.I)]
        actions = {a for w in words for a in RISKY_ACTIONS[w]}
        if not any(permissions.get(a) == "all" for a in actions):
            problems.append(f"button {button['text']!r} without data-permission: reads like "
                            f"{'/'.join(sorted(actions))}, which the member may not do")
    return problems


def test_routes_are_read_from_app_js_and_filled_with_seeded_ids(tmp_path):
    app = tmp_path / "app.js"
    app.write_text('route("/", mountHome, { title: "Overview" });\n'
                   'route("/login", mountLogin, { title: "Sign in", auth: false });\n'
                   'route("/compare-rides/:a/:b", mountRidePair,\n  { title: "Two" });\n'
                   "route('/rigs/:id', mountRig);\n")
    routes = registered_routes(app)
    assert routes == [Route("/"), Route("/login", auth=False), Route("/compare-rides/:a/:b"), Route("/rigs/:id")]
    ids = {"compare-rides": [3, 4], "rigs": [9]}
    assert [fill_route(r.pattern, ids) for r in routes] == ["/", "/login", "/compare-rides/3/4", "/rigs/9"]
    with pytest.raises(LookupError, match="nothing seeded for 'stables'"):
        fill_route("/stables/:id", ids)
    assert len(registered_routes()) >= 10  # the real app.js is read


def test_permission_problems_follow_the_members_grants():
    grants = {"ride.delete": "own", "job.retry": "own", "grade.create": "all"}  # a member's (no horse.delete)
    controls = [{"action": "ride.delete", "owner_id": "7", "tag": "button", "text": "Delete ride"},
                {"action": "ride.delete", "owner_id": None, "tag": "button", "text": "Delete ride"},
                {"action": "grade.create", "owner_id": None, "tag": "button", "text": "Save grade"},
                {"action": "horse.delete", "owner_id": None, "tag": "button", "text": "Delete horse"}]
    found = permission_problems(controls, [{"text": "Retry job 3"}, {"text": "Change role"}], grants,
                                user_id=7, page_owner_id=8)
    assert len(found) == 4  # another's ride, the horse, and the two buttons without the attribute
    assert "'Delete ride' needs ride.delete" in found[0] and "owner 8" in found[0]
    assert "Delete horse" in found[1] and "Retry job 3" in found[2] and "user.manage" in found[3]
    assert permission_problems(controls[:1] + controls[2:3], [], grants, user_id=7, page_owner_id=None) == []


def test_without_axe_core_the_audit_skips_and_under_ci_it_fails(monkeypatch, tmp_path):
    import browser_harness

    monkeypatch.setattr(browser_harness, "AXE_JS", tmp_path / "no-axe.min.js")
    monkeypatch.setattr(browser_harness, "IN_CI", False)
    with pytest.raises(pytest.skip.Exception, match="make install"):
        browser_harness.require_axe()
    monkeypatch.setattr(browser_harness, "IN_CI", True)
    with pytest.raises(pytest.fail.Exception, match="required under CI"):
        browser_harness.require_axe()


# ----------------------------------------------------------------------------- a seeded club


def _client(base: str, email: str, password: str) -> httpx.Client:
    api = httpx.Client(base_url=base, timeout=30)
    token = _ok(api.post("/api/auth/login", json={"email": email, "password": password}))["access_token"]
    api.cookies.clear()  # bearer only: no CSRF needed
    api.headers["Authorization"] = f"Bearer {token}"
    return api


def _seed(base: str, database_url: str, storage_dir: Path) -> dict:
    """A club with an admin and a member, a horse, a rider, a rig, analysed rides (the member made
    one), a grade and a failed job; returns the ids by the route segment that shows them."""
    rng = np.random.default_rng(23)
    email, password, name = ADMIN
    _ok(httpx.post(f"{base}/api/clubs", json={"club_name": "Audit Riding Club", "email": email,
                                              "password": password, "display_name": name}, timeout=30))
    with closing(_client(base, email, password)) as admin:
        member = _ok(admin.post("/api/users", json={"email": MEMBER[0], "password": MEMBER[1],
                                                    "display_name": MEMBER[2], "role": "member"}))
        rider = _ok(admin.post("/api/riders", json={"name": "Anna"}))["id"]
        horse = _ok(admin.post("/api/horses", json={"name": "Bella", "breed": "Dutch"}))["id"]
        saddle = _ok(admin.post("/api/saddles", json={"name": "Bella's GP", "saddle_type": "gp"}))["id"]
        rig = _ok(admin.post("/api/rigs", json={"name": "Arena rig", "board": {
            "inner_corners": [9, 6], "square_mm": 25.0}}))["id"]
        rides = []
        for gait in ("canter", "walk"):
            ride = _ok(admin.post("/api/rides", json={"horse_id": horse, "rider_id": rider, "gait": gait,
                                                      "direction": "CCW", "saddle_id": saddle}))["id"]
            store_result(database_url, storage_dir, ride, result_document(scale=1.0, gait=gait, rng=rng))
            rides.append(ride)
        _ok(admin.post("/api/grades", json={"ride_id": rides[0], "rider_id": rider, "grade": 4}))
        job = _ok(admin.post("/api/jobs", json={"kind": "selftest", "payload": {"steps": 1, "fail": True}}))["id"]
        # a ride whose analysis is queued or running (its page shows the job's progress)
        waiting_ride = _ok(admin.post("/api/rides", json={"horse_id": horse, "rider_id": rider, "gait": "sitting_trot",
                                                          "direction": "CW"}))["id"]
        _ok(admin.post("/api/jobs", json={"kind": "selftest", "ride_id": waiting_ride,
                                          "payload": {"steps": 1000, "delay_s": 5}}))
    with closing(_client(base, MEMBER[0], MEMBER[1])) as as_member:
        own_ride = _ok(as_member.post("/api/rides", json={"horse_id": horse, "rider_id": rider,
                                                          "gait": "canter", "direction": "CW"}))["id"]
    store_result(database_url, storage_dir, own_ride, result_document(scale=1.2, gait="canter", rng=rng))
    return {
        "ids": {"rides": rides, "compare-rides": [rides[0], own_ride], "horses": [horse], "riders": [rider],
                "saddles": [saddle], "rigs": [rig], "jobs": [job], "users": [member["id"]]},
        "member_ride": own_ride, "member_id": member["id"], "waiting_ride": waiting_ride,
    }


@pytest.fixture(scope="module")
def club(tmp_path_factory):
    require_browser()
    require_axe()
    with serve_fresh(tmp_path_factory.mktemp("audit")) as served:
        yield {"base": served.base, "log": served.log, **_seed(served.base, served.database_url, served.storage_dir)}


# ----------------------------------------------------------------------------- the audit


@dataclass
class Visit:
    """One page to audit: its URL path, a screenshot name and whose thing it shows."""

    path: str
    name: str
    owner_id: int | None = None
    problems: list[str] = field(default_factory=list)


def _visits(routes: list[Route], club: dict) -> list[Visit]:
    visits = []
    for route in routes:
        try:
            path = fill_route(route.pattern, club["ids"])
        except LookupError as exc:
            visits.append(Visit(route.pattern, "unfillable", problems=[str(exc)]))
            continue
        query = ROUTE_QUERY.get(route.pattern, "")
        name = route.pattern.strip("/").replace("/:", "-").replace("/", "-").replace(":", "") or "overview"
        visits.append(Visit(path + query, name))
        if route.pattern.startswith("/rides/:"):  # the member's own ride too: "own" controls show there
            own = path.replace(f"/{club['ids']['rides'][0]}", f"/{club['member_ride']}", 1)
            visits.append(Visit(own + query, f"{name}-own", owner_id=club["member_id"]))
            waiting = path.replace(f"/{club['ids']['rides'][0]}", f"/{club['waiting_ride']}", 1)
            visits.append(Visit(waiting + query, f"{name}-waiting"))
    return visits


RISKY_BUTTONS_JS = """(pattern) => [...document.querySelectorAll(
      'main button, main input[type=button], main input[type=submit], main [role=button], header button')]
    .filter(el => !el.closest('[data-permission]'))
    .filter(el => el.checkVisibility ? el.checkVisibility() : el.offsetParent !== null)
    .map(el => ({text: (el.innerText || el.value || el.getAttribute('aria-label') || '').trim()}))
    .filter(b => new RegExp(pattern, 'i').test(b.text))"""

READY_JS = """() => { const v = document.querySelector('[data-view]');
    return v && !v.hasAttribute('aria-busy') && v.children.length > 0 && !v.querySelector('[data-audit-stale]'); }"""


class InFlight:
    """The page's requests not yet answered (to wait until a page has its data and drew it)."""

    def __init__(self, page) -> None:
        self.open: set = set()
        page.on("request", lambda request: self.open.add(request))
        page.on("requestfinished", lambda request: self.open.discard(request))
        page.on("requestfailed", lambda request: self.open.discard(request))

    def wait_quiet(self, page, quiet_ms: int = 300, timeout_ms: int = 5_000) -> None:
        """Until no request has been open for `quiet_ms` (a page that polls gets `timeout_ms` at most)."""
        waited = quiet = 0
        while quiet < quiet_ms and waited < timeout_ms:
            page.wait_for_timeout(50)
            waited += 50
            quiet = quiet + 50 if not self.open else 0


def _open(page, base: str, path: str, in_flight: InFlight) -> None:
    """Go to the page as a user does (the hash changes; the dashboard is loaded once per role and
    width) and wait until it rendered and its requests are answered. A marker in the old view tells
    the old page from the new one: the router empties the view before it mounts the next page."""
    url = f"{base}/#{path}"
    if page.url == url:  # the same hash again (a new width): no hashchange, so load it afresh
        page.reload()
    else:
        if page.url.startswith(base):
            page.evaluate("() => { const i = document.createElement('i'); i.hidden = true;"
                          " i.setAttribute('data-audit-stale', '');"
                          " document.querySelector('[data-view]')?.append(i); }")
        page.goto(url)
    page.wait_for_function(READY_JS)
    in_flight.wait_quiet(page)


def _audit(page, errors: list[str], in_flight: InFlight, base: str, visit: Visit, role: str, width: int,
           me: dict | None) -> None:
    where = f"{visit.path} as {role} at {width} px"
    errors.clear()
    try:
        _open(page, base, visit.path, in_flight)
    except Exception as exc:  # a page that never finishes loading is a finding, not the end of the audit
        visit.problems.append(f"{where}: did not finish loading ({str(exc).splitlines()[0]})")
        screenshot(page, f"{role}-{visit.name}")
        return
    if me is not None and "/login" in page.url and not visit.path.startswith("/login"):
        visit.problems.append(f"{where}: sent to the sign-in page")
    screenshot(page, f"{role}-{visit.name}")
    visit.problems += [f"{where}: console: {e}" for e in errors]
    visit.problems += [f"{where}: shows {line!r}" for line in missing_words(page.evaluate(VISIBLE_TEXT_JS))]
    if width == PHONE_WIDTH_PX:
        try:
            assert_no_horizontal_scroll(page)
        except AssertionError as exc:
            visit.problems.append(f"{where}: {exc}")
    for v in axe_violations(page):
        visit.problems.append(f"{where}: axe {v['impact']} {v['id']} ({v['help']}): {v['nodes'][:4]}")
    if role == "member" and me is not None:
        buttons = page.evaluate(RISKY_BUTTONS_JS, RISKY_BUTTON.pattern)
        found = permission_problems(visible_permission_controls(page), buttons, me["permissions"],
                                    user_id=me["user"]["id"], page_owner_id=visit.owner_id)
        visit.problems += [f"{where}: member sees {p}" for p in found]


def test_every_page_as_admin_and_member_on_desktop_and_phone(club):
    routes = registered_routes()
    signed_in = _visits([r for r in routes if r.auth], club)
    signed_out = _visits([r for r in routes if not r.auth], club)
    manager = require_browser()().start()
    browser = launch_chromium(manager)
    try:
        for role, account in (("signed-out", None), ("admin", ADMIN), ("member", MEMBER)):
            context = browser.new_context(base_url=club["base"], viewport={"width": WIDTHS_PX[0], "height": 900})
            page = context.new_page()
            page.set_default_timeout(30_000)
            page.set_default_navigation_timeout(90_000)  # the first load parses Plotly: slow on a busy machine
            errors, in_flight = console_errors(page), InFlight(page)
            me = None
            if account is not None:
                sign_in(page, account[0], account[1])
                me = page.context.request.get("/api/auth/me").json()
            for width in WIDTHS_PX:
                page.set_viewport_size({"width": width, "height": 900 if width > 600 else 844})
                for visit in signed_in if account else signed_out:
                    if visit.name != "unfillable":
                        _audit(page, errors, in_flight, club["base"], visit, role, width, me)
            context.close()
    finally:
        browser.close()
        manager.stop()
    problems = [p for visit in signed_out + signed_in for p in visit.problems]
    pages = ", ".join(v.path for v in signed_out + signed_in)
    assert not problems, f"{len(problems)} problems on the dashboard's pages ({pages}):\n" + "\n".join(problems)


# ----------------------------------------------------------------------------- the browser's security headers

SECURITY_HEADERS = ("content-security-policy", "x-frame-options", "x-content-type-options", "referrer-policy",
                    "permissions-policy")
# Recorded from the first script of every document on: what the Content-Security-Policy refused.
CSP_RECORDER = """window.__cspViolations = [];
document.addEventListener('securitypolicyviolation', (e) => window.__cspViolations.push(
  `${e.violatedDirective} refused ${e.blockedURI || 'inline'} (${e.sourceFile}:${e.lineNumber})`));"""


def test_pages_run_under_the_content_security_policy_and_cannot_be_framed(club):
    base, ride = club["base"], club["ids"]["rides"][0]
    with closing(_client(base, *ADMIN[:2])) as admin:
        answers = {path: admin.get(path) for path in ("/", "/app.js", "/style.css", "/api/health", "/api/rides",
                                                       f"/api/rides/{ride}/report", "/api/rides/999999")}
    for path, answer in answers.items():
        missing = [h for h in SECURITY_HEADERS if h not in answer.headers]
        assert not missing, f"{path} ({answer.status_code}) lacks {missing}"
        assert "frame-ancestors 'none'" in answer.headers["content-security-policy"], path
        directives = dict(d.strip().split(" ", 1) for d in answer.headers["content-security-policy"].split(";"))
        assert "unsafe" not in directives.get("script-src", "'none'"), path  # no inline script, no eval
        assert answer.headers["x-frame-options"] == "DENY" and answer.headers["x-content-type-options"] == "nosniff"
    manager = require_browser()().start()
    browser = launch_chromium(manager)
    try:
        context = browser.new_context(base_url=base, viewport={"width": 1280, "height": 900})
        context.add_init_script(CSP_RECORDER)
        page = context.new_page()
        page.set_default_navigation_timeout(90_000)
        errors, in_flight = console_errors(page), InFlight(page)
        sign_in(page, ADMIN[0], ADMIN[1])
        problems, charts = [], 0
        for path in ("/", "/rides", f"/rides/{ride}", f"/horses/{club['ids']['horses'][0]}", "/upload",
                     f"/rigs/{club['ids']['rigs'][0]}", "/leaderboard"):
            errors.clear()
            _open(page, base, path, in_flight)
            problems += [f"{path}: {v}" for v in page.evaluate("window.__cspViolations")]
            problems += [f"{path}: console: {e}" for e in errors]
            charts += page.evaluate("document.querySelectorAll('.js-plotly-plot').length")
        page.goto(f"{base}/api/rides/{ride}/report")  # the cookie signs it in
        problems += [f"report: {v}" for v in page.evaluate("window.__cspViolations")]
        assert page.evaluate("getComputedStyle(document.body).fontFamily").startswith('"DejaVu Sans"')  # styled
        # A page of another origin framing the dashboard gets Chromium's error page, not the signed-in page.
        page.goto("about:blank")
        page.set_content(f'<iframe src="{base}/#/rides" width="800" height="600"></iframe>', wait_until="load")
        framed = page.frames[1]
        assert framed.url.startswith("chrome-error://"), framed.url
        context.close()
    finally:
        browser.close()
        manager.stop()
    assert charts > 0, "the ride's page drew no Plotly chart"
    assert not problems, "\n".join(problems)

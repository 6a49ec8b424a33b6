"""The browser tests' shared harness: a fresh `saddlescope serve`, Debian's chromium, and page checks.

- `serve_fresh(root)`: a real `saddlescope serve` (embedded mode) on a free port with an EMPTY
  SQLite database and storage in `root`; yields a `Served` (base URL, database URL, storage, log).
- `require_browser()`: Playwright's `sync_playwright`, or a skip with the reason (a failure under
  CI=true) where /usr/bin/chromium or playwright is missing; `launch_chromium(manager)` starts it.
- Page checks: `console_errors(page)` (a live list of console errors and uncaught exceptions),
  `assert_no_horizontal_scroll(page)`, `axe_violations(page)` (axe-core from the npm registry,
  installed by `make install` into .cache/npm), `screenshot(page, name)`, `sign_in(page, ...)`,
  `plotly_traces(page, selector)` and `visible_permission_controls(page)`.

No browser and no npm package is ever downloaded by the tests themselves.
"""

from __future__ import annotations

import re
import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import httpx
import integration_services
import pytest

from conftest import IN_CI, PROJECT_ROOT

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                 "--disable-background-networking"]
SADDLESCOPE = str(integration_services.VENV_BIN / "saddlescope")
AXE_VERSION = "4.10.3"  # the Makefile's AXE_VERSION
AXE_JS = PROJECT_ROOT / ".cache" / "npm" / "node_modules" / "axe-core" / "axe.min.js"
AXE_RULE_SETS = ["wcag2a", "wcag2aa", "best-practice"]
SCREENSHOTS = PROJECT_ROOT / "var" / "test-artifacts" / "screenshots"
PHONE_WIDTH_PX = 390


def fail_or_skip(reason: str, *, in_ci: bool | None = None) -> None:
    """Skip with the reason; under CI=true a missing tool is a failure instead."""
    if IN_CI if in_ci is None else in_ci:
        pytest.fail(f"{reason} (required under CI)")
    pytest.skip(reason)


def require_browser(chromium: Path = CHROMIUM, *, in_ci: bool | None = None):
    """Playwright's `sync_playwright`, or skip (fail under CI) naming what is missing."""
    if not chromium.exists():
        fail_or_skip(f"{chromium} is missing: install Debian's chromium (apt-get install chromium) "
                     "to run the dashboard's browser tests", in_ci=in_ci)
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        fail_or_skip("the python package playwright is not installed", in_ci=in_ci)
    return sync_playwright


def launch_chromium(manager, *extra_args: str):
    """Debian's chromium, headless, through a started Playwright `manager`."""
    return manager.chromium.launch(executable_path=str(CHROMIUM), args=[*CHROMIUM_ARGS, *extra_args])


# ----------------------------------------------------------------------------- a fresh server


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_healthy(base: str, proc: subprocess.Popen, log_path: Path, timeout_s: float = 60.0) -> None:
    """Wait until the server answers /api/health (200 or 503); fail with its log if it dies or hangs."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"saddlescope serve exited with {proc.returncode}:\n{log_path.read_text()[-3000:]}")
        try:
            if httpx.get(f"{base}/api/health", timeout=5).status_code in (200, 503):
                return
        except httpx.TransportError:
            time.sleep(0.2)
    pytest.fail(f"saddlescope serve did not answer within {timeout_s} s:\n{log_path.read_text()[-3000:]}")


@dataclass(frozen=True)
class Served:
    """A running `saddlescope serve` of a test."""

    base: str
    database_url: str
    storage_dir: Path
    log: Path
    process: subprocess.Popen


@contextmanager
def serve_fresh(root: Path, startup_timeout_s: float = 240.0, extra_env: dict[str, str] | None = None
                ) -> Iterator[Served]:
    """`saddlescope serve` on a free port with an empty SQLite database and storage under `root`
    (a generous start-up time: the machine running the tests may be busy); `extra_env` adds to or
    overrides its environment (e.g. object storage)."""
    database_url = f"sqlite:///{root / 'var' / 'db.sqlite'}"
    storage_dir = root / "var" / "storage"
    env = integration_services.service_env(database_url=database_url, storage_dir=storage_dir)
    env.update(extra_env or {})
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    log_path = root / "serve.log"
    with log_path.open("wb") as log:
        proc = subprocess.Popen([SADDLESCOPE, "serve", "--host", "127.0.0.1", "--port", str(port)], cwd=root,
                                env=env, stdout=log, stderr=subprocess.STDOUT)
    try:
        wait_healthy(base, proc, log_path, startup_timeout_s)
        yield Served(base, database_url, storage_dir, log_path, proc)
    finally:
        integration_services.stop_process(proc)


@contextmanager
def chromium_for_module(sync_playwright=None, extra_args: tuple[str, ...] = ()) -> Iterator:
    """Debian's chromium for a module's tests (skip, or fail under CI, where it is missing)."""
    manager = (sync_playwright or require_browser())().start()
    try:
        chromium = launch_chromium(manager, *extra_args)
        try:
            yield chromium
        finally:
            chromium.close()
    finally:
        manager.stop()


@contextmanager
def new_club_admin(base: str, *, club_name: str, email: str, password: str, display_name: str | None = None
                   ) -> Iterator[httpx.Client]:
    """Found a club on a fresh server; yields a bearer-token client of its admin (no cookies, so no
    CSRF token is needed), closed at the end."""
    founding = {"club_name": club_name, "email": email, "password": password}
    if display_name is not None:
        founding["display_name"] = display_name
    with httpx.Client(base_url=base, timeout=30) as api:
        created = api.post("/api/clubs", json=founding)
        assert created.status_code == 201, created.text
        login = api.post("/api/auth/login", json={"email": email, "password": password})
        assert login.status_code == 200, login.text
        api.cookies.clear()
        api.headers["Authorization"] = f"Bearer {login.json()['access_token']}"
        yield api


# ----------------------------------------------------------------------------- page checks


def console_errors(page) -> list[str]:
    """A list that fills with the page's console errors and uncaught exceptions from now on
    (clear it with `.clear()` between pages)."""
    errors: list[str] = []
    page.on("console", lambda msg: errors.append(msg.text) if msg.type == "error" else None)
    page.on("pageerror", lambda exc: errors.append(f"uncaught: {exc}"))
    return errors


def horizontal_overflow_px(page) -> int:
    """How far the document is wider than the window (0 when nothing scrolls sideways)."""
    return page.evaluate("Math.max(0, document.documentElement.scrollWidth - window.innerWidth)")


def widest_elements(page, limit: int = 5) -> list[str]:
    """The elements reaching furthest past the window's right edge (to name the culprit); those inside
    a box that scrolls or clips (overflow-x other than visible) are left out: they do not widen the page."""
    return page.evaluate(
        """(limit) => {
             const clipped = (el) => {
               if (['absolute', 'fixed'].includes(getComputedStyle(el).position)) return false;  // may escape
               for (let p = el.parentElement; p && p !== document.body; p = p.parentElement)
                 if (getComputedStyle(p).overflowX !== 'visible') return true;
               return false; };
             return [...document.querySelectorAll('body *')]
               .map(el => [el, el.getBoundingClientRect().right])
               .filter(([el, right]) => right > window.innerWidth + 1 && el.offsetParent !== null && !clipped(el))
               .sort((a, b) => b[1] - a[1]).slice(0, limit)
               .map(([el, right]) => {
                 const cls = typeof el.className === 'string' && el.className.trim()
                   ? '.' + el.className.trim().split(/\\s+/).join('.') : '';
                 return `${el.tagName.toLowerCase()}${el.id ? '#' + el.id : ''}${cls} right=${Math.round(right)}px`;
               }); }""", limit)


def assert_no_horizontal_scroll(page) -> None:
    """At the page's width nothing may scroll sideways: scrollWidth <= innerWidth."""
    over = horizontal_overflow_px(page)
    assert over == 0, f"{page.url} scrolls {over} px sideways at {page.viewport_size['width']} px: " \
                      f"{widest_elements(page)}"


def require_axe() -> Path:
    """axe.min.js from the checkout's npm cache, or skip (fail under CI) saying how to get it."""
    if not AXE_JS.exists():
        fail_or_skip(f"axe-core is not installed at {AXE_JS}: run `make install` (it runs "
                     f"`npm install --prefix .cache/npm axe-core@{AXE_VERSION}`; needs npm)")
    return AXE_JS


def axe_violations(page, impacts: tuple[str, ...] = ("serious", "critical")) -> list[dict]:
    """axe-core's violations of WCAG 2 A/AA and best practice with one of `impacts`, each as
    {id, impact, help, nodes: [target selector, ...]} (axe is injected once per document)."""
    if not page.evaluate("typeof window.axe !== 'undefined'"):
        # Evaluated through the DevTools protocol, which the page's Content-Security-Policy does not
        # govern (a <script> tag added to the page would be refused by it: no inline script).
        page.evaluate(require_axe().read_text() + "\n;undefined")
    found = page.evaluate("(sets) => axe.run(document, {runOnly: sets}).then(r => r.violations.map(v => "
                          "({id: v.id, impact: v.impact, help: v.help,"
                          "  nodes: v.nodes.map(n => n.target.join(' '))})))", AXE_RULE_SETS)
    return [v for v in found if v["impact"] in impacts]


def screenshot(page, name: str) -> Path:
    """A full-page PNG at var/test-artifacts/screenshots/<name>-<width>.png."""
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    path = SCREENSHOTS / f"{name}-{page.viewport_size['width']}.png"
    page.screenshot(path=str(path), full_page=True)
    return path


def sign_in(page, email: str, password: str) -> None:
    """Sign in through the page context's own API client (the session cookies are the page's)."""
    answer = page.context.request.post("/api/auth/login", data={"email": email, "password": password})
    assert answer.ok, answer.text()


def plotly_traces(page, selector: str) -> list[dict]:
    """The traces Plotly drew in `selector` (its `el.data`): type, name and number of points each."""
    return page.eval_on_selector(
        selector,
        "el => (el.data || []).map(t => ({type: t.type || 'scatter', name: t.name ?? null,"
        " n: (t.y || t.z || t.values || t.x || []).length}))")


# Charts below the fold are drawn when scrolled near (js/charts.js): each poll scrolls the first chart not
# yet drawn into view, until every named one is drawn.
_SCROLL_TO_UNDRAWN_JS = """names => { const els = names.map(n => document.querySelector(`[data-chart="${n}"]`));
    const undrawn = els.filter(el => !(el && Array.isArray(el.data) && el.data.length > 0));
    if (!undrawn.length) return true;
    undrawn.find(Boolean)?.scrollIntoView({block: 'center'}); return false; }"""


def wait_for_charts_drawn(page, names, timeout_ms: float = 30_000) -> None:
    """Wait until Plotly has drawn every chart `[data-chart=name]`, scrolling each into view in turn."""
    page.wait_for_function(_SCROLL_TO_UNDRAWN_JS, arg=list(names), polling=100, timeout=timeout_ms)


def visible_permission_controls(page) -> list[dict]:
    """Visible elements carrying data-permission="<action>": action, owner id (from the closest
    [data-owner-id], else None), tag and text, so a test can check each against the role."""
    return page.evaluate(
        """() => [...document.querySelectorAll('[data-permission]')]
             .filter(el => el.checkVisibility ? el.checkVisibility() : el.offsetParent !== null)
             .map(el => ({action: el.dataset.permission,
                          owner_id: el.closest('[data-owner-id]')?.dataset.ownerId ?? null,
                          tag: el.tagName.toLowerCase(),
                          text: (el.innerText || el.value || el.getAttribute('aria-label') || '').trim()}))""")


def shoot_both_widths(page, name: str) -> None:
    """Screenshots at 1280 and 390 px (`SCREENSHOTS/<name>-<width>.png`); at 390 px nothing may scroll
    sideways. The page is left at 1280 px."""
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    page.set_viewport_size({"width": 1280, "height": 900})
    page.screenshot(path=str(SCREENSHOTS / f"{name}-1280.png"), full_page=True)
    page.set_viewport_size({"width": 390, "height": 844})
    # charts re-lay themselves out on the resize event (debounced): give them up to 3 s to settle
    try:
        page.wait_for_function("() => document.documentElement.scrollWidth <= window.innerWidth", timeout=3_000)
    except Exception:  # noqa: BLE001 - the assertion below reports the widths
        pass
    widths = page.evaluate("[document.documentElement.scrollWidth, window.innerWidth]")
    page.screenshot(path=str(SCREENSHOTS / f"{name}-390.png"), full_page=True)
    assert widths[0] <= widths[1], f"{name} scrolls sideways at 390 px: {widths}"
    page.set_viewport_size({"width": 1280, "height": 900})


# --- what a page must never show (issue #37; test_no_null_text.py, test_page_audit.py) ---------------

# JavaScript's words for a missing value, alone or glued together ("nullnullnull" is what
# replaceChildren(null, null, null) shows); not inside other words ("annulled", "Nullarbor")
MISSING_WORDS = re.compile(r"(?<![A-Za-z])(?:null|undefined|NaN)+(?![A-Za-z])")
VISIBLE_TEXT_JS = "() => (document.querySelector('main') || document.body).innerText"


def missing_words(text: str) -> list[str]:
    """The lines of `text` that show null / undefined / NaN."""
    return [line.strip() for line in text.splitlines() if MISSING_WORDS.search(line)]


# No number a page shows has more than four significant digits (issue 37: "9.9712 km/h", "0.004163 km" claim
# a precision no ride has). What counts as a number, and why the rest does not:
# - a decimal ("18.00", "0.004163", "1,234.5"): its digits less the leading zeros are significant, the
#   trailing zeros too ("18.000" claims five);
# - a plain integer ("12346"): its digits less the leading and the trailing zeros ("10000" is one digit, as
#   a rounded value shows it: format.js fmt rounds 12345.6 to "12300");
# - not an integer written with thousands separators ("1,234 rides", "10,000 h"): that is how the pages
#   write counts (toLocaleString), and a count is exact whatever its size;
# - not a part of a date ("2026-11-29", "29/11/2026", "29.11.2026"), a time ("12:30"), a version or
#   dotted number ("1.2.3"), a word or code ("a16e38d", "M1", "W_b"), an id ("#12345") or a URL (a share
#   link's port and token): each number is taken whole between separators, and URLs are taken out first.
NUMBER = re.compile(r"(?<![\w.,:/#])(\d{1,3}(?:,\d{3})+|\d+)(\.\d+)?(?![\w:/]|[.,]\d)")
URL = re.compile(r"\b[a-z][a-z0-9+.-]*://\S+|(?<![\w])[#/][\w/#?=&.-]*", re.IGNORECASE)
MAX_DIGITS = 4


def significant_digits(whole: str, fraction: str | None) -> int | None:
    """How many significant digits a number shows (None: a count with thousands separators, not checked)."""
    if fraction is None:
        return None if "," in whole else len(whole.lstrip("0").rstrip("0"))
    return len((whole.replace(",", "") + fraction.lstrip(".")).lstrip("0"))


def long_numbers(text: str) -> list[str]:
    """The lines of `text` that show a number with more than `MAX_DIGITS` significant digits."""
    found = []
    for line in text.splitlines():
        words = URL.sub(" ", line)
        if any((significant_digits(m[1], m[2]) or 0) > MAX_DIGITS for m in NUMBER.finditer(words)):
            found.append(line.strip())
    return found


__all__ = ["AXE_JS", "CHROMIUM", "CHROMIUM_ARGS", "MISSING_WORDS", "PHONE_WIDTH_PX", "SADDLESCOPE", "SCREENSHOTS",
           "Served", "VISIBLE_TEXT_JS", "assert_no_horizontal_scroll", "axe_violations", "chromium_for_module",
           "console_errors", "fail_or_skip", "free_port", "horizontal_overflow_px", "launch_chromium",
           "long_numbers", "missing_words", "new_club_admin", "plotly_traces", "require_axe", "require_browser",
           "screenshot",
           "serve_fresh", "shoot_both_widths", "sign_in", "visible_permission_controls", "wait_for_charts_drawn",
           "wait_healthy",
           "widest_elements"]

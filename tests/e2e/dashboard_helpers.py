"""The seeded dashboard the browser tests share: a `saddlescope serve` with a club, horses, riders, rides
and results built from exact Fourier series (indicators from the core), Debian's chromium through
Playwright, and the small helpers the page tests use. test_dashboard.py and the other page tests import
from here (never from each other)."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import browser_harness
import httpx
import integration_services
import numpy as np
import pytest
from browser_harness import CHROMIUM, CHROMIUM_ARGS, new_club_admin, serve_fresh

from conftest import IN_CI
from saddlescope.core.kinematics import fit_marker_kinematics
from saddlescope.core.pipeline import fits_document
from saddlescope.core.vibration import ride_indicators

EMAIL, PASSWORD = "coach@example.org", "correct horse battery"
CLUB = "Test Riding Club"

# Horse -> (scale of the vertical acceleration harmonics, rides in canter). Ranked by W_b r.m.s. in
# canter, lower (more comfortable) first: Bella, Comet, Dancer.
HORSES = {"Bella": (0.6, 1), "Comet": (1.0, 2), "Dancer": (1.4, 1)}
BASE_AMPLITUDES_M_S2 = (4.0, 1.5, 0.5)
PHASES_RAD = (0.3, -0.8, 1.2)
STRIDE_HZ = {"canter": 1.65, "walk": 0.9}
SPEED_KMH = {"canter": 18.0, "walk": 5.4}
FPS = 30.0


def _fail_or_skip(reason: str) -> None:
    browser_harness.fail_or_skip(reason, in_ci=IN_CI)


def _require_browser():
    # CHROMIUM and IN_CI are looked up here, at call time, so a test can point them elsewhere.
    return browser_harness.require_browser(CHROMIUM, in_ci=IN_CI)


def js_fmt(value: float, digits: int = 3) -> str:
    """The dashboard's number format (frontend/js/format.js `fmt`): `digits` significant digits."""
    magnitude = math.floor(math.log10(abs(value)))
    if magnitude >= digits - 1:
        return str(int(math.floor(value + 0.5)))
    return f"{value:.{digits - 1 - magnitude}f}"


# ----------------------------------------------------------------------------- seeded results


def result_document(*, scale: float, gait: str, rng: np.random.Generator) -> dict:
    """A result document (CONTRACTS section 2 plus the pipeline's extra sections) whose vertical
    saddle acceleration is an exact Fourier series; indicators from `core.vibration`."""
    f0 = STRIDE_HZ[gait]
    amps = [scale * a for a in BASE_AMPLITUDES_M_S2]
    duration_s = 2.0 / f0  # two strides, as in the thesis
    t = np.arange(int(round(duration_s * FPS))) / FPS
    k = np.arange(1, len(amps) + 1)[:, None]
    w = 2 * np.pi * k * f0
    arg = w * t + np.asarray(PHASES_RAD)[:, None]
    a = np.asarray(amps)[:, None]
    acc_y = (a * np.cos(arg)).sum(0)
    vel_y = (a / w * np.sin(arg)).sum(0)
    pos_y = (-a / w**2 * np.cos(arg)).sum(0)
    v_x = SPEED_KMH[gait] / 3.6
    sway = np.sin(2 * np.pi * f0 * t)
    position = np.stack([v_x * t, pos_y, 0.02 * sway], 1)
    velocity = np.stack([np.full_like(t, v_x), vel_y, 0.02 * 2 * np.pi * f0 * np.cos(2 * np.pi * f0 * t)], 1)
    acceleration = np.stack([np.zeros_like(t), acc_y, -0.02 * (2 * np.pi * f0) ** 2 * sway], 1)
    omega = np.stack([0.1 * sway, 0.05 * np.cos(2 * np.pi * f0 * t),
                      0.4 * np.sin(2 * np.pi * f0 * t + 0.5)], 1)
    alpha = np.gradient(omega, t, axis=0)
    versions = omega[:, None, :] + 0.03 * rng.standard_normal((t.size, 6, 3))
    excluded = np.zeros((t.size, 6), dtype=bool)
    excluded[:5, 0] = True  # version 1,ver1 left out of the first five frames (poor conditioning)
    versions[:5, 0] += 50.0  # ... where it is far off, as near the singularity
    singularity = 0.15 + 0.1 * np.abs(sway)
    amplitude_y_m = float(pos_y.max() - pos_y.min())
    # three markers around S with a millimetre of tracking noise, fitted as the pipeline does
    markers = position[:, None, :] + np.array([[0.0, -0.05, 0.1], [-0.2, -0.04, 0.1], [-0.4, -0.06, 0.1]])
    markers += rng.normal(0.0, 0.001, markers.shape)
    fits = fits_document(fit_marker_kinematics(t, markers, period_s=1.0 / f0, x_model="fourier", trend_degree=1))
    indicators = ride_indicators(f0_hz=f0, acc_y_amplitudes_m_s2=amps, acc_y_phases_rad=PHASES_RAD,
                                 duration_s=duration_s, speed_kmh=SPEED_KMH[gait],
                                 amplitude_y_m=amplitude_y_m, stride_frequency_hz=f0)
    return {
        "format": "saddlescope.result/1", "fps": FPS, "gait": gait, "direction": "CCW",
        "calibration": {"cameras": {}, "extrinsics": {}, "checks": {"board_square_error_mm": 0.31}},
        "sync": {"motion": {"left": 0.0, "middle": 53.0, "right": 126.0}},
        "period_s": 1.0 / f0, "window": {"start_s": 0.0, "duration_s": duration_s},
        "saddle": {"t_s": t.tolist(), "position_m": position.tolist(), "velocity_m_s": velocity.tolist(),
                   "acceleration_m_s2": acceleration.tolist()},
        "angular": {"omega_rad_s": omega.tolist(), "alpha_rad_s2": alpha.tolist(),
                    "singularity_index": float(np.median(singularity)),
                    "singularity_index_per_frame": singularity.tolist(),
                    "omega_versions_rad_s": versions.tolist(),
                    "omega_versions_excluded": excluded.tolist()},
        "markers": {"fits": json.loads(json.dumps(fits, allow_nan=False))},
        "indicators": {key: float(value) for key, value in indicators.items()},
        "quality": {"flags": ["markers lost from 0.40 s to 0.47 s"], "calibration_ok": True,
                    "gravity_source": "plumb", "singularity_index_median": float(np.median(singularity))},
        "timings_s": {"total": 1.0},
    }


def store_result(database_url: str, storage_dir: Path, ride_id: int, doc: dict) -> None:
    """Put a finished analysis in as the analyse stage would: result JSON in storage, row in the DB."""
    from saddlescope.db.repositories import RideRepository
    from saddlescope.db.session import make_engine, make_session_factory, session_scope
    from saddlescope.services.results.documents import commit_result
    from saddlescope.storage import FileStorage

    engine = make_engine(database_url)
    try:
        sessions = make_session_factory(engine)
        with session_scope(sessions) as session:
            club_id = RideRepository(session).get(ride_id).club_id
        commit_result(sessions, FileStorage(storage_dir), club_id=club_id, ride_id=ride_id, job_id=None,
                      document=doc, code_version="test")
    finally:
        engine.dispose()


# ----------------------------------------------------------------------------- fixtures


def _ok(response: httpx.Response, *codes: int) -> dict:
    assert response.status_code in (codes or (200, 201)), f"{response.request.url}: {response.text}"
    return response.json() if response.content else {}


@pytest.fixture(scope="module")
def sync_playwright_factory():
    return _require_browser()


@pytest.fixture(scope="module")
def dashboard(sync_playwright_factory, tmp_path_factory):
    """A seeded `saddlescope serve`: yields base URL, ids of what was seeded and the expected numbers."""
    with browser_harness.serve_fresh(tmp_path_factory.mktemp("dashboard")) as served:
        seeded = _seed(served.base, served.database_url, served.storage_dir)
        yield {"base": served.base, "log": served.log, **seeded}


def _seed(base: str, database_url: str, storage_dir: Path) -> dict:
    rng = np.random.default_rng(7)
    with new_club_admin(base, club_name=CLUB, email=EMAIL, password=PASSWORD, display_name="Coach") as api:
        riders = [_ok(api.post("/api/riders", json={"name": name}))["id"] for name in ("Rider A", "Rider B")]
        horses, rides, docs = {}, [], {}
        for name, (scale, n_canter) in HORSES.items():
            horses[name] = _ok(api.post("/api/horses", json={"name": name, "breed": "Dutch"}))["id"]
            gaits = ["canter"] * n_canter + (["walk"] if name == "Bella" else [])
            for i, gait in enumerate(gaits):
                ride = _ok(api.post("/api/rides", json={"horse_id": horses[name], "rider_id": riders[i % 2],
                                                        "gait": gait, "direction": "CCW"}))
                # Comet's second canter ride is a little rougher: its mean lies between its rides.
                doc = result_document(scale=scale * (1.1 if i == 1 else 1.0), gait=gait, rng=rng)
                store_result(database_url, storage_dir, ride["id"], doc)
                rides.append({"id": ride["id"], "horse": name, "gait": gait})
                docs[ride["id"]] = doc
        for name, grade in (("Bella", 5), ("Comet", 3), ("Dancer", 2)):
            ride = next(r for r in rides if r["horse"] == name and r["gait"] == "canter")
            _ok(api.post("/api/grades", json={"ride_id": ride["id"], "rider_id": riders[0], "grade": grade}))
    return {"horses": horses, "riders": riders, "rides": rides, "docs": docs, "database_url": database_url}


@pytest.fixture(scope="module")
def browser(sync_playwright_factory):
    manager = sync_playwright_factory().start()
    chromium = manager.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
    try:
        yield chromium
    finally:
        chromium.close()
        manager.stop()


class Console:
    """Console messages of type error and uncaught page errors of one browser context."""

    def __init__(self) -> None:
        self.errors: list[str] = []

    def attach(self, page) -> None:
        page.on("console", lambda msg: self.errors.append(msg.text) if msg.type == "error" else None)
        page.on("pageerror", lambda exc: self.errors.append(f"uncaught: {exc}"))

    def unexpected(self, *allowed_statuses: int) -> list[str]:
        """Errors other than the browser's own note on an expected HTTP status of a request."""
        allowed = [f"status of {s} " for s in allowed_statuses]
        return [e for e in self.errors if not any(a in e for a in allowed)]


@pytest.fixture
def page(browser, dashboard):
    context = browser.new_context(base_url=dashboard["base"], viewport={"width": 1280, "height": 900})
    tab = context.new_page()
    console = Console()
    console.attach(tab)
    tab.console = console
    tab.set_default_timeout(15_000)
    try:
        yield tab
    finally:
        context.close()


def sign_in(page) -> None:
    """Sign in through the API of the page's own context (the cookies are shared with the page)."""
    answer = page.context.request.post("/api/auth/login", data={"email": EMAIL, "password": PASSWORD})
    assert answer.ok, answer.text()


@contextmanager
def api_client(dashboard) -> Iterator[httpx.Client]:
    """A client of the seeded server signed in with a bearer token (no cookies, so no CSRF)."""
    with httpx.Client(base_url=dashboard["base"], timeout=30) as api:
        token = _ok(api.post("/api/auth/login", json={"email": EMAIL, "password": PASSWORD}))["access_token"]
        api.cookies.clear()
        api.headers["Authorization"] = f"Bearer {token}"
        yield api


def api_get(dashboard, url: str, **params) -> dict:
    with api_client(dashboard) as api:
        return _ok(api.get(url, params=params))


def chart_traces(page, name: str) -> list[dict]:
    """The Plotly traces drawn in [data-chart=name]: name and number of points of each."""
    return page.eval_on_selector(
        f'[data-chart="{name}"]',
        "el => (el.data || []).map(t => ({name: t.name, n: (t.y || []).length}))")


# ----------------------------------------------------------------------------- the ride page's server and charts

# The ride page's charts at least; the tests wait for and check every chart the page holds (page_charts), so a
# chart added to the page is checked without a line here.
CHARTS = ("tracks3d", "fit-x", "fit-y", "fit-z", "weighted", "spectrum", "position", "velocity", "acceleration",
          "omega", "alpha", "versions")


@pytest.fixture(scope="module")
def ride_page_dashboard(sync_playwright_factory, tmp_path_factory):
    """The seeded server of the ride page tests (test_ride_page, test_ride_intervals: assigned there as
    `dashboard`), with its storage folder; started with more time (a loaded machine imports slowly)."""
    with serve_fresh(tmp_path_factory.mktemp("ridepage")) as server:
        yield {"base": server.base, "log": server.log, "storage_dir": server.storage_dir,
               **_seed(server.base, server.database_url, server.storage_dir)}


def page_charts(page) -> list[str]:
    """The names of every chart of the page's main view (``[data-chart]``)."""
    return page.eval_on_selector_all("main [data-chart]", "els => els.map(el => el.dataset.chart)")


def charts_drawn(page) -> dict[str, int]:
    """Per chart of the page (CHARTS among them): the number of points Plotly holds in its traces (0 when not drawn)."""
    return page.evaluate("""names => Object.fromEntries(names.map(n => {
        const el = document.querySelector(`[data-chart="${n}"]`);
        const points = (el?.data || []).reduce((s, t) => s + Math.max((t.x || []).length, (t.y || []).length), 0);
        return [n, el && el.data && el.data.length > 0 ? points : 0];
    }))""", sorted({*CHARTS, *page_charts(page)}))


def wait_for_charts(page) -> None:
    """Until every chart of the page (CHARTS among them) holds a trace (those below the fold: when scrolled to)."""
    browser_harness.wait_for_charts_drawn(page, sorted({*CHARTS, *page_charts(page)}))


# ----------------------------------------------------------------------------- pages of a fresh server


def open_page(browser, served, email=EMAIL, password=PASSWORD, width=1280):
    """A signed-in page of `served` (a fresh server's dict with its "base") with its console recorded."""
    context = browser.new_context(base_url=served["base"], viewport={"width": width, "height": 900})
    tab = context.new_page()
    tab.console = Console()
    tab.console.attach(tab)
    tab.set_default_timeout(20_000)
    answer = tab.context.request.post("/api/auth/login", data={"email": email, "password": password})
    assert answer.ok, answer.text()
    return tab


def tiny_clip(served, name: str) -> dict:
    """A six-frame MJPEG clip as Playwright's set_input_files takes it, written in `served`'s root."""
    path = integration_services.write_tiny_clip(served["root"] / "clips" / f"{name}.avi", frames=6)
    return {"name": path.name, "mimeType": "video/x-msvideo", "buffer": path.read_bytes()}

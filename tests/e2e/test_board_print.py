"""The calibration board printed by Debian's chromium at its stated size (issue 35).

A 750 x 700 mm board (checkerboard 12 x 11 inner corners, 50 mm squares, the arena's size) printed on
A4 tiles, and a 300 x 240 mm ChArUco board on one A3 sheet: Chromium's ``page.pdf`` of each print page
(as the browser's print dialog does at "actual size"), then in the PDF the page count and size, the
black squares' size measured from the vector rectangles (within 1 % of the stated mm), and the 100 mm
ruler bar on every page. The rig page offers the layouts (screenshots at 1280 and 390 px) and its
"Print the board" opens the chosen print page; it shows a stored calibration check per camera (coverage
map, distances, verdict in words).
"""

from __future__ import annotations

import statistics

import pytest
from browser_harness import axe_violations, chromium_for_module, new_club_admin, serve_fresh, shoot_both_widths
from dashboard_helpers import EMAIL, PASSWORD, Console, _ok, _require_browser

pytestmark = [pytest.mark.browser]

MM_PER_PT = 25.4 / 72
BIG_BOARD = {"kind": "checkerboard", "inner_corners": [12, 11], "square_mm": 50.0}  # 750 x 700 mm
A3_BOARD = {"kind": "charuco", "inner_corners": [7, 5], "square_mm": 30.0}  # 300 x 240 mm


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    sync_playwright = _require_browser()
    root = tmp_path_factory.mktemp("board-print")
    with serve_fresh(root) as server, new_club_admin(server.base, club_name="Print Riding Club", email=EMAIL,
                                                     password=PASSWORD) as api:
        big = _ok(api.post("/api/rigs", json={"name": "Outdoor arena", "board": BIG_BOARD}))["id"]
        small = _ok(api.post("/api/rigs", json={"name": "Indoor school", "board": A3_BOARD}))["id"]
        with chromium_for_module(sync_playwright) as chromium:
            yield {"base": server.base, "api": api, "big": big, "small": small, "chromium": chromium,
                   "storage": server.storage_dir}


@pytest.fixture
def page(served):
    context = served["chromium"].new_context(base_url=served["base"], viewport={"width": 1280, "height": 900})
    tab = context.new_page()
    tab.console = Console()
    tab.console.attach(tab)
    tab.set_default_timeout(20_000)
    assert tab.context.request.post("/api/auth/login", data={"email": EMAIL, "password": PASSWORD}).ok
    try:
        yield tab
    finally:
        context.close()


def printed(page, rig_id: int, layout: str):
    """The print page as Chromium prints it at 100 % (its own @page size), opened with pymupdf."""
    pymupdf = pytest.importorskip("pymupdf", reason="pymupdf (the test extras) measures the printed PDF")
    answer = page.goto(f"/api/rigs/{rig_id}/board-print?layout={layout}")
    assert answer is not None and answer.ok, answer and answer.text()
    return pymupdf.open(stream=page.pdf(prefer_css_page_size=True, print_background=True), filetype="pdf")


def sizes_mm(pdf_page) -> list[tuple[float, float]]:
    """Width and height (mm) of every filled vector shape on a page."""
    return [(d["rect"].width * MM_PER_PT, d["rect"].height * MM_PER_PT) for d in pdf_page.get_drawings()
            if d.get("fill") is not None]


def square_mm(pdf_page, near_mm: float) -> float:
    """The median size of the black squares (shapes about as wide as high, within 20 % of the size expected)."""
    squares = [w for w, h in sizes_mm(pdf_page) if abs(w - h) < 0.02 * w and abs(w - near_mm) < 0.2 * near_mm]
    assert len(squares) >= 2, f"no squares of about {near_mm} mm on the page: {sizes_mm(pdf_page)[:20]}"
    return statistics.median(squares)


def assert_ruler(pdf_page) -> None:
    bars = [w for w, h in sizes_mm(pdf_page) if abs(w - 100) < 5 and h < 5]
    assert bars and abs(bars[0] - 100.0) <= 1.0, f"no 100 mm ruler bar on the page: {bars}"
    assert "must measure exactly 100 mm" in pdf_page.get_text()


def test_a_large_board_prints_on_a4_tiles_at_its_size(page, served):
    sizes = _ok(served["api"].get(f"/api/rigs/{served['big']}/board-sizes"))
    assert (sizes["width_mm"], sizes["height_mm"]) == (750, 700)
    tiles = next(lay for lay in sizes["layouts"] if lay["layout"] == "a4-tiles")
    assert not any(lay["fits"] for lay in sizes["layouts"] if lay["layout"] in ("a4", "a3", "a2"))
    doc = printed(page, served["big"], "a4-tiles")
    assert len(doc) == tiles["sheets"] == 12  # the 650 x 600 mm of squares on 4 x 3 (or 3 x 4) A4 sheets
    names = set()
    for pdf_page in doc:
        w, h = sorted((pdf_page.rect.width * MM_PER_PT, pdf_page.rect.height * MM_PER_PT))
        assert w == pytest.approx(210, rel=0.01) and h == pytest.approx(297, rel=0.01)
        assert square_mm(pdf_page, 50) == pytest.approx(50.0, rel=0.01)
        assert_ruler(pdf_page)
        text = pdf_page.get_text()
        names.add(text.split("Sheet ", 1)[1].split(":", 1)[0])
    assert len(names) == 12 and "A1" in names  # every sheet labelled with its own row and column
    assert not page.console.errors


def test_a_small_board_prints_on_one_a3_sheet_and_refuses_a4(page, served):
    doc = printed(page, served["small"], "a3")
    assert len(doc) == 1
    w, h = sorted((doc[0].rect.width * MM_PER_PT, doc[0].rect.height * MM_PER_PT))
    assert w == pytest.approx(297, rel=0.01) and h == pytest.approx(420, rel=0.01)
    assert square_mm(doc[0], 30) == pytest.approx(30.0, rel=0.01)
    assert_ruler(doc[0])
    refused = served["api"].get(f"/api/rigs/{served['small']}/board-print", params={"layout": "a4"})
    assert refused.status_code == 422
    assert "does not fit on one A4 sheet" in refused.json()["detail"]


def test_the_rig_page_states_the_size_and_offers_the_layouts(page, served):
    page.goto(f"/#/rigs/{served['big']}")
    layouts = page.locator("[data-board-layouts] li")
    layouts.first.wait_for()
    words = page.locator("[data-board-sentences]").inner_text()
    assert "750 \u00d7 700 mm" in words and "at 8 m" in words
    options = page.locator("[data-print-layout] option")
    assert options.evaluate_all("os => os.map(o => o.value)") == ["a0", "a4-tiles"]  # too big for an A1 poster
    assert page.locator("[data-print-layout]").input_value() == "a0"
    page.locator("[data-print-layout]").select_option("a4-tiles")
    with page.expect_popup() as popup_info:
        page.get_by_role("button", name="Print the board").click()
    popup = popup_info.value
    popup.wait_for_load_state()
    assert popup.url.endswith(f"/api/rigs/{served['big']}/board-print?layout=a4-tiles")
    assert popup.locator("section.sheet").count() == 12
    popup.close()
    shoot_both_widths(page, "rig-board-print")
    assert not page.console.errors


def stored_check(storage_dir, rig_id: int) -> None:
    """A check as the check_calibration job stores it: the middle camera's board everywhere, the right
    camera's only in the middle band of its image (board corners projected by a known camera)."""
    import json

    import cv2
    import numpy as np

    from saddlescope.core.calibration.coverage_check import check_camera_coverage
    from saddlescope.core.types import Board
    from saddlescope.services.rigs.calibration_check import CalibrationCheck, check_document

    board, size = Board("checkerboard", (12, 11), 50.0), (1920, 1080)
    K = np.array([[1370.0, 0, 960], [0, 1370.0, 540], [0, 0, 1]])
    obj = board.object_points_mm() - board.object_points_mm().mean(axis=0)

    def seen(xs, ys, distances):
        out = []
        for (u, v), d in zip([(x, y) for x in xs for y in ys], np.resize(distances, len(xs) * len(ys)), strict=True):
            t = np.linalg.solve(K, [u, v, 1.0]) * d * 1000.0
            px = cv2.projectPoints(obj, np.array([0.2, -0.2, 0.0]), t, K, np.zeros(5))[0].reshape(-1, 2)
            out.append((px, np.arange(len(px))))
        return out

    cameras = {
        "middle": check_camera_coverage("middle", seen(np.linspace(250, 1670, 6), np.linspace(200, 880, 4),
                                                       [3.0, 4.5, 6.0]), board, size, frames_sampled=90),
        "right": check_camera_coverage("right", seen([900, 960, 1020], np.linspace(200, 880, 5), [4.0, 5.0]),
                                       board, size, frames_sampled=90),
    }
    path = storage_dir / "rigs" / str(rig_id) / "calibration-check.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(check_document(CalibrationCheck(cameras, 41.0), clips={"middle": 1, "right": 2})))


def test_the_rig_page_shows_the_check_before_anyone_rides(page, served):
    stored_check(served["storage"], served["big"])
    page.goto(f"/#/rigs/{served['big']}")
    verdict = page.locator("[data-check-verdict]")
    page.wait_for_function("() => document.querySelector('[data-check-verdict]')?.textContent.includes('Film again')")
    assert verdict.inner_text().startswith("Film again: the right camera")
    right = page.locator('[data-check-camera="right"]')
    assert "Right camera: film again." in right.inner_text()
    assert ("The board never reached the left third and right third of the right camera's view: film that part again."
            in right.inner_text())
    assert right.locator("rect.coverage-missed").count() > 0 and right.locator("svg.check-depth").count() == 1
    assert "Middle camera: good." in page.locator('[data-check-camera="middle"]').inner_text()
    page.locator("[data-check-panel]").scroll_into_view_if_needed()
    shoot_both_widths(page, "rig-calibration-check")
    assert axe_violations(page) == []
    assert not page.console.errors

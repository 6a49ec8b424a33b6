"""The rig page offers the wand way beside the board walk (issue 35, item 3), in Debian's chromium.

A rig with its close-up board and no clips: the page shows "Calibrate with a wand" with the wand's length
field, each camera's wand and close-up clip, and which way to choose (with where the filming guide says
more); asking for the wand way is refused in words: no length, a length in centimetres, no clips.
"""

from __future__ import annotations

import pytest
from browser_harness import axe_violations, chromium_for_module, new_club_admin, serve_fresh
from dashboard_helpers import EMAIL, PASSWORD, Console, _ok, _require_browser

pytestmark = [pytest.mark.browser]

SMALL_BOARD = {"kind": "checkerboard", "inner_corners": [5, 4], "square_mm": 20.0}


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    sync_playwright = _require_browser()
    root = tmp_path_factory.mktemp("rig-wand")
    with serve_fresh(root) as server, new_club_admin(server.base, club_name="Wand Riding Club", email=EMAIL,
                                                     password=PASSWORD) as api:
        rig = _ok(api.post("/api/rigs", json={"name": "Wide arena", "board": SMALL_BOARD}))["id"]
        with chromium_for_module(sync_playwright) as chromium:
            yield {"base": server.base, "api": api, "rig": rig, "chromium": chromium, "base_dir": root}


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


def _ask(page, length: str) -> str:
    """Type the wand's length, press "Calibrate with a wand" and return the refusal shown."""
    panel = page.locator("[data-wand-panel]")
    panel.get_by_label("Wand length (m, between the two discs' centres)").fill(length)
    error = panel.locator("[data-form-error]")
    before = error.text_content() if error.is_visible() else ""
    panel.get_by_role("button", name="Calibrate with a wand").click()
    page.wait_for_function("([el, before]) => !el.hidden && el.textContent && el.textContent !== before",
                           arg=[error.element_handle(), before])
    return error.text_content()


def test_the_rig_page_offers_the_wand_way_and_refuses_it_in_words(page, served):
    page.goto(f"/#/rigs/{served['rig']}")
    panel = page.locator("[data-wand-panel]")
    panel.get_by_role("heading", name="Calibrate with a wand").wait_for()
    # each camera's wand clip and close-up clip, beside the board walk's clips
    for camera in ("left", "middle", "right"):
        for kind, label in (("wand", "Wand (waved along"), ("close_up", "Close-up board")):
            cell = panel.locator(f'[data-clip-kind="{kind}"][data-camera="{camera}"]')
            assert label in cell.locator("label").text_content()
            assert cell.locator('input[type="file"]').count() == 1
            assert "not uploaded" in cell.text_content()
    assert page.locator('[data-rig-clips] [data-clip-kind="calibration"]').count() == 3
    panel.get_by_text("Board walk or wand: which to choose").click()
    assert panel.locator("[data-wand-choice] p").first.is_visible()
    assert "Which to choose" in panel.locator("[data-wand-guide]").inner_text()
    assert "docs/filming.md" in panel.locator("[data-wand-guide]").inner_text()

    no_length = _ask(page, "")
    assert "give the wand's length first (in metres, between the centres of its two markers" in no_length
    assert no_length[0].isupper() and no_length.endswith(".")
    centimetres = _ask(page, "100")
    assert "length 100 m is outside 0.05-5 m (in centimetres? 100 cm is 1.00 m)" in centimetres
    assert centimetres[0].isupper()
    no_clips = _ask(page, "1.0")
    assert "cannot be calibrated with a wand yet: upload the wand clip of the left, middle, right cameras and " \
           "the close-up clip of the left, middle, right cameras first." in no_clips
    assert served["api"].get(f"/api/rigs/{served['rig']}").json()["wand_length_m"] == 1.0  # the length was kept
    assert axe_violations(page) == []  # the panel with its refusal and the choice opened
    assert page.console.unexpected(409, 422) == []


def test_the_wand_clips_check_is_shown_beside_the_boards(page, served):
    """Issue 35 item 4: a wand clip uploaded to a rig with its wand's length is checked at once; the rig page
    shows each camera's wand check (here: clips without a wand, so "film again") beside the board's."""
    from integration_services import write_tiny_clip

    api = served["api"]
    rig = _ok(api.post("/api/rigs", json={"name": "Wand day", "board": SMALL_BOARD, "wand_length_m": 1.0}))["id"]
    clip = write_tiny_clip(served["base_dir"] / "wand.avi", frames=12).read_bytes()
    for camera in ("left", "middle"):
        _ok(api.put(f"/api/rigs/{rig}/clips/wand/{camera}", files={"file": (f"wand-{camera}.avi", clip)}))
    page.goto(f"/#/rigs/{rig}")
    block = page.locator("[data-wand-check]")
    block.locator("[data-check-camera=middle]").wait_for(timeout=120_000)  # the check job ran on the server
    assert block.locator("[data-wand-check-verdict]").inner_text().startswith(
        "Film again: the left and middle cameras' wand clips")
    caption = block.locator("[data-check-camera=left] figcaption").inner_text()
    assert caption.startswith("Left camera's wand clip: film again.")
    assert "Both wand ends were not found in any of the" in caption
    assert "0-0 %" not in caption
    assert page.locator("[data-check-verdict]").first.inner_text().startswith("Not checked yet")  # no board clip
    page.locator("[data-check-panel]").screenshot(path="/tmp/rig_wand_check.png")
    assert axe_violations(page) == []
    assert page.console.unexpected() == []

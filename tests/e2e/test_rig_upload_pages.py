"""The rig pages and the upload page in Debian's chromium, from an empty club: a rig with its board is
created in the browser, its board shown at true scale, its calibration clips uploaded one by one, and
the upload form names what is missing before anything is sent. Screenshots at 1280 and 390 px go to
var/test-artifacts/screenshots/."""

from __future__ import annotations

import sys

import integration_services
import numpy as np
import pytest
from browser_harness import chromium_for_module, new_club_admin, serve_fresh, shoot_both_widths
from dashboard_helpers import EMAIL, PASSWORD, _ok, _require_browser, open_page, tiny_clip

from conftest import PROJECT_ROOT

sys.path.insert(0, str(PROJECT_ROOT / "tests" / "api"))
from api_helpers import zip_folder  # noqa: E402

pytestmark = [pytest.mark.browser, pytest.mark.slow]

SHOTS = PROJECT_ROOT / "var" / "test-artifacts" / "screenshots"
MEMBER_EMAIL, MEMBER_PASSWORD = "groom@example.org", "member password 1"


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """An empty club on a fresh `saddlescope serve` (embedded: jobs run in the server), with one horse."""
    sync_playwright = _require_browser()
    root = tmp_path_factory.mktemp("rig-pages")
    with serve_fresh(root) as server, new_club_admin(server.base, club_name="Rig Riding Club", email=EMAIL,
                                                     password=PASSWORD, display_name="Secretary") as api:
        _ok(api.post("/api/users", json={"email": MEMBER_EMAIL, "password": MEMBER_PASSWORD, "role": "member"}), 201)
        horse = _ok(api.post("/api/horses", json={"name": "Bella"}))["id"]
        rider = _ok(api.post("/api/riders", json={"name": "Anna"}))["id"]
        calibrated = _ok(api.post("/api/rigs", json={"name": "Outdoor arena", "board": {
            "kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0}}))["id"]
        store_calibration(server.database_url, calibrated)
        yield {"base": server.base, "api": api, "root": root, "horse": horse, "rider": rider,
               "calibrated": calibrated, "playwright": sync_playwright}


def store_calibration(database_url: str, rig_id: int) -> None:
    """A calibration as the calibrate_rig job stores it, the board having stayed in the left of the
    left camera's image (as a calibration job would have found it)."""
    from saddlescope.db.repositories import RigRepository
    from saddlescope.db.session import make_engine, make_session_factory, session_scope

    rng = np.random.default_rng(5)
    size = (1280, 720)
    reach = {"left": (0.0, 0.55), "middle": (0.0, 1.0), "right": (0.2, 1.0)}
    corners = {cam: np.column_stack([rng.uniform(a * size[0], b * size[0], 400), rng.uniform(0, size[1], 400)])
               .round(1).tolist() for cam, (a, b) in reach.items()}
    cameras = {cam: {"K": [[900.0, 0, 640], [0, 900.0, 360], [0, 0, 1]], "dist": [0.0] * 5, "image_size": list(size),
                     "rms_px": rms} for cam, rms in (("left", 0.31), ("middle", 0.24), ("right", 0.42))}
    calibration = {"cameras": cameras, "extrinsics": {}, "checks": {"board_square_error_mm": 0.38}, "flags": [],
                   "pairs": {}, "n_views": {c: 24 for c in cameras}, "board_corners_px": corners}
    engine = make_engine(database_url)
    try:
        with session_scope(make_session_factory(engine)) as session:
            RigRepository(session).set_calibration(rig_id, calibration, {"flags": []})
    finally:
        engine.dispose()


@pytest.fixture(scope="module")
def browser(served):
    with chromium_for_module(served["playwright"]) as chromium:
        yield chromium


@pytest.fixture
def page(browser, served):
    tab = open_page(browser, served)
    try:
        yield tab
    finally:
        tab.context.close()


shoot = shoot_both_widths


def test_a_rig_with_its_board_then_its_calibration_clips_one_by_one(page, served):
    page.goto("/#/rigs")
    page.get_by_role("link", name="Outdoor arena").wait_for()  # the list shows the club's rigs
    form = page.locator("[data-rig-form]")
    form.get_by_label("Name").fill("Indoor arena")
    form.get_by_label("Inner corners across").fill("5")
    form.get_by_label("Inner corners down").fill("4")
    form.get_by_label("Square size (mm)").fill("30")
    form.get_by_role("button", name="Add the rig").click()
    page.wait_for_url("**/#/rigs/*")
    rig_id = int(page.url.rsplit("/", 1)[1])

    board = page.locator("[data-board-image] svg")
    board.wait_for()
    # 5 x 4 inner corners: 6 x 5 squares of 30 mm and a one-square margin: 240 x 210 mm.
    assert (board.get_attribute("width"), board.get_attribute("height")) == ("240mm", "210mm")
    assert "it must measure 30 mm" in page.locator("[data-board-note]").inner_text()
    # Printed (print stylesheet), the board keeps its size in mm: 240 mm is 907 CSS px at 96 px per inch.
    page.emulate_media(media="print")
    printed_px = page.evaluate("document.querySelector('[data-board-image] svg').getBoundingClientRect().width")
    page.emulate_media(media="screen")
    assert printed_px == pytest.approx(240 / 25.4 * 96, abs=1)
    assert page.locator("[data-board-form]").is_visible()  # the admin may change the board

    for camera in ("left", "middle"):
        page.locator(f'[data-rig-clip="calibration-{camera}"]').set_input_files(tiny_clip(served, f"cal-{camera}"))
        card = page.locator(f'.rig-clip[data-clip-kind="calibration"][data-camera="{camera}"]')
        card.get_by_text(f"cal-{camera}.avi").wait_for()
    status = page.locator("[data-calibration-status]")
    page.wait_for_function(
        "() => "
        "document.querySelector('[data-calibration-status]').textContent"
        ".includes('The calibration clip of the right camera is missing.')")
    assert "The calibration clip of the right camera is missing." in status.inner_text()
    shoot(page, "rig")

    page.goto("/#/rigs")
    page.get_by_role("link", name="Indoor arena").wait_for()
    shoot(page, "rigs")
    served["rig_id"] = rig_id
    assert page.console.unexpected() == []


def test_the_upload_form_names_what_is_missing_before_sending(page, served):
    rig_id = served.get("rig_id")
    if rig_id is None:
        pytest.skip("needs the rig of the test before")
    api = served["api"]
    rides_before = _ok(api.get("/api/rides"))["total"]
    page.goto("/#/upload")
    page.get_by_label("Clips one by one").check()
    page.locator("main:not([aria-busy])").wait_for()
    page.select_option("#up-rig", str(rig_id))
    missing = page.locator("[data-readiness]")
    page.wait_for_function(
        "() => "
        "document.querySelector('[data-readiness-list]').textContent.includes('only 2 cameras')")
    text = missing.inner_text()
    assert "calibration clips come from only 2 cameras (left and middle); upload the right camera's" in text
    assert "motion clips (the ride) of the left, middle and right cameras are missing" in text
    for camera in ("left", "middle", "right"):
        page.locator(f"#clip-motion-{camera}").set_input_files(tiny_clip(served, f"motion-{camera}"))
    page.wait_for_function("() => !document.querySelector('[data-readiness-list]').textContent.includes('motion clip')")
    page.get_by_role("button", name="Upload and analyse").click()
    error = page.locator("[data-upload-form] [data-form-error]")
    error.wait_for(state="visible")
    assert "Nothing was sent" in error.inner_text()
    assert _ok(api.get("/api/rides"))["total"] == rides_before  # no ride made, nothing queued
    shoot(page, "upload-clips")

    # The third calibration clip on the rig page completes the rig's clips: calibration is no longer missing.
    page.goto(f"/#/rigs/{rig_id}")
    page.locator('[data-rig-clip="calibration-right"]').set_input_files(tiny_clip(served, "cal-right"))
    page.locator('.rig-clip[data-clip-kind="calibration"][data-camera="right"]').get_by_text("cal-right.avi").wait_for()
    page.goto("/#/upload")
    page.get_by_label("Clips one by one").check()
    page.locator("main:not([aria-busy])").wait_for()
    page.select_option("#up-rig", str(rig_id))
    page.wait_for_function("() => (t => t.includes('static clip') && !t.includes('No camera rig'))"
                           "(document.querySelector('[data-readiness-list]').textContent)")
    assert "calibration" not in page.locator("[data-readiness-list]").inner_text()
    assert page.console.unexpected() == []


def test_a_bundle_prefills_the_form_and_the_ride_takes_what_the_user_chose(page, served):
    folder = integration_services.write_tiny_bundle(served["root"] / "bundle")
    page.goto("/#/upload")
    page.locator("main:not([aria-busy])").wait_for()
    page.locator("#up-bundle").set_input_files(
        files=[{"name": "sunday.zip", "mimeType": "application/zip", "buffer": zip_folder(folder)}])
    note = page.locator("[data-bundle-prefill]")
    note.wait_for(state="visible")
    assert "Horse 2" in note.inner_text() and "not in the club yet" in note.inner_text()
    assert page.locator("#up-horse option:checked").inner_text() == "Horse 2 (new horse, from the bundle)"
    assert page.locator("#up-gait").input_value() == "walk"
    shoot(page, "upload-bundle")
    page.select_option("#up-horse", label="Bella")
    page.select_option("#up-rider", label="Anna")
    page.select_option("#up-gait", "canter")
    page.fill("#up-date", "2026-05-03")
    page.get_by_role("button", name="Upload and analyse").click()
    page.wait_for_url("**/#/rides/*")
    ride = _ok(served["api"].get(f"/api/rides/{int(page.url.rsplit('/', 1)[1])}"))
    assert (ride["horse_id"], ride["rider_id"], ride["gait"], ride["ridden_on"]) == (
        served["horse"], served["rider"], "canter", "2026-05-03")
    names = [h["name"] for h in _ok(served["api"].get("/api/horses"))["items"]]
    assert "Horse 2" not in names


def test_a_member_sees_no_board_change_or_delete(browser, served):
    rig_id = served.get("rig_id")
    if rig_id is None:
        pytest.skip("needs the rig of the first test")
    tab = open_page(browser, served, MEMBER_EMAIL, MEMBER_PASSWORD)
    try:
        tab.goto(f"/#/rigs/{rig_id}")
        tab.locator("[data-board-image] svg").wait_for()
        for selector in ("[data-board-form]", "[data-rig-delete]"):
            assert not tab.locator(selector).is_visible(), selector
        hidden = tab.eval_on_selector_all("[data-permission]", "els => els.filter(e => e.offsetParent !== null)"
                                          ".map(e => e.dataset.permission)")
        assert set(hidden) <= {"rig.create", "ride.analyse"}  # what a member may do
        assert tab.console.unexpected() == []
    finally:
        tab.context.close()


def test_the_board_form_offers_the_registrys_kinds_and_each_kinds_own_fields(page, served):
    api = served["api"]
    kinds = _ok(api.get("/api/board-types"))
    rig = _ok(api.post("/api/rigs", json={"name": "Board form", "board": {
        "kind": "checkerboard", "inner_corners": [5, 4], "square_mm": 30.0}}))
    page.goto(f"/#/rigs/{rig['id']}")
    form = page.locator("[data-board-form]")
    kind = form.get_by_label("Board type")
    kind.locator("option").nth(len(kinds) - 1).wait_for(state="attached")
    assert kind.locator("option").all_inner_texts() == [k["label"] for k in kinds]  # none listed in the page
    assert not form.get_by_label("Marker size (mm)").is_visible()  # a checkerboard has no fields of its own
    kind.select_option("charuco")
    charuco = next(k for k in kinds if k["kind"] == "charuco")
    assert form.locator("[data-board-kind-hint]").inner_text() == charuco["short"]
    form.get_by_label("Marker size (mm)").fill("22")
    form.get_by_label("Marker dictionary").select_option("DICT_5X5_100")
    form.get_by_role("button", name="Save the board").click()
    page.locator("[data-board-text]").get_by_text("ChArUco, 5 \u00d7 4 inner corners").wait_for()
    stored = _ok(api.get(f"/api/rigs/{rig['id']}"))["board"]
    assert stored == {"kind": "charuco", "inner_corners": [5, 4], "square_mm": 30.0, "marker_mm": 22.0,
                      "dictionary": "DICT_5X5_100"}  # the legacy box unticked: not sent
    assert page.locator("[data-board-text]").inner_text() == \
        "ChArUco, 5 \u00d7 4 inner corners, squares 30 mm, markers 22 mm, DICT_5X5_100"
    assert page.console.unexpected() == []


def test_a_calibrated_rig_says_its_quality_and_where_the_board_has_been(page, served):
    page.goto(f"/#/rigs/{served['calibrated']}")
    pictures = page.locator("[data-coverage] svg.coverage")
    pictures.first.wait_for()
    assert pictures.count() == 3
    assert page.locator("[data-coverage] svg.coverage circle").count() == 1200  # every corner kept is drawn
    words = page.locator("[data-calibration-words]").inner_text()
    assert "Reprojection error 0.42 px (worst camera): good" in words
    assert "Board squares rebuilt within 0.38 mm: good" in words
    captions = page.locator("[data-coverage] figcaption").all_inner_texts()
    assert any("never reached the top-right corner" in c and "left camera" in c for c in captions), captions
    assert any("reached every part of the middle camera" in c for c in captions), captions
    assert page.locator("[data-calibration-status]").inner_text().startswith("Calibrated")
    shoot(page, "rig-calibrated")
    assert page.console.unexpected() == []


def test_an_incomplete_ride_says_what_is_missing_and_is_completed_on_the_upload_page(page, served):
    rig_id = served.get("rig_id")
    if rig_id is None:
        pytest.skip("needs the rig of the first test")
    api = served["api"]
    ride = _ok(api.post("/api/rides", json={"horse_id": served["horse"], "rider_id": served["rider"],
                                            "gait": "walk", "direction": "CW", "rig_id": rig_id}))
    for camera in ("left", "middle", "right"):
        data = tiny_clip(served, f"api-motion-{camera}")["buffer"]
        _ok(api.put(f"/api/rides/{ride['id']}/clips/motion/{camera}",
                    files={"file": (f"{camera}.avi", data, "video/x-msvideo")}))
    page.goto("/#/rides")
    # The module the ride page mounts for an incomplete ride.
    shown = page.evaluate("""async (id) => {
        const m = await import('/js/ride-readiness.js');
        const box = document.createElement('div');
        document.querySelector('main').append(box);
        const answer = await m.mountReadiness(box, id);
        return [answer.ready, box.textContent, box.querySelector('a').getAttribute('href')];
    }""", ride["id"])
    assert shown[0] is False and "static clips (horse standing still" in shown[1]
    assert shown[2] == f"#/upload?ride={ride['id']}"

    page.goto(f"/#/upload?ride={ride['id']}")
    page.get_by_role("heading", name=f"Complete ride {ride['id']}").wait_for()
    page.wait_for_function("() => document.querySelector('[data-readiness-list]').textContent.includes('static clips')")
    assert "motion" not in page.locator("[data-readiness-list]").inner_text()  # stored already
    for camera in ("left", "middle", "right"):
        page.locator(f"#clip-static-{camera}").set_input_files(tiny_clip(served, f"static-{camera}"))
    page.locator("[data-readiness]").wait_for(state="hidden")
    page.get_by_role("button", name="Upload and analyse").click()
    page.wait_for_url(f"**/#/rides/{ride['id']}")
    jobs = _ok(api.get("/api/jobs", params={"ride_id": ride["id"]}))
    assert jobs["total"] == 1  # complete now: its analysis was queued
    assert _ok(api.get(f"/api/rides/{ride['id']}/readiness")) == {"ready": True, "missing": []}


def test_two_renders_that_overlap_leave_one_page(page, served):
    """A hashchange queued while the app starts renders the page twice at once: the older mount, when it
    finishes late, must fill a detached root, not append a second form to the view (the CI failure of
    stop 30: two readiness lists on the upload page)."""
    page.goto("/#/upload")
    page.locator("[data-upload-form]").wait_for()
    forms = page.evaluate("""async () => {
        const router = await import('/js/router.js');
        await Promise.all([router.render(), router.render(), router.render()]);
        return document.querySelectorAll('main [data-upload-form]').length;
    }""")
    assert forms == 1


def test_the_same_clips_as_a_bundle_then_one_by_one_make_one_ride(page, served):
    """Issue 37: the second upload answers with the ride the clips already are, and leaves no empty ride."""
    api = served["api"]
    folder = integration_services.write_tiny_bundle(served["root"] / "twice")
    first = _ok(api.post("/api/rides/bundle", files={"file": ("twice.zip", zip_folder(folder), "application/zip")}),
                201)["ride"]
    rides_before = _ok(api.get("/api/rides"))["total"]
    page.goto("/#/upload")
    page.get_by_label("Clips one by one").check()
    page.locator("main:not([aria-busy])").wait_for()
    page.select_option("#up-rig", str(served["calibrated"]))
    page.select_option("#up-horse", label="Bella")
    page.select_option("#up-rider", label="Anna")
    for kind in ("static", "motion"):  # the rig's calibration serves
        for camera in ("left", "middle", "right"):
            page.locator(f"#clip-{kind}-{camera}").set_input_files(
                {"name": f"{camera}.avi", "mimeType": "video/x-msvideo",
                 "buffer": (folder / f"{kind}/{camera}.avi").read_bytes()})
    page.locator("[data-readiness]").wait_for(state="hidden")
    page.get_by_role("button", name="Upload and analyse").click()
    existing = page.locator("[data-upload-form] [data-existing-ride]")
    existing.wait_for()
    assert existing.get_attribute("href") == f"#/rides/{first['id']}"
    error = page.locator("[data-upload-form] [data-form-error]").inner_text()
    assert f"already uploaded as ride {first['id']}" in error
    assert _ok(api.get("/api/rides"))["total"] == rides_before  # the ride made for the clips was taken back
    shoot(page, "upload-same-clips")
    assert page.console.unexpected(409) == []


def test_a_chunk_refused_at_a_wrong_offset_is_sent_again_from_the_servers_offset(page, served):
    """The 409 of a chunk whose Upload-Offset is not the server's says where the upload stands (its Upload-Offset
    header, `offset_bytes`), and the page carries on from there: the first chunk's offset is spoilt in flight."""
    rig = _ok(served["api"].post("/api/rigs", json={"name": "Spoilt offset"}))["id"]
    spoilt: list[str] = []
    answers: list[tuple[str, int, str | None]] = []

    def spoil_the_first_chunk(route):
        if route.request.method == "PATCH" and not spoilt:
            spoilt.append(route.request.url)
            route.continue_(headers={**route.request.headers, "upload-offset": "4096"})
        else:
            route.continue_()

    page.route("**/api/uploads/*", spoil_the_first_chunk)
    page.on("response", lambda r: answers.append((r.request.method, r.status, r.headers.get("upload-offset")))
            if "/api/uploads/" in r.url else None)
    page.goto(f"/#/rigs/{rig}")
    page.locator('[data-rig-clip="static-left"]').set_input_files(tiny_clip(served, "spoilt-static"))
    page.locator('.rig-clip[data-clip-kind="static"][data-camera="left"]').get_by_text("spoilt-static.avi").wait_for()
    patches = [(status, offset) for method, status, offset in answers if method == "PATCH"]
    assert spoilt and patches[0] == (409, "0") and patches[1][0] == 204, answers
    clips = _ok(served["api"].get(f"/api/rigs/{rig}/clips"))
    assert [(c["clip_kind"], c["camera_role"]) for c in clips] == [("static", "left")]
    assert page.console.unexpected(409) == []

"""The dashboard on object storage (issue 26 part 2): the rig page's clip upload sends its bytes straight
to the bucket of a real SeaweedFS with part URLs the API signs (same dashboard code as the streamed path),
and the API keeps no byte of the clip."""

from __future__ import annotations

import pytest
import s3_server as s3_server_module
from browser_harness import chromium_for_module, new_club_admin, serve_fresh
from dashboard_helpers import EMAIL, PASSWORD, _ok, _require_browser, open_page, tiny_clip

from saddlescope.storage import S3Storage

s3_server = s3_server_module.s3_server  # one SeaweedFS for the session (tests/s3_server.py)

pytestmark = [pytest.mark.browser, pytest.mark.slow]


@pytest.fixture(scope="module")
def served(tmp_path_factory, s3_server):
    """A `saddlescope serve` whose clips live in a fresh bucket, with a club and a rig with a board."""
    sync_playwright = _require_browser()
    root = tmp_path_factory.mktemp("direct-pages")
    bucket = s3_server.new_bucket("pages")
    bucket_env = {**s3_server.environ(), "SADDLESCOPE_STORAGE_URL": f"s3://{bucket}/club"}
    with serve_fresh(root, extra_env=bucket_env) as server, new_club_admin(
            server.base, club_name="Bucket Club", email=EMAIL, password=PASSWORD, display_name="Secretary") as api:
        rig = _ok(api.post("/api/rigs", json={"name": "Bucket arena", "board": {
            "kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0}}))["id"]
        yield {"base": server.base, "api": api, "root": root, "rig": rig, "playwright": sync_playwright,
               "bucket": bucket, "log": server.log}


@pytest.fixture(scope="module")
def browser(served):
    with chromium_for_module(served["playwright"]) as chromium:
        yield chromium


def test_a_clip_goes_from_the_page_straight_to_the_bucket(browser, served, s3_server, monkeypatch):
    page = open_page(browser, served)
    sent_to: list[str] = []
    page.on("request", lambda request: sent_to.append(f"{request.method} {request.url.split('?')[0]}"))
    page.goto(f"/#/rigs/{served['rig']}")
    clip = tiny_clip(served, "bucket-left")
    page.locator('[data-rig-clip="calibration-left"]').set_input_files(clip)
    card = page.locator('.rig-clip[data-clip-kind="calibration"][data-camera="left"]')
    card.get_by_text("bucket-left.avi").wait_for()
    s3 = s3_server.endpoint_url
    assert any(line.startswith(f"PUT {s3}/{served['bucket']}/club/uploads/") for line in sent_to), sent_to
    assert not any(line.startswith("PATCH ") for line in sent_to)  # no byte through the API
    for name, value in s3_server.environ().items():
        monkeypatch.setenv(name, value)
    bucket = S3Storage(served["bucket"], "club", endpoint_url=s3)
    clips = list(bucket.iter_keys(f"rigs/{served['rig']}/clips"))
    assert len(clips) == 1 and bucket.read_bytes(clips[0]) == clip["buffer"]
    on_disk = [p for p in (served["root"] / "var").rglob("*") if p.is_file()]
    assert all(p.name.startswith(("db.sqlite", "secret_key")) for p in on_disk), on_disk
    assert page.console.unexpected() == []
    page.context.close()

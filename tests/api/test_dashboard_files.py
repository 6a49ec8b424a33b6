"""The dashboard's files as the browser gets them: each page's markup beside its module (issue 34 part 6)
is served as the modules are (revalidated by ETag, the security headers), and the shell is small."""

from __future__ import annotations

from pathlib import Path

import pytest
from api_helpers import settings_for
from fastapi.testclient import TestClient

from saddlescope.api import create_app

FRONTEND = Path(__file__).resolve().parents[2] / "frontend"


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    with TestClient(create_app(settings_for(tmp_path_factory.mktemp("files")))) as client:
        yield client


def test_each_pages_markup_is_served_like_its_module(client):
    files = sorted(p.relative_to(FRONTEND).as_posix() for p in (FRONTEND / "js").rglob("*.html"))
    assert "js/views/ride.html" in files and "js/ride-edit.html" in files
    for name in files:
        markup, module = client.get(f"/{name}"), client.get(f"/{name.removesuffix('.html')}.js")
        assert markup.status_code == 200 and module.status_code == 200, name
        assert markup.headers["content-type"].startswith("text/html"), name
        assert markup.text == (FRONTEND / name).read_text(encoding="utf-8")
        assert markup.headers["cache-control"] == module.headers["cache-control"] == "no-cache", name
        assert "frame-ancestors 'none'" in markup.headers["content-security-policy"], name
        again = client.get(f"/{name}", headers={"If-None-Match": markup.headers["etag"]})
        assert again.status_code == 304, name  # a returning browser revalidates it for a few bytes


def test_the_shell_is_small_and_holds_no_page(client):
    shell = client.get("/")
    assert shell.status_code == 200 and 'id="view"' in shell.text
    assert 'id="page-ride"' not in shell.text and 'id="page-unreachable"' in shell.text
    assert len(shell.content) < 8_000  # was 80 kB with every page's markup

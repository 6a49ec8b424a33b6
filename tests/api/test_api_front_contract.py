"""What the dashboard reads, the API sends (issue 34 part 6): each ride carries its horse's and rider's
names (the pages once looked them up in lists capped at 500), and the constants the pages label with
(the indicator table, the glossary) are open without signing in, so the app loads them before its first
page, sign-in page included."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from api_helpers import new_club
from engines import open_env

from saddlescope.core.vibration import GAITS, INDICATORS, PASSIVE_SEATED_CAVEAT
from saddlescope.db.enums import SaddleType


@pytest.fixture(scope="module", params=["embedded"])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


def test_every_ride_answer_names_its_horse_and_rider(env):
    api, _ = new_club(env.client)
    horse = api.ok("POST", "/horses", 201, json={"name": "Quintus"})
    rider = api.ok("POST", "/riders", 201, json={"name": "Rider Q"})
    other = api.ok("POST", "/horses", 201, json={"name": "Ulla"})
    made = api.ok("POST", "/rides", 201, json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk",
                                               "direction": "CW"})
    assert (made["horse_name"], made["rider_name"]) == ("Quintus", "Rider Q")
    listed = api.ok("GET", "/rides", params={"limit": 1})["items"]
    assert [(r["id"], r["horse_name"], r["rider_name"]) for r in listed] == [(made["id"], "Quintus", "Rider Q")]
    assert api.ok("GET", f"/rides/{made['id']}")["horse_name"] == "Quintus"
    moved = api.ok("PATCH", f"/rides/{made['id']}", json={"horse_id": other["id"]})
    assert moved["horse_name"] == "Ulla"
    api.ok("PATCH", f"/horses/{other['id']}", json={"name": "Ulla II"})
    assert api.ok("GET", "/rides")["items"][0]["horse_name"] == "Ulla II"


def test_the_indicator_table_and_glossary_need_no_sign_in(env):
    env.client.cookies.clear()
    indicators = env.client.get("/api/indicators")
    assert indicators.status_code == 200, indicators.text
    assert {item["key"] for item in indicators.json()} == set(INDICATORS)
    assert all(item["better"] in ("lower", "higher", None) for item in indicators.json())
    glossary = env.client.get("/api/glossary")
    assert glossary.status_code == 200, glossary.text
    by_kind: dict[str, dict[str, str]] = {}
    for entry in glossary.json():
        by_kind.setdefault(entry["kind"], {})[entry["code"]] = entry["label"]
    # what the dashboard once kept copies of: gaits (in the core's order), saddle types, the caveat
    assert list(by_kind["gait"]) == list(GAITS)
    assert set(by_kind["saddle_type"]) == {t.value for t in SaddleType}
    assert by_kind["saddle_type"]["gp"] == "general purpose"
    assert by_kind["caveat"] == {"passive_seated": PASSIVE_SEATED_CAVEAT}


def test_the_dashboards_page_size_is_the_apis_largest(env):
    """api.js getAll reads lists MAX_PAGE_ROWS at a time: more than the API allows would be refused (422)."""
    source = (Path(__file__).parents[2] / "frontend" / "js" / "api.js").read_text(encoding="utf-8")
    rows = int(re.search(r"export const MAX_PAGE_ROWS = (\d+);", source).group(1))
    schema = env.client.get("/openapi.json").json()
    for path in ("/api/horses", "/api/riders", "/api/saddles", "/api/rigs", "/api/rides"):
        limit = next(p for p in schema["paths"][path]["get"]["parameters"] if p["name"] == "limit")
        assert limit["schema"]["maximum"] == rows, path

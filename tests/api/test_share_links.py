"""Share links (issue 37, the vet's view): a member makes a read-only link to one ride's report or one
horse's page; anyone with it reads that and nothing else, without an account, until it expires or an
admin withdraws it.

Results are stored as the analyse stage would (tests/e2e/test_dashboard.py's seeded documents).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import re
import sys

import numpy as np
import pytest
from api_helpers import add_member, new_club, settings_for
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, select, update

from conftest import PROJECT_ROOT
from saddlescope.api import create_app
from saddlescope.db.models import ShareLink

sys.path.insert(0, str(PROJECT_ROOT / "tests" / "e2e"))
from dashboard_helpers import result_document, store_result  # noqa: E402


@pytest.fixture(scope="module")
def club(tmp_path_factory):
    root = tmp_path_factory.mktemp("share")
    settings = settings_for(root)
    rng = np.random.default_rng(5)
    with TestClient(create_app(settings)) as client:
        admin, _ = new_club(client)
        member, _ = add_member(admin)
        rider = admin.ok("POST", "/riders", 201, json={"name": "Anna"})
        horses, rides = {}, {}
        for name in ("Bella", "Cosmo"):
            horses[name] = admin.ok("POST", "/horses", 201, json={"name": name})["id"]
            rides[name] = []
            for i in range(2):
                ride = admin.ok("POST", "/rides", 201, json={
                    "horse_id": horses[name], "rider_id": rider["id"], "gait": "canter", "direction": "CW",
                    "ridden_on": (dt.date(2026, 4, 1) + dt.timedelta(days=i)).isoformat()})
                store_result(settings.database_url, root / "storage", ride["id"],
                             result_document(scale=1.0 + 0.1 * i, gait="canter", rng=rng))
                rides[name].append(ride["id"])
        other, _ = new_club(client)
        other_horse = other.ok("POST", "/horses", 201, json={"name": "Stranger"})["id"]
        yield {"client": client, "admin": admin, "member": member, "other": other, "other_horse": other_horse,
               "horses": horses, "rides": rides, "database_url": settings.database_url}


def _share(api, **body) -> dict:
    return api.ok("POST", "/share-links", 201, json=body)


def _open(client, path: str, *, method: str = "GET"):
    client.cookies.clear()
    return client.request(method, path)  # no Authorization header: the vet has no account


def test_a_member_makes_a_ride_link_that_opens_its_report_without_an_account(club):
    made = _share(club["member"], ride_id=club["rides"]["Bella"][0])
    assert made["kind"] == "ride" and made["state"] == "active" and made["path"].startswith("/shared/")
    token = made["path"].removeprefix("/shared/")
    assert len(token) >= 43 and re.fullmatch(r"[A-Za-z0-9_-]+", token)  # 32 random bytes, URL-safe
    lifetime = dt.datetime.fromisoformat(made["expires_at"]) - dt.datetime.fromisoformat(made["created_at"])
    assert round(lifetime.total_seconds() / 86400) == 30  # the default
    page = _open(club["client"], made["path"])
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "Ride report: Bella" in page.text and "Back to the ride" not in page.text  # no way into the app
    assert "/api/" not in page.text and "/#/" not in page.text
    csp = page.headers["content-security-policy"]
    assert "default-src 'none'" in csp and "script-src" not in csp and "frame-ancestors 'none'" in csp
    assert page.headers["cache-control"] == "private, no-store" and page.headers["referrer-policy"] == "no-referrer"
    assert page.headers["x-frame-options"] == "DENY"
    assert "Back to the horse" not in page.text and f'href="{token}/report.pdf"' in page.text


@pytest.mark.slow  # WeasyPrint
def test_a_ride_link_gives_its_report_as_pdf(club):
    made = _share(club["member"], ride_id=club["rides"]["Bella"][0])
    pdf = _open(club["client"], made["path"] + "/report.pdf")
    assert pdf.status_code == 200 and pdf.content.startswith(b"%PDF")


def test_only_the_tokens_hash_is_stored(club):
    made = _share(club["member"], ride_id=club["rides"]["Bella"][1], days=7)
    token = made["path"].removeprefix("/shared/")
    engine = create_engine(club["database_url"])
    try:
        with engine.connect() as connection:
            stored = connection.execute(select(ShareLink.token_hash).where(ShareLink.id == made["id"])).scalar_one()
    finally:
        engine.dispose()
    assert stored == hashlib.sha256(token.encode()).hexdigest() and token not in stored
    assert all("path" not in link and token not in str(link) for link in club["admin"].ok("GET", "/share-links"))


def test_a_ride_link_reaches_nothing_else(club):
    client, bella = club["client"], club["rides"]["Bella"]
    made = _share(club["member"], ride_id=bella[0])
    path = made["path"]
    for other in (f"{path}/rides/{bella[1]}", f"{path}/rides/{bella[0]}", f"{path}/rides/{club['rides']['Cosmo'][0]}"):
        answer = _open(client, other)
        assert answer.status_code == 404 and "does not show" in answer.text, other
        assert "Bella" not in answer.text and "Cosmo" not in answer.text
    # the club's API, its lists and the ride's own routes need an account, token or not
    for api_path in ("/api/rides", "/api/horses", f"/api/rides/{bella[0]}/report", f"/api/rides/{bella[0]}/result",
                     "/api/share-links", f"/api/horses/{club['horses']['Bella']}"):
        assert _open(client, api_path).status_code == 401, api_path
        client.cookies.clear()
        token = path.removeprefix("/shared/")
        assert client.get(api_path, headers={"Authorization": f"Bearer {token}"}).status_code == 401, api_path
    # GET only: no write through the link
    for method in ("POST", "PUT", "PATCH", "DELETE"):
        assert _open(client, path, method=method).status_code == 405, method
        assert _open(client, path + "/report.pdf", method=method).status_code == 405, method


def test_a_horse_link_shows_its_rides_and_their_reports_but_no_other_horses(club):
    client, bella, cosmo = club["client"], club["rides"]["Bella"], club["rides"]["Cosmo"]
    made = _share(club["member"], horse_id=club["horses"]["Bella"], days=365)
    assert made["kind"] == "horse" and "Bella" in made["shows"]
    page = _open(client, made["path"])
    assert page.status_code == 200 and "<h1>Bella</h1>" in page.text and "Canter: 2 analysed rides" in page.text
    assert "Cosmo" not in page.text and "<script" not in page.text
    text = re.sub(r"<[^>]+>", " ", page.text.split("<main", 1)[1])
    assert not re.findall(r"\bnull\b|\bNaN\b|\bundefined\b|\bNone\b|\b[a-z]+_[a-z0-9_]+\b", text)
    assert not re.findall(r"\d\.\d{4,}", text)  # no number with more digits than it means
    token = made["path"].removeprefix("/shared/")
    assert f'href="{token}/rides/{bella[1]}"' in page.text
    report = _open(client, f"{made['path']}/rides/{bella[1]}")
    assert report.status_code == 200 and "Ride report: Bella" in report.text and "Back to the horse" in report.text
    refused = _open(client, f"{made['path']}/rides/{cosmo[0]}")
    assert refused.status_code == 404 and "Cosmo" not in refused.text
    assert _open(client, f"{made['path']}/report.pdf").status_code == 404  # a horse link has no single report
    for method in ("POST", "DELETE"):
        assert _open(client, f"{made['path']}/rides/{bella[1]}", method=method).status_code == 405


def test_an_unknown_or_cut_token_is_a_plain_not_found_page(club):
    made = _share(club["member"], ride_id=club["rides"]["Bella"][0])
    for path in ("/shared/" + "A" * 43, made["path"][:-3], "/shared/x"):
        answer = _open(club["client"], path)
        assert answer.status_code == 404 and "This link is not known" in answer.text, path
        assert "location" not in answer.headers and "sign in" not in answer.text.lower()


def test_an_admin_withdraws_a_link_and_it_is_refused_in_plain_words(club):
    made = _share(club["member"], ride_id=club["rides"]["Bella"][0])
    assert _open(club["client"], made["path"]).status_code == 200
    listed = {link["id"]: link for link in club["admin"].ok("GET", "/share-links")}
    mine = listed[made["id"]]
    assert mine["state"] == "active" and mine["created_by"] and "Bella" in mine["shows"]
    assert "canter" in mine["shows"] and mine["expires_at"] == made["expires_at"]
    revoked = club["admin"].ok("POST", f"/share-links/{made['id']}/revoke")
    assert revoked["state"] == "withdrawn" and revoked["revoked_at"]
    for path in (made["path"], made["path"] + "/report.pdf"):
        answer = _open(club["client"], path)
        assert answer.status_code == 410 and "This link was withdrawn by the club" in answer.text, path
        assert answer.headers["content-type"].startswith("text/html") and "location" not in answer.headers
        assert "Bella" not in answer.text
    assert club["admin"].ok("POST", f"/share-links/{made['id']}/revoke")["state"] == "withdrawn"  # again: same


def test_an_expired_link_is_refused_in_plain_words(club):
    made = _share(club["member"], horse_id=club["horses"]["Cosmo"], days=1)
    engine = create_engine(club["database_url"])
    try:
        with engine.begin() as connection:
            connection.execute(update(ShareLink).where(ShareLink.id == made["id"])
                               .values(expires_at=dt.datetime.now(dt.UTC) - dt.timedelta(minutes=1)))
    finally:
        engine.dispose()
    answer = _open(club["client"], made["path"])
    assert answer.status_code == 410 and "This link has expired" in answer.text and "Cosmo" not in answer.text
    assert _open(club["client"], f"{made['path']}/rides/{club['rides']['Cosmo'][0]}").status_code == 410
    states = {link["id"]: link["state"] for link in club["admin"].ok("GET", "/share-links")}
    assert states[made["id"]] == "expired"


def test_only_admins_list_and_withdraw_links_and_only_their_clubs(club):
    made = _share(club["member"], ride_id=club["rides"]["Bella"][0])
    assert club["member"].get("/share-links").status_code == 403
    assert club["member"].post(f"/share-links/{made['id']}/revoke").status_code == 403
    assert club["other"].post(f"/share-links/{made['id']}/revoke").status_code == 404
    assert made["id"] not in {link["id"] for link in club["other"].ok("GET", "/share-links")}
    # a link to another club's ride or horse cannot be made
    assert club["member"].post("/share-links", json={"horse_id": club["other_horse"]}).status_code == 404
    assert club["other"].post("/share-links", json={"ride_id": club["rides"]["Bella"][0]}).status_code == 404


@pytest.mark.parametrize("body", [{}, {"ride_id": 1, "horse_id": 1}, {"ride_id": 1, "days": 0},
                                  {"ride_id": 1, "days": 366}, {"horse_id": 1, "token": "mine"}])
def test_a_link_needs_one_ride_or_horse_and_a_lifetime_of_a_day_to_a_year(club, body):
    answer = club["member"].post("/share-links", json=body)
    assert answer.status_code == 422 and answer.json()["detail"]


def test_deleting_the_ride_ends_its_links(club):
    rider = club["admin"].ok("GET", "/riders")["items"][0]["id"]
    ride = club["admin"].ok("POST", "/rides", 201, json={
        "horse_id": club["horses"]["Cosmo"], "rider_id": rider, "gait": "walk", "direction": "CW"})
    made = _share(club["admin"], ride_id=ride["id"])
    assert _open(club["client"], made["path"]).status_code == 404  # not analysed: no report yet, said so
    assert "not been analysed" in _open(club["client"], made["path"]).text
    club["admin"].ok("DELETE", f"/rides/{ride['id']}", 204)
    assert "This link is not known" in _open(club["client"], made["path"]).text

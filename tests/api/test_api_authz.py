"""The authorisation matrix: every endpoint of the app, called by a user of another club, answers 404 (or
403) and never that club's data; called without signing in, 401. The routes are enumerated from the app,
so a new endpoint without an entry here fails the test until it is thought about."""

from __future__ import annotations

import json

import integration_services
import pytest
from api_helpers import Api, add_member, new_club
from engines import ENGINES, open_env
from route_walk import api_routes, call_kwargs, fill

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url

PUBLIC = {
    ("GET", "/api/health"),
    ("POST", "/api/clubs"),
    ("POST", "/api/auth/login"),
    ("POST", "/api/auth/logout"),
    ("POST", "/api/auth/password-reset"),  # the one-time token is the credential
    ("GET", "/api/glossary"),  # the words for the service's codes, the same for everyone (the sign-in page's too)
    ("GET", "/api/indicators"),  # the indicator table, the same for everyone (loaded before the first page)
    ("GET", "/api/board-types"),  # the kinds of calibration board and their fields, the same for everyone
}
# Own-club routes that end the caller's sessions: checked signed out only (they would sign B out).
ENDS_SESSIONS = {("POST", "/api/auth/logout-everywhere")}
SECRET = "Zanzibar-Secret"  # in every name club A owns: it must never show up in club B's answers


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture(scope="module")
def world(env, tmp_path_factory):
    """Club A with one of everything; club B's admin and member."""
    a, account = new_club(env.client, name=f"{SECRET} club {env.engine}")
    a_member, a_user = add_member(a)
    horse = a.ok("POST", "/horses", 201, json={"name": f"{SECRET} horse"})
    rider = a.ok("POST", "/riders", 201, json={"name": f"{SECRET} rider", "user_id": a_user["id"]})
    rig = a.ok(
        "POST",
        "/rigs",
        201,
        json={"name": f"{SECRET} rig", "board": {"inner_corners": [9, 6], "square_mm": 50}},
    )
    saddle = a.ok("POST", "/saddles", 201, json={"name": f"{SECRET} saddle", "notes": SECRET})
    ride = a.ok(
        "POST",
        "/rides",
        201,
        json={
            "horse_id": horse["id"],
            "rider_id": rider["id"],
            "rig_id": rig["id"],
            "saddle_id": saddle["id"],
            "gait": "walk",
            "direction": "CW",
            "notes": SECRET,
        },
    )
    grade = a.ok(
        "POST",
        "/grades",
        201,
        json={"ride_id": ride["id"], "rider_id": rider["id"], "grade": 3, "comment": SECRET},
    )
    job = a.ok("POST", "/jobs", 201, json={"kind": "selftest", "payload": {"steps": 1, "delay_s": 0}})
    upload = a.ok(
        "POST",
        "/uploads",
        201,
        json={
            "target": "ride_clip",
            "ride_id": ride["id"],
            "clip_kind": "motion",
            "camera": "left",
            "length_bytes": 10,
            "filename": f"{SECRET}.mp4",
        },
    )
    link = a.ok("POST", "/share-links", 201, json={"horse_id": horse["id"]})
    b, _ = new_club(env.client)
    b_member, _ = add_member(b)
    ids = {
        "link_id": link["id"],
        "horse_id": horse["id"],
        "rider_id": rider["id"],
        "rig_id": rig["id"],
        "saddle_id": saddle["id"],
        "ride_id": ride["id"],
        "other_id": ride["id"],
        "grade_id": grade["id"],
        "job_id": job["id"],
        "upload_id": upload["id"],
        "user_id": a_user["id"],
        "fmt": "json",
        "clip_kind": "motion",
        "camera": "left",
    }
    return {
        "a": a,
        "b": b,
        "b_member": b_member,
        "ids": ids,
        "a_admin_id": account["user"]["id"],
        "tiny": integration_services.write_tiny_bundle(tmp_path_factory.mktemp("authz") / "ride"),
    }


# Routes that touch no other club's row by construction: they answer for the caller's own club.
OWN_CLUB = {
    ("GET", "/api/auth/me"),
    ("GET", "/api/health/details"),  # the server's, no club's: admins of any club
    ("POST", "/api/auth/password"),
    ("GET", "/api/jobs/kinds"),
    ("POST", "/api/horses"),
    ("POST", "/api/saddles"),
    ("GET", "/api/saddles"),
    ("POST", "/api/rigs"),
    ("GET", "/api/horses"),
    ("GET", "/api/riders"),
    ("GET", "/api/rigs"),
    ("GET", "/api/users"),
    ("GET", "/api/grades/correlation"),
    ("GET", "/api/leaderboard"),
    ("GET", "/api/rides/export/{fmt}"),
    ("POST", "/api/users"),
    ("GET", "/api/rides"),
    ("GET", "/api/grades"),
    ("GET", "/api/jobs"),
    ("GET", "/api/share-links"),
}
# Routes whose body or query names club A's things: refused as not found (or invalid), never done.
REFERENCES = {
    ("POST", "/api/rides"),
    ("POST", "/api/grades"),
    ("POST", "/api/jobs"),
    ("POST", "/api/uploads"),
    ("POST", "/api/riders"),
    ("POST", "/api/rides/bundle"),
    ("POST", "/api/mocap"),
    ("GET", "/api/comparison"),
    ("POST", "/api/share-links"),
}


def test_every_route_is_in_the_matrix(env):
    routes = api_routes(env.client.app)
    assert len(routes) > 40
    for method, path in routes:
        known = (method, path) in PUBLIC | OWN_CLUB | REFERENCES | ENDS_SESSIONS or "{" in path
        assert known, f"{method} {path}: add it to the authorisation matrix"


def test_another_clubs_ids_are_not_found_and_no_data_leaks(env, world):
    ids, tiny = world["ids"], world["tiny"]
    checked = 0
    for caller in (world["b"], world["b_member"]):
        for method, path in api_routes(env.client.app):
            if (method, path) in PUBLIC | ENDS_SESSIONS:
                continue
            response = caller.request(method, fill(path, ids), **call_kwargs(method, path, ids, tiny))
            where = f"{method} {path} -> {response.status_code} {response.text[:300]}"
            assert SECRET not in response.text, where
            assert response.status_code < 500, where
            if (method, path) in OWN_CLUB:
                assert response.status_code in (200, 201, 403, 409, 422), where
            elif (method, path) in REFERENCES:
                assert response.status_code in (403, 404, 422), where
                if response.status_code == 422:  # only for a reference that cannot be in the caller's club
                    assert "no horse" in response.text or "not found" in response.text, where
            else:
                assert response.status_code in (403, 404), where
            if (
                response.status_code == 404 and method != "HEAD"
            ):  # ours ("ride 3 not found"), not a missing route's
                assert response.json()["detail"] != "Not Found", where
            checked += 1
    assert checked > 80
    # nothing of club A changed
    a = world["a"]
    assert a.ok("GET", f"/horses/{ids['horse_id']}")["name"] == f"{SECRET} horse"
    assert a.ok("GET", f"/rides/{ids['ride_id']}")["notes"] == SECRET
    assert a.ok("GET", f"/grades/{ids['grade_id']}")["grade"] == 3
    assert a.ok("GET", f"/uploads/{ids['upload_id']}")["offset_bytes"] == 0
    assert a.ok("GET", f"/users/{ids['user_id']}")["display_name"] == ""
    assert a.ok("GET", "/rides")["total"] == 1


def test_signed_out_calls_are_401(env, world):
    anonymous = Api(env.client)
    env.client.cookies.clear()
    ids, tiny = world["ids"], world["tiny"]
    for method, path in api_routes(env.client.app):
        if (method, path) in PUBLIC:
            continue
        response = anonymous.request(method, fill(path, ids), **call_kwargs(method, path, ids, tiny))
        assert response.status_code == 401, f"{method} {path} -> {response.status_code} {response.text[:200]}"
        if method != "HEAD":
            assert "not signed in" in response.json()["detail"]
        assert response.headers.get("www-authenticate") == "Bearer"


def test_a_forged_or_expired_token_is_401(env, world):
    import datetime as dt

    import jwt

    from saddlescope.services.accounts.users import TOKEN_AUDIENCE

    token = world["b"].headers["Authorization"].removeprefix("Bearer ")
    claims = jwt.decode(token, options={"verify_signature": False})
    claims["club"] = 1 if claims["club"] != 1 else 2  # try to move into another club
    forged = jwt.encode(claims, "guessed-secret-of-some-length-000000", algorithm="HS256")
    assert Api(env.client, forged).get("/horses").status_code == 401
    past = dict(claims, exp=dt.datetime(2020, 1, 1, tzinfo=dt.UTC), aud=TOKEN_AUDIENCE)
    expired = jwt.encode(past, "whatever-secret-000000000000000000", algorithm="HS256")
    response = Api(env.client, expired).get("/horses")
    assert response.status_code == 401
    assert json.loads(response.text)["detail"] in (
        "invalid access token; sign in again",
        "the sign-in has expired; sign in again",
    )

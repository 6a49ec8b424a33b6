"""Sessions can be ended: logout everywhere, a password change and an admin's password reset make every
older token invalid; the reset is a one-time token; adding a user names no other club's account."""

from __future__ import annotations

import datetime as dt

import integration_services
import pytest
from api_helpers import Api, add_member, new_club, sign_in
from engines import ENGINES, open_env

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url

ENDED = "this sign-in was ended"


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


def test_logout_everywhere_ends_every_token(env):
    admin, account = new_club(env.client)
    second = sign_in(env.client, account["email"], account["password"])
    assert admin.get("/auth/me").status_code == second.get("/auth/me").status_code == 200
    assert second.request("POST", "/auth/logout-everywhere").status_code == 204
    for api in (admin, second):
        refused = api.get("/auth/me")
        assert refused.status_code == 401 and ENDED in refused.json()["detail"]
    assert sign_in(env.client, account["email"], account["password"]).get("/auth/me").status_code == 200


def test_a_password_change_needs_the_current_one_and_ends_the_old_sessions(env):
    admin, account = new_club(env.client, password="old password 1")
    wrong = admin.request("POST", "/auth/password",
                          json={"current_password": "not it at all", "new_password": "new password 2"})
    assert wrong.status_code == 422 and "current password is wrong" in wrong.json()["detail"]
    assert admin.get("/auth/me").status_code == 200
    changed = admin.request("POST", "/auth/password",
                            json={"current_password": "old password 1", "new_password": "new password 2"})
    assert changed.status_code == 204, changed.text
    assert admin.get("/auth/me").status_code == 401
    old = env.client.post("/api/auth/login", data={"username": account["email"], "password": "old password 1"})
    assert old.status_code == 401
    assert sign_in(env.client, account["email"], "new password 2").get("/auth/me").status_code == 200


def test_an_admin_reset_ends_the_users_sessions_and_issues_a_one_time_token(env):
    admin, _ = new_club(env.client)
    member, user = add_member(admin, password="member password")
    out = admin.ok("POST", f"/users/{user['id']}/password-reset", 201)
    assert out["reset_token"] and "/api/auth/password-reset" in out["how"]
    assert dt.datetime.fromisoformat(out["expires_at"]) > dt.datetime.now(dt.UTC)
    assert member.get("/auth/me").status_code == 401  # the old token is dead
    old = env.client.post("/api/auth/login", data={"username": user["email"], "password": "member password"})
    assert old.status_code == 401  # and so is the old password
    body = {"token": out["reset_token"], "new_password": "brand new secret"}
    assert env.client.post("/api/auth/password-reset", json=body).status_code == 204
    again = env.client.post("/api/auth/password-reset", json={**body, "new_password": "attacker's choice"})
    assert again.status_code == 401 and "already used" in again.json()["detail"]
    assert sign_in(env.client, user["email"], "brand new secret").get("/auth/me").status_code == 200
    forged = env.client.post("/api/auth/password-reset", json={**body, "token": "made-up"})
    assert forged.status_code == 401


def test_an_admin_changing_a_password_by_patch_also_ends_the_sessions(env):
    admin, _ = new_club(env.client)
    member, user = add_member(admin)
    admin.ok("PATCH", f"/users/{user['id']}", json={"password": "set by the admin"})
    assert member.get("/auth/me").status_code == 401


def test_adding_a_user_does_not_reveal_an_address_of_another_club(env):
    a, _ = new_club(env.client)
    _, a_user = add_member(a)
    b, b_account = new_club(env.client)
    other_club = b.request("POST", "/users", json={"email": a_user["email"], "password": "password 123"})
    own_club = b.request("POST", "/users", json={"email": b_account["email"], "password": "password 123"})
    assert other_club.status_code == own_club.status_code == 409
    assert other_club.json() == own_club.json()
    assert a_user["email"] not in other_club.text and "already exists" not in other_club.text


def test_a_token_without_the_session_version_is_refused_after_a_logout_everywhere(env):
    import jwt

    admin, account = new_club(env.client)
    token = admin.headers["Authorization"].removeprefix("Bearer ")
    assert jwt.decode(token, options={"verify_signature": False})["sv"] == 0
    admin.request("POST", "/auth/logout-everywhere")
    assert Api(env.client, token).get("/auth/me").status_code == 401


def test_guessing_the_current_password_locks_it_like_a_sign_in(env):
    admin, _ = new_club(env.client, password="the real one 1")
    for i in range(env.settings.login_max_failures):
        wrong = admin.request("POST", "/auth/password",
                              json={"current_password": f"guess number {i}", "new_password": "taken over 1"})
        assert wrong.status_code == 422
    right = admin.request("POST", "/auth/password",
                          json={"current_password": "the real one 1", "new_password": "taken over 1"})
    assert right.status_code == 429 and "locked" in right.json()["detail"] and right.headers["Retry-After"]


def test_a_newer_reset_cancels_the_earlier_token(env):
    admin, _ = new_club(env.client)
    _, user = add_member(admin)
    first = admin.ok("POST", f"/users/{user['id']}/password-reset", 201)["reset_token"]
    second = admin.ok("POST", f"/users/{user['id']}/password-reset", 201)["reset_token"]
    stale = env.client.post("/api/auth/password-reset", json={"token": first, "new_password": "from the old link"})
    assert stale.status_code == 401
    fresh = env.client.post("/api/auth/password-reset", json={"token": second, "new_password": "from the new link"})
    assert fresh.status_code == 204


def test_signing_out_ends_that_sign_ins_bearer_token_and_no_other(env):
    admin, account = new_club(env.client)
    other = sign_in(env.client, account["email"], account["password"])
    assert admin.request("POST", "/auth/logout").status_code == 204
    refused = admin.get("/auth/me")
    assert refused.status_code == 401 and "signed out" in refused.json()["detail"]
    assert other.get("/auth/me").status_code == 200  # another browser or script stays signed in
    assert admin.request("POST", "/auth/logout").status_code == 204  # twice: nothing more to end


def test_signing_out_by_the_cookie_needs_the_csrf_header_and_ends_the_token(env):
    client = env.client
    _, account = new_club(client)
    login = client.post("/api/auth/login", data={"username": account["email"], "password": account["password"]})
    token, csrf = login.json()["access_token"], login.json()["csrf_token"]
    try:
        forged = client.post("/api/auth/logout")  # what a page on another site could make the browser send
        assert forged.status_code == 403 and "X-CSRF-Token" in forged.json()["detail"]
        assert client.cookies.get("saddlescope_session") and client.get("/api/auth/me").status_code == 200
        out = client.post("/api/auth/logout", headers={"X-CSRF-Token": csrf})
        assert out.status_code == 204 and not client.cookies.get("saddlescope_session")
    finally:
        client.cookies.clear()
    # The same sign-in's token as a bearer (a script that copied it) is dead too, not just the cookie.
    refused = Api(client, token).get("/auth/me")
    assert refused.status_code == 401 and "signed out" in refused.json()["detail"]
    assert client.post("/api/auth/logout").status_code == 204  # no cookie, no token: nothing to end

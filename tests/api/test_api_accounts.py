"""Accounts: club registration, password sign-in (form and JSON), bearer tokens, the browser session cookie
with its CSRF token, roles, and users managed by the club's admins."""

from __future__ import annotations

import datetime as dt

import integration_services
import pytest
from api_helpers import Api, add_member, new_club, sign_in
from engines import ENGINES, open_env
from fastapi.testclient import TestClient

from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import User
from saddlescope.db.session import session_factory_for
from saddlescope.services.accounts.users import issue_token, verify_password
from saddlescope.settings import load_settings

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


def test_register_sign_in_with_form_or_json_and_read_me(env):
    api, account = new_club(env.client, password="a long password")
    me = api.ok("GET", "/auth/me")
    assert me["user"]["email"] == account["email"] and me["user"]["role"] == "admin"
    assert me["club"]["id"] == account["club"]["id"]
    credentials = {"email": account["email"].upper(), "password": "a long password"}
    by_json = env.client.post("/api/auth/login", json=credentials)
    assert by_json.status_code == 200 and by_json.json()["token_type"] == "bearer"
    assert by_json.json()["expires_in"] == env.settings.token_lifetime_s
    env.client.cookies.clear()
    with session_factory_for(env.settings.database_url)() as session:
        stored = session.query(User).filter_by(email=account["email"]).one().password_hash
    assert stored.startswith("$argon2id$") and "a long password" not in stored
    assert verify_password(stored, "a long password") and not verify_password(stored, "a long passwore")


def test_wrong_credentials_get_one_message(env):
    _, account = new_club(env.client)
    wrong = env.client.post("/api/auth/login", data={"username": account["email"], "password": "nope nope"})
    unknown = env.client.post(
        "/api/auth/login", data={"username": "nobody@x.example", "password": "nope nope"}
    )
    assert wrong.status_code == unknown.status_code == 401
    assert wrong.json() == unknown.json() == {"detail": "wrong e-mail address or password"}
    missing = env.client.post("/api/auth/login", data={"username": account["email"]})
    assert missing.status_code == 422 and "password" in missing.json()["detail"]
    duplicate = env.client.post(
        "/api/clubs",
        json={"club_name": account["club"]["name"], "email": "x@y.example", "password": "long enough"},
    )
    assert duplicate.status_code == 409 and "already exists" in duplicate.json()["detail"]
    short = env.client.post(
        "/api/clubs", json={"club_name": "Short", "email": "s@y.example", "password": "short"}
    )
    assert short.status_code == 422 and "body.password" in short.json()["detail"]


def test_the_browser_session_cookie_needs_the_csrf_header_on_unsafe_methods(env):
    _, account = new_club(env.client)
    client = env.client
    client.cookies.clear()
    login = client.post(
        "/api/auth/login", data={"username": account["email"], "password": account["password"]}
    )
    session_cookie, csrf = client.cookies.get("saddlescope_session"), client.cookies.get("saddlescope_csrf")
    assert session_cookie and csrf == login.json()["csrf_token"]
    set_cookie = login.headers.get_list("set-cookie")
    assert any("saddlescope_session=" in c and "HttpOnly" in c and "SameSite=lax" in c for c in set_cookie)
    assert any("saddlescope_csrf=" in c and "HttpOnly" not in c for c in set_cookie)
    try:
        assert client.get("/api/horses").status_code == 200  # safe method: the cookie is enough
        refused = client.post("/api/horses", json={"name": "Forged"})
        assert refused.status_code == 403 and "X-CSRF-Token" in refused.json()["detail"]
        wrong = client.post("/api/horses", json={"name": "Forged"}, headers={"X-CSRF-Token": "guess"})
        assert wrong.status_code == 403
        made = client.post("/api/horses", json={"name": "Genuine"}, headers={"X-CSRF-Token": csrf})
        assert made.status_code == 201
        out = client.post("/api/auth/logout", headers={"X-CSRF-Token": csrf})  # a state change too
        assert out.status_code == 204 and not client.cookies.get("saddlescope_session")
        assert client.get("/api/horses").status_code == 401
    finally:
        client.cookies.clear()


def test_admins_manage_users_and_roles_apply_at_once(env):
    admin, account = new_club(env.client)
    member, user = add_member(admin)
    assert member.get("/users").status_code == 403
    assert member.post("/users", json={"email": "x@x.example", "password": "12345678"}).status_code == 403
    duplicate = admin.post("/users", json={"email": user["email"], "password": "password 1"})
    assert duplicate.status_code == 409
    assert admin.ok("GET", "/users")["total"] == 2

    promoted = admin.ok("PATCH", f"/users/{user['id']}", json={"role": "admin"})
    assert promoted["role"] == "admin"
    assert member.ok("GET", "/users")["total"] == 2  # the same token, the new role
    lonely = admin.patch(f"/users/{account['user']['id']}", json={"role": "member"})
    assert lonely.status_code == 200  # another admin remains
    last = member.patch(f"/users/{user['id']}", json={"role": "member"})
    assert last.status_code == 409 and "at least one active admin" in last.json()["detail"]

    member.ok("PATCH", f"/users/{account['user']['id']}", json={"is_active": False})
    gone = admin.get("/horses")
    assert gone.status_code == 401 and "deactivated" in gone.json()["detail"]
    refused = env.client.post(
        "/api/auth/login", data={"username": account["email"], "password": account["password"]}
    )
    assert refused.status_code == 401

    member.ok("PATCH", f"/users/{user['id']}", json={"password": "a new password"})
    assert (
        sign_in(env.client, user["email"], "a new password").ok("GET", "/auth/me")["user"]["id"] == user["id"]
    )


def test_the_last_admin_can_neither_demote_nor_disable_themselves_and_members_manage_no_one(env):
    admin, account = new_club(env.client)
    member, user = add_member(admin)
    me = account["user"]["id"]
    for change in ({"role": "member"}, {"is_active": False}):
        refused = admin.patch(f"/users/{me}", json=change)
        assert refused.status_code == 409, refused.text
        assert "last active admin" in refused.json()["detail"] and "make another member an admin" in (
            refused.json()["detail"])
    mine = admin.ok("GET", f"/users/{me}")
    assert mine["role"] == "admin" and mine["is_active"]  # nothing was changed
    for method, path in (("GET", "/users"), ("GET", f"/users/{me}"), ("POST", f"/users/{me}/password-reset"),
                         ("PATCH", f"/users/{user['id']}"), ("GET", "/health/details")):
        answer = member.request(method, path, json={"role": "admin"} if method == "PATCH" else None)
        assert answer.status_code == 403, (method, path, answer.text)
    assert admin.ok("GET", f"/users/{user['id']}")["role"] == "member"


def test_an_expired_token_is_refused(env):
    _, account = new_club(env.client)
    with session_factory_for(env.settings.database_url)() as session:
        user = session.get(User, account["user"]["id"])
        token, _, _ = issue_token(user, env.settings, now=dt.datetime.now(dt.UTC) - dt.timedelta(days=2))
    response = Api(env.client, token).get("/horses")
    assert (
        response.status_code == 401 and response.json()["detail"] == "the sign-in has expired; sign in again"
    )


def test_registration_is_closed_in_a_deployment_once_a_club_exists(tmp_path):
    settings = load_settings(
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}",
        storage_dir=str(tmp_path / "s"),
        broker_url="redis://127.0.0.1:1/0",
        secret_key="a-deployment-secret-0123456789",
    )
    upgrade_to_head(settings.database_url)
    with TestClient(create_app(settings)) as client:
        new_club(client)  # the first club of a deployment may register
        closed = client.post(
            "/api/clubs", json={"club_name": "Second", "email": "b@b.example", "password": "long enough"}
        )
        assert closed.status_code == 403 and "registration of new clubs is closed" in closed.json()["detail"]
    with TestClient(create_app(settings, open_registration=True)) as client:
        assert (
            client.post(
                "/api/clubs", json={"club_name": "Second", "email": "b@b.example", "password": "long enough"}
            ).status_code
            == 201
        )


def test_passwords_take_rfc_9106_parameters_and_a_suites_cheapest_ones_are_rehashed_at_sign_in(env, caplog):
    from saddlescope.services.accounts import users

    assert load_settings().model_fields["password_hashing"].default == "rfc9106-low-memory"
    assert env.settings.password_hashing == "cheapest-for-tests"  # tests/conftest.py: thousands of sign-ins
    _, account = new_club(env.client, password="a long password")

    def stored() -> str:
        with session_factory_for(env.settings.database_url)() as session:
            return session.query(User).filter_by(email=account["email"]).one().password_hash

    assert "$m=8,t=1,p=1$" in stored()
    club_server = env.settings.model_copy(update={"password_hashing": "rfc9106-low-memory"})
    try:
        with caplog.at_level("WARNING"), TestClient(create_app(club_server)) as client:
            assert "cheapest" not in caplog.text
            signed_in = client.post("/api/auth/login",
                                    data={"username": account["email"], "password": "a long password"})
            assert signed_in.status_code == 200, signed_in.text
        assert "$m=65536,t=3,p=4$" in stored()  # re-hashed with the club server's parameters at sign-in
        assert verify_password(stored(), "a long password") and not verify_password(stored(), "a long passwore")
        with caplog.at_level("WARNING"):
            create_app(env.settings)
        assert "cheapest-for-tests" in caplog.text and "test suites only" in caplog.text
    finally:
        users.use_password_hashing(env.settings.password_hashing)

"""Every Argon2 hash or check of a password runs on the bounded hash pool, never on the request threads.

Admin routes (add a user, set a user's password) and a user's own password change hash too; on the
shared request threads a flood of them would starve every reader (issue 25, item 1).
"""

from __future__ import annotations

import threading

import pytest
from engines import open_env
from integration_services import add_member, new_club

from saddlescope.services.accounts import users as accounts


@pytest.fixture(scope="module", params=["embedded"])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture
def argon2_threads(monkeypatch):
    """The names of the threads that ran Argon2 (hash or verify) during the test."""
    names: list[str] = []
    real = accounts._hasher

    class Recording:
        def hash(self, password, **kw):
            names.append(threading.current_thread().name)
            return real.hash(password, **kw)

        def verify(self, stored, password):
            names.append(threading.current_thread().name)
            return real.verify(stored, password)

        def check_needs_rehash(self, stored):
            return real.check_needs_rehash(stored)

    monkeypatch.setattr(accounts, "_hasher", Recording())
    return names


def _off_the_request_threads(names: list[str]) -> None:
    assert names, "no password was hashed or checked"
    assert all(n.startswith("saddlescope-hash") for n in names), names


def test_adding_a_user_hashes_on_the_pool(env, argon2_threads):
    admin, _ = new_club(env.client)
    argon2_threads.clear()
    admin.ok("POST", "/users", 201, json={"email": "pool.added@club.example", "password": "a good password"})
    _off_the_request_threads(argon2_threads)


def test_an_admin_setting_a_password_hashes_on_the_pool(env, argon2_threads):
    admin, _ = new_club(env.client)
    _, member = add_member(admin)
    argon2_threads.clear()
    admin.ok("PATCH", f"/users/{member['id']}", json={"password": "another good password"})
    _off_the_request_threads(argon2_threads)
    argon2_threads.clear()
    renamed = admin.ok("PATCH", f"/users/{member['id']}", json={"display_name": "Renamed"})
    assert renamed["display_name"] == "Renamed" and argon2_threads == []  # no password: no Argon2


def test_changing_ones_own_password_checks_and_hashes_on_the_pool(env, argon2_threads):
    admin, account = new_club(env.client, password="the old password")
    argon2_threads.clear()
    wrong = admin.post(
        "/auth/password", json={"current_password": "not it", "new_password": "a new password"}
    )
    assert wrong.status_code == 422, wrong.text
    admin.ok(
        "POST",
        "/auth/password",
        204,
        json={"current_password": "the old password", "new_password": "a new password"},
    )
    _off_the_request_threads(argon2_threads)
    assert (
        env.client.post(
            "/api/auth/login", data={"username": account["email"], "password": "a new password"}
        ).status_code
        == 200
    )
    env.client.cookies.clear()


def test_a_full_pool_answers_busy_for_admin_routes_too(env):
    from saddlescope.services.accounts.login_guard import HashPool

    admin, _ = new_club(env.client)
    app = env.client.app
    full, kept = HashPool(workers=1, queue=0), app.state.hash_pool
    gate = threading.Event()
    app.state.hash_pool = full
    try:
        full._executor.submit(gate.wait)  # occupies the one worker ...
        full._slots.acquire()  # ... and its slot
        response = admin.post("/users", json={"email": "busy@club.example", "password": "a good password"})
        assert response.status_code == 503 and "busy" in response.json()["detail"], response.text
    finally:
        gate.set()
        full._slots.release()
        app.state.hash_pool = kept
        full.close()
    assert admin.get("/users").json()["total"] == 1  # nobody was added half-way

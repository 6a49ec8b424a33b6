"""Sign-in under abuse: lock-out per account and per address (429 + Retry-After), Argon2's bounded pool."""

from __future__ import annotations

import asyncio
import threading

import integration_services
import pytest
from api_helpers import new_club
from engines import ENGINES, open_env

from saddlescope.services.login_guard import HashPool, HashPoolBusy, LoginGuard, MemoryCounters

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url


@pytest.fixture(scope="module", params=ENGINES)
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


def _login(env, email, password):
    return env.client.post("/api/auth/login", data={"username": email, "password": password})


def test_sixty_wrong_passwords_then_the_right_one_is_refused(env):
    _, account = new_club(env.client, password="the right password")
    answers = [_login(env, account["email"], f"wrong guess {i}").status_code for i in range(60)]
    assert set(answers[: env.settings.login_max_failures]) == {401}
    assert set(answers[env.settings.login_max_failures:]) == {429}
    right = _login(env, account["email"], "the right password")
    assert right.status_code == 429, right.text
    assert int(right.headers["Retry-After"]) > 0
    assert "too many wrong passwords" in right.json()["detail"] and "locked" in right.json()["detail"]
    env.client.cookies.clear()


def test_a_lockout_of_one_account_leaves_others_signing_in(env):
    _, locked = new_club(env.client)
    _, other = new_club(env.client, password="other password")
    for i in range(env.settings.login_max_failures):
        _login(env, locked["email"], f"wrong {i}")
    assert _login(env, locked["email"], locked["password"]).status_code == 429
    assert _login(env, other["email"], "other password").status_code == 200
    env.client.cookies.clear()


def test_the_address_limit_catches_guessing_over_many_accounts():
    guard = LoginGuard(MemoryCounters(), max_failures=3, lockout_s=60)
    for i in range(12):
        guard.check(f"user{i}@x.example", "10.0.0.9")
        guard.failed(f"user{i}@x.example", "10.0.0.9")
    with pytest.raises(Exception, match="network address") as refused:
        guard.check("fresh@x.example", "10.0.0.9")
    assert refused.value.retry_after_s > 0
    guard.check("fresh@x.example", "10.0.0.10")  # another address is not affected


def test_the_lockout_ends_after_its_window():
    now = [1000.0]
    guard = LoginGuard(MemoryCounters(clock=lambda: now[0]), max_failures=2, lockout_s=60)
    guard.failed("a@x.example", "1.2.3.4")
    guard.failed("a@x.example", "1.2.3.4")
    with pytest.raises(Exception, match="locked for 1 minute"):
        guard.check("a@x.example", "1.2.3.4")
    now[0] += 61
    guard.check("a@x.example", "1.2.3.4")


def test_a_full_hash_pool_answers_busy_instead_of_queueing_without_end():
    pool = HashPool(workers=1, queue=1)
    release = threading.Event()

    async def flood():
        first = asyncio.ensure_future(pool.run(release.wait))
        second = asyncio.ensure_future(pool.run(release.wait))
        await asyncio.sleep(0)
        with pytest.raises(HashPoolBusy, match="busy"):
            await pool.run(lambda: True)
        release.set()
        assert await first and await second
        assert await pool.run(lambda: "free again") == "free again"

    try:
        asyncio.run(flood())
    finally:
        release.set()
        pool.close()


def test_sign_in_and_registration_answer_503_while_the_hash_pool_is_full(env):
    app = env.client.app
    full, kept = HashPool(workers=1, queue=0), app.state.hash_pool
    assert full._slots.acquire(blocking=False)  # every slot taken, as during a flood
    app.state.hash_pool = full
    try:
        club = {"club_name": f"Busy club {env.engine}", "email": f"busy.{env.engine}@x.example",
                "password": "long enough"}
        for response in (env.client.post("/api/clubs", json=club),
                         env.client.post("/api/auth/login", data={"username": club["email"], "password": "x"})):
            assert response.status_code == 503, response.text
            assert "busy" in response.json()["detail"] and int(response.headers["Retry-After"]) > 0
        full._slots.release()
        assert env.client.post("/api/clubs", json=club).status_code == 201
    finally:
        app.state.hash_pool = kept
        full.close()

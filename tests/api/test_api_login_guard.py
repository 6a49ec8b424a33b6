"""Sign-in under abuse: back-offs per account and address, then per address (429 + Retry-After), without
locking out others; Argon2's bounded pool."""

from __future__ import annotations

import asyncio
import threading

import integration_services
import pytest
from api_helpers import new_club
from engines import ENGINES, open_env
from fastapi.testclient import TestClient

from saddlescope.api import create_app
from saddlescope.services.accounts.login_guard import HashPool, HashPoolBusy, LoginGuard, LoginThrottled, MemoryCounters
from saddlescope.settings import load_settings

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


def test_the_address_limit_stops_guessing_over_many_accounts_but_not_a_fresh_account():
    guard = LoginGuard(MemoryCounters(), max_failures=3, lockout_s=60)
    for i in range(12):
        guard.check(f"user{i}@x.example", "10.0.0.9")
        guard.failed(f"user{i}@x.example", "10.0.0.9")
    with pytest.raises(LoginThrottled, match="network address") as refused:
        guard.check("user0@x.example", "10.0.0.9")  # a second guess at an account that failed from here
    assert refused.value.retry_after_s > 0
    guard.check("fresh@x.example", "10.0.0.9")  # an account that has not failed from here may sign in
    guard.check("user0@x.example", "10.0.0.10")  # and another address is not affected


def test_the_lockout_ends_after_its_window():
    now = [1000.0]
    guard = LoginGuard(MemoryCounters(clock=lambda: now[0]), max_failures=2, lockout_s=60)
    guard.failed("a@x.example", "1.2.3.4")
    guard.failed("a@x.example", "1.2.3.4")
    with pytest.raises(Exception, match="locked for 1 minute"):
        guard.check("a@x.example", "1.2.3.4")
    now[0] += 61
    guard.check("a@x.example", "1.2.3.4")


def test_the_back_off_grows_with_failures_and_refused_tries_do_not_prolong_it():
    now = [0.0]
    guard = LoginGuard(MemoryCounters(clock=lambda: now[0]), max_failures=2, lockout_s=900, backoff_s=30,
                       window_s=3600)
    guard.failed("owner@x.example", "10.0.0.1")
    guard.check("owner@x.example", "10.0.0.1")  # one failure is free
    waits = []
    for _ in range(7):  # a guesser who tries again as soon as each back-off ends
        guard.failed("owner@x.example", "10.0.0.1")
        with pytest.raises(LoginThrottled) as refused:
            guard.check("owner@x.example", "10.0.0.1")
        waits.append(refused.value.retry_after_s)
        for _ in range(50):  # hammering during the back-off is refused and not counted
            now[0] += refused.value.retry_after_s / 100
            with pytest.raises(LoginThrottled):
                guard.check("owner@x.example", "10.0.0.1")
        now[0] += refused.value.retry_after_s / 2 + 1  # the back-off is over
        guard.check("owner@x.example", "10.0.0.1")
    assert guard.counters.get(guard._keys("owner@x.example", "10.0.0.1")[0]).count == 8
    assert waits == [30, 60, 120, 240, 480, 900, 900]  # doubling from the 2nd failure's 30 s, at most 900
    # The window is fixed from the first failure: an hour later the count starts again.
    now[0] = 3601.0
    guard.check("owner@x.example", "10.0.0.1")
    guard.failed("owner@x.example", "10.0.0.1")
    guard.check("owner@x.example", "10.0.0.1")


def test_a_guesser_and_another_member_behind_one_router(tmp_path):
    """Two people behind one address (the club's router, seen through a trusted proxy): the guesser is
    stopped, the other member signs in, and the guessed account's owner signs in from home."""
    settings = load_settings(database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=str(tmp_path / "s"),
                             secret_key="a-test-secret-of-enough-length", forwarded_allow_ips="testclient")
    with TestClient(create_app(settings)) as client:
        _, victim = new_club(client, password="the victim's password")
        _, member = new_club(client, password="the member's password")

        def login(account, password, address):
            answer = client.post("/api/auth/login", data={"username": account["email"], "password": password},
                                 headers={"X-Forwarded-For": address})
            client.cookies.clear()
            return answer.status_code

        router, home = "203.0.113.7", "198.51.100.20"
        guesses = [login(victim, f"guess {i}", router) for i in range(60)]
        assert guesses[:settings.login_max_failures] == [401] * settings.login_max_failures
        assert set(guesses[settings.login_max_failures:]) == {429}  # the guesser is stopped
        assert login(victim, "the victim's password", router) == 429  # even the right one, from there
        assert login(member, "the member's password", router) == 200  # the other person signs in
        assert login(victim, "the victim's password", home) == 200  # and the owner, from another address
        # The header of a peer that is not a trusted proxy is ignored: no dodging by inventing addresses.
        settings_untrusted = settings.model_copy(update={"forwarded_allow_ips": "127.0.0.1"})
        client.app.state.settings = settings_untrusted
        for i in range(settings.login_max_failures):
            assert login(member, f"guess {i}", f"192.0.2.{i}") == 401
        assert login(member, "the member's password", "192.0.2.99") == 429


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

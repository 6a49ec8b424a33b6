"""Drill: the sign-in counters live in Redis, so every API process sees one back-off; Redis going away
does not turn sign-in into a 500 (the processes count locally meanwhile). Uses a redis-server of its own."""

from __future__ import annotations

import pytest
from integration_services import own_redis_server

from saddlescope.services.accounts.login_guard import LoginGuard, LoginThrottled, RedisCounters, make_login_guard
from saddlescope.settings import load_settings

pytestmark = pytest.mark.integration


@pytest.fixture
def own_redis(tmp_path):
    with own_redis_server(tmp_path) as (proc, url):
        yield proc, url


def test_two_api_processes_share_one_lockout_and_survive_redis_going_away(own_redis):
    proc, url = own_redis
    settings = load_settings(broker_url=url, secret_key="a-drill-secret-0123456789",
                             login_max_failures=3, login_lockout_s=600)
    first, second = make_login_guard(settings), make_login_guard(settings)
    assert isinstance(first.counters, RedisCounters)
    for _ in range(3):
        first.check("rider@club.example", "10.1.1.1")
        first.failed("rider@club.example", "10.1.1.1")
    with pytest.raises(LoginThrottled, match="locked") as refused:
        second.check("rider@club.example", "10.1.1.1")  # the other process sees the same back-off
    assert 0 < refused.value.retry_after_s <= 600
    second.check("rider@club.example", "10.9.9.9")  # the owner from another address is not refused
    second.check("someone.else@club.example", "10.1.1.1")  # nor another account from the same one
    # Refused tries are not counted and the window is fixed from the first failure (EXPIRE NX).
    for _ in range(20):
        with pytest.raises(LoginThrottled):
            second.check("rider@club.example", "10.1.1.1")
    pair = second._keys("rider@club.example", "10.1.1.1")[0]
    assert second.counters.get(pair).count == 3
    import redis

    ttl = redis.Redis.from_url(url).ttl("saddlescope:login:" + pair)
    first.failed("rider@club.example", "10.1.1.1")
    assert 0 < redis.Redis.from_url(url).ttl("saddlescope:login:" + pair) <= ttl
    proc.terminate()
    proc.wait(timeout=10)
    lone = LoginGuard(first.counters, max_failures=3, lockout_s=600)
    lone.check("rider2@club.example", "10.1.1.1")  # Redis down: no exception, counted locally
    for _ in range(3):
        lone.failed("rider2@club.example", "10.1.1.1")
    with pytest.raises(LoginThrottled):
        lone.check("rider2@club.example", "10.1.1.1")

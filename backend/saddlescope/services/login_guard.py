"""Sign-in under abuse: failed-attempt counters (per account and per client address) and Argon2's pool.

The counters live in Redis when the service runs with a broker (every API process sees the same
numbers) and in memory in embedded mode. After ``max_failures`` wrong passwords for one account (or four
times as many from one address) sign-in is refused with `LoginThrottled` until ``lockout_s`` after the
last failure, even with the right password. A counter key holds a hash of the e-mail, never the address.

Password hashing takes tens of milliseconds of CPU, so it runs in a small pool of its own with a bounded
queue (`HashPool`): a flood of sign-ins is answered `HashPoolBusy` (503) instead of stalling every route.
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
import math
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Protocol, TypeVar

from saddlescope.core.errors import SaddleScopeError

__all__ = ["HashPool", "HashPoolBusy", "LoginGuard", "LoginThrottled", "MemoryCounters", "RedisCounters",
           "make_login_guard"]

log = logging.getLogger(__name__)
T = TypeVar("T")
ADDRESS_FACTOR = 4


class LoginThrottled(SaddleScopeError):
    """Too many failed sign-ins: HTTP 429 with a Retry-After header."""

    def __init__(self, message: str, retry_after_s: int) -> None:
        super().__init__(message)
        self.retry_after_s = max(1, int(retry_after_s))


class HashPoolBusy(SaddleScopeError):
    """Too many sign-ins waiting for the password check: HTTP 503 with a Retry-After header."""

    retry_after_s = 5


class Counters(Protocol):
    """Failure counters that expire ``window_s`` after their last increment."""

    def get(self, key: str) -> tuple[int, int]:
        """(count, seconds until it expires); (0, 0) when absent."""
        ...

    def incr(self, key: str, window_s: int) -> int:
        """Add one failure and restart the window; the new count."""
        ...

    def clear(self, key: str) -> None:
        """Forget the key."""
        ...


class MemoryCounters:
    """Counters of one process (embedded mode)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._data: dict[str, tuple[int, float]] = {}

    def get(self, key: str) -> tuple[int, int]:
        """(count, seconds until it expires); (0, 0) when absent."""
        with self._lock:
            count, until = self._data.get(key, (0, 0.0))
            left = until - self._clock()
            if left <= 0:
                self._data.pop(key, None)
                return 0, 0
            return count, max(1, math.ceil(left))

    def incr(self, key: str, window_s: int) -> int:
        """Add one failure and restart the window; the new count."""
        with self._lock:
            now = self._clock()
            if len(self._data) > 100_000:  # bounded memory: drop what has expired
                self._data = {k: v for k, v in self._data.items() if v[1] > now}
            count, until = self._data.get(key, (0, 0.0))
            count = (count if until > now else 0) + 1
            self._data[key] = (count, now + window_s)
            return count

    def clear(self, key: str) -> None:
        """Forget the key."""
        with self._lock:
            self._data.pop(key, None)


class RedisCounters:
    """Counters shared by every API process through Redis (falls back to memory while it is down)."""

    def __init__(self, url: str, *, prefix: str = "saddlescope:login:") -> None:
        import redis

        self._redis = redis.Redis.from_url(url, socket_timeout=2, socket_connect_timeout=2)
        self._errors = (redis.RedisError, OSError)
        self._prefix = prefix
        self._fallback = MemoryCounters()

    def _run(self, fn: Callable[[], T], fallback: Callable[[], T]) -> T:
        try:
            return fn()
        except self._errors as exc:
            log.warning("sign-in counters: Redis unavailable (%s); counting in this process meanwhile", exc)
            return fallback()

    def get(self, key: str) -> tuple[int, int]:
        """(count, seconds until it expires); (0, 0) when absent."""
        def read() -> tuple[int, int]:
            pipe = self._redis.pipeline()
            pipe.get(self._prefix + key)
            pipe.ttl(self._prefix + key)
            value, ttl = pipe.execute()
            return (int(value), max(int(ttl), 1)) if value is not None else (0, 0)

        return self._run(read, lambda: self._fallback.get(key))

    def incr(self, key: str, window_s: int) -> int:
        """Add one failure and restart the window; the new count."""
        def write() -> int:
            pipe = self._redis.pipeline()
            pipe.incr(self._prefix + key)
            pipe.expire(self._prefix + key, window_s)
            return int(pipe.execute()[0])

        return self._run(write, lambda: self._fallback.incr(key, window_s))

    def clear(self, key: str) -> None:
        """Forget the key."""
        self._run(lambda: self._redis.delete(self._prefix + key), lambda: self._fallback.clear(key))


def _minutes(seconds: int) -> str:
    minutes = -(-seconds // 60)
    return f"{minutes} minute{'s' if minutes != 1 else ''}"


class LoginGuard:
    """Counts failed sign-ins per account and per client address and refuses sign-in past the limit."""

    def __init__(self, counters: Counters, *, max_failures: int, lockout_s: int) -> None:
        self.counters = counters
        self.max_failures = max_failures
        self.lockout_s = lockout_s

    @staticmethod
    def _keys(email: str, address: str) -> tuple[str, str]:
        account = hashlib.sha256(email.strip().lower().encode()).hexdigest()[:32]
        return f"account:{account}", f"address:{address or 'unknown'}"

    def check(self, email: str, address: str) -> None:
        """Raise `LoginThrottled` when this account or this address is locked out."""
        account, client = self._keys(email, address)
        count, left = self.counters.get(account)
        if count >= self.max_failures:
            raise LoginThrottled(
                f"too many wrong passwords for this account: sign-in is locked for {_minutes(left)}; "
                "try again later or ask a club admin to reset the password", left)
        count, left = self.counters.get(client)
        if count >= self.max_failures * ADDRESS_FACTOR:
            raise LoginThrottled(
                f"too many failed sign-ins from your network address: try again in {_minutes(left)}", left)

    def failed(self, email: str, address: str) -> None:
        """Count a failed sign-in against the account and the address."""
        for key in self._keys(email, address):
            self.counters.incr(key, self.lockout_s)

    def succeeded(self, email: str, address: str) -> None:
        """A successful sign-in clears the account's count (the address keeps its own)."""
        self.counters.clear(self._keys(email, address)[0])


class HashPool:
    """A few threads for Argon2 with a bounded number of sign-ins waiting for them."""

    def __init__(self, workers: int, queue: int) -> None:
        self._executor = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="saddlescope-hash")
        self._slots = threading.BoundedSemaphore(workers + queue)

    async def run(self, fn: Callable[[], T]) -> T:
        """Run `fn` in the pool; `HashPoolBusy` at once when the pool and its queue are full."""
        if not self._slots.acquire(blocking=False):
            raise HashPoolBusy("the server is busy checking other sign-ins; try again in a few seconds")
        try:
            future = self._executor.submit(fn)
        except BaseException:
            self._slots.release()
            raise
        future.add_done_callback(lambda _f: self._slots.release())
        return await asyncio.wrap_future(future)

    def close(self) -> None:
        """Stop the threads (waiting for the checks under way)."""
        self._executor.shutdown(wait=True, cancel_futures=True)


def make_login_guard(settings) -> LoginGuard:
    """Redis counters when the broker is Redis (a deployment), memory counters otherwise."""
    url = settings.broker_url or ""
    counters: Counters = RedisCounters(url) if url.startswith(("redis://", "rediss://")) else MemoryCounters()
    return LoginGuard(counters, max_failures=settings.login_max_failures, lockout_s=settings.login_lockout_s)

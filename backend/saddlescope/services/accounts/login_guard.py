"""Sign-in under abuse: failed-attempt counters that stop a guesser without locking others out.

Argon2's pool is here too.

Failures are counted per (account, client address) pair and per client address. A pair that has failed
``max_failures`` times waits a back-off before its next try: ``backoff_s``, doubling with each further
failure, at most ``lockout_s``. An address with ``ADDRESS_FACTOR`` times as many failures (over any
accounts) waits its own back-off, but only for accounts that have already failed from it: the right
password of an account that has not failed from that address is never refused, and an address that
has not failed is never refused because someone else guessed (a club behind one router keeps signing
in while one person guesses). Tries refused during a back-off are not counted, and counts expire
``window_s`` after a pair's or address's first failure (a fixed window: it does not restart on each
failure), so an owner is never locked out for longer than one back-off.

The counters live in Redis when the service runs with a broker (every API process sees the same
numbers) and in memory in embedded mode. A counter key holds a hash of the e-mail and the address.

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
from dataclasses import dataclass
from typing import Protocol, TypeVar

from saddlescope.core.errors import SaddleScopeError

__all__ = ["Failures", "HashPool", "HashPoolBusy", "LoginGuard", "LoginThrottled", "MemoryCounters",
           "RedisCounters", "make_login_guard"]

log = logging.getLogger(__name__)
T = TypeVar("T")
ADDRESS_FACTOR = 4
MAX_DOUBLINGS = 20  # 2**20 times the first back-off is far beyond any lockout_s: no overflow


class LoginThrottled(SaddleScopeError):
    """Too many failed sign-ins: HTTP 429 with a Retry-After header."""

    def __init__(self, message: str, retry_after_s: int) -> None:
        super().__init__(message)
        self.retry_after_s = max(1, int(retry_after_s))


class HashPoolBusy(SaddleScopeError):
    """Too many sign-ins waiting for the password check: HTTP 503 with a Retry-After header."""

    retry_after_s = 5


@dataclass(frozen=True)
class Failures:
    """Failures counted under one key: how many, and when the last one was (s, the counters' clock)."""

    count: int = 0
    last_s: float = 0.0


class Counters(Protocol):
    """Failure counters; a key's count expires ``window_s`` after its first failure."""

    def now(self) -> float:
        """The clock `Failures.last_s` is read on (s)."""
        ...

    def get(self, key: str) -> Failures:
        """The failures counted under `key` (none when absent or expired)."""
        ...

    def add(self, key: str, window_s: int) -> Failures:
        """Count one failure now; a new key's window starts (an existing key's window is kept)."""
        ...

    def clear(self, key: str) -> None:
        """Forget the key."""
        ...


class MemoryCounters:
    """Counters of one process (embedded mode)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._data: dict[str, tuple[Failures, float]] = {}  # key: (failures, end of its window)

    def now(self) -> float:
        """The clock of this process (monotonic by default)."""
        return self._clock()

    def get(self, key: str) -> Failures:
        """The failures counted under `key` (none when absent or expired)."""
        with self._lock:
            failures, until = self._data.get(key, (Failures(), 0.0))
            if until <= self._clock():
                self._data.pop(key, None)
                return Failures()
            return failures

    def add(self, key: str, window_s: int) -> Failures:
        """Count one failure now; a new key's window starts (an existing key's window is kept)."""
        with self._lock:
            now = self._clock()
            if len(self._data) > 100_000:  # bounded memory: drop what has expired
                self._data = {k: v for k, v in self._data.items() if v[1] > now}
            failures, until = self._data.get(key, (Failures(), 0.0))
            if until <= now:
                failures, until = Failures(), now + window_s
            failures = Failures(failures.count + 1, now)
            self._data[key] = (failures, until)
            return failures

    def clear(self, key: str) -> None:
        """Forget the key."""
        with self._lock:
            self._data.pop(key, None)


class RedisCounters:
    """Counters shared by every API process through Redis (falls back to memory while it is down).

    A key is a hash ``{count, last}``; its expiry is set by the first failure only (``EXPIRE ... NX``).
    """

    def __init__(self, url: str, *, prefix: str = "saddlescope:login:") -> None:
        import redis

        self._redis = redis.Redis.from_url(url, socket_timeout=2, socket_connect_timeout=2)
        self._errors = (redis.RedisError, OSError)
        self._prefix = prefix
        self._fallback = MemoryCounters(clock=time.time)

    def _run(self, fn: Callable[[], T], fallback: Callable[[], T]) -> T:
        try:
            return fn()
        except self._errors as exc:
            log.warning("sign-in counters: Redis unavailable (%s); counting in this process meanwhile", exc)
            return fallback()

    def now(self) -> float:
        """Wall-clock time (every API process stamps failures with its own; they agree to NTP's accuracy)."""
        return time.time()

    def get(self, key: str) -> Failures:
        """The failures counted under `key` (none when absent or expired)."""
        def read() -> Failures:
            count, last = self._redis.hmget(self._prefix + key, "count", "last")
            return Failures(int(count), float(last)) if count is not None and last is not None else Failures()

        return self._run(read, lambda: self._fallback.get(key))

    def add(self, key: str, window_s: int) -> Failures:
        """Count one failure now; a new key's window starts (an existing key's window is kept)."""
        def write() -> Failures:
            now = self.now()
            pipe = self._redis.pipeline()
            pipe.hincrby(self._prefix + key, "count", 1)
            pipe.hset(self._prefix + key, "last", repr(now))
            pipe.expire(self._prefix + key, window_s, nx=True)
            return Failures(int(pipe.execute()[0]), now)

        return self._run(write, lambda: self._fallback.add(key, window_s))

    def clear(self, key: str) -> None:
        """Forget the key."""
        self._run(lambda: self._redis.delete(self._prefix + key), lambda: self._fallback.clear(key))


def _minutes(seconds: int) -> str:
    minutes = -(-seconds // 60)
    return f"{minutes} minute{'s' if minutes != 1 else ''}"


class LoginGuard:
    """Back-offs per (account, address) pair, then per address for accounts that failed from it."""

    def __init__(self, counters: Counters, *, max_failures: int, lockout_s: int, backoff_s: int = 30,
                 window_s: int | None = None) -> None:
        self.counters = counters
        self.max_failures = max_failures
        self.lockout_s = lockout_s  # the longest back-off
        self.backoff_s = min(backoff_s, lockout_s)  # the first back-off
        self.window_s = max(window_s or 0, lockout_s)

    @staticmethod
    def _keys(email: str, address: str) -> tuple[str, str]:
        account = email.strip().lower().encode()
        where = (address or "unknown").encode()
        pair = hashlib.sha256(account + b"\0" + where).hexdigest()[:32]
        return f"pair:{pair}", f"address:{hashlib.sha256(where).hexdigest()[:32]}"

    def _wait_s(self, failures: Failures, free: int) -> int:
        """Seconds still to wait after `failures`, when `free` failures come without a back-off."""
        if failures.count < free:
            return 0
        doublings = min(failures.count - free, MAX_DOUBLINGS)
        backoff_s = min(self.lockout_s, self.backoff_s * 2**doublings)
        return max(0, math.ceil(failures.last_s + backoff_s - self.counters.now()))

    def check(self, email: str, address: str) -> None:
        """Raise `LoginThrottled` while this account is backed off from this address."""
        pair, client = self._keys(email, address)
        failed_here = self.counters.get(pair)
        left = self._wait_s(failed_here, self.max_failures)
        if left:
            raise LoginThrottled(
                f"too many wrong passwords for this account from your network address: sign-in is locked for "
                f"{_minutes(left)}; try again later or ask a club admin to reset the password", left)
        if failed_here.count == 0:
            return  # the address's limit never refuses an account that has not failed from it
        left = self._wait_s(self.counters.get(client), self.max_failures * ADDRESS_FACTOR)
        if left:
            raise LoginThrottled(
                f"too many failed sign-ins from your network address: try again in {_minutes(left)}", left)

    def failed(self, email: str, address: str) -> None:
        """Count a failed sign-in against the account at this address, and against the address."""
        for key in self._keys(email, address):
            self.counters.add(key, self.window_s)

    def succeeded(self, email: str, address: str) -> None:
        """A successful sign-in clears the pair's count (the address keeps its own)."""
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
    return LoginGuard(counters, max_failures=settings.login_max_failures, lockout_s=settings.login_lockout_s,
                      backoff_s=settings.login_backoff_s, window_s=settings.login_window_s)

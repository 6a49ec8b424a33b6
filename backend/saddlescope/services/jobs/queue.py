"""How the API hands work to workers.

Two queues behind one small interface (`JobQueue`):

- `EmbeddedQueue` (no broker configured): a local pool of worker *processes* inside the server
  or command, so a long analysis never blocks the web server's event loop or the GIL.
- `CeleryQueue` (``SADDLESCOPE_BROKER_URL`` set): ``send_task`` by name to Celery workers
  (`saddlescope_worker`), so the API needs no import of the worker's code.

Both end in the same function, `saddlescope.services.jobs.runner.run_job(job_id)`. Only ids travel;
the job row must be committed before `submit` is called.
"""

from __future__ import annotations

import logging
import multiprocessing
import threading
import time
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from functools import partial
from typing import Protocol

from saddlescope.core.errors import SaddleScopeError
from saddlescope.settings import Settings, get_settings

log = logging.getLogger(__name__)

RUN_JOB_TASK = "saddlescope.run_job"
QUEUE_NAME = "saddlescope"
# GET /api/jobs pings the workers at most this often, waiting this long for their answers.
PING_CACHE_S = 10.0
PING_TIMEOUT_S = 0.5


class QueueUnavailable(SaddleScopeError):
    """The job could not be handed to a worker (broker unreachable, pool shut down): HTTP 503.

    `retry_after_s` is sent as the answer's Retry-After: a broker restarting is back within seconds.
    """

    retry_after_s = 10


class JobQueue(Protocol):
    """Where submitted jobs go to be run: a pool in this process, inline, or a Celery broker."""

    mode: str

    def submit(self, job_id: int) -> None:
        """Hand job `job_id` (already committed) to a worker."""

    def health(self) -> tuple[bool, str]:
        """(ok, detail) for /api/health."""

    def close(self) -> None:
        """Release the pool or connections."""


def _run_in_child(job_id: int, settings: Settings) -> str:
    # Imported here: the child process needs the services, the parent (API) does not.
    from saddlescope.services.jobs.runner import run_job

    return run_job(job_id, settings=settings)


class EmbeddedQueue:
    """Jobs run in a local process pool ("spawn": safe next to the server's threads)."""

    mode = "embedded"

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self._pool: ProcessPoolExecutor | None = None
        self._lock = threading.Lock()
        self._pending: set[Future] = set()

    def _executor(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._pool is None:
                self._pool = ProcessPoolExecutor(max_workers=self.settings.embedded_workers,
                                                 mp_context=multiprocessing.get_context("spawn"))
            return self._pool

    def submit(self, job_id: int) -> None:
        """Run job `job_id` in the local process pool; `QueueUnavailable` when the pool cannot take it."""
        try:
            future = self._executor().submit(_run_in_child, job_id, self.settings)
        except (RuntimeError, BrokenProcessPool) as exc:
            raise QueueUnavailable(f"the local job pool cannot take job {job_id}: {exc}") from None
        with self._lock:
            self._pending.add(future)
        future.add_done_callback(partial(self._done, job_id))

    def _done(self, job_id: int, future: Future) -> None:
        with self._lock:
            self._pending.discard(future)
        if future.cancelled():
            return
        exc = future.exception()
        from saddlescope.services.jobs.runner import RETRY, STORE_RETRY_S

        if exc is None and future.result() == RETRY:
            # the file store did not answer: the runner queued the job again; run it after a pause
            timer = threading.Timer(STORE_RETRY_S, self._resubmit, (job_id,))
            timer.daemon = True
            timer.start()
        elif isinstance(exc, BrokenProcessPool):
            # A child died (out of memory, killed): the job row still says "running".
            log.error("job %s: its worker process died (%s); the pool will be restarted", job_id, exc)
            with self._lock:
                self._pool = None
            _mark_lost(self.settings, job_id)
        elif exc is not None:
            log.error("job %s failed with an internal error", job_id, exc_info=exc)

    def _resubmit(self, job_id: int) -> None:
        try:
            self.submit(job_id)
        except QueueUnavailable as exc:  # the server is closing: the job stays queued, as after a restart
            log.warning("job %s not run again: %s", job_id, exc)

    @property
    def pending(self) -> int:
        """Jobs submitted and not finished."""
        with self._lock:
            return len(self._pending)

    def health(self) -> tuple[bool, str]:
        """(healthy, what a person reads) of the local pool."""
        workers = self.settings.embedded_workers
        return True, (f"embedded: local pool of {workers} process{'es' if workers > 1 else ''}, "
                      f"{self.pending} job(s) pending")

    def close(self) -> None:
        """Stop the local pool: jobs not started are cancelled, running ones are not waited for."""
        with self._lock:
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)

    def wait_idle(self, timeout_s: float | None = None) -> bool:
        """Block until every submitted job's process call has returned (for commands and tests)."""
        from concurrent.futures import wait

        with self._lock:
            pending = set(self._pending)
        _, not_done = wait(pending, timeout=timeout_s)
        return not not_done


class InlineQueue:
    """Runs each job at once in the calling thread (commands that wait anyway, and tests)."""

    mode = "embedded"

    def __init__(self, settings: Settings) -> None:
        self.settings = settings

    def submit(self, job_id: int) -> None:
        """Run job `job_id` now, in the calling process, retrying while the store is unavailable."""
        from saddlescope.services.jobs.runner import RETRY, STORE_RETRY_S, run_job

        while run_job(job_id, settings=self.settings) == RETRY:  # the runner bounds the attempts
            time.sleep(STORE_RETRY_S)

    def health(self) -> tuple[bool, str]:
        """(healthy, what a person reads): always healthy."""
        return True, "embedded: jobs run inline in the calling process"

    def close(self) -> None:
        """Nothing to release."""
        pass


def _mark_lost(settings: Settings, job_id: int) -> None:
    """Fail a job whose embedded worker process died, so it does not stay "running" forever."""
    from saddlescope.db.enums import JobStatus
    from saddlescope.db.repositories import JobRepository
    from saddlescope.db.session import session_factory_for, session_scope
    from saddlescope.services.rides.registration import refresh_ride_status

    with session_scope(session_factory_for(settings.database_url)) as session:
        jobs = JobRepository(session)
        if jobs.finish(job_id, JobStatus.FAILED, error="its worker process died (out of memory or killed)"):
            job = jobs.find(job_id)
            refresh_ride_status(session, job.ride_id if job is not None else None)


def celery_config(settings: Settings) -> dict:
    """Celery settings shared by the API's client and the workers (`saddlescope_worker.app`)."""
    return {
        "broker_url": settings.broker_url,
        "task_serializer": "json",
        "accept_content": ["json"],
        "result_serializer": "json",
        "task_ignore_result": True,  # outcomes live in the jobs table
        "task_default_queue": QUEUE_NAME,
        "task_acks_late": True,  # a job whose worker died is delivered again ...
        "task_reject_on_worker_lost": True,  # ... also when the worker process was killed
        "worker_prefetch_multiplier": 1,  # long tasks: never hoard jobs another worker could run
        # Minutes: a killed worker's task comes back soon; the fencing keeps a healthy job's copy from running.
        # kombu sweeps unacknowledged tasks back only every interval x throttle seconds (100 s by default):
        # a sweep on every idle poll of at most a third of the timeout makes "soon" mean the timeout.
        "broker_transport_options": {"visibility_timeout": settings.visibility_timeout_s,
                                     "unacked_restore_interval": max(1, min(10, settings.visibility_timeout_s // 3)),
                                     "unacked_restore_throttle": 1},
        "broker_connection_retry_on_startup": True,
        # Soft limit: raised inside the task, so the job is recorded as failed; hard limit just after.
        "task_soft_time_limit": settings.job_time_limit_s,
        "task_time_limit": settings.job_time_limit_s + 300,
        "worker_hijack_root_logger": False,
        "timezone": "UTC",
        "enable_utc": True,
    }


class CeleryQueue:
    """Jobs go to Celery workers through the broker, by task name."""

    mode = "celery"

    def __init__(self, settings: Settings) -> None:
        from celery import Celery

        if settings.broker_url is None:
            raise QueueUnavailable("CeleryQueue needs SADDLESCOPE_BROKER_URL")
        self.settings = settings
        self.app = Celery("saddlescope-api", set_as_current=False)
        self.app.conf.update(celery_config(settings))
        # Fail fast in a web request rather than retrying a dead broker for long.
        self.app.conf.broker_connection_timeout = 5
        self.app.conf.task_publish_retry_policy = {"max_retries": 2, "interval_start": 0.2,
                                                   "interval_step": 0.5, "interval_max": 1.0}
        self._ping_lock = threading.Lock()
        self._ping_at = -1e9
        self._alive: int | None = None

    def submit(self, job_id: int) -> None:
        """Send job `job_id` to the broker; `QueueUnavailable` when it does not answer."""
        from kombu.exceptions import OperationalError

        try:
            self.app.send_task(RUN_JOB_TASK, args=[job_id], queue=QUEUE_NAME)
        except OperationalError as exc:
            raise QueueUnavailable(
                f"the job broker is unreachable, nothing was queued (job {job_id} was not kept): {exc}") from None

    def health(self) -> tuple[bool, str]:
        """(healthy, what a person reads) of the broker and its workers."""
        from kombu.exceptions import OperationalError

        try:
            with self.app.connection_for_write() as conn:
                conn.ensure_connection(max_retries=1, interval_start=0, interval_step=0.2, timeout=3)
                transport = conn.transport_cls
        except (OperationalError, OSError) as exc:
            return False, f"broker unreachable at {_redact(self.settings.broker_url)}: {exc}"
        return True, f"celery over {transport} at {_redact(self.settings.broker_url)}"

    def workers_alive(self) -> int | None:
        """How many workers answer a ping (None: the broker cannot be asked); cached a few seconds.

        A worker running a job on the solo pool cannot answer; callers also look at the jobs'
        heartbeats in the database before saying that no worker is alive.
        """
        with self._ping_lock:
            now = time.monotonic()
            if now - self._ping_at > PING_CACHE_S:
                try:
                    self._alive = len(self.app.control.ping(timeout=PING_TIMEOUT_S) or [])
                except Exception as exc:  # noqa: BLE001 -- a broker down: not known, not "none"
                    log.warning("cannot ping the workers: %s", exc)
                    self._alive = None
                self._ping_at = now
            return self._alive

    def close(self) -> None:
        """Release the broker's connections."""
        self.app.close()


def broker_job_ids(app) -> set[int] | None:
    """Ids of the jobs a Redis broker holds (waiting in the queue or delivered, not acknowledged).

    None when that cannot be told (another transport, an unreadable message): the caller then
    sends again every job queued for long, which is safe since a job starts once.
    """
    import base64
    import json

    held: set[int] = set()
    try:
        with app.connection_for_read() as conn:
            if conn.transport.driver_type != "redis":
                return None
            client = conn.default_channel.client
            raw = [m for key in client.scan_iter(match=f"{QUEUE_NAME}*") if client.type(key) == b"list"
                   for m in client.lrange(key, 0, -1)]
            raw += [json.dumps(json.loads(v)[0]).encode() for v in client.hvals("unacked")]
        for message in raw:
            envelope = json.loads(message)
            if envelope.get("headers", {}).get("task") != RUN_JOB_TASK:
                continue
            body = envelope["body"]
            if envelope.get("properties", {}).get("body_encoding") == "base64":
                body = base64.b64decode(body)
            held.add(int(json.loads(body)[0][0]))
    except Exception as exc:  # noqa: BLE001 -- any doubt means "unknown", never "not held"
        log.warning("cannot list the jobs the broker holds: %s", exc)
        return None
    return held


def _redact(url: str | None) -> str:
    """A broker URL without its password, for health reports and logs."""
    from kombu.utils.url import maybe_sanitize_url

    return maybe_sanitize_url(url or "")


def make_queue(settings: Settings) -> JobQueue:
    """The queue the settings ask for: embedded without a broker URL, Celery with one."""
    return EmbeddedQueue(settings) if settings.embedded else CeleryQueue(settings)


_default_queue: JobQueue | None = None
_default_lock = threading.Lock()


def default_queue() -> JobQueue:
    """The process-wide queue built from `get_settings()` (commands; the API keeps its own)."""
    global _default_queue
    with _default_lock:
        if _default_queue is None:
            _default_queue = make_queue(get_settings())
        return _default_queue


def submit(job_id: int, *, queue: JobQueue | None = None) -> None:
    """Hand a committed job to a worker: Celery ``send_task`` by name, or the local pool."""
    (queue or default_queue()).submit(job_id)

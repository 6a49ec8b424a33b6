"""The body of every job: run a job's stages in order, reporting progress and timings.

`run_job` is what a Celery task calls (`saddlescope_worker.tasks`) and what the embedded process
pool calls (`saddlescope.services.jobs.queue`). It takes an id, never objects, and is safe to run again: a job
already finished is left alone, and a job interrupted half-way (lost worker, restarted server) is
re-run from its first stage, each stage replacing only its own outputs.
"""

from __future__ import annotations

import datetime as dt
import logging
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Generic, TypeVar

from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import SaddleScopeError
from saddlescope.db.enums import JobStatus
from saddlescope.db.models import utcnow
from saddlescope.db.repositories import JobRepository
from saddlescope.db.session import session_factory_for, session_scope
from saddlescope.services.jobs.inputs import RideJobInputs, RigInputs, read_ride_job_inputs, read_rig_inputs
from saddlescope.services.jobs.stages import JOB_KINDS, STAGES, JobCancelled, JobFenced, JobKind, StageContext
from saddlescope.services.rides.registration import refresh_ride_status
from saddlescope.settings import Settings, get_settings
from saddlescope.storage import StoreUnavailable, open_storage

__all__ = [
    "FENCED", "HEARTBEAT_S", "MAX_ATTEMPTS", "PROGRESS_INTERVAL_S", "STALE_AFTER_S", "job_is_lost", "recover_lost_jobs",
    "resend_queued_jobs", "run_job", "worker_gone", "worker_host", "RETRY", "STORE_ATTEMPTS", "STORE_RETRY_S",
]

log = logging.getLogger(__name__)

# Progress is written at most this often (plus at every stage boundary), to spare the database.
PROGRESS_INTERVAL_S = 0.25
# A running job's worker writes a heartbeat this often, even while a stage reports no progress ...
HEARTBEAT_S = 10.0
# ... so a job silent for this long has lost its worker and may be handed to another one. Both are the
# defaults of the settings `heartbeat_s` and `stale_after_s` (SADDLESCOPE_HEARTBEAT_S, _STALE_AFTER_S).
STALE_AFTER_S = 180.0
# A job whose worker was lost this many times is failed with the reason instead of queued again.
MAX_ATTEMPTS = 3
# What `run_job` returns when its attempt was fenced out (another worker took the job over).
FENCED = "fenced"
# What `run_job` returns when the file store did not answer: the job is queued again, to be run after
# STORE_RETRY_S (Celery's retry; the embedded pool's timer), at most STORE_ATTEMPTS attempts in all.
RETRY = "retry"
STORE_RETRY_S = 10.0
STORE_ATTEMPTS = 6


def worker_host(settings: Settings | None = None) -> str:
    """The worker process as ``host:pid`` (recorded on the jobs it runs, to tell when it is gone).

    The host is `Settings.resolved_host_name` (SADDLESCOPE_HOST_NAME, else the machine's host name).
    """
    return f"{_host_name(settings)}:{os.getpid()}"


def _host_name(settings: Settings | None) -> str:
    return (settings or get_settings()).resolved_host_name


@dataclass(frozen=True)
class _Fence:
    """The run of a job this process holds: its attempt and host guard every write of the job's state."""

    job_id: int
    attempt: int
    host: str

    def refused(self, what: str) -> JobFenced:
        """Log and return the error that stops a stale run (another worker took the job over)."""
        log.warning("job %s: %s of attempt %s on %s refused: the job was taken over by another attempt",
                    self.job_id, what, self.attempt, self.host)
        return JobFenced(self.job_id, self.attempt)


@dataclass
class _Progress:
    """Maps a stage's own 0-1 progress onto the job's bar and writes it, throttled."""

    fence: _Fence
    sessions: sessionmaker[Session]
    weights: dict[str, float]
    done_weight: float = 0.0
    stage: str = ""
    last_write: float = field(default=-1e9)

    @property
    def total(self) -> float:
        return sum(self.weights.values())

    def start(self, stage: str) -> None:
        self.stage = stage
        self.write(0.0, None, force=True)

    def finish(self) -> None:
        self.done_weight += self.weights[self.stage]

    def write(self, fraction: float, detail: str | None, *, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self.last_write < PROGRESS_INTERVAL_S:
            return
        self.last_write = now
        fraction = min(max(float(fraction), 0.0), 1.0)
        overall = (self.done_weight + fraction * self.weights[self.stage]) / self.total
        label = self.stage if not detail else f"{self.stage}: {detail}"
        fence = self.fence
        with session_scope(self.sessions) as session:
            repo = JobRepository(session)
            if repo.set_progress(fence.job_id, min(overall, 0.999), label[:64], attempt=fence.attempt,
                                 host=fence.host):
                return
            if repo.status_of(fence.job_id) == JobStatus.CANCELLED.value:
                raise JobCancelled(fence.job_id)
        raise fence.refused("a progress report")

    def __call__(self, fraction: float, detail: str | None = None) -> None:
        self.write(fraction, detail, force=fraction >= 1.0)


class _Heartbeat:
    """A daemon thread touching the job row every `HEARTBEAT_S` while its stages run.

    It stops beating once its attempt is fenced out (the next progress report then stops the stages).
    """

    def __init__(self, fence: _Fence, sessions: sessionmaker[Session], interval_s: float = HEARTBEAT_S) -> None:
        self.fence, self.sessions, self.interval_s = fence, sessions, interval_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"job-{fence.job_id}-heartbeat", daemon=True)

    def _run(self) -> None:
        fence = self.fence
        while not self._stop.wait(self.interval_s):
            try:
                with session_scope(self.sessions) as session:
                    beating = JobRepository(session).touch(fence.job_id, attempt=fence.attempt, host=fence.host)
            except OperationalError as exc:  # the database blinked; the next beat tries again
                log.warning("job %s: heartbeat not written (%s)", fence.job_id, exc)
                continue
            if not beating:  # finished, cancelled or taken over: nothing left to keep alive
                log.info("job %s: heartbeat of attempt %s stopped (the job is no longer this attempt's)",
                         fence.job_id, fence.attempt)
                return

    def __enter__(self) -> _Heartbeat:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5)


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def worker_gone(host: str | None, age_s: float | None, *, stale_after_s: float = STALE_AFTER_S,
                here: str | None = None) -> bool:
    """True when a running job's worker is gone: a dead process on this machine, or no heartbeat for long.

    `age_s` is the time since the job's last heartbeat, measured by the database's clock. `here`: this
    machine's name (default `worker_host`'s); only a job of this machine has its process looked up, as
    another machine's pids mean nothing here.
    """
    if host and ":" in host:
        name, _, pid = host.rpartition(":")
        if name == (here or _host_name(None)) and pid.isdigit() and int(pid) != os.getpid():
            if not _process_alive(int(pid)):
                return True
    return age_s is None or age_s > stale_after_s


def job_is_lost(host: str | None, updated_at: dt.datetime | None, *, now: dt.datetime | None = None,
                stale_after_s: float = STALE_AFTER_S, here: str | None = None) -> bool:
    """`worker_gone` from a heartbeat time and a clock (`now`; default this host's)."""
    now = now or utcnow()
    age_s = None if updated_at is None else (now - updated_at).total_seconds()
    return worker_gone(host, age_s, stale_after_s=stale_after_s, here=here)


def recover_lost_jobs(sessions: sessionmaker[Session], submit, *, stale_after_s: float = STALE_AFTER_S,
                      max_attempts: int = MAX_ATTEMPTS, here: str | None = None) -> list[int]:
    """Queue again every running job whose worker died (killed, out of memory, machine lost).

    A worker calls this when it starts (and now and then), so a job interrupted by a killed worker
    completes on the next one; its stages are idempotent, so re-running from the first is safe. A
    job that lost its worker `max_attempts` times is failed with the reason instead. Heartbeats
    are judged by the database's clock against `stale_after_s` (a worker passes its setting); `here` is
    this machine's name (see `worker_gone`). `submit(job_id)` hands a job to the queue. Returns the ids
    queued again.
    """
    with session_scope(sessions) as session:
        candidates = JobRepository(session).running_with_age()
    recovered = []
    for job_id, ride_id, host, age_s, attempts in candidates:
        if not worker_gone(host, age_s, stale_after_s=stale_after_s, here=here):
            continue
        silent = "never" if age_s is None else f"{age_s:.0f} s ago"
        with session_scope(sessions) as session:
            jobs = JobRepository(session)
            if attempts >= max_attempts:
                jobs.fail_lost(job_id, host=host, error=(
                    f"its worker {host} stopped (last heartbeat {silent}) on attempt {attempts} of "
                    f"{max_attempts}; not retried again"))
                refresh_ride_status(session, ride_id)
                log.error("job %s: its worker %s is gone, attempt %s: failed", job_id, host, attempts)
                continue
            if not jobs.requeue_lost(job_id, host=host):
                continue  # finished or taken over meanwhile
            refresh_ride_status(session, ride_id)
        log.warning("job %s: its worker %s is gone (last heartbeat %s); queued again", job_id, host, silent)
        submit(job_id)
        recovered.append(job_id)
    return recovered


def resend_queued_jobs(sessions: sessionmaker[Session], submit, *, older_than_s: float,
                       known: set[int] | None = None) -> list[int]:
    """Hand to the broker again the jobs queued longer than `older_than_s` that it does not hold.

    A broker that lost its data (Redis restarted with nothing persisted) forgets queued jobs; the
    database still has them. `known`: the job ids the broker holds (None: unknown, send them all,
    which is safe: `run_job` starts a job once). Returns the ids sent again.
    """
    with session_scope(sessions) as session:
        waiting = JobRepository(session).queued_longer_than(older_than_s)
    resent = []
    for job_id in waiting:
        if known is not None and job_id in known:
            continue
        with session_scope(sessions) as session:
            if not JobRepository(session).mark_resent(job_id):
                continue  # started, finished or cancelled meanwhile
        log.warning("job %s: queued for over %.0f s and not held by the broker; sent again", job_id, older_than_s)
        submit(job_id)
        resent.append(job_id)
    return resent


def _refresh_ride_status(sessions: sessionmaker[Session], ride_id: int | None) -> None:
    if ride_id is not None:
        with session_scope(sessions) as session:
            refresh_ride_status(session, ride_id)


@contextmanager
def _removed_after(folder: Path) -> Iterator[Path]:
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


_T = TypeVar("_T")


class _ReadOnce(Generic[_T]):
    """Calls `read` on first use and hands every later caller (every stage of the run) the same answer."""

    def __init__(self, read: Callable[[], _T]) -> None:
        self._read = read
        self._value: _T | None = None

    def __call__(self) -> _T:
        if self._value is None:
            self._value = self._read()
        return self._value


@dataclass(frozen=True)
class _Claimed:
    """A job this process now runs: its fence and what its stages need."""

    fence: _Fence
    kind: JobKind
    club_id: int | None
    ride_id: int | None
    rig_id: int | None
    payload: dict

    def readers(self, sessions: sessionmaker[Session]) -> tuple[Callable[[], RideJobInputs] | None,
                                                             Callable[[], RigInputs] | None]:
        """The job's ride and rig, each read from the database once per run, when a stage first asks."""
        job_id, ride_id, rig_id = self.fence.job_id, self.ride_id, self.rig_id
        ride = None if ride_id is None else _ReadOnce(lambda: read_ride_job_inputs(sessions, ride_id, job_id=job_id))
        rig = None if rig_id is None else _ReadOnce(lambda: read_rig_inputs(sessions, rig_id, job_id=job_id))
        return ride, rig


def _claim(sessions: sessionmaker[Session], settings: Settings, job_id: int) -> _Claimed | str:
    """Start job `job_id` as this process's next attempt; its status instead when it is not to run here."""
    with session_scope(sessions) as session:
        jobs = JobRepository(session)
        job = jobs.find(job_id)
        if job is None:
            log.warning("job %s does not exist (deleted?); nothing to run", job_id)
            return "missing"
        host, version, stale_after_s = worker_host(settings), settings.resolved_code_version, settings.stale_after_s
        kind: JobKind | None = JOB_KINDS.get(job.kind)
        if kind is None:
            if jobs.mark_running(job_id, host=host, code_version=version, stale_after_s=stale_after_s):
                known = ", ".join(sorted(JOB_KINDS))
                jobs.finish(job_id, JobStatus.FAILED,
                            error=f"unknown job kind {job.kind!r} (this worker knows {known})")
            return jobs.status_of(job_id) or "missing"
        attempt = jobs.mark_running(job_id, host=host, code_version=version, stale_after_s=stale_after_s)
        if attempt is None:
            # Finished already, cancelled before it started, or running on a live worker (a copy
            # re-sent after the broker lost its data): never run twice at once.
            return jobs.status_of(job_id) or job.status
        refresh_ride_status(session, job.ride_id)  # "processing", in the transaction that starts the job
        return _Claimed(_Fence(job_id, attempt, host), kind, job.club_id, job.ride_id, job.rig_id,
                        dict(job.payload or {}))


def _store_unavailable(sessions: sessionmaker[Session], fence: _Fence, ride_id: int | None, reason: str) -> str:
    """The file store did not answer: a passing failure.

    Queue the job again with the reason (`RETRY`), or fail it with the reason after `STORE_ATTEMPTS` attempts.
    """
    if fence.attempt >= STORE_ATTEMPTS:
        return _end(sessions, fence, ride_id, JobStatus.FAILED,
                    f"{reason} (gave up after {fence.attempt} attempts; start the analysis again later)")
    with session_scope(sessions) as session:
        if not JobRepository(session).retry_later(fence.job_id, reason=f"waiting to try again: {reason}",
                                                  attempt=fence.attempt, host=fence.host):
            fence.refused("a retry after the file store did not answer")
            return FENCED
        refresh_ride_status(session, ride_id)
    log.warning("job %s: %s; queued again (attempt %s of %s)", fence.job_id, reason, fence.attempt, STORE_ATTEMPTS)
    return RETRY


def _end(sessions: sessionmaker[Session], fence: _Fence, ride_id: int | None, status: JobStatus,
         error: str | None) -> str:
    """Write the run's outcome, fenced: a cancelled job stays cancelled, a job taken over is left alone."""
    with session_scope(sessions) as session:
        jobs = JobRepository(session)
        if not jobs.finish(fence.job_id, status, error=error, attempt=fence.attempt, host=fence.host):
            if jobs.status_of(fence.job_id) == JobStatus.CANCELLED.value:
                return JobStatus.CANCELLED.value
            fence.refused(f"the outcome {status.value!r}")
            return FENCED
        refresh_ride_status(session, ride_id)
    return status.value


def run_job(job_id: int, *, settings: Settings | None = None) -> str:
    """Run job `job_id` to its end; returns its final status (done, failed, cancelled, fenced, ...).

    Errors a user can cause (`SaddleScopeError`) end the job as failed with their message. Any
    other error is recorded the same way and then re-raised, so the worker logs its traceback.
    Every write is fenced by this run's attempt: once another worker took the job over, the run
    stops at its next write and returns `FENCED`, leaving the job alone.
    """
    settings = settings or get_settings()
    sessions = session_factory_for(settings.database_url)
    storage = open_storage(settings)
    claimed = _claim(sessions, settings, job_id)
    if isinstance(claimed, str):
        return claimed
    fence, kind, ride_id = claimed.fence, claimed.kind, claimed.ride_id
    progress = _Progress(fence, sessions, {name: STAGES[name].weight for name in kind.stages})
    timings: dict[str, float] = {}
    t_job = time.perf_counter()
    current = kind.stages[0]

    def save_timings() -> None:
        timings["total"] = round(time.perf_counter() - t_job, 4)
        with session_scope(sessions) as session:
            JobRepository(session).set_timings(job_id, timings, attempt=fence.attempt, host=fence.host)

    def end(status: JobStatus, error: str | None) -> str:
        save_timings()
        return _end(sessions, fence, ride_id, status, error)

    # This run's own local folder: the stages fetch their inputs into it and write their outputs in it.
    scratch = Path(tempfile.mkdtemp(prefix=f"saddlescope-job{job_id}-attempt{fence.attempt}-"))
    read_inputs, read_rig_inputs = claimed.readers(sessions)
    with _Heartbeat(fence, sessions, settings.resolved_heartbeat_s), _removed_after(scratch):
        try:
            for current in kind.stages:
                progress.start(current)
                ctx = StageContext(job_id=job_id, attempt=fence.attempt, host=fence.host, kind=kind.name,
                                   stage=current, club_id=claimed.club_id, ride_id=ride_id, rig_id=claimed.rig_id,
                                   payload=claimed.payload, settings=settings, storage=storage,
                                   sessions=sessions, report=progress, scratch=scratch, read_inputs=read_inputs,
                                   read_rig_inputs=read_rig_inputs)
                t_stage = time.perf_counter()
                try:
                    STAGES[current].run(ctx)
                finally:  # a failed or cancelled stage's time is worth seeing too
                    timings[current] = round(time.perf_counter() - t_stage, 4)
                progress.finish()
                save_timings()
        except JobFenced:
            return FENCED  # another worker runs the job now: leave its row and outputs alone
        except StoreUnavailable as exc:
            save_timings()
            return _store_unavailable(sessions, fence, ride_id, f"{current}: {exc}")
        except JobCancelled:
            save_timings()
            _refresh_ride_status(sessions, ride_id)
            return JobStatus.CANCELLED.value
        except SaddleScopeError as exc:
            return end(JobStatus.FAILED, f"{current}: {exc}")
        except OperationalError:
            # The database went away: leave the job "running" so the worker's retry runs it again.
            raise
        except Exception as exc:
            # Record, then re-raise: the job must not stay "running" forever, and the worker's log
            # needs the traceback of a bug.
            end(JobStatus.FAILED, f"{current}: internal error ({type(exc).__name__}: {exc})")
            raise
        return end(JobStatus.DONE, None)

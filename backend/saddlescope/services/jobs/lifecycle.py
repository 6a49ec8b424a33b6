"""Use cases around jobs: create and queue one, read it, cancel it, wait for it.

The API routes and the commands call these; none of them knows whether the queue is Celery or
the embedded pool.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Protocol

from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import InputError
from saddlescope.db.enums import JobStatus
from saddlescope.db.models import Job, utcnow
from saddlescope.db.repositories import JobRepository, RideRepository, RigRepository
from saddlescope.db.session import session_scope
from saddlescope.services.jobs.failure_advice import explain_failure
from saddlescope.services.jobs.queue import JobQueue, QueueUnavailable
from saddlescope.services.jobs.stage_labels import progress_percent, stage_label
from saddlescope.services.jobs.stages import job_kind
from saddlescope.services.rides.registration import refresh_ride_status
from saddlescope.settings import get_settings

__all__ = [
    "JobStateError", "WorkersAlive", "cancel_job", "create_job", "get_job", "job_as_dict", "job_note", "retry_job",
    "submit_job",
    "wait_for_job",
]


class WorkersAlive(Protocol):
    """What a job's note asks of the queue: whether any worker answers (None: cannot tell)."""

    def workers_alive(self) -> bool | None:
        """True when a worker answered, False when none did, None when the queue cannot tell."""


def create_job(session: Session, *, kind: str, ride_id: int | None = None, rig_id: int | None = None,
               payload: dict[str, Any] | None = None, club_id: int | None = None) -> Job:
    """Validate and add a queued job (not committed, not submitted)."""
    spec = job_kind(kind)
    payload = dict(payload or {})
    if spec.validate_payload is not None:
        payload = spec.validate_payload(payload)
    if spec.needs_ride and ride_id is None:
        raise InputError(f"a {kind!r} job needs a ride_id")
    if ride_id is not None:
        club_id = RideRepository(session, club_id=club_id).get(ride_id).club_id  # NotFound: 404
    if rig_id is not None:
        club_id = RigRepository(session, club_id=club_id).get(rig_id).club_id
    job = JobRepository(session).add(kind=kind, club_id=club_id, ride_id=ride_id, rig_id=rig_id, payload=payload)
    refresh_ride_status(session, ride_id)
    return job


def submit_job(sessions: sessionmaker[Session], queue: JobQueue, *, kind: str, ride_id: int | None = None,
               rig_id: int | None = None, payload: dict[str, Any] | None = None,
               club_id: int | None = None) -> int:
    """Create a job, commit it, then hand it to a worker; returns its id.

    If the queue refuses it, the job row is taken back (no job that never ran is left "failed" with no
    attempt; the caller answers 503 with Retry-After and the club asks again) and `QueueUnavailable`
    is raised.
    """
    with session_scope(sessions) as session:
        job_id = create_job(session, kind=kind, ride_id=ride_id, rig_id=rig_id, payload=payload,
                            club_id=club_id).id
    # Committed above: a fast worker must find the row.
    try:
        queue.submit(job_id)
    except QueueUnavailable:
        _take_back(sessions, job_id)
        raise
    return job_id


def _take_back(sessions: sessionmaker[Session], job_id: int) -> None:
    """Remove a new job the queue refused, while it is still queued and never started."""
    with session_scope(sessions) as session:
        jobs = JobRepository(session)
        ride_id = jobs.get(job_id).ride_id
        jobs.discard_unstarted(job_id)
        refresh_ride_status(session, ride_id)


def _fail_queued(sessions: sessionmaker[Session], job_id: int, error: str) -> None:
    """Fail a job the queue refused (and show it on its ride)."""
    with session_scope(sessions) as session:
        jobs = JobRepository(session)
        jobs.fail_queued(job_id, error=error)
        refresh_ride_status(session, jobs.get(job_id).ride_id)


def _printable(value: Any) -> Any:
    """`value` with any text that is not valid Unicode (a lone surrogate) repaired, so it can be sent as JSON."""
    if isinstance(value, str):
        return value.encode("utf-8", "replace").decode("utf-8")
    if isinstance(value, dict):
        return {_printable(k): _printable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_printable(v) for v in value]
    return value


def job_as_dict(job: Job) -> dict[str, Any]:
    """The public view of a job (what GET /api/jobs/{id} returns); stored text that cannot be sent is repaired."""
    return {
        "id": job.id, "kind": job.kind, "status": job.status, "stage": _printable(job.stage),
        "progress": job.progress, "timings_s": dict(job.timings or {}), "error": _printable(job.error),
        "ride_id": job.ride_id, "rig_id": job.rig_id,
        "payload": _printable(dict(job.payload or {})), "attempts": job.attempts, "code_version": job.code_version,
        "host": job.host, "created_at": job.created_at, "started_at": job.started_at,
        "finished_at": job.finished_at, "note": None,
        "progress_percent": progress_percent(job.progress, job.status),
        "stage_label": stage_label(_printable(job.stage), job.status),
        "failure": _failure(job), "remaining_s": remaining_seconds(job), "duration_s": _duration_s(job),
    }


# A running job's expected remaining time is extrapolated from its progress only past this fraction
# (the first percent is dominated by start-up, and would promise hours).
_MIN_PROGRESS_FOR_ESTIMATE = 0.03


def remaining_seconds(job: Job, *, now=None) -> float | None:
    """A running job's expected remaining time: its elapsed time stretched over the progress still to go.

    None for a job not running, or too early to tell.
    """
    if job.status != JobStatus.RUNNING.value or job.started_at is None:
        return None
    progress = float(job.progress or 0.0)
    if progress < _MIN_PROGRESS_FOR_ESTIMATE:
        return None
    elapsed_s = ((now or utcnow()) - job.started_at).total_seconds()
    if elapsed_s <= 0:
        return None
    return round(elapsed_s * (1.0 - progress) / progress, 1)


def _duration_s(job: Job) -> float | None:
    """How long a finished job ran (None while it has not both started and ended)."""
    if job.started_at is None or job.finished_at is None:
        return None
    return round(max((job.finished_at - job.started_at).total_seconds(), 0.0), 1)


def _failure(job: Job) -> dict[str, Any] | None:
    """A failed job's advice (one sentence, the clip, the action) as the API sends it."""
    if job.status != JobStatus.FAILED.value:
        return None
    advice = explain_failure(_printable(job.error))
    if advice is None:
        return None
    return {"sentence": advice.sentence, "action": advice.action, "camera": advice.camera,
            "clip_kind": advice.clip_kind}


def job_note(session: Session, job: Job, queue: JobQueue | WorkersAlive, *,
             stale_after_s: float | None = None) -> str | None:
    """What an unfinished job is waiting for, when it is not simply progressing (None otherwise).

    A running job whose heartbeat (by the database's clock) is older than the stale limit
    (`stale_after_s`; None: the setting SADDLESCOPE_STALE_AFTER_S) has lost its worker; a queued job
    with no worker alive (no answer to a ping and no running job beating) waits for one.
    """
    if stale_after_s is None:
        stale_after_s = get_settings().stale_after_s
    jobs = JobRepository(session)
    if job.status == JobStatus.RUNNING.value:
        age_s = jobs.seconds_since_heartbeat(job.id)
        if age_s is not None and age_s > stale_after_s:
            return (f"waiting for a worker: its worker {job.host} sent no heartbeat for {age_s:.0f} s; "
                    "it will be run again or failed with the reason")
        return None
    if job.status != JobStatus.QUEUED.value:
        return None
    workers_alive = getattr(queue, "workers_alive", None)
    if workers_alive is None or workers_alive() != 0:
        return None
    if any(age is not None and age <= stale_after_s for *_, age, _ in jobs.running_with_age()):
        return None  # a worker busy with another job (it cannot answer a ping meanwhile)
    return "waiting for a worker: no worker is running; the job starts when one does"


def get_job(session: Session, job_id: int, *, club_id: int | None = None) -> Job:
    """The job (in this club when `club_id` is given); `NotFound` otherwise."""
    return JobRepository(session, club_id=club_id).get(job_id)


def cancel_job(session: Session, job_id: int, *, club_id: int | None = None) -> Job:
    """Cancel a queued or running job (a no-op on a finished one); returns the job."""
    repo = JobRepository(session, club_id=club_id)
    repo.get(job_id)
    repo.request_cancel(job_id)
    session.flush()
    session.expire_all()
    job = repo.get(job_id)
    refresh_ride_status(session, job.ride_id)
    return job


def retry_job(sessions: sessionmaker[Session], queue: JobQueue, job_id: int, *,
              club_id: int | None = None) -> int:
    """Run a failed or cancelled job again (same id; its uploads and earlier outputs are kept)."""
    with session_scope(sessions) as session:
        repo = JobRepository(session, club_id=club_id)
        job = repo.get(job_id)
        if not repo.requeue(job_id):
            raise JobStateError(
                f"job {job_id} is {job.status}; only a failed or cancelled job can be retried")
        refresh_ride_status(session, job.ride_id)
    try:
        queue.submit(job_id)
    except QueueUnavailable as exc:
        _fail_queued(sessions, job_id, str(exc))
        raise
    return job_id


class JobStateError(InputError):
    """The job is not in a state that allows this (HTTP 409)."""


def wait_for_job(sessions: sessionmaker[Session], job_id: int, *, timeout_s: float = 3600.0,
                 poll_s: float = 0.2,
                 on_update: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Poll a job until it is finished; returns its public view. `TimeoutError` after `timeout_s`."""
    deadline = time.monotonic() + timeout_s
    last: tuple | None = None
    while True:
        with session_scope(sessions) as session:
            view = job_as_dict(get_job(session, job_id))
        key = (view["status"], view["stage"], round(view["progress"], 3))
        if on_update is not None and key != last:
            on_update(view)
        last = key
        if JobStatus(view["status"]).finished:
            return view
        if time.monotonic() > deadline:
            raise TimeoutError(f"job {job_id} still {view['status']} after {timeout_s:.0f} s")
        time.sleep(poll_s)

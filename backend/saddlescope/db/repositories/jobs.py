"""Jobs (their state, progress and timings) and resumable uploads: the rows the workers and uploaders race on.

Their state changes are single conditional UPDATEs, so two workers, or two requests, never both win.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from typing import Any

from sqlalchemy import DateTime, Float, delete, func, or_, select, update
from sqlalchemy.ext.compiler import compiles
from sqlalchemy.sql.expression import ColumnElement, FunctionElement

from saddlescope.db.enums import JobStatus, UploadStatus
from saddlescope.db.models import Job, Upload, utcnow
from saddlescope.db.repositories.base import Page, Repository, changed_rows

__all__ = ["JobRepository", "UploadRepository", "db_utcnow", "seconds_since"]

_ACTIVE = (JobStatus.QUEUED.value, JobStatus.RUNNING.value)
# A running job silent this long (by the database's clock) has lost its worker (services.jobs.runner.STALE_AFTER_S).
STALE_AFTER_S = 180.0


class db_utcnow(FunctionElement):  # noqa: N801 (a SQL function, named like one)
    """The DATABASE's clock, so heartbeats are judged by one clock, not each host's."""

    type = DateTime()
    inherit_cache = True


@compiles(db_utcnow, "postgresql")
def _db_utcnow_pg(element, compiler, **kw) -> str:
    return "statement_timestamp()"  # the columns are TIMESTAMP WITH TIME ZONE


@compiles(db_utcnow)
def _db_utcnow_sqlite(element, compiler, **kw) -> str:
    # The format SQLAlchemy stores SQLite DateTimes in (microseconds, 6 digits).
    return "(strftime('%Y-%m-%d %H:%M:%f', 'now') || '000')"


class seconds_since(FunctionElement):  # noqa: N801
    """Seconds from a timestamp column to the database's clock now."""

    type = Float()
    inherit_cache = True


@compiles(seconds_since, "postgresql")
def _seconds_since_pg(element, compiler, **kw) -> str:
    column = compiler.process(element.clauses, **kw)
    return f"EXTRACT(EPOCH FROM (statement_timestamp() - {column}))"


@compiles(seconds_since)
def _seconds_since_sqlite(element, compiler, **kw) -> str:
    column = compiler.process(element.clauses, **kw)
    return f"((julianday('now') - julianday({column})) * 86400.0)"


def _heartbeat_age() -> ColumnElement[float]:
    return seconds_since(func.coalesce(Job.updated_at, Job.created_at))


class JobRepository(Repository):
    """Jobs and their progress. Progress writes are single UPDATEs so they stay cheap."""

    model = Job
    sort_fields = {"created_at": Job.created_at, "status": Job.status, "kind": Job.kind}
    default_sort = "-id"

    def add(self, *, kind: str, club_id: int | None = None, ride_id: int | None = None,
            rig_id: int | None = None, payload: dict[str, Any] | None = None) -> Job:
        """Add a queued job of `kind` for a ride or a rig (or neither: a system job)."""
        return self._add(Job(kind=kind, club_id=self._club_for_new(club_id), ride_id=ride_id, rig_id=rig_id,
                             payload=payload or {}, status=JobStatus.QUEUED.value, progress=0.0, timings={},
                             updated_at=db_utcnow()))

    def list_page(self, *, ride_id: int | None = None, rig_id: int | None = None, status: str | None = None,
                  kind: str | None = None, sort: str | None = None, limit: int = 50, offset: int = 0) -> Page:
        """Return a page of the jobs (of this club) of a ride, a rig, a status or a kind (None: any).

        Newest first unless `sort` says otherwise.
        """
        where = [column == value
                 for column, value in ((Job.ride_id, ride_id), (Job.rig_id, rig_id), (Job.status, status),
                                       (Job.kind, kind))
                 if value is not None]
        return self._page(where, sort=sort, limit=limit, offset=offset)

    def status_of(self, job_id: int) -> str | None:
        """Return the job's status read now from the database (None: no such job)."""
        return self.session.scalar(select(Job.status).where(Job.id == job_id))

    def _set(self, job_id: int, **values: Any) -> None:
        values.setdefault("updated_at", db_utcnow())
        self.session.execute(update(Job).where(Job.id == job_id).values(**values))

    def mark_running(self, job_id: int, *, host: str, code_version: str,
                     stale_after_s: float = STALE_AFTER_S) -> int | None:
        """Start a queued job (or take over a running one whose worker is gone); returns its new attempt.

        Clears the outcome of an earlier attempt. Returns None, changing nothing, when the job is
        finished (done, failed or cancelled), so a redelivered task does no work twice, and when it
        is running on another live worker: a running job is taken only from the same `host` (a retry
        in the same process) or when its heartbeat is older than `stale_after_s` by the database's
        clock. The attempt number returned fences the writes of this run (`set_progress`, `touch`,
        `finish`, `hold`): once another worker has taken the job over, they are refused.
        """
        active = or_(Job.status == JobStatus.QUEUED.value,
                     (Job.status == JobStatus.RUNNING.value)
                     & or_(Job.host == host, Job.updated_at.is_(None), _heartbeat_age() > stale_after_s))
        attempt = self.session.scalar(
            update(Job).where(Job.id == job_id, active).values(
                status=JobStatus.RUNNING.value, started_at=db_utcnow(), finished_at=None, error=None,
                progress=0.0, stage=None, timings={}, host=host, code_version=code_version,
                attempts=Job.attempts + 1, updated_at=db_utcnow()).returning(Job.attempts))
        return attempt

    def _fenced(self, job_id: int, attempt: int | None, host: str | None, **values: Any) -> bool:
        """One UPDATE of a running job, only while it is still attempt `attempt` on `host` (None: any)."""
        stmt = update(Job).where(Job.id == job_id, Job.status == JobStatus.RUNNING.value)
        if attempt is not None:
            stmt = stmt.where(Job.attempts == attempt)
        if host is not None:
            stmt = stmt.where(Job.host == host)
        values.setdefault("updated_at", db_utcnow())
        return changed_rows(self.session.execute(stmt.values(**values))) == 1

    def set_progress(self, job_id: int, progress: float, stage: str | None, *, attempt: int | None = None,
                     host: str | None = None) -> bool:
        """Store a running job's progress (clipped to 0-1) and the stage it is in.

        False (nothing written) when the job is no longer running as `attempt` on `host`.
        """
        return self._fenced(job_id, attempt, host, progress=min(max(float(progress), 0.0), 1.0), stage=stage)

    def set_timings(self, job_id: int, timings: dict[str, float], *, attempt: int | None = None,
                    host: str | None = None) -> bool:
        """Store the wall seconds of the job's stages; False when another attempt has taken the job over.

        Not limited to running jobs: a cancelled run's timings are worth seeing too.
        """
        stmt = update(Job).where(Job.id == job_id)
        if attempt is not None:
            stmt = stmt.where(Job.attempts == attempt)
        if host is not None:
            stmt = stmt.where(Job.host == host)
        return changed_rows(self.session.execute(stmt.values(timings=dict(timings), updated_at=db_utcnow()))) == 1

    def finish(self, job_id: int, status: JobStatus, *, error: str | None = None, attempt: int | None = None,
               host: str | None = None) -> bool:
        """End a running job; False when it was cancelled, finished or taken over by another attempt meanwhile."""
        values: dict[str, Any] = {"status": status.value, "finished_at": db_utcnow(), "error": error,
                                  "updated_at": db_utcnow()}
        if status is JobStatus.DONE:
            values["progress"] = 1.0
        return self._fenced(job_id, attempt, host, **values)

    def retry_later(self, job_id: int, *, reason: str, attempt: int | None = None, host: str | None = None) -> bool:
        """Put a running job back in the queue after a passing failure (the file store did not answer).

        The reason is shown meanwhile; fenced like `finish`. Its attempts are kept: they bound the retries.
        """
        return self._fenced(job_id, attempt, host, status=JobStatus.QUEUED.value, error=reason, progress=0.0,
                            stage=None, finished_at=None)

    def fail_queued(self, job_id: int, *, error: str) -> bool:
        """Fail a job that never started (e.g. the queue refused it)."""
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.status == JobStatus.QUEUED.value).values(
                status=JobStatus.FAILED.value, error=error, finished_at=utcnow(), updated_at=utcnow()))
        return changed_rows(result) == 1

    def discard_unstarted(self, job_id: int) -> bool:
        """Delete a job that is queued and was never started (the queue refused it as it was created)."""
        result = self.session.execute(delete(Job).where(Job.id == job_id, Job.status == JobStatus.QUEUED.value,
                                                        Job.attempts == 0, Job.started_at.is_(None)))
        return changed_rows(result) == 1

    def request_cancel(self, job_id: int) -> bool:
        """Cancel a queued or running job; a running one stops at its next progress report."""
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.status.in_(_ACTIVE)).values(
                status=JobStatus.CANCELLED.value, finished_at=utcnow(), updated_at=utcnow()))
        return changed_rows(result) == 1

    def requeue(self, job_id: int) -> bool:
        """Put a failed or cancelled job back in the queue (its outcome cleared; attempts kept)."""
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.status.in_((JobStatus.FAILED.value,
                                                                 JobStatus.CANCELLED.value))).values(
                status=JobStatus.QUEUED.value, error=None, finished_at=None, progress=0.0, stage=None,
                updated_at=utcnow()))
        return changed_rows(result) == 1

    def active_for(self, *, ride_id: int | None = None, rig_id: int | None = None, kind: str | None = None
                   ) -> Job | None:
        """A queued or running job of this ride or rig (of this kind), if any."""
        stmt = select(Job).where(Job.status.in_(_ACTIVE))
        if ride_id is not None:
            stmt = stmt.where(Job.ride_id == ride_id)
        if rig_id is not None:
            stmt = stmt.where(Job.rig_id == rig_id)
        if kind is not None:
            stmt = stmt.where(Job.kind == kind)
        return self.session.scalars(self._scoped(stmt).order_by(Job.id.desc())).first()

    def latest_for_ride(self, ride_id: int, *, kind: str | None = None) -> Job | None:
        """Return the ride's newest job (of `kind`; None: of any kind), or None."""
        stmt = select(Job).where(Job.ride_id == ride_id)
        if kind is not None:
            stmt = stmt.where(Job.kind == kind)
        stmt = self._scoped(stmt).order_by(Job.id.desc())
        return self.session.scalars(stmt).first()

    def touch(self, job_id: int, *, attempt: int | None = None, host: str | None = None) -> bool:
        """A running job's heartbeat (its worker is alive); False when `attempt` on `host` no longer holds it."""
        return self._fenced(job_id, attempt, host)

    def hold(self, job_id: int, *, attempt: int, host: str) -> bool:
        """Lock the job's row for this transaction if `attempt` on `host` still runs it (a fence for outputs).

        Written as an UPDATE (a heartbeat), so the row stays locked until the caller's commit: a
        worker taking the job over waits for it, and after it the stale attempt's `hold` is False.
        """
        return self._fenced(job_id, attempt, host)

    def requeue_lost(self, job_id: int, *, host: str | None) -> bool:
        """Put a running job whose worker is gone back in the queue (only if still held by `host`)."""
        stmt = update(Job).where(Job.id == job_id, Job.status == JobStatus.RUNNING.value)
        if host is not None:
            stmt = stmt.where(Job.host == host)
        result = self.session.execute(
            stmt.values(status=JobStatus.QUEUED.value, stage=None, updated_at=db_utcnow()))
        return changed_rows(result) == 1

    def fail_lost(self, job_id: int, *, host: str | None, error: str) -> bool:
        """Fail a running job whose worker is gone for good (only if still held by `host`)."""
        stmt = update(Job).where(Job.id == job_id, Job.status == JobStatus.RUNNING.value)
        if host is not None:
            stmt = stmt.where(Job.host == host)
        result = self.session.execute(stmt.values(status=JobStatus.FAILED.value, error=error,
                                                  finished_at=utcnow(), updated_at=db_utcnow()))
        return changed_rows(result) == 1

    def running_with_age(self) -> list[tuple[int, int | None, str | None, float | None, int]]:
        """(id, ride_id, host, seconds since its heartbeat by the database's clock, attempts) of running jobs."""
        stmt = self._scoped(select(Job.id, Job.ride_id, Job.host, _heartbeat_age(), Job.attempts)
                            .where(Job.status == JobStatus.RUNNING.value)).order_by(Job.id)
        return [tuple(row) for row in self.session.execute(stmt)]

    def queued_longer_than(self, seconds: float) -> list[int]:
        """Ids of the jobs queued (or last re-sent) more than `seconds` ago by the database's clock."""
        stmt = self._scoped(select(Job.id).where(Job.status == JobStatus.QUEUED.value,
                                                 _heartbeat_age() > seconds)).order_by(Job.id)
        return list(self.session.scalars(stmt))

    def mark_resent(self, job_id: int) -> bool:
        """Note that a queued job was handed to the broker again (its wait starts over)."""
        result = self.session.execute(update(Job).where(Job.id == job_id, Job.status == JobStatus.QUEUED.value)
                                      .values(updated_at=db_utcnow()))
        return changed_rows(result) == 1

    def seconds_since_heartbeat(self, job_id: int) -> float | None:
        """Seconds since the job's last heartbeat (or progress, or queuing), by the database's clock."""
        return self.session.scalar(select(_heartbeat_age()).where(Job.id == job_id))

    def running(self) -> Sequence[Job]:
        """Return the running jobs (of this club)."""
        stmt = self._scoped(select(Job).where(Job.status == JobStatus.RUNNING.value))
        return self.session.scalars(stmt).all()

    def unfinished(self) -> Sequence[Job]:
        """Return the queued and running jobs (of this club), oldest first."""
        stmt = self._scoped(select(Job).where(Job.status.in_(_ACTIVE))).order_by(Job.id)
        return self.session.scalars(stmt).all()



class UploadRepository(Repository):
    """Resumable uploads: bytes arrive at increasing offsets until the upload is finalised."""

    model = Upload

    def add(self, *, id_: str, club_id: int | None = None, user_id: int | None, target: str,
            ride_id: int | None, rig_id: int | None, clip_kind: str | None, camera_role: str | None,
            filename: str | None, length_bytes: int) -> Upload:
        """Add an open upload of `length_bytes` bytes (`id_` is its unguessable id)."""
        now = utcnow()
        return self._add(Upload(id=id_, club_id=self._club_for_new(club_id), user_id=user_id, target=target,
                                ride_id=ride_id, rig_id=rig_id, clip_kind=clip_kind, camera_role=camera_role,
                                filename=filename, length_bytes=length_bytes, offset_bytes=0,
                                status=UploadStatus.OPEN.value, outcome={}, created_at=now, updated_at=now))

    def lock(self, upload_id: str) -> bool:
        """Lock the upload's row until this transaction ends (a no-op UPDATE: PostgreSQL and SQLite alike)."""
        stmt = update(Upload).where(Upload.id == upload_id)
        if self.club_id is not None:
            stmt = stmt.where(Upload.club_id == self.club_id)
        return changed_rows(self.session.execute(stmt.values(offset_bytes=Upload.offset_bytes))) == 1

    def advance(self, upload_id: str, *, from_offset: int, to_offset: int) -> bool:
        """Move the offset forward, only if nobody else moved it meanwhile (two PATCHes racing)."""
        stmt = update(Upload).where(Upload.id == upload_id, Upload.offset_bytes == from_offset,
                                    Upload.status == UploadStatus.OPEN.value).values(
            offset_bytes=to_offset, updated_at=utcnow())
        if self.club_id is not None:
            stmt = stmt.where(Upload.club_id == self.club_id)
        return changed_rows(self.session.execute(stmt)) == 1

    def claim(self, upload_id: str) -> bool:
        """Mark an open upload finalising, only if it still is open (one conditional UPDATE).

        True for the one caller that claimed it; a concurrent finalise gets False.
        """
        stmt = update(Upload).where(Upload.id == upload_id, Upload.status == UploadStatus.OPEN.value).values(
            status=UploadStatus.FINALISING.value, updated_at=utcnow())
        if self.club_id is not None:
            stmt = stmt.where(Upload.club_id == self.club_id)
        return changed_rows(self.session.execute(stmt)) == 1

    def reopen(self, upload_id: str, *, offset_bytes: int) -> None:
        """Give a claimed upload back, open at `offset_bytes` (its finalising stopped before using its bytes)."""
        row = self.get(upload_id)
        row.status, row.offset_bytes, row.updated_at = UploadStatus.OPEN.value, offset_bytes, utcnow()
        self.session.flush()

    def close(self, upload_id: str, *, status: UploadStatus, error: str | None = None,
              outcome: dict[str, Any] | None = None) -> None:
        """End an upload: finalised (with what it made) or failed (with the reason)."""
        row = self.get(upload_id)
        row.status, row.error, row.outcome = status.value, error, dict(outcome or {})
        row.updated_at = utcnow()
        self.session.flush()

    def ids_of(self, *, ride_id: int | None = None, rig_id: int | None = None) -> list[str]:
        """The ids of the uploads (any status) of a ride or of a rig."""
        column, value = (Upload.ride_id, ride_id) if ride_id is not None else (Upload.rig_id, rig_id)
        return list(self.session.scalars(self._scoped(select(Upload.id).where(column == value))))

    def open_since_before(self, before: dt.datetime) -> list[str]:
        """The ids of the open uploads (of this club, or all) that last moved before `before`.

        Finalising ones too: a finalise whose process died (its staged bytes are swept).
        """
        unfinished = (UploadStatus.OPEN.value, UploadStatus.FINALISING.value)
        stmt = select(Upload.id).where(Upload.status.in_(unfinished), Upload.updated_at < before)
        return list(self.session.scalars(self._scoped(stmt)))

    def delete_ids(self, upload_ids: Sequence[str]) -> None:
        """Delete uploads' rows by id (their bytes are the caller's to delete)."""
        if upload_ids:
            self.session.execute(self._scoped_delete().where(Upload.id.in_(list(upload_ids))))

    def _scoped_delete(self):
        stmt = delete(Upload)
        return stmt.where(Upload.club_id == self.club_id) if self.club_id is not None else stmt

    def delete(self, upload_id: str) -> None:
        """Delete an upload's row (its bytes are the caller's to delete)."""
        self.session.delete(self.get(upload_id))
        self.session.flush()

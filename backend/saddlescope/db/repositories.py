"""All SQL lives here: one small repository per aggregate.

A repository wraps a `Session` and, optionally, a ``club_id``: when given, every read and write is
confined to that club (the API will build club-scoped repositories from the signed-in user; the
job runner and the command line use unscoped ones). Repositories flush but never commit: the
caller owns the transaction (`saddlescope.db.session.session_scope`).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from typing import Any, TypeVar

from sqlalchemy import Select, delete, func, select, update
from sqlalchemy.orm import Session

from saddlescope.db.models import (
    LEADERBOARD_COLUMNS,
    Base,
    Club,
    Grade,
    Horse,
    Job,
    JobStatus,
    Recording,
    Result,
    Ride,
    Rider,
    Rig,
    utcnow,
)

M = TypeVar("M", bound=Base)
_ACTIVE = (JobStatus.QUEUED.value, JobStatus.RUNNING.value)


class NotFound(LookupError):
    """No row with that id (or not in this club)."""


class Repository:
    """Base: a session and an optional club scope."""

    model: type[Base]

    def __init__(self, session: Session, *, club_id: int | None = None) -> None:
        self.session = session
        self.club_id = club_id

    def _scoped(self, stmt: Select) -> Select:
        if self.club_id is not None and hasattr(self.model, "club_id"):
            stmt = stmt.where(self.model.club_id == self.club_id)
        return stmt

    def _club_for_new(self, club_id: int | None) -> int | None:
        if self.club_id is not None and club_id is not None and club_id != self.club_id:
            raise PermissionError(f"cannot create a row in club {club_id} from a repository scoped to "
                                  f"club {self.club_id}")
        return self.club_id if club_id is None else club_id

    def find(self, id_: int):
        """The row with primary key `id_` (in this club), or None."""
        return self.session.scalars(self._scoped(select(self.model).where(self.model.id == id_))).first()

    def get(self, id_: int):
        """The row with primary key `id_` (in this club); `NotFound` otherwise."""
        row = self.find(id_)
        if row is None:
            raise NotFound(f"{self.model.__tablename__[:-1]} {id_} not found")
        return row

    def _add(self, row: M) -> M:
        self.session.add(row)
        self.session.flush()
        return row


class ClubRepository(Repository):
    model = Club

    def get_or_create(self, name: str) -> Club:
        club = self.session.scalars(select(Club).where(Club.name == name)).first()
        return club or self._add(Club(name=name))


class HorseRepository(Repository):
    model = Horse

    def get_or_create(self, *, club_id: int | None = None, name: str, breed: str | None = None,
                      birth_year: int | None = None, height_withers_m: float | None = None) -> Horse:
        club_id = self._club_for_new(club_id)
        horse = self.session.scalars(
            select(Horse).where(Horse.club_id == club_id, Horse.name == name)).first()
        if horse is None:
            horse = self._add(Horse(club_id=club_id, name=name, breed=breed, birth_year=birth_year,
                                    height_withers_m=height_withers_m))
        return horse


class RiderRepository(Repository):
    model = Rider

    def get_or_create(self, *, club_id: int | None = None, name: str) -> Rider:
        club_id = self._club_for_new(club_id)
        rider = self.session.scalars(
            select(Rider).where(Rider.club_id == club_id, Rider.name == name)).first()
        return rider or self._add(Rider(club_id=club_id, name=name))


class RigRepository(Repository):
    model = Rig

    def add(self, *, club_id: int | None = None, name: str, recorded_on: dt.date | None = None,
            cameras: dict | None = None) -> Rig:
        return self._add(Rig(club_id=self._club_for_new(club_id), name=name, recorded_on=recorded_on,
                             cameras=cameras or {}))

    def set_calibration(self, rig_id: int, calibration: dict, quality: dict) -> None:
        rig = self.get(rig_id)
        rig.calibration = calibration
        rig.quality = quality
        self.session.flush()


class RideRepository(Repository):
    model = Ride

    def add(self, *, club_id: int | None = None, horse_id: int, rider_id: int, gait: str, direction: str,
            rig_id: int | None = None, ridden_on: dt.date | None = None, notes: str = "") -> Ride:
        return self._add(Ride(club_id=self._club_for_new(club_id), horse_id=horse_id, rider_id=rider_id,
                              rig_id=rig_id, gait=gait, direction=direction, ridden_on=ridden_on,
                              notes=notes))

    def set_status(self, ride_id: int, status: str) -> None:
        self.session.execute(self._scoped_update(ride_id).values(status=status))

    def set_bundle_key(self, ride_id: int, bundle_key: str) -> None:
        self.session.execute(self._scoped_update(ride_id).values(bundle_key=bundle_key))

    def _scoped_update(self, ride_id: int):
        stmt = update(Ride).where(Ride.id == ride_id)
        return stmt.where(Ride.club_id == self.club_id) if self.club_id is not None else stmt

    def delete(self, ride_id: int) -> None:
        """Delete a ride; its recordings, jobs, result and grades go with it (ON DELETE CASCADE)."""
        stmt = delete(Ride).where(Ride.id == ride_id)
        if self.club_id is not None:
            stmt = stmt.where(Ride.club_id == self.club_id)
        self.session.execute(stmt)

    def latest_with_bundle(self, club_id: int) -> int | None:
        """Id of the club's newest ride that has a stored bundle, or None."""
        stmt = self._scoped(select(Ride.id).where(Ride.club_id == club_id, Ride.bundle_key.is_not(None)))
        return self.session.scalar(stmt.order_by(Ride.id.desc()).limit(1))

    def latest(self, limit: int = 50) -> Sequence[Ride]:
        return self.session.scalars(self._scoped(select(Ride)).order_by(Ride.id.desc()).limit(limit)).all()


class RecordingRepository(Repository):
    model = Recording

    def add(self, *, club_id: int | None = None, ride_id: int | None = None, rig_id: int | None = None,
            camera_role: str, clip_kind: str, path: str, sha256: str | None = None,
            size_bytes: int | None = None) -> Recording:
        return self._add(Recording(club_id=self._club_for_new(club_id), ride_id=ride_id, rig_id=rig_id,
                                   camera_role=camera_role, clip_kind=clip_kind, path=path, sha256=sha256,
                                   size_bytes=size_bytes))

    def for_ride(self, ride_id: int) -> Sequence[Recording]:
        stmt = self._scoped(select(Recording).where(Recording.ride_id == ride_id)).order_by(Recording.id)
        return self.session.scalars(stmt).all()

    def for_rig(self, rig_id: int) -> Sequence[Recording]:
        stmt = self._scoped(select(Recording).where(Recording.rig_id == rig_id)).order_by(Recording.id)
        return self.session.scalars(stmt).all()

    def set_probe(self, recording_id: int, *, sha256: str, size_bytes: int, fps: float | None,
                  frame_count: int | None, width: int | None, height: int | None) -> None:
        """Record what the probe stage found (replaces any earlier probe)."""
        self.session.execute(
            update(Recording).where(Recording.id == recording_id).values(
                sha256=sha256, size_bytes=size_bytes, fps=fps, frame_count=frame_count, width=width,
                height=height, probed_at=utcnow()))


class JobRepository(Repository):
    """Jobs and their progress. Progress writes are single UPDATEs so they stay cheap."""

    model = Job

    def add(self, *, kind: str, club_id: int | None = None, ride_id: int | None = None,
            rig_id: int | None = None, payload: dict[str, Any] | None = None) -> Job:
        return self._add(Job(kind=kind, club_id=self._club_for_new(club_id), ride_id=ride_id, rig_id=rig_id,
                             payload=payload or {}, status=JobStatus.QUEUED.value, progress=0.0, timings={}))

    def status_of(self, job_id: int) -> str | None:
        return self.session.scalar(select(Job.status).where(Job.id == job_id))

    def _set(self, job_id: int, **values: Any) -> None:
        values.setdefault("updated_at", utcnow())
        self.session.execute(update(Job).where(Job.id == job_id).values(**values))

    def mark_running(self, job_id: int, *, host: str, code_version: str) -> bool:
        """Start (or restart, after a lost worker) a queued or running job.

        Clears the outcome of an earlier attempt. Returns False, changing nothing, when the job is
        already finished (done, failed or cancelled), so a redelivered task does no work twice.
        """
        now = utcnow()
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.status.in_(_ACTIVE)).values(
                status=JobStatus.RUNNING.value, started_at=now, finished_at=None, error=None, progress=0.0,
                stage=None, timings={}, host=host, code_version=code_version, attempts=Job.attempts + 1,
                updated_at=now))
        return result.rowcount == 1

    def set_progress(self, job_id: int, progress: float, stage: str | None) -> None:
        self._set(job_id, progress=min(max(float(progress), 0.0), 1.0), stage=stage)

    def set_timings(self, job_id: int, timings: dict[str, float]) -> None:
        self._set(job_id, timings=dict(timings))

    def finish(self, job_id: int, status: JobStatus, *, error: str | None = None) -> bool:
        """End a running job; False when it was cancelled (or finished) meanwhile."""
        values: dict[str, Any] = {"status": status.value, "finished_at": utcnow(), "error": error,
                                  "updated_at": utcnow()}
        if status is JobStatus.DONE:
            values["progress"] = 1.0
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.status == JobStatus.RUNNING.value).values(**values))
        return result.rowcount == 1

    def fail_queued(self, job_id: int, *, error: str) -> bool:
        """Fail a job that never started (e.g. the queue refused it)."""
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.status == JobStatus.QUEUED.value).values(
                status=JobStatus.FAILED.value, error=error, finished_at=utcnow(), updated_at=utcnow()))
        return result.rowcount == 1

    def request_cancel(self, job_id: int) -> bool:
        """Cancel a queued or running job; a running one stops at its next progress report."""
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.status.in_(_ACTIVE)).values(
                status=JobStatus.CANCELLED.value, finished_at=utcnow(), updated_at=utcnow()))
        return result.rowcount == 1

    def unfinished(self) -> Sequence[Job]:
        stmt = self._scoped(select(Job).where(Job.status.in_(_ACTIVE))).order_by(Job.id)
        return self.session.scalars(stmt).all()

    def count_by_status(self) -> dict[str, int]:
        rows = self.session.execute(self._scoped(select(Job.status, func.count()).group_by(Job.status)))
        return {status: n for status, n in rows}


class ResultRepository(Repository):
    model = Result

    def for_ride(self, ride_id: int) -> Result | None:
        return self.session.scalars(self._scoped(select(Result).where(Result.ride_id == ride_id))).first()

    def replace_for_ride(self, *, club_id: int, ride_id: int, job_id: int | None, indicators: dict[str, Any],
                         quality: dict[str, Any], result_key: str | None, arrays_key: str | None,
                         code_version: str | None) -> Result:
        """Store a ride's result, replacing the previous one (re-running a job is idempotent)."""
        result = self.for_ride(ride_id)
        if result is None:
            result = Result(club_id=self._club_for_new(club_id), ride_id=ride_id)
            self.session.add(result)
        result.job_id = job_id
        result.indicators = dict(indicators)
        result.quality = dict(quality)
        result.result_key = result_key
        result.arrays_key = arrays_key
        result.code_version = code_version
        result.created_at = utcnow()
        for name in LEADERBOARD_COLUMNS:
            value = indicators.get(name)
            setattr(result, name, float(value) if isinstance(value, int | float) else None)
        self.session.flush()
        return result


class GradeRepository(Repository):
    model = Grade

    def set_grade(self, *, club_id: int | None = None, ride_id: int, rider_id: int, grade: int,
                  comment: str = "") -> Grade:
        """A rider's grade of a ride; grading again replaces the earlier grade."""
        row = self.session.scalars(self._scoped(
            select(Grade).where(Grade.ride_id == ride_id, Grade.rider_id == rider_id))).first()
        if row is None:
            return self._add(Grade(club_id=self._club_for_new(club_id), ride_id=ride_id, rider_id=rider_id,
                                   grade=grade, comment=comment))
        row.grade = grade
        row.comment = comment
        self.session.flush()
        return row

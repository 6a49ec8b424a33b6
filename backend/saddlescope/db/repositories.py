"""All SQL lives here: one small repository per aggregate.

A repository wraps a `Session` and, optionally, a ``club_id``: when given, every read and write is
confined to that club (the API will build club-scoped repositories from the signed-in user; the
job runner and the command line use unscoped ones). Repositories flush but never commit: the
caller owns the transaction (`saddlescope.db.session.session_scope`).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from sqlalchemy import ColumnElement, Select, delete, exists, func, select, update
from sqlalchemy.orm import Session

from saddlescope.db.enums import JobStatus, UploadStatus
from saddlescope.db.models import (
    LEADERBOARD_COLUMNS,
    Base,
    Club,
    Grade,
    Horse,
    Job,
    Recording,
    Result,
    Ride,
    Rider,
    Rig,
    Upload,
    User,
    utcnow,
)

M = TypeVar("M", bound=Base)
_ACTIVE = (JobStatus.QUEUED.value, JobStatus.RUNNING.value)


class NotFound(LookupError):
    """No row with that id (or not in this club)."""


class Conflict(ValueError):
    """The change would break a rule of the data (a duplicate name, a horse that rides still use)."""


class BadQuery(ValueError):
    """A list query asks for something unknown (a sort field, a filter value)."""


@dataclass(frozen=True)
class Page:
    """One page of a list: the rows and the total number of rows matching the filters."""

    items: Sequence[Any]
    total: int
    limit: int
    offset: int


def like_pattern(text: str) -> str:
    """A LIKE pattern matching `text` anywhere, with LIKE's wildcards taken literally."""
    escaped = text.replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_")
    return f"%{escaped}%"


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

    # Sortable fields of `list_page`: public name -> column (override per repository).
    sort_fields: dict[str, Any] = {}
    default_sort = "id"

    def _order(self, sort: str | None):
        sort = sort or self.default_sort
        name = sort.removeprefix("-")
        column = self.sort_fields.get(name) if name != "id" else self.model.id
        if column is None:
            known = ", ".join(sorted({"id", *self.sort_fields}))
            raise BadQuery(f"cannot sort by {name!r}; sort by one of {known} (prefix '-' for descending)")
        ordered = column.desc() if sort.startswith("-") else column.asc()
        # Ties (and NULLs) in a stable order, so pages never overlap.
        return [ordered.nulls_last(), self.model.id.desc() if sort.startswith("-") else self.model.id.asc()]

    def list_page(self, *, where: Sequence[ColumnElement[bool]] = (), sort: str | None = None,
                  limit: int = 50, offset: int = 0, stmt: Select | None = None) -> Page:
        """Rows matching `where` (in this club), `limit` of them from `offset`, and their total."""
        stmt = self._scoped(stmt if stmt is not None else select(self.model)).where(*where)
        total = self.session.scalar(select(func.count()).select_from(stmt.order_by(None).subquery()))
        rows = self.session.scalars(stmt.order_by(*self._order(sort)).limit(limit).offset(offset)).all()
        return Page(rows, int(total or 0), limit, offset)

    def update_fields(self, id_: int, **values: Any):
        """Set columns of one row (in this club); returns the row."""
        row = self.get(id_)
        for name, value in values.items():
            setattr(row, name, value)
        self.session.flush()
        return row


class ClubRepository(Repository):
    model = Club

    def _scoped(self, stmt: Select) -> Select:
        return stmt.where(Club.id == self.club_id) if self.club_id is not None else stmt

    def get_or_create(self, name: str) -> Club:
        club = self.session.scalars(select(Club).where(Club.name == name)).first()
        return club or self._add(Club(name=name))

    def add(self, name: str) -> Club:
        if self.session.scalar(select(Club.id).where(func.lower(Club.name) == name.lower())) is not None:
            raise Conflict(f"a club named {name!r} already exists")
        return self._add(Club(name=name))

    def count(self) -> int:
        return int(self.session.scalar(select(func.count(Club.id))) or 0)


class UserRepository(Repository):
    model = User
    sort_fields = {"email": User.email, "display_name": User.display_name, "role": User.role,
                   "created_at": User.created_at}
    default_sort = "email"

    def by_email(self, email: str) -> User | None:
        """The user with this e-mail address (any club: sign-in comes before the club is known)."""
        return self.session.scalars(select(User).where(User.email == email.strip().lower())).first()

    def add(self, *, club_id: int | None = None, email: str, password_hash: str, display_name: str = "",
            role: str) -> User:
        email = email.strip().lower()
        if self.by_email(email) is not None:
            raise Conflict(f"a user with the e-mail address {email!r} already exists")
        return self._add(User(club_id=self._club_for_new(club_id), email=email, password_hash=password_hash,
                              display_name=display_name, role=role, is_active=True))

    def count_admins(self) -> int:
        stmt = self._scoped(select(func.count(User.id)).where(User.role == "admin", User.is_active.is_(True)))
        return int(self.session.scalar(stmt) or 0)


def _in_use(session: Session, column, id_: int) -> bool:
    return bool(session.scalar(select(exists().where(column == id_))))


class _NamedMixin:
    """Names unique within a club (horses, riders)."""

    def _check_name_free(self, name: str, *, club_id: int, exclude_id: int | None = None) -> None:
        stmt = select(self.model.id).where(self.model.club_id == club_id, self.model.name == name)
        if exclude_id is not None:
            stmt = stmt.where(self.model.id != exclude_id)
        if self.session.scalar(stmt) is not None:
            raise Conflict(f"the club already has a {self.model.__tablename__[:-1]} named {name!r}")


class HorseRepository(_NamedMixin, Repository):
    model = Horse
    sort_fields = {"name": Horse.name, "breed": Horse.breed, "birth_year": Horse.birth_year,
                   "height_withers_m": Horse.height_withers_m, "created_at": Horse.created_at}
    default_sort = "name"

    def add(self, *, club_id: int | None = None, name: str, breed: str | None = None,
            birth_year: int | None = None, height_withers_m: float | None = None) -> Horse:
        club_id = self._club_for_new(club_id)
        self._check_name_free(name, club_id=club_id)
        return self._add(Horse(club_id=club_id, name=name, breed=breed, birth_year=birth_year,
                               height_withers_m=height_withers_m))

    def update_fields(self, id_: int, **values: Any) -> Horse:
        if "name" in values:
            self._check_name_free(values["name"], club_id=self.get(id_).club_id, exclude_id=id_)
        return super().update_fields(id_, **values)

    def delete(self, horse_id: int) -> None:
        horse = self.get(horse_id)
        if _in_use(self.session, Ride.horse_id, horse_id):
            raise Conflict(f"horse {horse_id} ({horse.name}) still has rides; delete them first")
        self.session.delete(horse)
        self.session.flush()

    def get_or_create(self, *, club_id: int | None = None, name: str, breed: str | None = None,
                      birth_year: int | None = None, height_withers_m: float | None = None) -> Horse:
        club_id = self._club_for_new(club_id)
        horse = self.session.scalars(
            select(Horse).where(Horse.club_id == club_id, Horse.name == name)).first()
        if horse is None:
            horse = self._add(Horse(club_id=club_id, name=name, breed=breed, birth_year=birth_year,
                                    height_withers_m=height_withers_m))
        return horse


class RiderRepository(_NamedMixin, Repository):
    model = Rider
    sort_fields = {"name": Rider.name, "created_at": Rider.created_at}
    default_sort = "name"

    def add(self, *, club_id: int | None = None, name: str, user_id: int | None = None) -> Rider:
        club_id = self._club_for_new(club_id)
        self._check_name_free(name, club_id=club_id)
        return self._add(Rider(club_id=club_id, name=name, user_id=user_id))

    def update_fields(self, id_: int, **values: Any) -> Rider:
        if "name" in values:
            self._check_name_free(values["name"], club_id=self.get(id_).club_id, exclude_id=id_)
        return super().update_fields(id_, **values)

    def delete(self, rider_id: int) -> None:
        rider = self.get(rider_id)
        if _in_use(self.session, Ride.rider_id, rider_id):
            raise Conflict(f"rider {rider_id} ({rider.name}) still has rides; delete them first")
        self.session.delete(rider)
        self.session.flush()

    def get_or_create(self, *, club_id: int | None = None, name: str) -> Rider:
        club_id = self._club_for_new(club_id)
        rider = self.session.scalars(
            select(Rider).where(Rider.club_id == club_id, Rider.name == name)).first()
        return rider or self._add(Rider(club_id=club_id, name=name))


class RigRepository(Repository):
    model = Rig
    sort_fields = {"name": Rig.name, "recorded_on": Rig.recorded_on, "created_at": Rig.created_at}
    default_sort = "-recorded_on"

    def add(self, *, club_id: int | None = None, name: str, recorded_on: dt.date | None = None,
            cameras: dict | None = None, board: dict | None = None) -> Rig:
        return self._add(Rig(club_id=self._club_for_new(club_id), name=name, recorded_on=recorded_on,
                             cameras=cameras or {}, board=board))

    def set_calibration(self, rig_id: int, calibration: dict, quality: dict) -> None:
        rig = self.get(rig_id)
        rig.calibration = calibration
        rig.quality = quality
        self.session.flush()

    def set_calibration_if_missing(self, rig_id: int, calibration: dict, quality: dict) -> bool:
        """Store a calibration unless the rig has one already (two jobs may race); True if stored."""
        stmt = update(Rig).where(Rig.id == rig_id, Rig.calibration.is_(None)).values(
            calibration=calibration, quality=quality)
        if self.club_id is not None:
            stmt = stmt.where(Rig.club_id == self.club_id)
        return self.session.execute(stmt).rowcount == 1

    def clear_calibration(self, rig_id: int) -> None:
        """Forget a rig's calibration (its calibration clips changed)."""
        self.get(rig_id)
        self.session.execute(update(Rig).where(Rig.id == rig_id).values(calibration=None, quality=None))

    def delete(self, rig_id: int) -> None:
        rig = self.get(rig_id)
        if _in_use(self.session, Ride.rig_id, rig_id):
            raise Conflict(f"rig {rig_id} ({rig.name}) is used by rides; delete them or move them first")
        self.session.delete(rig)
        self.session.flush()


class RideRepository(Repository):
    model = Ride
    sort_fields = {"ridden_on": Ride.ridden_on, "created_at": Ride.created_at, "gait": Ride.gait,
                   "status": Ride.status, "horse_id": Ride.horse_id, "rider_id": Ride.rider_id,
                   **{name: getattr(Result, name) for name in LEADERBOARD_COLUMNS}}
    default_sort = "-ridden_on"

    def _check_references(self, *, horse_id: int | None, rider_id: int | None, rig_id: int | None) -> None:
        """Horse, rider and rig must exist in this club (another club's ids are not found)."""
        for repo, id_ in ((HorseRepository, horse_id), (RiderRepository, rider_id), (RigRepository, rig_id)):
            if id_ is not None:
                repo(self.session, club_id=self.club_id).get(id_)

    def add(self, *, club_id: int | None = None, horse_id: int, rider_id: int, gait: str, direction: str,
            rig_id: int | None = None, ridden_on: dt.date | None = None, notes: str = "",
            meta: dict | None = None) -> Ride:
        self._check_references(horse_id=horse_id, rider_id=rider_id, rig_id=rig_id)
        return self._add(Ride(club_id=self._club_for_new(club_id), horse_id=horse_id, rider_id=rider_id,
                              rig_id=rig_id, gait=gait, direction=direction, ridden_on=ridden_on,
                              notes=notes, meta=meta or {}))

    def update_fields(self, id_: int, **values: Any) -> Ride:
        self._check_references(horse_id=values.get("horse_id"), rider_id=values.get("rider_id"),
                                rig_id=values.get("rig_id"))
        return super().update_fields(id_, **values)

    def list_page(self, *, where: Sequence[ColumnElement[bool]] = (), sort: str | None = None,
                  limit: int = 50, offset: int = 0, stmt: Select | None = None) -> Page:
        # Outer join: rides sort by their result's indicators; rides without a result come last.
        stmt = select(Ride).outerjoin(Result, Result.ride_id == Ride.id) if stmt is None else stmt
        return super().list_page(where=where, sort=sort, limit=limit, offset=offset, stmt=stmt)

    @staticmethod
    def filters(*, horse_id: int | None = None, rider_id: int | None = None, rig_id: int | None = None,
                gait: str | None = None, status: str | None = None, date_from: dt.date | None = None,
                date_to: dt.date | None = None) -> list[ColumnElement[bool]]:
        """WHERE clauses of the ride list filters (None: no filter)."""
        where: list[ColumnElement[bool]] = []
        for column, value in ((Ride.horse_id, horse_id), (Ride.rider_id, rider_id), (Ride.rig_id, rig_id),
                              (Ride.gait, gait), (Ride.status, status)):
            if value is not None:
                where.append(column == value)
        if date_from is not None:
            where.append(Ride.ridden_on >= date_from)
        if date_to is not None:
            where.append(Ride.ridden_on <= date_to)
        return where

    def set_meta(self, ride_id: int, meta: dict) -> None:
        self.session.execute(self._scoped_update(ride_id).values(meta=dict(meta)))

    def set_status(self, ride_id: int, status: str) -> None:
        self.session.execute(self._scoped_update(ride_id).values(status=status))

    def set_bundle_key(self, ride_id: int, bundle_key: str) -> None:
        self.session.execute(self._scoped_update(ride_id).values(bundle_key=bundle_key))

    def _scoped_update(self, ride_id: int):
        stmt = update(Ride).where(Ride.id == ride_id)
        return stmt.where(Ride.club_id == self.club_id) if self.club_id is not None else stmt

    def delete(self, ride_id: int) -> None:
        """Delete a ride; its recordings, jobs, result, grades and uploads go with it (ON DELETE CASCADE)."""
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
                  frame_count: int | None, width: int | None, height: int | None,
                  codec: str | None = None) -> None:
        """Record what the probe stage found (replaces any earlier probe)."""
        values = dict(sha256=sha256, size_bytes=size_bytes, fps=fps, frame_count=frame_count, width=width,
                      height=height, probed_at=utcnow())
        if codec is not None:
            values["codec"] = codec
        self.session.execute(update(Recording).where(Recording.id == recording_id).values(**values))

    def find_clip(self, *, ride_id: int | None = None, rig_id: int | None = None, clip_kind: str,
                  camera_role: str) -> Recording | None:
        owner = Recording.ride_id == ride_id if ride_id is not None else Recording.rig_id == rig_id
        stmt = self._scoped(select(Recording).where(owner, Recording.clip_kind == clip_kind,
                                                    Recording.camera_role == camera_role))
        return self.session.scalars(stmt).first()

    def put_clip(self, *, club_id: int | None = None, ride_id: int | None = None, rig_id: int | None = None,
                 clip_kind: str, camera_role: str, path: str, sha256: str, size_bytes: int, fps: float,
                 frame_count: int, width: int, height: int, codec: str | None,
                 original_filename: str | None) -> Recording:
        """Add a probed clip, or replace the one this owner had for that clip kind and camera."""
        row = self.find_clip(ride_id=ride_id, rig_id=rig_id, clip_kind=clip_kind, camera_role=camera_role)
        if row is None:
            row = self.add(club_id=club_id, ride_id=ride_id, rig_id=rig_id, camera_role=camera_role,
                           clip_kind=clip_kind, path=path)
        row.path, row.sha256, row.size_bytes = path, sha256, size_bytes
        row.fps, row.frame_count, row.width, row.height, row.codec = fps, frame_count, width, height, codec
        row.original_filename, row.probed_at = original_filename, utcnow()
        self.session.flush()
        return row


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

    sort_fields = {"created_at": Job.created_at, "status": Job.status, "kind": Job.kind}
    default_sort = "-id"

    def requeue(self, job_id: int) -> bool:
        """Put a failed or cancelled job back in the queue (its outcome cleared; attempts kept)."""
        result = self.session.execute(
            update(Job).where(Job.id == job_id, Job.status.in_((JobStatus.FAILED.value,
                                                                 JobStatus.CANCELLED.value))).values(
                status=JobStatus.QUEUED.value, error=None, finished_at=None, progress=0.0, stage=None,
                updated_at=utcnow()))
        return result.rowcount == 1

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

    def latest_for_ride(self, ride_id: int) -> Job | None:
        stmt = self._scoped(select(Job).where(Job.ride_id == ride_id)).order_by(Job.id.desc())
        return self.session.scalars(stmt).first()

    def touch(self, job_id: int) -> None:
        """A running job's heartbeat: its worker is alive."""
        self.session.execute(update(Job).where(Job.id == job_id, Job.status == JobStatus.RUNNING.value)
                             .values(updated_at=utcnow()))

    def requeue_lost(self, job_id: int, *, host: str | None) -> bool:
        """Put a running job whose worker is gone back in the queue (only if still held by `host`)."""
        stmt = update(Job).where(Job.id == job_id, Job.status == JobStatus.RUNNING.value)
        if host is not None:
            stmt = stmt.where(Job.host == host)
        result = self.session.execute(
            stmt.values(status=JobStatus.QUEUED.value, stage=None, updated_at=utcnow()))
        return result.rowcount == 1

    def running(self) -> Sequence[Job]:
        stmt = self._scoped(select(Job).where(Job.status == JobStatus.RUNNING.value))
        return self.session.scalars(stmt).all()

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

    def indicators_for(self, ride_ids: Sequence[int]) -> dict[int, dict[str, Any]]:
        """Ride id -> indicators of those rides (of this club) that have a result."""
        if not ride_ids:
            return {}
        stmt = self._scoped(
            select(Result.ride_id, Result.indicators).where(Result.ride_id.in_(list(ride_ids))))
        return {ride_id: dict(indicators or {}) for ride_id, indicators in self.session.execute(stmt)}

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
    sort_fields = {"grade": Grade.grade, "created_at": Grade.created_at, "ride_id": Grade.ride_id,
                   "rider_id": Grade.rider_id}
    default_sort = "-id"

    def check_references(self, *, ride_id: int | None, rider_id: int | None) -> None:
        if ride_id is not None:
            RideRepository(self.session, club_id=self.club_id).get(ride_id)
        if rider_id is not None:
            RiderRepository(self.session, club_id=self.club_id).get(rider_id)

    def list_page(self, *, where: Sequence[ColumnElement[bool]] = (), sort: str | None = None,
                  limit: int = 50, offset: int = 0, stmt: Select | None = None) -> Page:
        stmt = select(Grade).join(Ride, Ride.id == Grade.ride_id) if stmt is None else stmt
        return super().list_page(where=where, sort=sort, limit=limit, offset=offset, stmt=stmt)

    @staticmethod
    def filters(*, ride_id: int | None = None, rider_id: int | None = None, horse_id: int | None = None,
                gait: str | None = None) -> list[ColumnElement[bool]]:
        where: list[ColumnElement[bool]] = []
        for column, value in ((Grade.ride_id, ride_id), (Grade.rider_id, rider_id), (Ride.horse_id, horse_id),
                              (Ride.gait, gait)):
            if value is not None:
                where.append(column == value)
        return where

    def delete(self, grade_id: int) -> None:
        self.session.delete(self.get(grade_id))
        self.session.flush()

    def grade_rows(self, *, gait: str | None = None) -> list[dict[str, Any]]:
        """``{"ride_id", "horse", "gait", "rider", "grade"}`` of every grade (in this club)."""
        stmt = (select(Grade.ride_id, Horse.name, Ride.gait, Rider.name, Grade.grade)
                .join(Ride, Ride.id == Grade.ride_id).join(Horse, Horse.id == Ride.horse_id)
                .join(Rider, Rider.id == Grade.rider_id))
        if self.club_id is not None:
            stmt = stmt.where(Grade.club_id == self.club_id)
        if gait is not None:
            stmt = stmt.where(Ride.gait == gait)
        return [{"ride_id": r, "horse": h, "gait": g, "rider": who, "grade": grade}
                for r, h, g, who, grade in self.session.execute(stmt)]

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


class UploadRepository(Repository):
    model = Upload

    def add(self, *, id_: str, club_id: int | None = None, user_id: int | None, target: str,
            ride_id: int | None, rig_id: int | None, clip_kind: str | None, camera_role: str | None,
            filename: str | None, length_bytes: int) -> Upload:
        now = utcnow()
        return self._add(Upload(id=id_, club_id=self._club_for_new(club_id), user_id=user_id, target=target,
                                ride_id=ride_id, rig_id=rig_id, clip_kind=clip_kind, camera_role=camera_role,
                                filename=filename, length_bytes=length_bytes, offset_bytes=0,
                                status=UploadStatus.OPEN.value, outcome={}, created_at=now, updated_at=now))

    def advance(self, upload_id: str, *, from_offset: int, to_offset: int) -> bool:
        """Move the offset forward, only if nobody else moved it meanwhile (two PATCHes racing)."""
        stmt = update(Upload).where(Upload.id == upload_id, Upload.offset_bytes == from_offset,
                                    Upload.status == UploadStatus.OPEN.value).values(
            offset_bytes=to_offset, updated_at=utcnow())
        if self.club_id is not None:
            stmt = stmt.where(Upload.club_id == self.club_id)
        return self.session.execute(stmt).rowcount == 1

    def close(self, upload_id: str, *, status: UploadStatus, error: str | None = None,
              outcome: dict[str, Any] | None = None) -> None:
        row = self.get(upload_id)
        row.status, row.error, row.outcome = status.value, error, dict(outcome or {})
        row.updated_at = utcnow()
        self.session.flush()

    def delete(self, upload_id: str) -> None:
        self.session.delete(self.get(upload_id))
        self.session.flush()


class AnalyticsRepository:
    """Read-only queries behind comparisons, leaderboards and exports (one club)."""

    def __init__(self, session: Session, *, club_id: int) -> None:
        self.session = session
        self.club_id = club_id

    def indicator_rows(self, indicator: str | None = None, *, gait: str | None = None,
                       horse_ids: Sequence[int] | None = None, where: Sequence[ColumnElement[bool]] = (),
                       ) -> list[dict[str, Any]]:
        """One row per analysed ride: ``ride_id``, ``horse_id``, ``horse``, ``rider``, ``gait``,
        ``date`` and the indicators (all of them, or only `indicator`: read from its own indexed
        column where it has one, which is much faster over thousands of rides)."""
        column = getattr(Result, indicator) if indicator in LEADERBOARD_COLUMNS else None
        value = column if column is not None else Result.indicators
        stmt = (select(Ride.id, Ride.horse_id, Horse.name, Rider.name, Ride.gait, Ride.ridden_on, value)
                .join(Result, Result.ride_id == Ride.id).join(Horse, Horse.id == Ride.horse_id)
                .join(Rider, Rider.id == Ride.rider_id)
                .where(Result.club_id == self.club_id, Ride.club_id == self.club_id, *where))
        if gait is not None:
            stmt = stmt.where(Ride.gait == gait)
        if horse_ids is not None:
            stmt = stmt.where(Ride.horse_id.in_(list(horse_ids)))
        rows = []
        for ride_id, horse_id, horse, rider, ride_gait, date, data in self.session.execute(
                stmt.order_by(Ride.id)):
            row = {"ride_id": ride_id, "horse_id": horse_id, "horse": horse, "rider": rider,
                   "gait": ride_gait, "date": date}
            if column is not None:
                row[indicator] = data
            elif indicator is not None:
                row[indicator] = (data or {}).get(indicator)
            else:
                row["indicators"] = dict(data or {})
            rows.append(row)
        return rows

    def indicator_values(self, indicator: str, *, gait: str) -> list[tuple[int, str, float | None]]:
        """(horse id, horse name, value) of every analysed ride in `gait`: the least a ranking needs.

        The value comes from the indicator's own column where it has one, else out of the result's
        JSON inside the database; no ride, rider or date columns are read (a leaderboard over ten
        thousand rides stays in the milliseconds).
        """
        value = (getattr(Result, indicator) if indicator in LEADERBOARD_COLUMNS
                 else Result.indicators[indicator].as_float())
        stmt = (select(Horse.id, Horse.name, value).select_from(Result)
                .join(Ride, Ride.id == Result.ride_id).join(Horse, Horse.id == Ride.horse_id)
                .where(Result.club_id == self.club_id, Ride.gait == gait))
        return [tuple(row) for row in self.session.execute(stmt)]

    def horse_names(self, horse_ids: Sequence[int] | None = None) -> dict[int, str]:
        stmt = select(Horse.id, Horse.name).where(Horse.club_id == self.club_id)
        if horse_ids is not None:
            stmt = stmt.where(Horse.id.in_(list(horse_ids)))
        return dict(self.session.execute(stmt).all())

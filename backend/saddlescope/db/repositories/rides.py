"""Rides and what hangs on them: their recordings (clips), their result and riders' grades."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from sqlalchemy import ColumnElement, delete, or_, select, update
from sqlalchemy.orm import selectinload

from saddlescope.db.models import (
    LEADERBOARD_COLUMNS,
    Grade,
    Horse,
    Recording,
    Result,
    Ride,
    Rider,
    SimilarityPair,
    utcnow,
)
from saddlescope.db.repositories.base import Page, Repository
from saddlescope.db.repositories.catalogue import HorseRepository, RiderRepository, RigRepository, SaddleRepository

__all__ = ["GradeRepository", "RecordingRepository", "ResultRepository", "RideFilter", "RideRepository"]


@dataclass(frozen=True)
class RideFilter:
    """The ride list's filters (None: no filter); the dates bound ``ridden_on`` (both included)."""

    horse_id: int | None = None
    rider_id: int | None = None
    rig_id: int | None = None
    saddle_id: int | None = None
    gait: str | None = None
    status: str | None = None
    date_from: dt.date | None = None
    date_to: dt.date | None = None

    def where(self) -> list[ColumnElement[bool]]:
        """Return the WHERE clauses of these filters (on the rides table)."""
        where: list[ColumnElement[bool]] = [
            column == value
            for column, value in ((Ride.horse_id, self.horse_id), (Ride.rider_id, self.rider_id),
                                  (Ride.rig_id, self.rig_id), (Ride.saddle_id, self.saddle_id), (Ride.gait, self.gait),
                                  (Ride.status, self.status))
            if value is not None]
        if self.date_from is not None:
            where.append(Ride.ridden_on >= self.date_from)
        if self.date_to is not None:
            where.append(Ride.ridden_on <= self.date_to)
        return where


class RideRepository(Repository):
    """The club's rides (a horse, a rider, a gait and the clips of one recording session)."""

    model = Ride
    sort_fields = {"ridden_on": Ride.ridden_on, "created_at": Ride.created_at, "gait": Ride.gait,
                   "status": Ride.status, "horse_id": Ride.horse_id, "rider_id": Ride.rider_id,
                   "direction": Ride.direction, "saddle_id": Ride.saddle_id,
                   "rider_weight_kg": Ride.rider_weight_kg,
                   **{name: getattr(Result, name) for name in LEADERBOARD_COLUMNS}}
    default_sort = "-ridden_on"

    def _check_references(self, *, horse_id: int | None, rider_id: int | None, rig_id: int | None,
                          saddle_id: int | None = None) -> None:
        """Horse, rider, rig and saddle must exist in this club (another club's ids are not found)."""
        for repo, id_ in ((HorseRepository, horse_id), (RiderRepository, rider_id), (RigRepository, rig_id),
                          (SaddleRepository, saddle_id)):
            if id_ is not None:
                repo(self.session, club_id=self.club_id).get(id_)

    def rider_weights_kg(self) -> dict[int, float]:
        """The rider's weight on each of the club's rides that records one (ride id -> kg)."""
        stmt = self._scoped(select(Ride.id, Ride.rider_weight_kg).where(Ride.rider_weight_kg.is_not(None)))
        return {ride_id: float(kg) for ride_id, kg in self.session.execute(stmt)}

    def add(self, *, club_id: int | None = None, horse_id: int, rider_id: int, gait: str, direction: str,
            rig_id: int | None = None, ridden_on: dt.date | None = None, notes: str = "",
            meta: dict | None = None, saddle_id: int | None = None, pad: str | None = None,
            rider_weight_kg: float | None = None) -> Ride:
        """Add a ride; its horse, rider, rig and saddle must be the club's (`NotFound` otherwise).

        Without `rider_weight_kg` the ride takes the rider's usual weight (None when not recorded).
        """
        self._check_references(horse_id=horse_id, rider_id=rider_id, rig_id=rig_id, saddle_id=saddle_id)
        if rider_weight_kg is None:
            rider_weight_kg = RiderRepository(self.session, club_id=self.club_id).get(rider_id).weight_kg
        return self._add(Ride(club_id=self._club_for_new(club_id), horse_id=horse_id, rider_id=rider_id,
                              rig_id=rig_id, gait=gait, direction=direction, ridden_on=ridden_on,
                              notes=notes, meta=meta or {}, saddle_id=saddle_id, pad=pad,
                              rider_weight_kg=rider_weight_kg))

    def update_fields(self, id_: int, **values: Any) -> Ride:
        """Set columns of a ride; a new horse, rider, rig or saddle must be the club's."""
        self._check_references(horse_id=values.get("horse_id"), rider_id=values.get("rider_id"),
                                rig_id=values.get("rig_id"), saddle_id=values.get("saddle_id"))
        return super().update_fields(id_, **values)

    def list_page(self, rides: RideFilter | None = None, *, sort: str | None = None, limit: int = 50,
                  offset: int = 0) -> Page:
        """Return a page of the rides (of this club) matching `rides`, sorted by `sort`.

        `sort` is a ride field or an indicator with its own column; rides without a result come last.
        """
        # Outer join only to sort by a result's indicator: the count and the other sorts stay on the
        # rides table and its (club_id, ...) indexes.
        by_result = (sort or "").removeprefix("-") in LEADERBOARD_COLUMNS
        stmt = select(Ride).outerjoin(Result, Result.ride_id == Ride.id) if by_result else select(Ride)
        # the names the list sends with each ride, in one query per page rather than one per ride
        stmt = stmt.options(selectinload(Ride.horse), selectinload(Ride.rider))
        return self._page((rides or RideFilter()).where(), sort=sort, limit=limit, offset=offset, stmt=stmt,
                          count_stmt=select(Ride))

    def set_status(self, ride_id: int, status: str) -> None:
        """Store a ride's status (derived by `services.rides.registration.refresh_ride_status`, its one caller)."""
        self.session.execute(self._scoped_update(ride_id).values(status=status))

    def with_bundle_sha256(self, sha256: str) -> int | None:
        """The id of the club's ride registered from a bundle with this content hash, if any."""
        stmt = self._scoped(select(Ride.id).where(Ride.meta["_bundle_sha256"].as_string() == sha256))
        return self.session.scalars(stmt.order_by(Ride.id)).first()

    def note(self, ride_id: int, **values: Any) -> None:
        """Keep internal facts of a ride (keys starting with '_', not shown) in its meta."""
        ride = self.get(ride_id)
        ride.meta = {**dict(ride.meta or {}), **values}
        self.session.flush()

    def creator_of(self, ride_id: int) -> int | None:
        """The id of the user who made the ride (None when not recorded)."""
        value = dict(self.get(ride_id).meta or {}).get("_created_by")
        return value if isinstance(value, int) else None

    def creators_of(self, ride_ids: Sequence[int]) -> dict[int, int | None]:
        """Ride id -> the id of the user who made it (None when not recorded), for the rides (of this club)."""
        if not ride_ids:
            return {}
        stmt = self._scoped(select(Ride.id, Ride.meta).where(Ride.id.in_(set(ride_ids))))
        made_by = {ride_id: dict(meta or {}).get("_created_by") for ride_id, meta in self.session.execute(stmt)}
        return {ride_id: value if isinstance(value, int) else None for ride_id, value in made_by.items()}

    def horses_and_gaits(self, ride_ids: Sequence[int]) -> dict[int, tuple[str, str]]:
        """Ride id -> (its horse's name, its gait), for the rides (of this club): how a club names a ride."""
        if not ride_ids:
            return {}
        stmt = self._scoped(select(Ride.id, Horse.name, Ride.gait).join(Horse, Horse.id == Ride.horse_id)
                            .where(Ride.id.in_(set(ride_ids))))
        return {ride_id: (name, gait) for ride_id, name, gait in self.session.execute(stmt)}

    def set_bundle_key(self, ride_id: int, bundle_key: str) -> None:
        """Store where the ride's bundle (ride.json and clips) lives in storage."""
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

    def ids_of_rig(self, rig_id: int) -> list[int]:
        """The ids of the rides filmed with rig `rig_id` (whose completeness its clips and calibration decide)."""
        return list(self.session.scalars(self._scoped(select(Ride.id).where(Ride.rig_id == rig_id)).order_by(Ride.id)))

    def latest_with_bundle(self, club_id: int) -> int | None:
        """Return the id of the club's newest ride that has a stored bundle, or None."""
        stmt = self._scoped(select(Ride.id).where(Ride.club_id == club_id, Ride.bundle_key.is_not(None)))
        return self.session.scalar(stmt.order_by(Ride.id.desc()).limit(1))

    def latest(self, limit: int = 50) -> Sequence[Ride]:
        """Return the `limit` newest rides (of this club), newest first."""
        return self.session.scalars(self._scoped(select(Ride)).order_by(Ride.id.desc()).limit(limit)).all()


class RecordingRepository(Repository):
    """Clips: one camera's recording of one clip kind, owned by a ride or by a rig."""

    model = Recording

    def add(self, *, club_id: int | None = None, ride_id: int | None = None, rig_id: int | None = None,
            camera_role: str, clip_kind: str, path: str, sha256: str | None = None,
            size_bytes: int | None = None) -> Recording:
        """Add a clip of a ride or a rig (stored at storage key `path`)."""
        return self._add(Recording(club_id=self._club_for_new(club_id), ride_id=ride_id, rig_id=rig_id,
                                   camera_role=camera_role, clip_kind=clip_kind, path=path, sha256=sha256,
                                   size_bytes=size_bytes))

    def for_ride(self, ride_id: int) -> Sequence[Recording]:
        """Return the ride's own clips, oldest first."""
        stmt = self._scoped(select(Recording).where(Recording.ride_id == ride_id)).order_by(Recording.id)
        return self.session.scalars(stmt).all()

    def ride_with_clip(self, sha256s: Sequence[str], *, clip_kind: str = "motion",
                       exclude_ride_id: int | None = None) -> int | None:
        """The id of the club's oldest ride holding a `clip_kind` clip with one of these content hashes, if any."""
        wanted = [h for h in sha256s if h]
        if not wanted:
            return None
        stmt = self._scoped(select(Recording.ride_id).where(
            Recording.ride_id.is_not(None), Recording.clip_kind == clip_kind, Recording.sha256.in_(wanted)))
        if exclude_ride_id is not None:
            stmt = stmt.where(Recording.ride_id != exclude_ride_id)
        return self.session.scalars(stmt.order_by(Recording.ride_id).limit(1)).first()

    def for_rig(self, rig_id: int) -> Sequence[Recording]:
        """Return the rig's clips (shared by its rides), oldest first."""
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
        """Return the ride's (or rig's) clip of this kind and camera, or None."""
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


class ResultRepository(Repository):
    """Results: a ride's indicators, its leaderboard columns and where its result document is stored."""

    model = Result

    def for_ride(self, ride_id: int) -> Result | None:
        """Return the ride's result, or None before its first analysis."""
        return self.session.scalars(self._scoped(select(Result).where(Result.ride_id == ride_id))).first()

    def indicators_for(self, ride_ids: Sequence[int]) -> dict[int, dict[str, Any]]:
        """Return ride id -> indicators, for those of the rides (of this club) that have a result."""
        if not ride_ids:
            return {}
        stmt = self._scoped(
            select(Result.ride_id, Result.indicators).where(Result.ride_id.in_(list(ride_ids))))
        return {ride_id: dict(indicators or {}) for ride_id, indicators in self.session.execute(stmt)}

    def replace_for_ride(self, *, club_id: int, ride_id: int, job_id: int | None, indicators: dict[str, Any],
                         result_key: str | None, code_version: str | None, uncertain_reason: str | None,
                         job_attempt: int | None = None) -> Result:
        """Store a ride's result, replacing the previous one (re-running a job is idempotent).

        The ride's cached comparisons with other rides are deleted: they were computed from the old
        analysis. ``uncertain_reason``: why the ride is too uncertain for a decision (None: it is not);
        required, so no writer can leave the verdict out (``services.results.documents.commit_result`` derives it
        from the document).
        """
        self.session.execute(delete(SimilarityPair).where(
            or_(SimilarityPair.ride_a_id == ride_id, SimilarityPair.ride_b_id == ride_id)))
        result = self.for_ride(ride_id)
        if result is None:
            result = Result(club_id=self._club_for_new(club_id), ride_id=ride_id)
            self.session.add(result)
        result.job_id, result.job_attempt = job_id, job_attempt
        result.indicators = dict(indicators)
        result.result_key = result_key
        result.code_version = code_version
        result.uncertain_reason = uncertain_reason
        result.created_at = utcnow()
        for name in LEADERBOARD_COLUMNS:
            value = indicators.get(name)
            setattr(result, name, float(value) if isinstance(value, int | float) else None)
        self.session.flush()
        return result


class GradeRepository(Repository):
    """Riders' comfort grades of rides (one per rider and ride)."""

    model = Grade
    sort_fields = {"grade": Grade.grade, "created_at": Grade.created_at, "ride_id": Grade.ride_id,
                   "rider_id": Grade.rider_id}
    default_sort = "-id"

    def check_references(self, *, ride_id: int | None, rider_id: int | None) -> None:
        """Raise `NotFound` unless the ride and the rider (where given) are the club's."""
        if ride_id is not None:
            RideRepository(self.session, club_id=self.club_id).get(ride_id)
        if rider_id is not None:
            RiderRepository(self.session, club_id=self.club_id).get(rider_id)

    def list_page(self, *, ride_id: int | None = None, rider_id: int | None = None, horse_id: int | None = None,
                  gait: str | None = None, sort: str | None = None, limit: int = 50, offset: int = 0) -> Page:
        """Return a page of the grades (of this club) of a ride, a rider, a horse or a gait (None: any)."""
        where = [column == value
                 for column, value in ((Grade.ride_id, ride_id), (Grade.rider_id, rider_id),
                                       (Ride.horse_id, horse_id), (Ride.gait, gait))
                 if value is not None]
        stmt = select(Grade).join(Ride, Ride.id == Grade.ride_id)
        return self._page(where, sort=sort, limit=limit, offset=offset, stmt=stmt)

    def delete(self, grade_id: int) -> None:
        """Delete a grade."""
        self.session.delete(self.get(grade_id))
        self.session.flush()

    def grade_rows(self, *, gait: str | None = None) -> list[dict[str, Any]]:
        """Return ``{"ride_id", "horse", "gait", "rider", "grade"}`` of every grade (in this club)."""
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
        """Store a rider's grade of a ride; grading again replaces the earlier grade."""
        row = self.session.scalars(self._scoped(
            select(Grade).where(Grade.ride_id == ride_id, Grade.rider_id == rider_id))).first()
        if row is None:
            return self._add(Grade(club_id=self._club_for_new(club_id), ride_id=ride_id, rider_id=rider_id,
                                   grade=grade, comment=comment))
        row.grade = grade
        row.comment = comment
        self.session.flush()
        return row

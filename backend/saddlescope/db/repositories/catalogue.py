"""The club's catalogue: its horses, riders, saddles and rigs (named things rides refer to)."""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import func, select, update

from saddlescope.db.models import Horse, Ride, Rider, Rig, Saddle
from saddlescope.db.repositories.base import Conflict, Page, Repository, changed_rows, like_pattern

__all__ = ["HorseRepository", "RiderRepository", "RigRepository", "SaddleRepository"]


class _Named(Repository):
    """Rows with a name: listed by a part of it, and (horses, riders) unique by it within a club."""

    def list_page(self, *, name_like: str | None = None, sort: str | None = None, limit: int = 50,
                  offset: int = 0) -> Page:
        """Return a page of the rows (of this club) whose name contains `name_like` (any letter case).

        Sorted by `sort` (a field of `sort_fields`, or ``id``; ``-`` first for descending).
        """
        where = [self.model.name.ilike(like_pattern(name_like), escape="\\")] if name_like else []
        return self._page(where, sort=sort, limit=limit, offset=offset)

    def _refuse_while_ridden(self, column, row, noun: str) -> None:
        """`Conflict` saying how many rides use `row` and what to do, when any do."""
        count = self.session.scalar(select(func.count()).select_from(Ride).where(column == row.id)) or 0
        if count:
            rides = "1 ride" if count == 1 else f"{count} rides"
            raise Conflict(f"{noun} {row.name!r} still has {rides}; delete those rides first, or edit them to "
                           f"use another {noun} (the Rides page filters by {noun})")

    def _check_name_free(self, name: str, *, club_id: int | None, exclude_id: int | None = None) -> None:
        stmt = select(self.model.id).where(self.model.club_id == club_id, self.model.name == name)
        if exclude_id is not None:
            stmt = stmt.where(self.model.id != exclude_id)
        if self.session.scalar(stmt) is not None:
            raise Conflict(f"the club already has a {self.model.__tablename__[:-1]} named {name!r}")


class HorseRepository(_Named):
    """The club's horses (names unique within the club)."""

    model = Horse
    sort_fields = {"name": Horse.name, "breed": Horse.breed, "birth_year": Horse.birth_year,
                   "height_withers_m": Horse.height_withers_m, "created_at": Horse.created_at}
    default_sort = "name"

    def add(self, *, club_id: int | None = None, name: str, breed: str | None = None,
            birth_year: int | None = None, height_withers_m: float | None = None) -> Horse:
        """Add a horse; `Conflict` when the club has one of that name."""
        club_id = self._club_for_new(club_id)
        self._check_name_free(name, club_id=club_id)
        return self._add(Horse(club_id=club_id, name=name, breed=breed, birth_year=birth_year,
                               height_withers_m=height_withers_m))

    def update_fields(self, id_: int, **values: Any) -> Horse:
        """Set columns of a horse; `Conflict` when renamed to a name the club uses."""
        if "name" in values:
            self._check_name_free(values["name"], club_id=self.get(id_).club_id, exclude_id=id_)
        return super().update_fields(id_, **values)

    def delete(self, horse_id: int) -> None:
        """Delete a horse; `Conflict` while rides use it."""
        horse = self.get(horse_id)
        self._refuse_while_ridden(Ride.horse_id, horse, "horse")
        self.session.delete(horse)
        self.session.flush()

    def get_or_create(self, *, club_id: int | None = None, name: str, breed: str | None = None,
                      birth_year: int | None = None, height_withers_m: float | None = None) -> Horse:
        """Return the club's horse named `name`, added with these details if new."""
        club_id = self._club_for_new(club_id)
        horse = self.session.scalars(
            select(Horse).where(Horse.club_id == club_id, Horse.name == name)).first()
        if horse is None:
            horse = self._add(Horse(club_id=club_id, name=name, breed=breed, birth_year=birth_year,
                                    height_withers_m=height_withers_m))
        return horse


class RiderRepository(_Named):
    """The club's riders (names unique within the club)."""

    model = Rider
    sort_fields = {"name": Rider.name, "created_at": Rider.created_at}
    default_sort = "name"

    def add(self, *, club_id: int | None = None, name: str, user_id: int | None = None,
            weight_kg: float | None = None) -> Rider:
        """Add a rider; `Conflict` when the club has one of that name."""
        club_id = self._club_for_new(club_id)
        self._check_name_free(name, club_id=club_id)
        return self._add(Rider(club_id=club_id, name=name, user_id=user_id, weight_kg=weight_kg))

    def update_fields(self, id_: int, **values: Any) -> Rider:
        """Set columns of a rider; `Conflict` when renamed to a name the club uses."""
        if "name" in values:
            self._check_name_free(values["name"], club_id=self.get(id_).club_id, exclude_id=id_)
        return super().update_fields(id_, **values)

    def delete(self, rider_id: int) -> None:
        """Delete a rider; `Conflict` while rides use them."""
        rider = self.get(rider_id)
        self._refuse_while_ridden(Ride.rider_id, rider, "rider")
        self.session.delete(rider)
        self.session.flush()

    def get_or_create(self, *, club_id: int | None = None, name: str) -> Rider:
        """Return the club's rider named `name`, added if new."""
        club_id = self._club_for_new(club_id)
        rider = self.session.scalars(
            select(Rider).where(Rider.club_id == club_id, Rider.name == name)).first()
        return rider or self._add(Rider(club_id=club_id, name=name))


class SaddleRepository(_Named):
    """The club's saddles (names unique within the club)."""

    model = Saddle
    sort_fields = {"name": Saddle.name, "maker": Saddle.maker, "saddle_type": Saddle.saddle_type,
                   "created_at": Saddle.created_at}
    default_sort = "name"

    def add(self, *, club_id: int | None = None, name: str, maker: str | None = None,
            saddle_type: str | None = None, tree_width: str | None = None, notes: str = "") -> Saddle:
        """Add a saddle; `Conflict` when the club has one of that name."""
        club_id = self._club_for_new(club_id)
        self._check_name_free(name, club_id=club_id)
        return self._add(Saddle(club_id=club_id, name=name, maker=maker, saddle_type=saddle_type,
                                tree_width=tree_width, notes=notes))

    def update_fields(self, id_: int, **values: Any) -> Saddle:
        """Set columns of a saddle; `Conflict` when renamed to a name the club uses."""
        if "name" in values:
            self._check_name_free(values["name"], club_id=self.get(id_).club_id, exclude_id=id_)
        return super().update_fields(id_, **values)

    def delete(self, saddle_id: int) -> None:
        """Delete a saddle; `Conflict` while rides use it."""
        saddle = self.get(saddle_id)
        self._refuse_while_ridden(Ride.saddle_id, saddle, "saddle")
        self.session.delete(saddle)
        self.session.flush()

    def find_by_name(self, name: str) -> Saddle | None:
        """The club's saddle named `name` exactly, or None."""
        return self.session.scalars(self._scoped(select(Saddle).where(Saddle.name == name))).first()

    def ride_counts(self, saddle_ids: list[int]) -> dict[int, int]:
        """Saddle id -> how many of the club's rides name it (saddles without rides are left out)."""
        if not saddle_ids:
            return {}
        stmt = (select(Ride.saddle_id, func.count()).where(Ride.saddle_id.in_(saddle_ids))
                .group_by(Ride.saddle_id))
        if self.club_id is not None:
            stmt = stmt.where(Ride.club_id == self.club_id)
        return {int(sid): int(n) for sid, n in self.session.execute(stmt) if sid is not None}


class RigRepository(_Named):
    """The club's rigs (a day's three-camera set-up) and their calibrations."""

    model = Rig
    sort_fields = {"name": Rig.name, "recorded_on": Rig.recorded_on, "created_at": Rig.created_at}
    default_sort = "-recorded_on"

    def add(self, *, club_id: int | None = None, name: str, recorded_on: dt.date | None = None,
            cameras: dict | None = None, board: dict | None = None, wand_length_m: float | None = None) -> Rig:
        """Add a rig (names need not be unique: the same set-up on another day)."""
        return self._add(Rig(club_id=self._club_for_new(club_id), name=name, recorded_on=recorded_on,
                             cameras=cameras or {}, board=board, wand_length_m=wand_length_m))

    def set_calibration(self, rig_id: int, calibration: dict, quality: dict) -> None:
        """Store a rig's calibration and its quality flags (replacing earlier ones)."""
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
        return changed_rows(self.session.execute(stmt)) == 1

    def lock(self, rig_id: int) -> Rig:
        """The rig's row, locked until the transaction ends.

        A calibration stored under the lock cannot cross an upload that clears it (PostgreSQL; SQLite's writes are
        one at a time anyway).
        """
        stmt = select(Rig).where(Rig.id == rig_id).with_for_update()
        rig = self.session.scalars(self._scoped(stmt)).first()
        if rig is None:
            return self.get(rig_id)  # the repository's own "not found"
        return rig

    def clear_calibration(self, rig_id: int) -> None:
        """Forget a rig's calibration (its calibration clips changed)."""
        self.get(rig_id)
        self.session.execute(update(Rig).where(Rig.id == rig_id).values(calibration=None, quality=None))

    def delete(self, rig_id: int) -> None:
        """Delete a rig; `Conflict` while rides use it."""
        rig = self.get(rig_id)
        if self._in_use(Ride.rig_id, rig_id):
            raise Conflict(f"rig {rig_id} ({rig.name}) is used by rides; delete them or move them first")
        self.session.delete(rig)
        self.session.flush()

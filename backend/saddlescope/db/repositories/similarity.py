"""Cached ride comparisons and the analysed rides a comparison reads (ride, horse, result)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from sqlalchemy import delete, or_, select

from saddlescope.db.models import Horse, Result, Ride, SimilarityPair
from saddlescope.db.repositories.base import Repository, changed_rows

__all__ = ["AnalysedRide", "SimilarityRepository", "analysis_version", "ordered_pair"]


def analysis_version(code_version: str | None, analysed_at: dt.datetime | None) -> str:
    """Which analysis of a ride a cached comparison was computed from: its code version and time."""
    stamp = analysed_at.astimezone(dt.UTC).strftime("%Y%m%dT%H%M%S.%f") if analysed_at is not None else "-"
    return f"{code_version or '-'}@{stamp}"[:100]


def ordered_pair(ride_id: int, other_id: int) -> tuple[int, int]:
    """The pair as the cache stores it: smaller id first."""
    return (ride_id, other_id) if ride_id < other_id else (other_id, ride_id)


@dataclass(frozen=True)
class AnalysedRide:
    """A ride with a stored result: what a comparison needs to load it and a list needs to show it."""

    ride_id: int
    club_id: int
    horse_id: int
    horse: str
    gait: str
    ridden_on: dt.date | None
    result_key: str
    version: str


class SimilarityRepository(Repository):
    """The cache of ride comparisons (`SimilarityPair`), per pair, marker set, span and versions."""

    model = SimilarityPair

    def analysed(self, *, ride_ids: Iterable[int] | None = None, gait: str | None = None,
                 horse_id: int | None = None) -> list[AnalysedRide]:
        """The club's rides with a stored result (of these ids, gait, horse; None: any), by date then id."""
        stmt = (select(Ride.id, Ride.club_id, Ride.horse_id, Horse.name, Ride.gait, Ride.ridden_on,
                       Result.result_key, Result.code_version, Result.created_at)
                .join(Result, Result.ride_id == Ride.id).join(Horse, Horse.id == Ride.horse_id)
                .where(Result.result_key.is_not(None)))
        if self.club_id is not None:
            stmt = stmt.where(Ride.club_id == self.club_id)
        if ride_ids is not None:
            stmt = stmt.where(Ride.id.in_(list(ride_ids)))
        if gait is not None:
            stmt = stmt.where(Ride.gait == gait)
        if horse_id is not None:
            stmt = stmt.where(Ride.horse_id == horse_id)
        stmt = stmt.order_by(Ride.ridden_on.asc().nulls_first(), Ride.id.asc())
        return [AnalysedRide(rid, club, hid, name, gait_, day, str(key), analysis_version(code, at))
                for rid, club, hid, name, gait_, day, key, code, at in self.session.execute(stmt)]

    def cached(self, pairs: Sequence[tuple[int, int]], *, markers: str, span: str, method_version: str,
               versions: dict[int, str]) -> dict[tuple[int, int], SimilarityPair]:
        """The valid cached rows of `pairs` (each ordered), keyed by pair.

        A row is valid when it was computed by `method_version` from the analyses `versions` names
        (ride id -> `analysis_version`).
        """
        wanted = {ordered_pair(*p) for p in pairs}
        if not wanted:
            return {}
        ids = sorted({i for p in wanted for i in p})
        out: dict[tuple[int, int], SimilarityPair] = {}
        for start in range(0, len(ids), 500):  # bounded IN lists
            chunk = ids[start:start + 500]
            stmt = self._scoped(select(SimilarityPair).where(
                SimilarityPair.markers == markers, SimilarityPair.span == span,
                SimilarityPair.method_version == method_version,
                or_(SimilarityPair.ride_a_id.in_(chunk), SimilarityPair.ride_b_id.in_(chunk))))
            for row in self.session.scalars(stmt):
                key = (row.ride_a_id, row.ride_b_id)
                if key in wanted and versions.get(key[0]) == row.version_a and versions.get(key[1]) == row.version_b:
                    out[key] = row
        return out

    def store(self, *, club_id: int, pair: tuple[int, int], markers: str, span: str, versions: tuple[str, str],
              method_version: str, similarity: float | None, measure: str | None, answer: dict[str, Any],
              error: str | None = None) -> SimilarityPair:
        """Store (or replace) the comparison of `pair` (ordered: smaller id first)."""
        a, b = pair
        if not a < b:
            raise ValueError(f"pair {pair} must be ordered, smaller ride id first")
        row = self.session.scalars(select(SimilarityPair).where(
            SimilarityPair.ride_a_id == a, SimilarityPair.ride_b_id == b, SimilarityPair.markers == markers,
            SimilarityPair.span == span)).first()
        if row is None:
            row = SimilarityPair(club_id=self._club_for_new(club_id), ride_a_id=a, ride_b_id=b, markers=markers,
                                 span=span)
            self.session.add(row)
        row.version_a, row.version_b = versions
        row.method_version, row.similarity, row.measure = method_version, similarity, measure
        row.answer, row.error = dict(answer), error
        self.session.flush()
        return row

    def invalidate_ride(self, ride_id: int) -> int:
        """Delete every cached comparison of a ride (its analysis changed); returns how many."""
        stmt = delete(SimilarityPair).where(
            or_(SimilarityPair.ride_a_id == ride_id, SimilarityPair.ride_b_id == ride_id))
        return changed_rows(self.session.execute(stmt))

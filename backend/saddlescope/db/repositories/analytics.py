"""Read-only queries behind comparisons, leaderboards and exports: narrow rows over many rides."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from saddlescope.db.models import LEADERBOARD_COLUMNS, Horse, Result, Ride, Rider, Saddle
from saddlescope.db.repositories.rides import RideFilter

__all__ = ["AnalyticsRepository"]


class AnalyticsRepository:
    """Read-only queries behind comparisons, leaderboards and exports (one club)."""

    def __init__(self, session: Session, *, club_id: int) -> None:
        self.session = session
        self.club_id = club_id

    def indicator_rows(self, indicator: str | None = None, *, gait: str | None = None,
                       horse_ids: Sequence[int] | None = None, rides: RideFilter | None = None,
                       include_uncertain: bool = True) -> list[dict[str, Any]]:
        """Return one row per analysed ride (of `gait`, of `horse_ids`, matching `rides`; None: all).

        A row holds ``ride_id``, ``horse_id``, ``horse``, ``rider``, ``gait``, ``date``, ``saddle_id``,
        ``saddle`` (None: not recorded), ``uncertain_reason`` (None: certain enough) and the indicators
        (all of them, or only `indicator`: read from its own indexed column where it has one, which is
        much faster over thousands of rides). Without `include_uncertain` rides too uncertain for a
        decision are left out.
        """
        column = getattr(Result, indicator) if indicator in LEADERBOARD_COLUMNS else None
        value = column if column is not None else Result.indicators
        stmt = (select(Ride.id, Ride.horse_id, Horse.name, Rider.name, Ride.gait, Ride.ridden_on, Ride.saddle_id,
                       Saddle.name, Result.uncertain_reason, value)
                .join(Result, Result.ride_id == Ride.id).join(Horse, Horse.id == Ride.horse_id)
                .join(Rider, Rider.id == Ride.rider_id).outerjoin(Saddle, Saddle.id == Ride.saddle_id)
                .where(Result.club_id == self.club_id, Ride.club_id == self.club_id,
                       *(rides or RideFilter()).where()))
        if gait is not None:
            stmt = stmt.where(Ride.gait == gait)
        if horse_ids is not None:
            stmt = stmt.where(Ride.horse_id.in_(list(horse_ids)))
        if not include_uncertain:
            stmt = stmt.where(Result.uncertain_reason.is_(None))
        rows = []
        for ride_id, horse_id, horse, rider, ride_gait, date, saddle_id, saddle, reason, data in self.session.execute(
                stmt.order_by(Ride.id)):
            row = {"ride_id": ride_id, "horse_id": horse_id, "horse": horse, "rider": rider,
                   "gait": ride_gait, "date": date, "saddle_id": saddle_id, "saddle": saddle,
                   "uncertain_reason": reason}
            if indicator is not None and column is not None:
                row[indicator] = data
            elif indicator is not None:
                row[indicator] = (data or {}).get(indicator)
            else:
                row["indicators"] = dict(data or {})
            rows.append(row)
        return rows

    def marked_indicator_values(self, indicator: str, *, gait: str, saddle_id: int | None = None,
                                ) -> list[tuple[int, str, float | None, int, str | None]]:
        """As :meth:`indicator_values`, with each ride's id and why it is too uncertain (None: it is not).

        `saddle_id`: only the rides in that saddle (None: all).
        """
        value = (getattr(Result, indicator) if indicator in LEADERBOARD_COLUMNS
                 else Result.indicators[indicator].as_float())
        stmt = (select(Horse.id, Horse.name, value, Ride.id, Result.uncertain_reason).select_from(Result)
                .join(Ride, Ride.id == Result.ride_id).join(Horse, Horse.id == Ride.horse_id)
                .where(Result.club_id == self.club_id, Ride.gait == gait))
        if saddle_id is not None:
            stmt = stmt.where(Ride.saddle_id == saddle_id)
        return [tuple(row) for row in self.session.execute(stmt)]

    def indicator_values(self, indicator: str, *, gait: str) -> list[tuple[int, str, float | None]]:
        """Return (horse id, horse name, value) of every analysed ride in `gait`: the least a ranking needs.

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
        """Return horse id -> name of the club's horses (of `horse_ids`; None: all)."""
        stmt = select(Horse.id, Horse.name).where(Horse.club_id == self.club_id)
        if horse_ids is not None:
            stmt = stmt.where(Horse.id.in_(list(horse_ids)))
        return dict(self.session.execute(stmt).all())

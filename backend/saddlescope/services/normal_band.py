"""A horse's own normal band: mean ± 2 SD of an indicator over its earlier rides in one gait.

A vet reads a new ride against the horse's own history, not the club's: "is this horse moving as it
usually does?". The band exists once the horse has at least `MIN_RIDES_FOR_BAND` earlier analysed
rides in that gait (fewer give a standard deviation too unsure to flag anything). The horse page's
trend, the ride page and the one-page report all take their bands from here.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Sequence
from typing import Any

from sqlalchemy.orm import Session

from saddlescope.db.repositories import AnalyticsRepository

__all__ = ["MIN_RIDES_FOR_BAND", "band_of", "horse_history", "normal_bands_before", "ride_order_key"]

MIN_RIDES_FOR_BAND = 4
BAND_SD = 2.0  # mean ± 2 SD: about 95 % of a normally varying horse's rides


def band_of(values: Sequence[float | None], *, min_rides: int = MIN_RIDES_FOR_BAND) -> dict[str, Any] | None:
    """Return ``{n, mean, sd, low, high}`` of the finite `values`, or None with fewer than `min_rides`."""
    finite = [float(v) for v in values if isinstance(v, int | float) and math.isfinite(v)]
    if len(finite) < min_rides:
        return None
    mean = sum(finite) / len(finite)
    sd = math.sqrt(sum((v - mean) ** 2 for v in finite) / (len(finite) - 1))  # sample SD
    return {"n": len(finite), "mean": mean, "sd": sd, "low": mean - BAND_SD * sd, "high": mean + BAND_SD * sd}


def ride_order_key(row: dict[str, Any]) -> tuple[dt.date, int]:
    """Order of rides in time: the day ridden (undated rides first), then the ride id (upload order)."""
    return (row.get("date") or dt.date.min, int(row["ride_id"]))


def horse_history(session: Session, *, club_id: int, horse_id: int, gait: str | None = None,
                  include_uncertain: bool = False) -> list[dict[str, Any]]:
    """Every analysed ride of the horse (in `gait`; None: all), oldest first, with all its indicators.

    Rows are those of `AnalyticsRepository.indicator_rows`: ``ride_id``, ``horse_id``, ``horse``,
    ``rider``, ``gait``, ``date``, ``uncertain_reason`` and ``indicators``. Rides too uncertain for a
    decision are left out unless `include_uncertain`: they never widen or shift a band.
    """
    rows = AnalyticsRepository(session, club_id=club_id).indicator_rows(gait=gait, horse_ids=[horse_id],
                                                                        include_uncertain=include_uncertain)
    return sorted(rows, key=ride_order_key)


def normal_bands_before(history: Sequence[dict[str, Any]], ride_id: int, indicators: Sequence[str],
                        ) -> dict[str, dict[str, Any] | None]:
    """Per indicator the band of the rides in `history` (one horse, one gait) before ride `ride_id`.

    "Before" is `ride_order_key` order; a ride not in `history` (not analysed yet) is compared with
    all of it. An indicator maps to None where there are fewer than `MIN_RIDES_FOR_BAND` earlier rides.
    """
    ordered = sorted(history, key=ride_order_key)
    position = next((i for i, row in enumerate(ordered) if row["ride_id"] == ride_id), len(ordered))
    earlier = ordered[:position]
    return {key: band_of([(row.get("indicators") or {}).get(key) for row in earlier]) for key in indicators}

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

__all__ = ["MIN_OWN_RIDES", "MIN_RIDES_FOR_BAND", "band_of", "band_with_uncertainty", "horse_history",
           "normal_bands_before", "page_band", "ride_order_key"]

MIN_RIDES_FOR_BAND = 4
BAND_SD = 2.0  # mean ± 2 SD: about 95 % of a normally varying horse's rides
# The band the horse page draws: the horse's own rides from this many on, the club's horses in the gait
# before (a horse's first rides say nothing of its normal range).
MIN_OWN_RIDES = 5
Z_95 = 1.959964


def band_of(values: Sequence[float | None], *, min_rides: int = MIN_RIDES_FOR_BAND) -> dict[str, Any] | None:
    """Return ``{n, mean, sd, low, high}`` of the finite `values`, or None with fewer than `min_rides`."""
    finite = [float(v) for v in values if isinstance(v, int | float) and math.isfinite(v)]
    if len(finite) < min_rides:
        return None
    mean = sum(finite) / len(finite)
    sd = math.sqrt(sum((v - mean) ** 2 for v in finite) / (len(finite) - 1))  # sample SD
    return {"n": len(finite), "mean": mean, "sd": sd, "low": mean - BAND_SD * sd, "high": mean + BAND_SD * sd}


def band_with_uncertainty(values: Sequence[float | None], *, min_rides: int) -> dict[str, Any] | None:
    """`band_of` with the 95 % interval of each edge (``low_interval_95``, ``high_interval_95``).

    An edge mean ± 2 SD from n rides is itself uncertain: var(mean) = SD²/n and, for normal data,
    var(SD) ≈ SD²/(2(n-1)), so var(edge) ≈ SD²/n + 4 SD²/(2(n-1)) (the two are independent). With 5
    rides an edge is uncertain by about ±1.5 SD: the page shows it, so a band from few rides is read as such.
    """
    band = band_of(values, min_rides=max(min_rides, 2))
    if band is None:
        return None
    n, sd = band["n"], band["sd"]
    half = Z_95 * math.sqrt(sd**2 / n + BAND_SD**2 * sd**2 / (2 * (n - 1)))
    return {**band, "low_interval_95": [band["low"] - half, band["low"] + half],
            "high_interval_95": [band["high"] - half, band["high"] + half]}


def page_band(own: Sequence[float | None], club: Sequence[float | None], *, horses_in_club: int,
              ) -> dict[str, Any] | None:
    """The band the horse page draws: the horse's own, else the club's horses' in the gait.

    From the horse's own rides when it has `MIN_OWN_RIDES`, else from the club's other horses' rides in
    the gait (``source`` says which, ``reason`` in words); None with neither.
    """
    own_band = band_with_uncertainty(own, min_rides=MIN_OWN_RIDES)
    if own_band is not None:
        return {**own_band, "source": "horse", "horses": 1,
                "reason": f"from this horse's own {own_band['n']} rides in this gait"}
    club_band = band_with_uncertainty(club, min_rides=MIN_OWN_RIDES)
    if club_band is None:
        return None
    n_own = sum(1 for v in own if isinstance(v, int | float) and math.isfinite(v))
    return {**club_band, "source": "club", "horses": horses_in_club,
            "reason": (f"from the club's {horses_in_club} other horse{'s' if horses_in_club != 1 else ''} in this "
                       f"gait ({club_band['n']} rides): this horse has {n_own} of the {MIN_OWN_RIDES} rides "
                       "its own band needs")}


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

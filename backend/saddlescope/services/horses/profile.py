"""Use cases of the horse page.

One indicator's trend over dates with the horse's own normal band, and two of its rides side by side.

The band of every ride is `services.horses.normal_band`'s: mean ± 2 SD of the same horse's EARLIER analysed
rides in the same gait, present once there are at least `MIN_RIDES_FOR_BAND` of them. A ride outside
its band is marked, so a vet sees at a glance "this horse moved unlike itself that day".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from sqlalchemy.orm import Session

from saddlescope.core.errors import InputError
from saddlescope.core.vibration import INDICATORS, indicator_unit
from saddlescope.db.repositories import AnalyticsRepository, Conflict, HorseRepository, RideRepository
from saddlescope.services.comparisons.analytics import check_gait, check_indicator
from saddlescope.services.horses.normal_band import (
    MIN_OWN_RIDES,
    MIN_RIDES_FOR_BAND,
    band_of,
    horse_history,
    page_band,
    ride_order_key,
)

__all__ = ["PAIR_INDICATORS", "horse_trend", "ride_pair"]

# What a trainer or vet compares between two rides, in reading order: the vertical comfort measures
# (W_b then W_k), peak and crest, the exposure time and distance, then speed, bounce and stride.
PAIR_INDICATORS = (
    "acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vdv_y_wk", "acc_y_max", "crest_factor_y", "t_a8_limit_wb_h",
    "d_a8_limit_wb_km", "vel_x_avg_kmh", "amplitude_y_m", "stride_frequency_hz",
)


def _finite(value: Any) -> float | None:
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else None


def horse_trend(session: Session, horse_id: int, *, club_id: int, gait: str, indicator: str,
                include_uncertain: bool = False) -> dict[str, Any]:
    """One indicator of one horse in one gait over its rides, oldest first, each with its normal band.

    Each point: ``ride_id``, ``date``, ``rider``, ``value``, ``band`` (``{n, mean, sd, low, high}`` of
    the earlier rides, or None while fewer than `MIN_RIDES_FOR_BAND`), ``outside`` (True/False
    against the band, None without one) and ``uncertain_reason``. Rides too uncertain for a decision
    are points only when `include_uncertain` (counted in ``uncertain_left_out`` otherwise) and never
    enter a band.
    """
    check_gait(gait)
    check_indicator(indicator)
    horse = HorseRepository(session, club_id=club_id).get(horse_id)
    history = horse_history(session, club_id=club_id, horse_id=horse_id, gait=gait, include_uncertain=True)
    points: list[dict[str, Any]] = []
    earlier: list[float | None] = []
    left_out = 0
    for row in history:  # already in ride_order_key order
        reason = row.get("uncertain_reason")
        if reason is not None and not include_uncertain:
            left_out += 1
            continue
        value = _finite((row.get("indicators") or {}).get(indicator))
        band = band_of(earlier)
        outside = None
        if band is not None and value is not None:
            outside = not band["low"] <= value <= band["high"]
        points.append({"ride_id": row["ride_id"], "date": row["date"], "rider": row["rider"], "value": value,
                       "band": band, "outside": outside, "uncertain_reason": reason})
        if reason is None:
            earlier.append(value)
    # the club's other horses in the gait, for the band until the horse has its own (rides too uncertain left out)
    club = AnalyticsRepository(session, club_id=club_id).indicator_rows(gait=gait, include_uncertain=False)
    club_rows = [row for row in club if row["horse_id"] != horse.id]
    club_values = [_finite((row.get("indicators") or {}).get(indicator)) for row in club_rows]
    horses_in_club = len({row["horse_id"] for row, v in zip(club_rows, club_values, strict=True) if v is not None})
    return {
        "horse_id": horse.id,
        "horse": horse.name,
        "gait": gait,
        "indicator": indicator,
        "unit": indicator_unit(indicator),
        "label": INDICATORS[indicator].label,
        "min_rides_for_band": MIN_RIDES_FOR_BAND,
        "uncertain_left_out": left_out,
        "min_own_rides": MIN_OWN_RIDES,
        # the band the page draws across the chart (issue 37): the horse's own, else the club's in the gait
        "band": page_band(earlier, club_values, horses_in_club=horses_in_club),
        "points": points,
    }


def _percent_difference(first: float | None, second: float | None) -> float | None:
    """(second - first) / |first| in %; None where either is missing or the first is zero."""
    if first is None or second is None or first == 0:
        return None
    return (second - first) / abs(first) * 100.0


def _ride_of_horse(session: Session, *, club_id: int, horse_id: int, ride_id: int, which: str):
    ride = RideRepository(session, club_id=club_id).get(ride_id)  # another club's ride: NotFound (404)
    if ride.horse_id != horse_id:
        raise InputError(f"{which}: ride {ride_id} is a ride of another horse, not of horse {horse_id}; "
                         "pick two rides of this horse")
    return ride


def ride_pair(session: Session, horse_id: int, *, club_id: int, first_id: int, second_id: int,
              indicators: Sequence[str] | None = None) -> dict[str, Any]:
    """Two analysed rides of one horse side by side: every indicator of both and its % difference.

    The difference is the second ride against the first: (b - a) / |a| × 100. 404 for a horse or ride
    not in the club, 422 for a ride of another horse or the same ride twice, 409 for a ride without
    an analysis result yet.
    """
    horse = HorseRepository(session, club_id=club_id).get(horse_id)
    if first_id == second_id:
        raise InputError(f"a and b are both ride {first_id}; pick two different rides to compare")
    keys = [check_indicator(i) for i in (indicators or PAIR_INDICATORS)]
    rides = [_ride_of_horse(session, club_id=club_id, horse_id=horse_id, ride_id=rid, which=which)
             for rid, which in ((first_id, "a"), (second_id, "b"))]
    rows = {row["ride_id"]: row for row in AnalyticsRepository(session, club_id=club_id).indicator_rows(
        horse_ids=[horse_id])}
    for ride in rides:
        if ride.id not in rows:
            raise Conflict(f"ride {ride.id} has no analysis result yet (status {ride.status}); "
                           "compare it once its analysis is done")
    first, second = (rows[ride.id] for ride in rides)
    table = []
    for key in keys:
        a = _finite(first["indicators"].get(key))
        b = _finite(second["indicators"].get(key))
        table.append({"key": key, "label": INDICATORS[key].label, "unit": indicator_unit(key),
                      "better": INDICATORS[key].better, "a": a, "b": b,
                      "difference_percent": _percent_difference(a, b)})
    describe = [{"ride_id": row["ride_id"], "date": row["date"], "gait": row["gait"], "rider": row["rider"]}
                for row in (first, second)]
    ordered = sorted((first, second), key=ride_order_key)
    return {"horse_id": horse.id, "horse": horse.name, "a": describe[0], "b": describe[1],
            "b_is_later": ordered[1] is second, "indicators": table}

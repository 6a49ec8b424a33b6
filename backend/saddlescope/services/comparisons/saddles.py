"""Use cases of saddles: one horse's saddles compared, and one saddle across the club's horses.

The numbers are the rides' indicators grouped by saddle: per group the number of rides, the mean and its
95 % interval (Student's t over the rides' spread), and between two saddles on one horse Welch's
comparison (``core.vibration.group_difference``): the difference "exceeds the uncertainty" when its 95 %
interval excludes zero. Rides too uncertain for a decision are left out unless asked for, and counted.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

from sqlalchemy.orm import Session

from saddlescope.core.vibration import INDICATORS, indicator_unit, mean_interval, welch_difference
from saddlescope.db.repositories import AnalyticsRepository, HorseRepository, RideFilter, SaddleRepository
from saddlescope.services.comparisons.analytics import check_gait, check_indicator

__all__ = ["METHOD", "SADDLE_INDICATORS", "SHORT_LABELS", "difference_sentence", "horse_saddles",
           "saddle_across_horses"]

# What a saddle fitter compares first: the vertical comfort of the seat (W_b, the standard's seated
# weighting, then W_k) as r.m.s. and as VDV (which weighs the jolts).
SADDLE_INDICATORS = ("acc_y_wb_rms", "vdv_y_wb", "acc_y_wk_rms", "vdv_y_wk")
# Their short names, as the ride page's table and the README name them (W_b: BS 6841, W_k: ISO 2631-1).
SHORT_LABELS = {"acc_y_wb_rms": "W_b r.m.s.", "vdv_y_wb": "VDV W_b", "acc_y_wk_rms": "W_k r.m.s.",
                "vdv_y_wk": "VDV W_k"}


def _label(key: str) -> str:
    """An indicator's short name where it has one, else its label."""
    return SHORT_LABELS.get(key) or INDICATORS[key].label
METHOD = ("Each saddle's mean has a 95 % interval from the spread of its rides (Student's t). Two saddles "
          "differ beyond the uncertainty when the 95 % interval of the difference of their means, by "
          "Welch's t-test (unequal spreads), does not include zero. Each needs at least two rides.")


def _value(row: dict[str, Any], key: str) -> float | None:
    value = (row.get("indicators") or {}).get(key)
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else None


def _stats(rows: Sequence[dict[str, Any]], keys: Sequence[str]) -> dict[str, dict[str, Any]]:
    out = {}
    for key in keys:
        interval = mean_interval([_value(row, key) for row in rows])
        out[key] = {"n": interval.n, "mean": interval.mean, "sd": interval.sd, "low": interval.low,
                    "high": interval.high}
    return out


def _number(value: float, unit: str) -> str:
    unit_text = {"m/s^2": "m/s²", "m/s^1.75": "m/s¹·⁷⁵"}.get(unit, unit)
    return f"{value:.3g} {unit_text}".strip()


def difference_sentence(key: str, first: str, second: str, difference: Any) -> str:
    """The comparison of saddle `second` against `first` in words (`difference`: a `GroupDifference` or None)."""
    label = _label(key).replace("W_", "W")  # "W_b" as the page writes it: Wb
    label = label[:1].upper() + label[1:]
    if difference is None:
        return f"{label}: {first} and {second} cannot be compared yet; each saddle needs at least two rides."
    unit = indicator_unit(key)
    size = _number(abs(difference.difference), unit)
    interval = f"95 % interval {_number(difference.low, unit)} to {_number(difference.high, unit)}"
    if not difference.exceeds_uncertainty:
        return (f"{label}: the difference between {first} and {second} ({size}; {interval}) is within the "
                "uncertainty: these rides cannot tell the two saddles apart.")
    word = "higher" if difference.difference > 0 else "lower"
    better = INDICATORS[key].better
    verdict = "" if better is None else (
        f" {second} is the more comfortable here." if (word == "lower") == (better == "lower")
        else f" {first} is the more comfortable here.")
    p_text = "p < 0.001" if difference.p_value < 0.001 else f"p = {difference.p_value:.2g}"
    return (f"{label}: {second} is {size} {word} than {first} ({interval}, Welch {p_text}): "
            f"more than the uncertainty.{verdict}")


def _groups(rows: Sequence[dict[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    groups: dict[int, list[dict[str, Any]]] = {}
    for row in rows:
        if row["saddle_id"] is not None:
            groups.setdefault(row["saddle_id"], []).append(row)
    return groups


def _differences(groups: dict[int, list[dict[str, Any]]], names: dict[int, str], keys: Sequence[str],
                 ) -> list[dict[str, Any]]:
    out = []
    for a, b in itertools.combinations(sorted(groups, key=lambda sid: names[sid].lower()), 2):
        for key in keys:
            diff = welch_difference([_value(r, key) for r in groups[a]], [_value(r, key) for r in groups[b]])
            out.append({
                "indicator": key, "saddle_a_id": a, "saddle_a": names[a], "saddle_b_id": b, "saddle_b": names[b],
                "difference": diff.difference if diff else None, "low": diff.low if diff else None,
                "high": diff.high if diff else None, "p_value": diff.p_value if diff else None,
                "exceeds_uncertainty": diff.exceeds_uncertainty if diff else None,
                "sentence": difference_sentence(key, names[a], names[b], diff),
            })
    return out


def horse_saddles(session: Session, horse_id: int, *, club_id: int, gait: str,
                  indicators: Sequence[str] | None = None, include_uncertain: bool = False) -> dict[str, Any]:
    """One horse's saddles in one gait: per saddle n and the mean with its interval, and every pair compared."""
    check_gait(gait)
    keys = [check_indicator(k) for k in (indicators or SADDLE_INDICATORS)]
    horse = HorseRepository(session, club_id=club_id).get(horse_id)
    rows = AnalyticsRepository(session, club_id=club_id).indicator_rows(gait=gait, horse_ids=[horse_id])
    left_out = 0 if include_uncertain else sum(row["uncertain_reason"] is not None for row in rows)
    rows = [row for row in rows if include_uncertain or row["uncertain_reason"] is None]
    groups = _groups(rows)
    names = {sid: group[0]["saddle"] for sid, group in groups.items()}
    saddles = [{"saddle_id": sid, "saddle": names[sid], "rides": len(groups[sid]),
                "indicators": _stats(groups[sid], keys)}
               for sid in sorted(groups, key=lambda sid: names[sid].lower())]
    return {
        "horse_id": horse.id, "horse": horse.name, "gait": gait, "include_uncertain": include_uncertain,
        "uncertain_left_out": left_out, "without_saddle": sum(row["saddle_id"] is None for row in rows),
        "units": {key: indicator_unit(key) for key in keys},
        "labels": {key: _label(key) for key in keys},
        "saddles": saddles, "differences": _differences(groups, names, keys), "method": METHOD,
    }


def saddle_across_horses(session: Session, saddle_id: int, *, club_id: int, gait: str | None = None,
                         indicators: Sequence[str] | None = None, include_uncertain: bool = False
                         ) -> dict[str, Any]:
    """One saddle across the club's horses: its analysed rides and per horse and gait n, mean and interval.

    Rides too uncertain for a decision are listed either way (marked) but averaged only when asked.
    """
    if gait is not None:
        check_gait(gait)
    keys = [check_indicator(k) for k in (indicators or SADDLE_INDICATORS)]
    saddles = SaddleRepository(session, club_id=club_id)
    saddle = saddles.get(saddle_id)
    rows = AnalyticsRepository(session, club_id=club_id).indicator_rows(
        gait=gait, rides=RideFilter(saddle_id=saddle_id))
    per_horse: dict[tuple[int, str], list[dict[str, Any]]] = {}
    for row in rows:
        if include_uncertain or row["uncertain_reason"] is None:
            per_horse.setdefault((row["horse_id"], row["gait"]), []).append(row)
    horses = [{"horse_id": horse_id, "horse": group[0]["horse"], "gait": ride_gait, "rides": len(group),
               "indicators": _stats(group, keys)}
              for (horse_id, ride_gait), group in sorted(per_horse.items(),
                                                         key=lambda item: (item[1][0]["horse"].lower(), item[0][1]))]
    return {
        "saddle": saddle, "rides_total": saddles.ride_counts([saddle_id]).get(saddle_id, 0),
        "gait": gait, "include_uncertain": include_uncertain,
        "units": {key: indicator_unit(key) for key in keys},
        "labels": {key: _label(key) for key in keys},
        "rides": [{"ride_id": row["ride_id"], "date": row["date"], "horse_id": row["horse_id"], "horse": row["horse"],
                   "rider": row["rider"], "gait": row["gait"], "uncertain_reason": row["uncertain_reason"],
                   "indicators": {key: _value(row, key) for key in keys}}
                  for row in sorted(rows, key=lambda r: (r["date"] is None, r["date"], r["ride_id"]), reverse=True)],
        "horses": horses, "method": METHOD,
    }

"""Use cases of comparisons: a horse across gaits, horses within a gait, the leaderboard, grades vs indicators.

The statistics are `saddlescope.core.vibration`'; this module only fetches the club's rows
(`AnalyticsRepository`) and names the horses by id as well.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from sqlalchemy.orm import Session

from saddlescope.core.errors import InputError
from saddlescope.core.vibration import (
    COMFORT_INDICATORS,
    GAITS,
    INDICATORS,
    compare_gaits,
    compare_horses,
    grades_vs_indicators,
    indicator_unit,
    leaderboard,
)
from saddlescope.db.repositories import (
    AnalyticsRepository,
    GradeRepository,
    HorseRepository,
    RideFilter,
    SaddleRepository,
)

__all__ = [
    "check_gait", "check_indicator", "club_leaderboard", "grade_correlation_report", "horse_comparison",
    "horses_comparison",
]


def check_indicator(indicator: str) -> str:
    """The indicator key, if known; `InputError` otherwise."""
    if indicator not in INDICATORS:
        raise InputError(f"unknown indicator {indicator!r}; GET /api/indicators lists them")
    return indicator


def check_gait(gait: str) -> str:
    """The gait, if known; `InputError` otherwise."""
    if gait not in GAITS:
        raise InputError(f"unknown gait {gait!r}; the gaits are {', '.join(GAITS)}")
    return gait


def _finite(value: float | None) -> float | None:
    return value if isinstance(value, int | float) and math.isfinite(value) else None


def _clean(stats: dict[str, Any]) -> dict[str, Any]:
    """NaN (a standard deviation of one ride) and infinities become None in JSON."""
    return {k: (_finite(v) if isinstance(v, float) else v) for k, v in stats.items()}


def _uncertain_apart(rows: list[dict[str, Any]], include_uncertain: bool) -> tuple[list[dict[str, Any]], int]:
    """The rows to average (too uncertain ones only when asked) and how many were left out."""
    if include_uncertain:
        return rows, 0
    kept = [row for row in rows if row.get("uncertain_reason") is None]
    return kept, len(rows) - len(kept)


def horse_comparison(
    session: Session, horse_id: int, *, club_id: int, indicators: Sequence[str] | None = None,
    include_uncertain: bool = False,
) -> dict[str, Any]:
    """One horse across gaits (thesis Figs 8.29-8.32): per indicator, per gait n, mean, std, min, max.

    Rides too uncertain for a decision are left out unless `include_uncertain` (counted in
    ``uncertain_left_out``).
    """
    horse = HorseRepository(session, club_id=club_id).get(horse_id)
    indicators = [check_indicator(i) for i in (indicators or COMFORT_INDICATORS)]
    rows, left_out = _uncertain_apart(
        AnalyticsRepository(session, club_id=club_id).indicator_rows(horse_ids=[horse_id]), include_uncertain)
    return {
        "horse_id": horse.id,
        "horse": horse.name,
        "rides": len(rows),
        "uncertain_left_out": left_out,
        "indicators": {
            ind: {
                "unit": indicator_unit(ind),
                "gaits": [_clean(g) for g in compare_gaits(rows, ind, horse=horse.name)],
            }
            for ind in indicators
        },
    }


def horses_comparison(
    session: Session,
    *,
    club_id: int,
    gait: str,
    horse_ids: Sequence[int] | None = None,
    indicators: Sequence[str] | None = None,
    saddle_id: int | None = None,
    include_uncertain: bool = False,
) -> dict[str, Any]:
    """Horses within one gait (thesis 8.5.2): per indicator, per horse n, mean, std, min, max.

    `saddle_id`: only rides in that saddle of the club. Rides too uncertain for a decision are left out
    unless `include_uncertain` (counted in ``uncertain_left_out``).
    """
    check_gait(gait)
    indicators = [check_indicator(i) for i in (indicators or COMFORT_INDICATORS)]
    analytics = AnalyticsRepository(session, club_id=club_id)
    if horse_ids:
        names = analytics.horse_names(horse_ids)
        unknown = sorted(set(horse_ids) - set(names))
        if unknown:
            raise InputError(f"no horse {', '.join(map(str, unknown))} in this club")
    if saddle_id is not None:
        SaddleRepository(session, club_id=club_id).get(saddle_id)  # another club's saddle: not found
    rows, left_out = _uncertain_apart(analytics.indicator_rows(
        gait=gait, horse_ids=horse_ids or None, rides=RideFilter(saddle_id=saddle_id)), include_uncertain)
    ids = {row["horse"]: row["horse_id"] for row in rows}
    return {
        "gait": gait,
        "saddle_id": saddle_id,
        "rides": len(rows),
        "uncertain_left_out": left_out,
        "indicators": {
            ind: {
                "unit": indicator_unit(ind),
                "horses": [
                    {"horse_id": ids.get(g["group"]), "horse": g["group"], **_clean(g)}
                    for g in compare_horses(rows, ind, gait=gait)
                ],
            }
            for ind in indicators
        },
    }


def club_leaderboard(
    session: Session, *, club_id: int, gait: str, indicator: str, lower_is_better: bool | None = None,
    include_uncertain: bool = False, saddle_id: int | None = None,
) -> dict[str, Any]:
    """The club's horses ranked in one gait by one indicator, most comfortable first (`saddle_id`: in that saddle).

    Each entry: rank, horse id and name, ``n`` (rides behind it), mean, std, min, max and spread, and
    ``uncertain_rides`` (how many of them are too uncertain for a decision). Rides too uncertain for a
    decision (their W_b r.m.s. interval too wide; ``docs/accuracy.md``) are left out of the ranking
    unless ``include_uncertain``; either way they are listed in ``uncertain`` with their reason.
    Only the indicator's column is read (indexed for the usual ones), so it stays fast over many rides.
    """
    check_gait(gait)
    check_indicator(indicator)
    if lower_is_better is None and INDICATORS[indicator].better is None:
        raise InputError(f"{indicator!r} has no comfort direction; pass lower_is_better=true or false")
    if saddle_id is not None:
        SaddleRepository(session, club_id=club_id).get(saddle_id)  # another club's saddle: not found
    values = AnalyticsRepository(session, club_id=club_id).marked_indicator_values(indicator, gait=gait,
                                                                                    saddle_id=saddle_id)
    ids = {name: horse_id for horse_id, name, *_ in values}
    kept = [v for v in values if include_uncertain or v[4] is None]
    rows = [{"horse": name, "gait": gait, indicator: value} for _, name, value, _, _ in kept]
    ranking = leaderboard(rows, indicator, gait=gait, lower_is_better=lower_is_better)
    marked: dict[str, int] = {}
    for _, name, _, _, reason in kept:
        marked[name] = marked.get(name, 0) + (reason is not None)
    lower = lower_is_better if lower_is_better is not None else INDICATORS[indicator].better == "lower"
    return {
        "gait": gait,
        "indicator": indicator,
        "unit": indicator_unit(indicator),
        "better": "lower" if lower else "higher",
        "rides": sum(r["n"] for r in ranking),
        "include_uncertain": include_uncertain,
        "saddle_id": saddle_id,
        "entries": [{"horse_id": ids.get(r["horse"]), **_clean(r), "uncertain_rides": marked.get(r["horse"], 0)}
                    for r in ranking],
        "uncertain": [{"ride_id": ride_id, "horse_id": horse_id, "horse": name, "value": _finite(value),
                       "reason": reason, "included": include_uncertain}
                      for horse_id, name, value, ride_id, reason in values if reason is not None],
    }


def grade_correlation_report(
    session: Session, *, club_id: int, gait: str | None = None, indicators: Sequence[str] | None = None
) -> dict[str, Any]:
    """The riders' average grades per horse and gait against the mean indicators (thesis Figs 8.33-8.36)."""
    if gait is not None:
        check_gait(gait)
    indicators = [check_indicator(i) for i in (indicators or COMFORT_INDICATORS)]
    grade_rows = GradeRepository(session, club_id=club_id).grade_rows(gait=gait)
    rows = AnalyticsRepository(session, club_id=club_id).indicator_rows(gait=gait, include_uncertain=False)
    report = grades_vs_indicators(grade_rows, rows, indicators, gait=gait)
    for r in report.values():
        r["points"] = _described_points(r["points"], grade_rows, rows)
        _withhold_correlation_on_few_points(r)
    return {
        "gait": gait,
        "grades": len(grade_rows),
        "indicators": {
            ind: {
                **_clean({k: v for k, v in r.items() if k != "points"}),
                "unit": indicator_unit(ind),
                "points": r["points"],
            }
            for ind, r in report.items()
        },
    }


# Pearson's r and Spearman's rho from fewer points are noise (r = -1.0 from two points): withheld, and
# the page says how many are needed.
MIN_CORRELATION_POINTS = 5


def _withhold_correlation_on_few_points(r: dict[str, Any]) -> None:
    """Blank the correlation coefficients, p-values and intervals of an indicator with too few points."""
    n = int(r.get("n") or 0)
    r["min_points"] = MIN_CORRELATION_POINTS
    if n >= MIN_CORRELATION_POINTS:
        r["withheld_reason"] = None
        return
    for key in list(r):
        if key.startswith(("pearson", "spearman")):
            r[key] = None
    r["withheld_reason"] = (f"needs at least {MIN_CORRELATION_POINTS} graded horse-gait pairs to show a "
                            f"correlation ({n} so far)")


def _described_points(points: Sequence[dict[str, Any]], grade_rows: Sequence[dict[str, Any]],
                      rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each horse-gait point with what a hover names.

    The horse's id, the riders who graded it, the number of analysed rides behind its mean and their first and last
    day (ISO dates, None: undated).
    """
    riders: dict[tuple[str, str], set[str]] = {}
    for g in grade_rows:
        riders.setdefault((g["horse"], g["gait"]), set()).add(g["rider"])
    rides: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for row in rows:
        rides.setdefault((row["horse"], row["gait"]), []).append(row)
    described = []
    for p in points:
        behind = rides.get((p["horse"], p["gait"]), [])
        dates = sorted(row["date"] for row in behind if row["date"] is not None)
        described.append({
            **p,
            "horse_id": behind[0]["horse_id"] if behind else None,
            "riders": sorted(riders.get((p["horse"], p["gait"]), ())),
            "rides": len(behind),
            "first_date": dates[0].isoformat() if dates else None,
            "last_date": dates[-1].isoformat() if dates else None,
        })
    return described

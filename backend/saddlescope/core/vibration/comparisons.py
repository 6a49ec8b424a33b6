"""Comparisons of rides across gaits, horses and riders' grades (thesis section 8.5).

Relative comfort, per-group summaries, leaderboards (Figs 8.29-8.32) and the riders' 1-5 grades
against the indicators (Table 8.8, Figs 8.33-8.36).

Everything here is a pure function of plain numbers, lists and dicts: no database.  A *row*
is a dict describing one ride: metadata ``ride_id``, ``horse``, ``rider``, ``gait``,
``date`` and the indicator values, either at the top level or under ``"indicators"``.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy import stats

from saddlescope.core.errors import InputError
from saddlescope.core.vibration.indicator_keys import (
    COMFORT_INDICATORS,
    GAITS,
    INDICATORS,
    PASSIVE_SEATED_CAVEAT,
    IndicatorInfo,
    indicator_unit,
)
from saddlescope.core.vibration.indicators import _check_positive

__all__ = [
    "relative_comfort",
    "relative_comfort_table",
    "summarize",
    "compare_gaits",
    "compare_horses",
    "leaderboard",
    "average_grades",
    "grade_correlation",
    "grades_vs_indicators",
]


# --------------------------------------------------------------------------------------------
# Relative comfort


def relative_comfort(allowed_a_h: float, allowed_b_h: float) -> float:
    """How many times more comfortable horse B is than horse A (thesis 8.5).

    The ratio of their allowed exposure times (or distances): with T_A(8),limit,Wb of 1.5 h
    for A and 3 h for B, B is 2 times as comfortable.  Note that the ratio depends on the
    criterion: A(8) times scale with (a_rms,A / a_rms,B)^2, VDV times with
    (VDV_A / VDV_B)^4.  See :data:`PASSIVE_SEATED_CAVEAT`.

    Parameters
    ----------
    allowed_a_h, allowed_b_h : float
        Allowed exposure times (h) or distances (km) of horses A and B.

    Returns
    -------
    float
        allowed_b / allowed_a.
    """
    a = _check_positive("allowed_a_h", allowed_a_h)
    b = _check_positive("allowed_b_h", allowed_b_h, allow_zero=True)
    return b / a


def _value(row: Mapping, key: str) -> float:
    """Indicator value of a row (top level or under 'indicators'); NaN when absent."""
    source = row.get("indicators", row) if key not in row else row
    value = source.get(key, math.nan) if isinstance(source, Mapping) else math.nan
    if value is None:
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"ride {row.get('ride_id', '?')}: {key} = {value!r} is not a number") from exc


def _better(indicator: str, lower_is_better: bool | None) -> bool:
    if lower_is_better is not None:
        return bool(lower_is_better)
    info = INDICATORS.get(indicator)
    if info is None or info.better is None:
        raise InputError(
            f"{indicator!r} has no comfort direction; pass lower_is_better=True or False"
        )
    return info.better == "lower"


def relative_comfort_table(rows: Iterable[Mapping], *, gait: str,
                           indicator: str = "t_a8_limit_wb_h",
                           reference_horse: str | None = None) -> dict:
    """Relative comfort of the horses in one gait next to the absolute allowed times.

    Parameters
    ----------
    rows : iterable of dict
        Ride rows (``horse``, ``gait`` and the indicator).
    gait : str
        Gait to compare.
    indicator : str
        An allowed time or distance (``t_*_h`` or ``d_*_km``); default T_A(8),limit,Wb as in
        thesis 8.5.
    reference_horse : str, optional
        Horse whose relative comfort is 1; default the least comfortable (shortest time).

    Returns
    -------
    dict
        ``indicator``, ``unit``, ``gait``, ``reference_horse``, ``caveat`` and ``rows``: one
        dict per horse with ``horse``, ``n``, ``mean`` (absolute value) and ``relative``
        (mean / reference mean), most comfortable first.
    """
    if not (indicator.startswith(("t_", "d_")) and INDICATORS.get(indicator, IndicatorInfo("", "")).better
            == "higher"):
        raise InputError(
            f"relative comfort compares allowed times or distances (t_*_h, d_*_km), not {indicator!r}"
        )
    groups = summarize(rows, indicator, by="horse", where=lambda row: row.get("gait") == gait)
    if not groups:
        raise InputError(f"no rides in gait {gait!r} with a value for {indicator}")
    means = {g["group"]: g["mean"] for g in groups}
    if reference_horse is None:
        reference_horse = min(means, key=means.__getitem__)
    elif reference_horse not in means:
        raise InputError(f"reference horse {reference_horse!r} has no {gait} rides with {indicator}")
    ref = means[reference_horse]
    if not ref > 0:
        raise InputError(f"reference horse {reference_horse!r} has {indicator} = {ref}; cannot divide")
    table = [{"horse": g["group"], "n": g["n"], "mean": g["mean"], "relative": g["mean"] / ref}
             for g in groups]
    table.sort(key=lambda r: -r["relative"])
    return {"indicator": indicator, "unit": indicator_unit(indicator), "gait": gait,
            "reference_horse": reference_horse, "rows": table, "caveat": PASSIVE_SEATED_CAVEAT}


# --------------------------------------------------------------------------------------------
# Comparisons (thesis Figs 8.29-8.32)


def _group_order(key: str, names: Iterable[str]) -> list[str]:
    names = list(names)
    if key == "gait":
        known = [g for g in GAITS if g in names]
        return known + sorted(n for n in names if n not in GAITS)
    return sorted(names)


def summarize(rows: Iterable[Mapping], indicator: str, *, by: str,
              where: Callable[[Mapping], bool] | None = None) -> list[dict]:
    """Per-group statistics of one indicator.

    Parameters
    ----------
    rows : iterable of dict
        Ride rows.
    indicator : str
        Indicator key.
    by : str
        Row field to group by ("gait", "horse", "rider", ...).
    where : callable, optional
        Keep only rows for which it returns True.

    Returns
    -------
    list of dict
        One per group (gaits in walk, sitting trot, rising trot, canter order, others sorted):
        ``group``, ``n``, ``mean``, ``std`` (sample, ddof = 1; NaN for n = 1), ``min``,
        ``max``.  Rows without a finite-or-infinite value (missing or NaN) are skipped.
    """
    values: dict[str, list[float]] = defaultdict(list)
    for row in rows:
        if where is not None and not where(row):
            continue
        if by not in row:
            raise InputError(f"ride {row.get('ride_id', '?')} has no {by!r} to group by")
        value = _value(row, indicator)
        if not math.isnan(value):
            values[str(row[by])].append(value)
    out = []
    for group in _group_order(by, values):
        arr = np.asarray(values[group])
        out.append({
            "group": group,
            "n": int(arr.size),
            "mean": float(arr.mean()),
            "std": float(arr.std(ddof=1)) if arr.size > 1 else math.nan,
            "min": float(arr.min()),
            "max": float(arr.max()),
        })
    return out


def compare_gaits(rows: Iterable[Mapping], indicator: str, *, horse: str) -> list[dict]:
    """One horse across gaits (thesis Figs 8.29-8.32): :func:`summarize` by gait.

    Parameters
    ----------
    rows : iterable of dict
        Ride rows.
    indicator : str
        Indicator key.
    horse : str
        The horse compared.

    Returns
    -------
    list of dict
        As :func:`summarize`, one per gait.
    """
    return summarize(rows, indicator, by="gait", where=lambda row: row.get("horse") == horse)


def compare_horses(rows: Iterable[Mapping], indicator: str, *, gait: str) -> list[dict]:
    """Horses within one gait (thesis 8.5.2): :func:`summarize` by horse.

    Parameters
    ----------
    rows : iterable of dict
        Ride rows.
    indicator : str
        Indicator key.
    gait : str
        The gait compared in.

    Returns
    -------
    list of dict
        As :func:`summarize`, one per horse.
    """
    return summarize(rows, indicator, by="horse", where=lambda row: row.get("gait") == gait)


def leaderboard(rows: Iterable[Mapping], indicator: str, *, gait: str,
                lower_is_better: bool | None = None) -> list[dict]:
    """Horses ranked by an indicator in one gait, most comfortable first.

    Parameters
    ----------
    rows : iterable of dict
        Ride rows.
    indicator : str
        Indicator key.
    gait : str
        Gait to rank in.
    lower_is_better : bool, optional
        Ranking direction; by default taken from :data:`INDICATORS` (raises for indicators
        such as speed that have no comfort direction).

    Returns
    -------
    list of dict
        ``rank`` (ties share the better rank), ``horse``, ``n`` (rides behind the mean),
        ``mean``, ``std``, ``min``, ``max``, ``spread`` (max - min).
    """
    lower = _better(indicator, lower_is_better)
    groups = compare_horses(rows, indicator, gait=gait)
    groups.sort(key=lambda g: (g["mean"] if lower else -g["mean"], g["group"]))
    out: list[dict[str, Any]] = []
    for i, g in enumerate(groups):
        tied = out and out[-1]["mean"] == g["mean"]
        out.append({
            "rank": out[-1]["rank"] if tied else i + 1,
            "horse": g["group"],
            "n": g["n"],
            "mean": g["mean"],
            "std": g["std"],
            "min": g["min"],
            "max": g["max"],
            "spread": g["max"] - g["min"],
        })
    return out


# --------------------------------------------------------------------------------------------
# Riders' grades (thesis Table 8.8, Figs 8.33-8.36)


def average_grades(grade_rows: Iterable[Mapping], *, gait: str | None = None) -> list[dict]:
    """Average of the riders' 1-5 grades per horse and gait (thesis Table 8.8 'avg' rows).

    Parameters
    ----------
    grade_rows : iterable of dict
        ``{"horse", "gait", "rider", "grade"}`` with grade in 1..5.
    gait : str, optional
        Keep only this gait.

    Returns
    -------
    list of dict
        ``horse``, ``gait``, ``grade`` (mean), ``n`` (number of grades), ``std``.
    """
    grades: dict[tuple[str, str], list[float]] = defaultdict(list)
    for row in grade_rows:
        for field in ("horse", "gait", "grade"):
            if field not in row:
                raise InputError(f"grade row {dict(row)!r} has no {field!r}")
        if gait is not None and row["gait"] != gait:
            continue
        grade = row["grade"]
        if isinstance(grade, bool) or not isinstance(grade, int | float | np.integer | np.floating) \
                or not 1 <= grade <= 5:
            raise InputError(
                f"grade of rider {row.get('rider', '?')} for {row['horse']} ({row['gait']}) must be "
                f"1-5, got {grade!r}"
            )
        grades[(str(row["horse"]), str(row["gait"]))].append(float(grade))
    gait_rank = {g: i for i, g in enumerate(GAITS)}
    keys = sorted(grades, key=lambda hg: (gait_rank.get(hg[1], len(GAITS)), hg[1], hg[0]))
    return [{"horse": h, "gait": g, "grade": float(np.mean(grades[(h, g)])), "n": len(grades[(h, g)]),
             "std": float(np.std(grades[(h, g)], ddof=1)) if len(grades[(h, g)]) > 1 else math.nan}
            for h, g in keys]


def _fisher_ci(r: float, n: int, se_scale: float, confidence: float) -> tuple[float, float]:
    if n <= 3 or math.isnan(r):
        return math.nan, math.nan
    if abs(r) >= 1:
        return r, r
    z = math.atanh(r)
    half = stats.norm.ppf(0.5 + confidence / 2) * se_scale / math.sqrt(n - 3)
    return math.tanh(z - half), math.tanh(z + half)


def _t_test_p(r: float, n: int) -> float:
    if math.isnan(r) or n < 3:
        return math.nan
    if abs(r) >= 1:
        return 0.0
    t = r * math.sqrt((n - 2) / (1 - r * r))
    return float(2 * stats.t.sf(abs(t), n - 2))


def _pearson(x: np.ndarray, y: np.ndarray) -> float:
    dx, dy = x - x.mean(), y - y.mean()
    denom = math.sqrt(float(dx @ dx) * float(dy @ dy))
    if denom == 0:
        return math.nan  # a constant variable has no correlation
    return float(np.clip((dx @ dy) / denom, -1.0, 1.0))


def grade_correlation(grades: Sequence[float], values: Sequence[float], *,
                      confidence: float = 0.95) -> dict[str, float]:
    """Pearson and Spearman correlation of riders' grades with an indicator.

    Parameters
    ----------
    grades, values : array_like of shape (n,)
        Paired observations (e.g. average grade of a horse in a gait, and its indicator).
        Pairs with a NaN are dropped.
    confidence : float
        Confidence level of the intervals (default 0.95).

    Returns
    -------
    dict
        ``n``, ``pearson_r``, ``pearson_p`` (two-sided, t test with n - 2 degrees of freedom,
        as :func:`scipy.stats.pearsonr`), ``pearson_ci_low``, ``pearson_ci_high`` (Fisher z,
        standard error 1/sqrt(n - 3)), ``spearman_rho``, ``spearman_p`` (t approximation, as
        :func:`scipy.stats.spearmanr`), ``spearman_ci_low``, ``spearman_ci_high`` (Fisher z
        with the Fieller-Hartley-Pearson standard error sqrt(1.06 / (n - 3))).  NaN where
        undefined: a constant variable, fewer than 3 pairs (p) or 4 pairs (intervals).
    """
    x = np.asarray(grades, dtype=float).ravel()
    y = np.asarray(values, dtype=float).ravel()
    if x.shape != y.shape:
        raise InputError(f"{x.size} grades but {y.size} indicator values; they must be paired")
    if not 0 < confidence < 1:
        raise InputError(f"confidence must be between 0 and 1, got {confidence}")
    keep = ~(np.isnan(x) | np.isnan(y))
    x, y = x[keep], y[keep]
    n = int(x.size)
    r = _pearson(x, y) if n >= 2 else math.nan
    rho = _pearson(stats.rankdata(x), stats.rankdata(y)) if n >= 2 else math.nan
    p_lo, p_hi = _fisher_ci(r, n, 1.0, confidence)
    s_lo, s_hi = _fisher_ci(rho, n, math.sqrt(1.06), confidence)
    return {
        "n": n,
        "pearson_r": r,
        "pearson_p": _t_test_p(r, n),
        "pearson_ci_low": p_lo,
        "pearson_ci_high": p_hi,
        "spearman_rho": rho,
        "spearman_p": _t_test_p(rho, n),
        "spearman_ci_low": s_lo,
        "spearman_ci_high": s_hi,
    }


def grades_vs_indicators(grade_rows: Iterable[Mapping], indicator_rows: Iterable[Mapping],
                         indicators: Sequence[str] = COMFORT_INDICATORS, *,
                         gait: str | None = None, confidence: float = 0.95) -> dict[str, dict]:
    """Riders' grades against indicators (thesis Figs 8.33-8.36).

    As in the thesis, each point is one horse in one gait: the average of the riders'
    grades (:func:`average_grades`) against the mean indicator over that horse's rides in
    that gait.

    Parameters
    ----------
    grade_rows : iterable of dict
        ``{"horse", "gait", "rider", "grade"}``.
    indicator_rows : iterable of dict
        Ride rows with ``horse``, ``gait`` and the indicators.
    indicators : sequence of str
        Indicator keys; default the eight comfort indicators.
    gait : str, optional
        One gait (one figure of the thesis), or all gaits pooled.

    Returns
    -------
    dict of indicator -> dict
        The :func:`grade_correlation` result plus ``expected_sign`` (-1 where a lower value is
        more comfortable, +1 where higher is, 0 without direction) and ``points``: the list of
        ``{"horse", "gait", "grade", "value"}`` behind it.
    """
    mean_grades = {(g["horse"], g["gait"]): g["grade"] for g in average_grades(grade_rows, gait=gait)}
    indicator_rows = [row for row in indicator_rows if gait is None or row.get("gait") == gait]
    out = {}
    for indicator in indicators:
        per_pair: dict[tuple[str, str], list[float]] = defaultdict(list)
        for row in indicator_rows:
            value = _value(row, indicator)
            if not math.isnan(value):
                per_pair[(str(row.get("horse")), str(row.get("gait")))].append(value)
        points = [{"horse": h, "gait": g, "grade": mean_grades[(h, g)], "value": float(np.mean(v))}
                  for (h, g), v in per_pair.items() if (h, g) in mean_grades]
        points.sort(key=lambda p: (p["gait"], p["horse"]))
        result: dict = grade_correlation([p["grade"] for p in points], [p["value"] for p in points],
                                         confidence=confidence)
        better = INDICATORS.get(indicator, IndicatorInfo("", "")).better
        result["expected_sign"] = {"lower": -1, "higher": 1}.get(better or "", 0)
        result["points"] = points
        out[indicator] = result
    return out

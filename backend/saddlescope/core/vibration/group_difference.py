"""Whether two groups of rides differ by more than their uncertainty (two saddles on one horse, ...).

Each group's mean gets a 95 % interval from Student's t with n - 1 degrees of freedom (the rides'
own spread, which holds both the horse's day-to-day variation and each ride's measurement error).
Two groups are compared by Welch's t-test (unequal variances, Welch-Satterthwaite degrees of
freedom): the difference of the means with its 95 % interval and the two-sided p-value. The
difference *exceeds the uncertainty* when that interval excludes zero (equivalently p < 0.05).
Fewer than two rides in a group give no spread, so no interval and no verdict.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = ["CONFIDENCE", "GroupDifference", "MeanInterval", "mean_interval", "welch_difference"]

CONFIDENCE = 0.95


@dataclass(frozen=True)
class MeanInterval:
    """A group's mean with its 95 % interval (``low``/``high`` None below two values)."""

    n: int
    mean: float | None
    sd: float | None
    low: float | None
    high: float | None


@dataclass(frozen=True)
class GroupDifference:
    """Group b's mean minus group a's, its 95 % interval, Welch's p and whether it exceeds the uncertainty."""

    difference: float
    low: float
    high: float
    p_value: float
    df: float
    exceeds_uncertainty: bool


def _finite(values: Sequence[float | None]) -> np.ndarray:
    arr = np.asarray([v for v in values if isinstance(v, int | float) and math.isfinite(v)], dtype=float)
    return arr


def mean_interval(values: Sequence[float | None], *, confidence: float = CONFIDENCE) -> MeanInterval:
    """The mean of the finite `values` and its Student-t interval (none below two values)."""
    arr = _finite(values)
    if arr.size == 0:
        return MeanInterval(0, None, None, None, None)
    mean = float(arr.mean())
    if arr.size < 2:
        return MeanInterval(1, mean, None, None, None)
    sd = float(arr.std(ddof=1))
    half = float(stats.t.ppf(0.5 + confidence / 2, arr.size - 1)) * sd / math.sqrt(arr.size)
    return MeanInterval(int(arr.size), mean, sd, mean - half, mean + half)


def welch_difference(a: Sequence[float | None], b: Sequence[float | None], *,
                     confidence: float = CONFIDENCE) -> GroupDifference | None:
    """Welch's comparison of b against a; None when either has fewer than two finite values.

    Two groups without any spread (every ride identical) differ beyond doubt when their means differ.
    """
    xa, xb = _finite(a), _finite(b)
    if xa.size < 2 or xb.size < 2:
        return None
    va, vb = xa.var(ddof=1) / xa.size, xb.var(ddof=1) / xb.size
    difference = float(xb.mean() - xa.mean())
    se = math.sqrt(va + vb)
    if se == 0.0:
        return GroupDifference(difference, difference, difference, 0.0 if difference else 1.0, math.inf,
                               difference != 0.0)
    df = (va + vb) ** 2 / (va**2 / (xa.size - 1) + vb**2 / (xb.size - 1))
    half = float(stats.t.ppf(0.5 + confidence / 2, df)) * se
    p_value = float(2 * stats.t.sf(abs(difference) / se, df))
    low, high = difference - half, difference + half
    return GroupDifference(difference, low, high, p_value, float(df), bool(low > 0 or high < 0))

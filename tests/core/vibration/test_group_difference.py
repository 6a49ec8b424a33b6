"""A group's mean interval and Welch's comparison of two groups (core/vibration/group_difference.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from saddlescope.core.vibration import mean_interval, welch_difference


def test_the_mean_interval_is_students_t_over_the_rides_spread():
    values = [1.0, 1.1, 0.9, 1.05]
    interval = mean_interval(values)
    low, high = stats.t.interval(0.95, len(values) - 1, loc=np.mean(values), scale=stats.sem(values))
    assert (interval.n, interval.mean) == (4, pytest.approx(1.0125))
    assert (interval.low, interval.high) == (pytest.approx(low), pytest.approx(high))
    # NaN and None are not rides; one ride has no interval; none has no mean
    assert mean_interval([1.2, None, math.nan]) == mean_interval([1.2])
    assert mean_interval([1.2]).low is None and mean_interval([]).mean is None


def test_welch_agrees_with_scipy_and_says_when_the_difference_exceeds_the_uncertainty():
    a, b = [1.0, 1.1, 0.9, 1.05], [0.6, 0.66, 0.55]
    diff = welch_difference(a, b)
    want = stats.ttest_ind(b, a, equal_var=False)
    assert diff.difference == pytest.approx(np.mean(b) - np.mean(a))
    assert diff.p_value == pytest.approx(want.pvalue) and diff.df == pytest.approx(want.df)
    ci = want.confidence_interval(0.95)
    assert (diff.low, diff.high) == (pytest.approx(ci.low), pytest.approx(ci.high))
    assert diff.exceeds_uncertainty is True
    close = welch_difference([1.0, 1.2, 0.8], [1.05, 0.85, 1.15])
    assert close.exceeds_uncertainty is False and close.low < 0 < close.high
    assert welch_difference([1.0], [1.0, 2.0]) is None  # one ride: no spread, no verdict
    same = welch_difference([1.0, 1.0], [2.0, 2.0])  # no spread at all: the means differ beyond doubt
    assert same.exceeds_uncertainty is True and same.difference == 1.0

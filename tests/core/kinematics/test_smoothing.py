"""Robust LOESS smoothing and gap bridging against known curves."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.core.kinematics.smoothing import bridge_gaps, rloess, span_points

FPS = 30.0


def _curve(t):
    return 0.05 * np.sin(2 * np.pi * 0.2 * t) + 0.02 * t


@pytest.fixture
def noisy():
    rng = np.random.default_rng(0)
    t = np.arange(300) / FPS
    truth = _curve(t)
    return t, truth, truth + rng.normal(0.0, 0.005, t.size)


def test_rloess_error_well_below_noise(noisy):
    t, truth, y = noisy
    smooth = rloess(t, y)
    rms = np.sqrt(np.mean((smooth - truth) ** 2))
    assert rms < 0.5 * 0.005


def test_rloess_reproduces_a_quadratic_exactly():
    t = np.linspace(0.0, 3.0, 91)
    y = 1.0 - 0.4 * t + 0.3 * t**2
    np.testing.assert_allclose(rloess(t, y), y, atol=1e-10)


def test_rloess_rejects_outliers(noisy):
    t, truth, y = noisy
    spoiled = y.copy()
    spoiled[[50, 51, 120, 200]] += 0.2  # spikes 40 noise sigmas high
    robust = rloess(t, spoiled)
    plain = rloess(t, spoiled, iterations=0)
    err_robust = np.max(np.abs(robust - truth))
    err_plain = np.max(np.abs(plain - truth))
    assert err_robust < 0.01
    assert err_plain > 2 * err_robust


def test_rloess_columns_and_nan(noisy):
    t, truth, y = noisy
    stacked = np.column_stack([y, 2 * y])
    stacked[10, 1] = np.nan
    out = rloess(t, stacked)
    assert out.shape == stacked.shape
    assert np.isnan(out[10, 1]) and np.isfinite(out[10, 0])
    np.testing.assert_allclose(out[:, 0], rloess(t, y))


def test_rloess_uneven_sampling_matches_even_fit_for_a_polynomial():
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 4, 200))
    y = 2.0 + t - 0.1 * t**2
    np.testing.assert_allclose(rloess(t, y, span=0.2), y, atol=1e-9)


def test_span_points():
    assert span_points(300, 0.10) == 30
    assert span_points(20, 0.10) == 5  # at least 5 points for a local quadratic
    assert span_points(300, 15) == 15


def test_bad_inputs():
    t = np.arange(10) / FPS
    with pytest.raises(InputError, match="strictly increasing"):
        rloess(t[::-1], np.zeros(10))
    with pytest.raises(InputError, match="samples"):
        rloess(t, np.zeros(11))
    with pytest.raises(InputError, match="finite samples"):
        rloess(t, np.full(10, np.nan))


def test_bridge_gaps_fills_short_and_reports_long(noisy):
    t, truth, y = noisy
    holed = y.copy()
    holed[100:103] = np.nan  # 0.1 s: bridged
    holed[150:190] = np.nan  # 1.33 s: reported
    holed[:2] = np.nan  # at the start: cannot interpolate, reported
    filled, mask, long_gaps = bridge_gaps(t, holed, max_gap_s=0.2)
    assert mask.sum() == 3 and mask[100:103].all()
    assert np.max(np.abs(filled[100:103] - truth[100:103])) < 0.006
    assert np.isnan(filled[150:190]).all() and np.isnan(filled[:2]).all()
    np.testing.assert_array_equal(filled[~np.isnan(holed)], y[~np.isnan(holed)])  # raw data untouched
    assert long_gaps == [(pytest.approx(t[0]), pytest.approx(t[1])),
                         (pytest.approx(t[150]), pytest.approx(t[189]))]


def test_bridge_gaps_cubic_and_columns(noisy):
    t, truth, _ = noisy
    y = np.column_stack([truth, truth + 1.0])
    y[40:44, 0] = np.nan
    y[60, 1] = np.nan
    filled, mask, long_gaps = bridge_gaps(t, y, max_gap_s=0.2, method="cubic")
    assert mask[:, 0].sum() == 4 and mask[:, 1].sum() == 1 and long_gaps == []
    np.testing.assert_allclose(filled, np.column_stack([truth, truth + 1.0]), atol=1e-6)


def test_span_in_seconds_and_robust_edges_stay_bounded():
    rng = np.random.default_rng(3)
    t = np.arange(120) / FPS
    truth = 120.0 * np.cos(2 * np.pi * 1.6 * t) + 1500.0 * t  # a cantering marker, mm
    y = truth + rng.normal(0, 1.0, t.size)
    for span_s in (0.1, 0.2):
        out = rloess(t, y, span_s=span_s)
        # Robust passes may reject the biased samples at a peak near the record's end; the fit
        # must then interpolate or extrapolate linearly, never blow up.
        assert np.max(np.abs(out - truth)) < 40.0
        assert np.sqrt(np.mean((out - truth) ** 2)) < 5.0
    with pytest.raises(InputError, match="span_s"):
        rloess(t, y, span_s=0.0)

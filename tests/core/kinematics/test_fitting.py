"""Linear and Fourier fits (eq. 5.22-5.30) against known series."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.kinematics import count_extrema, fit_fourier, fit_linear, fit_marker_kinematics

PERIOD_S = 0.6
W = 2 * np.pi / PERIOD_S
T = np.arange(0, 2 * PERIOD_S + 1e-9, 1 / 30)  # two periods at 30 fps, as the thesis


def series(t, a0, a, b, w=W):
    k = np.arange(1, len(a) + 1)
    th = np.multiply.outer(t, k * w)
    return a0 + np.cos(th) @ np.asarray(a) + np.sin(th) @ np.asarray(b)


A0, A, B = 0.02, [0.10, -0.04], [0.03, 0.01]


def test_noise_free_recovers_coefficients_and_omega():
    y = series(T, A0, A, B)
    fit = fit_fourier(T, y, period_s=PERIOD_S * 1.02, order=2)  # started 2 % off
    assert fit.omega_rad_s == pytest.approx(W, abs=1e-8)
    np.testing.assert_allclose([fit.a0, *fit.a, *fit.b], [A0, *A, *B], atol=1e-8)
    assert fit.gof.r2 == pytest.approx(1.0) and fit.gof.sse < 1e-20
    assert fit.omega_source == "fitted"


def test_order_from_extrema_rule_and_criterion():
    # Walk-like vertical: 2x stride dominates -> 4 extrema per stride -> orders 2 and 3 tried.
    y = series(T, 0.0, [0.005, 0.02], [0.0, 0.004])
    assert count_extrema(T, y, period_s=PERIOD_S) == 4
    fit = fit_fourier(T, y, period_s=PERIOD_S)
    assert fit.extrema_per_period == 4 and fit.criterion == "aicc"
    assert [c["order"] for c in fit.candidates] == [2, 3]
    assert fit.order == 2  # exact at order 2: the extra harmonic is not worth its parameters


def test_max_order_caps_the_orders_tried():
    y = series(T, 0.0, [0.005, 0.02, 0.003], [0.0, 0.004, 0.002])
    assert fit_fourier(T, y, period_s=PERIOD_S, extra_orders=3).order == 3
    capped = fit_fourier(T, y, period_s=PERIOD_S, extra_orders=3, max_order=2)
    assert capped.order == 2 and [c["order"] for c in capped.candidates] == [2]
    xyz = np.stack([np.stack([4.0 * T, y, 0.27 + 0 * T], axis=1)] * 3, axis=1) + np.array([0.0, 0.0, 0.1])[:, None]
    kin = fit_marker_kinematics(T, xyz, period_s=PERIOD_S, extra_orders=3, max_order=2, x_model="fourier")
    assert all(f.order <= 2 for f in (*kin.fits_y, *kin.fits_z))
    with pytest.raises(InputError, match="max_order"):
        fit_fourier(T, y, period_s=PERIOD_S, max_order=0)


def test_count_extrema_ignores_noise_wiggles():
    rng = np.random.default_rng(5)
    t = np.arange(0, 2.4, 1 / 30)
    y = series(t, 0.0, [0.1], [0.0]) + rng.normal(0, 0.004, t.size)
    assert count_extrema(t, y, period_s=PERIOD_S) == 2


def test_confidence_intervals_cover_the_truth():
    rng = np.random.default_rng(6)
    truth = np.array([A0, *A, *B, W])
    inside = []
    for _ in range(150):
        y = series(T, A0, A, B) + rng.normal(0, 0.005, T.size)
        fit = fit_fourier(T, y, period_s=PERIOD_S, order=2)
        ci = fit.ci
        lo = np.concatenate([[ci["a0"][0]], ci["a"][:, 0], ci["b"][:, 0], [ci["omega_rad_s"][0]]])
        hi = np.concatenate([[ci["a0"][1]], ci["a"][:, 1], ci["b"][:, 1], [ci["omega_rad_s"][1]]])
        inside.append((lo <= truth) & (truth <= hi))
    coverage = np.mean(inside, axis=0)
    assert np.all(coverage > 0.88) and np.all(coverage <= 1.0)
    assert np.mean(coverage) == pytest.approx(0.95, abs=0.03)


def ar1_noise(rng, n, rho, sd):
    """First-order autoregressive noise of standard deviation sd and lag-1 autocorrelation rho."""
    e = rng.normal(0.0, sd, n)
    for i in range(1, n):
        e[i] = rho * e[i - 1] + np.sqrt(1 - rho**2) * e[i]
    return e


def test_confidence_intervals_cover_the_truth_when_the_noise_is_correlated():
    """Tracked markers' noise is correlated over frames: the textbook intervals (white residuals)
    cover 95 % intervals about 75 % of the time there; the fits' own take the correlation in."""
    rng = np.random.default_rng(8)
    t = np.arange(0, 4 * PERIOD_S + 1e-9, 1 / 60)  # four strides at 60 fps (t0 = two periods)
    truth = np.array([A0, *A, *B])
    inside, inside_textbook, lag1 = [], [], []
    for _ in range(200):
        y = series(t, A0, A, B) + ar1_noise(rng, t.size, 0.5, 0.005)
        fit = fit_fourier(t, y, period_s=PERIOD_S, order=2, fit_omega=False)
        coef = np.array([fit.a0, *fit.a, *fit.b])
        half = np.concatenate([[np.diff(fit.ci["a0"])[0]], np.diff(fit.ci["a"])[:, 0],
                               np.diff(fit.ci["b"])[:, 0]]) / 2
        inside.append(np.abs(coef - truth) <= half)
        # the same fit's intervals as MATLAB computes them
        design = np.column_stack([np.ones_like(t), np.cos(np.outer(t - fit.t0, [W, 2 * W])),
                                  np.sin(np.outer(t - fit.t0, [W, 2 * W]))])
        cov = fit.gof.sse / fit.gof.dfe * np.linalg.inv(design.T @ design)
        inside_textbook.append(np.abs(coef - truth) <= 1.98 * np.sqrt(np.diag(cov)))
        lag1.append(fit.gof.noise_lag1)
    assert np.mean(inside) == pytest.approx(0.95, abs=0.03) and np.all(np.mean(inside, axis=0) > 0.88)
    assert np.mean(inside_textbook) < 0.85
    assert np.mean(lag1) == pytest.approx(0.5, abs=0.05)


@pytest.mark.slow
def test_correlated_noise_does_not_pass_for_a_harmonic():
    """A walk's vertical (second harmonic) with noise correlated over frames: the textbook AICc
    takes a third harmonic made of noise about a third of the time, the default one seldom more
    than with white noise (where both keep it about one time in eight)."""
    t = np.arange(0, 4 * PERIOD_S + 1e-9, 1 / 60)
    clean = series(t, 0.0, [0.005, 0.02], [0.0, 0.004])
    too_high: dict[tuple[str, float], int] = {}
    for rho in (0.0, 0.5):
        rng = np.random.default_rng(9)
        noises = [ar1_noise(rng, t.size, rho, 0.001) for _ in range(200)]
        for criterion in ("aicc", "aicc_white"):
            too_high[criterion, rho] = sum(fit_fourier(t, clean + e, period_s=PERIOD_S, criterion=criterion).order > 2
                                           for e in noises)
    assert too_high["aicc_white", 0.5] > 60
    assert too_high["aicc", 0.5] < 45
    assert abs(too_high["aicc", 0.0] - too_high["aicc_white", 0.0]) <= 10


def test_derivatives_and_harmonics_are_analytic():
    y = series(T, A0, A, B)
    fit = fit_fourier(T, y, period_s=PERIOD_S, order=2)
    t = np.linspace(-1.0, 3.0, 101)
    k = np.array([1, 2])
    th = np.multiply.outer(t, k * W)
    vel = (-np.sin(th) * (k * W)) @ A + (np.cos(th) * (k * W)) @ B
    acc = (-np.cos(th) * (k * W) ** 2) @ A + (-np.sin(th) * (k * W) ** 2) @ B
    np.testing.assert_allclose(fit.evaluate(t, 1), vel, atol=1e-7)
    np.testing.assert_allclose(fit.evaluate(t, 2), acc, atol=1e-6)
    for d in (0, 1, 2):
        f0, amp, ph = fit.harmonics(d)
        rebuilt = sum(amp[i] * np.cos(2 * np.pi * (i + 1) * f0 * t + ph[i]) for i in range(amp.size))
        np.testing.assert_allclose(rebuilt + (fit.a0 if d == 0 else 0.0), fit.evaluate(t, d), atol=1e-8)
    assert fit.harmonics(0)[1] == pytest.approx(np.hypot(A, B), abs=1e-9)


def test_linear_fit_speed_and_interval():
    rng = np.random.default_rng(7)
    x = 1.0 + 4.9 * T + 0.01 * np.sin(W * T) + rng.normal(0, 0.002, T.size)
    fit = fit_linear(T, x)
    assert fit.slope == pytest.approx(4.9, abs=0.02)
    assert fit.ci[1, 0] < fit.slope < fit.ci[1, 1]
    assert np.all(fit.evaluate(T, 1) == fit.slope) and np.all(fit.evaluate(T, 2) == 0.0)
    assert 0.99 < fit.gof.r2 <= 1.0 and fit.gof.n_params == 2 and fit.residuals.shape == T.shape


def test_marker_kinematics_share_one_fundamental():
    rng = np.random.default_rng(8)
    xyz = np.empty((T.size, 3, 3))
    for m in range(3):
        xyz[:, m, 0] = 4.9 * T + 0.25 * m
        xyz[:, m, 1] = series(T, 0.1 * m, [0.12, 0.03 * m], [0.02, 0.01])
        xyz[:, m, 2] = series(T, 0.3, [0.01, 0.0], [0.02 + 0.005 * m, 0.0])
    noisy = xyz + rng.normal(0, 0.001, xyz.shape)
    kin = fit_marker_kinematics(T, noisy, period_s=PERIOD_S * 0.98)
    assert kin.omega_rad_s == pytest.approx(W, rel=2e-3)
    fits = kin.fits_y + kin.fits_z
    assert all(f.omega_rad_s == kin.omega_rad_s and f.omega_source == "pooled" for f in fits)
    assert kin.average_speed_m_s == pytest.approx(4.9, abs=0.01)
    true_vy = -0.12 * W * np.sin(W * T) + 0.02 * W * np.cos(W * T) + 2 * W * 0.01 * np.cos(2 * W * T)
    assert np.max(np.abs(kin.velocity_m_s[:, 0, 1] - true_vy)) < 0.05
    assert kin.acceleration_m_s2.shape == (T.size, 3, 3)
    noise_free = fit_marker_kinematics(T, xyz, period_s=PERIOD_S * 0.98)
    assert noise_free.omega_rad_s == pytest.approx(W, abs=1e-8)
    np.testing.assert_allclose(noise_free.velocity_m_s[:, 0, 1], true_vy, atol=1e-7)


def test_the_fundamental_comes_from_the_vertical_series_not_from_a_drifting_depth():
    # A narrow rig's depth leaks slow, non-periodic errors into x and z: a free w there drifts off
    # with a standard error too small to down-weight it (a thesis-rig canter read w 2.8 % off in x,
    # pulling the pooled stride 0.44 % off and doubling its vertical acceleration error).
    rng = np.random.default_rng(9)
    xyz = np.empty((T.size, 3, 3))
    tau = (T - T.mean()) / np.ptp(T)
    for m in range(3):
        xyz[:, m, 0] = 4.9 * T + 0.02 * np.sin(W * T) + 0.03 * tau**3 + 0.01 * np.sin(1.4 * W * T)
        xyz[:, m, 1] = series(T, 0.1 * m, [0.05, 0.02], [0.01, 0.004])
        xyz[:, m, 2] = series(T, 0.3, [0.004, 0.0], [0.003, 0.0]) + 0.02 * np.sin(1.15 * W * T + m)
    noisy = xyz + rng.normal(0, 0.0005, xyz.shape)
    vertical = fit_marker_kinematics(T, noisy, period_s=PERIOD_S, x_model="fourier")
    every = fit_marker_kinematics(T, noisy, period_s=PERIOD_S, x_model="fourier", omega_from="all")
    assert abs(vertical.omega_rad_s / W - 1) < 1e-3
    assert abs(every.omega_rad_s / W - 1) > 3 * abs(vertical.omega_rad_s / W - 1)  # the old pooling drifted
    with pytest.raises(InputError, match="omega_from"):
        fit_marker_kinematics(T, noisy, period_s=PERIOD_S, omega_from="x")


def test_bad_inputs():
    with pytest.raises(KinematicsError, match="too few"):
        fit_fourier(T[:5], series(T[:5], A0, A, B), period_s=PERIOD_S, order=2)
    with pytest.raises(InputError, match="criterion"):
        fit_fourier(T, series(T, A0, A, B), period_s=PERIOD_S, criterion="r2")
    with pytest.raises(InputError, match="derivative"):
        fit_fourier(T, series(T, A0, A, B), period_s=PERIOD_S, order=2).evaluate(T, 3)


def test_trend_and_fourier_x_model():
    # A drifting series: the pure series cannot follow it, the trend term can.
    y = series(T, A0, A, B) + 0.05 * (T - T.mean()) + 0.3 * (T - T.mean()) ** 2
    fit = fit_fourier(T, y, period_s=PERIOD_S, order=2, trend_degree=2)
    np.testing.assert_allclose(fit.trend, [0.05, 0.3], atol=1e-8)
    assert fit.omega_rad_s == pytest.approx(W, abs=1e-8)
    assert fit.evaluate(T, 2) == pytest.approx(series(T, 0.0, -(np.array(A) * [W**2, 4 * W**2]),
                                                      -(np.array(B) * [W**2, 4 * W**2])) + 0.6, abs=1e-6)
    # Surge: x = travel + a periodic speed variation, kept by the "fourier" x model.
    xyz = np.zeros((T.size, 3, 3))
    for m in range(3):
        xyz[:, m, 0] = 4.9 * T + 0.02 * np.sin(W * T) + 0.25 * m
        xyz[:, m, 1] = series(T, 0.0, [0.12, 0.02], [0.0, 0.01])
        xyz[:, m, 2] = series(T, 0.0, [0.01], [0.02])
    kin = fit_marker_kinematics(T, xyz, period_s=PERIOD_S, x_model="fourier")
    assert kin.average_speed_m_s == pytest.approx(4.9, abs=1e-8)
    np.testing.assert_allclose(kin.acceleration_m_s2[:, 0, 0], -0.02 * W**2 * np.sin(W * T), atol=1e-6)
    linear = fit_marker_kinematics(T, xyz, period_s=PERIOD_S)
    assert np.all(linear.acceleration_m_s2[:, :, 0] == 0.0)  # the thesis's straight line


@pytest.mark.slow
def test_the_markers_share_the_order_their_centroid_needs():
    """A canter's fourth harmonic is under a millimetre yet weighs in the acceleration (k² = 16):
    each marker's series drops it in its own noise, the markers' centroid (noise averaged over three)
    keeps it, and the markers take the centroid's order."""
    period = 0.6
    w = 2 * np.pi / period
    t = np.arange(0, 1.25, 1 / 30)  # two strides and a little, as a fast canter across the thesis view
    k = np.arange(1, 5)
    amps, phases = np.array([0.09, 0.009, 0.0024, 0.0006]), np.array([0.3, 1.1, -0.7, 2.0])
    y = np.cos(np.outer(t, k * w) + phases) @ amps
    acc = -np.cos(np.outer(t, k * w) + phases) @ (amps * (k * w) ** 2)
    errors: dict[bool, list[float]] = {True: [], False: []}
    full_order: dict[bool, int] = {True: 0, False: 0}
    for seed in range(20):
        xyz = np.zeros((t.size, 3, 3))
        xyz[:, :, 0] = 4.0 * t[:, None] + np.array([0.0, -0.2, -0.4])
        xyz[:, :, 1] = y[:, None] + np.array([0.0, 0.04, 0.0])
        xyz[:, :, 2] = 0.27
        xyz += np.random.default_rng(seed).normal(0.0, 0.0012, xyz.shape)
        for shared in (True, False):
            kin = fit_marker_kinematics(t, xyz, period_s=period, extra_orders=3, x_model="fourier", trend_degree=1,
                                        shared_order=shared)
            a = kin.acceleration_m_s2[:, :, 1].mean(axis=1)
            errors[shared].append(float(np.sqrt(np.mean((a - acc) ** 2) / np.mean(acc ** 2))))
            full_order[shared] += all(f.order >= 4 for f in kin.fits_y)
    assert full_order[True] > full_order[False] + 5
    assert np.mean(errors[True]) < 0.8 * np.mean(errors[False])


def test_the_fundamental_is_pooled_from_the_rule_order_vertical_fits():
    """Harmonics up to the frame rate refit the vertical series at higher orders, whose free ω trade with the
    small high harmonics: the pooled fundamental comes from the extrema rule's orders, as without them (issue 38;
    a partial-view canter's stride frequency went from 0.77 % to 1.38 % off when pooled from the higher ones)."""
    rng = np.random.default_rng(3)
    y = series(T, 0.0, [0.01, 0.02, 0.004, 0.002, 0.001, 0.002], [0.002, 0.004, 0.002, 0.001, 0.001, 0.0015])
    xyz = np.stack([np.stack([4.0 * T, y + rng.normal(0, 3e-4, T.size), 0.27 + rng.normal(0, 3e-4, T.size)], axis=1)
                    for _ in range(3)], axis=1) + np.array([0.0, 0.1, 0.2])[:, None]
    high = fit_marker_kinematics(T, xyz, period_s=PERIOD_S * 1.01, up_to_frame_rate=True)
    rule = fit_marker_kinematics(T, xyz, period_s=PERIOD_S * 1.01, up_to_frame_rate=False)
    assert min(f.order for f in high.fits_y) > max(f.order for f in rule.fits_y)  # the higher orders were fitted
    assert high.omega_rad_s == pytest.approx(rule.omega_rad_s, rel=1e-12)
    # and every series, the higher-order ones too, is refitted with that fundamental
    assert all(f.omega_rad_s == pytest.approx(high.omega_rad_s) and f.omega_source == "pooled" for f in high.fits_y)

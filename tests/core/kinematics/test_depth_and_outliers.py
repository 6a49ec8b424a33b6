"""Narrow-rig depth regularisation and wild samples in the fits."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.core.kinematics.fitting import fit_marker_kinematics
from saddlescope.core.kinematics.smoothing import regularize_depth

PERIOD_S = 0.6
T = np.arange(0, 2 * PERIOD_S + 1e-9, 1 / 30)


def _path(t: np.ndarray, *, sway_mm: float = 0.0) -> np.ndarray:
    """Three markers crossing the view 7.5 m away, bobbing 50 mm and swaying in depth."""
    w = 2 * np.pi / PERIOD_S
    base = np.stack([-1500 + 3800 * t, 50 * np.cos(w * t), 7500 + 300 * t + sway_mm * np.sin(w * t)], axis=1)
    return base[:, None, :] + np.array([[0, 0, 0], [220, 40, 10], [440, -10, 5]])[None]


def test_depth_noise_removed_along_the_rays():
    rng = np.random.default_rng(0)
    truth = _path(T)
    origin = np.array([230.0, 0.0, 0.0])
    # noise along each point's ray from the cameras: the image positions stay exact
    rel = truth - origin
    noisy = origin + rel * (1 + rng.normal(0, 20.0, rel.shape[:2]) / rel[..., 2])[..., None]
    out, orders = regularize_depth(T, noisy, origin, np.array([0.0, 0.0, 1.0]), period_s=PERIOD_S, max_order=0)
    assert orders == [0, 0, 0]
    err_before = np.sqrt(np.mean((noisy - truth) ** 2, axis=(0, 1)))
    err_after = np.sqrt(np.mean((out - truth) ** 2, axis=(0, 1)))
    assert err_after[2] < 0.3 * err_before[2]
    assert err_after[0] < 0.5 * err_before[0]  # the depth noise had leaked into x = depth * ray
    # directions from the origin are unchanged
    d_in = rel / np.linalg.norm(rel, axis=2, keepdims=True)
    d_out = (out - origin) / np.linalg.norm(out - origin, axis=2, keepdims=True)
    np.testing.assert_allclose(d_in, d_out, atol=1e-12)
    # noise-free straight crossing comes back exactly
    exact, _ = regularize_depth(T, truth, origin, np.array([0.0, 0.0, 1.0]), period_s=PERIOD_S, max_order=0)
    np.testing.assert_allclose(exact, truth, atol=1e-9)


def test_bic_keeps_the_sway_a_precise_rig_sees():
    rng = np.random.default_rng(1)
    truth = _path(T, sway_mm=15.0)
    origin = np.zeros(3)
    noisy = truth * (1 + rng.normal(0, 0.5, truth.shape[:2]) / truth[..., 2])[..., None]
    out, orders = regularize_depth(T, noisy, origin, np.array([0.0, 0.0, 1.0]), period_s=PERIOD_S, max_order=4)
    assert all(o >= 1 for o in orders)
    assert np.sqrt(np.mean((out[..., 2] - truth[..., 2]) ** 2)) < 0.5


def test_regularize_depth_rejects_bad_input():
    with pytest.raises(InputError, match="finite"):
        bad = _path(T)
        bad[3, 1, 2] = np.nan
        regularize_depth(T, bad, np.zeros(3), np.array([0.0, 0.0, 1.0]), period_s=PERIOD_S)
    with pytest.raises(InputError, match="shape"):
        regularize_depth(T, _path(T)[:, 0], np.zeros(3), np.array([0.0, 0.0, 1.0]), period_s=PERIOD_S)


def test_a_wild_sample_is_left_out_of_the_fits():
    w = 2 * np.pi / PERIOD_S
    xyz = np.zeros((T.size, 1, 3))
    xyz[:, 0, 0] = 3.8 * T + 0.02 * np.sin(w * T)
    xyz[:, 0, 1] = 0.05 * np.cos(w * T) + 0.01 * np.sin(2 * w * T)
    xyz[:, 0, 2] = 0.01 * np.cos(w * T)
    clean = fit_marker_kinematics(T, xyz, period_s=PERIOD_S, x_model="fourier")
    assert "fit.wild_samples" not in [f.code for f in clean.flags]
    wild = xyz.copy()
    wild[17, 0, 1] += 0.08  # a glint taken for the marker
    kept = fit_marker_kinematics(T, wild, period_s=PERIOD_S, x_model="fourier", reject_sigma=None)
    fixed = fit_marker_kinematics(T, wild, period_s=PERIOD_S, x_model="fourier")
    assert [f.values["samples"] for f in fixed.flags if f.code == "fit.wild_samples"] == [1]
    exact_acc = -(w**2) * 0.05 * np.cos(w * T) - (2 * w) ** 2 * 0.01 * np.sin(2 * w * T)
    err_kept = np.sqrt(np.mean((kept.acceleration_m_s2[:, 0, 1] - exact_acc) ** 2))
    err_fixed = np.sqrt(np.mean((fixed.acceleration_m_s2[:, 0, 1] - exact_acc) ** 2))
    assert err_fixed < 1e-6 < 0.1 * err_kept
    assert np.isfinite(fixed.acceleration_m_s2).all()


def test_a_few_frames_of_look_alike_do_not_hide_the_stride():
    from saddlescope.core.kinematics.period import estimate_period
    from saddlescope.core.saddle import _despiked

    t = np.arange(0, 3.0, 1 / 60)
    xyz = _path(t)
    # trot: two bounces per 0.71 s stride, one a little higher
    xyz[:, :, 1] = np.array([0.0, 40.0, -10.0]) + (40 * np.sin(2 * np.pi * 2.8 * t)
                                                    + 10 * np.sin(2 * np.pi * 1.4 * t))[:, None]
    period_clean, _ = estimate_period(t, _despiked(xyz, 1 / 60), f_range_hz=(1.0, 1.9))
    assert period_clean == pytest.approx(2 / 2.8, rel=0.02)
    spiked = xyz.copy()
    spiked[5:9, 0, 0] += 850.0  # a look-alike for four frames
    with pytest.raises(Exception, match="no periodic motion"):
        estimate_period(t, spiked, f_range_hz=(1.0, 1.9))
    period, _ = estimate_period(t, _despiked(spiked, 1 / 60), f_range_hz=(1.0, 1.9))
    assert period == pytest.approx(2 / 2.8, rel=0.02)

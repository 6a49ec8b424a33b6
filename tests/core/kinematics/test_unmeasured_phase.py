"""The stride phase no fitted frame measured (issue 38), and the Fourier orders up to what the frame rate resolves."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.findings import Finding
from saddlescope.core.kinematics import fit_fourier, resolvable_order
from saddlescope.core.kinematics.hidden_phase import phase_coverage, unmeasured_phase

FPS, PERIOD_S = 30.0, 1 / 1.65


def _markers(t: np.ndarray) -> np.ndarray:
    """Three markers travelling in +x, front to rear: x 0.4, 0.2, 0.0 m."""
    xyz = np.zeros((t.size, 3, 3))
    xyz[:, :, 0] = 4.0 * t[:, None] + np.array([0.4, 0.2, 0.0])
    return xyz


def test_a_wholly_measured_stride_covers_the_phase_and_a_short_one_does_not():
    t = np.arange(0, 2 * PERIOD_S, 1 / FPS)
    assert phase_coverage(t, np.ones(t.size, bool), PERIOD_S) == 1.0
    half = t < 0.5 * PERIOD_S
    assert phase_coverage(t[half], np.ones(half.sum(), bool), PERIOD_S) == pytest.approx(0.5, abs=0.1)


def test_a_marker_hidden_at_the_same_moment_of_every_stride_is_named_and_marks_the_ride():
    t = np.arange(0, 3 * PERIOD_S, 1 / FPS)
    phase = (t / PERIOD_S) % 1.0
    measured = np.ones((t.size, 3), bool)
    measured[:, 2] = ~((phase > 0.38) & (phase < 0.6))  # the rear marker, a fifth of every stride
    flags: list[Finding] = []
    out = unmeasured_phase(t, measured, _markers(t), PERIOD_S, flags)
    assert out["share"] == pytest.approx(0.2, abs=0.07)
    assert out["per_marker"]["rear"] == pytest.approx(out["share"]) and out["per_marker"]["front"] == 0.0
    (flag,) = flags
    assert flag.code == "kinematics.stride_phase_unmeasured"
    # a sixth or a fifth: the phase is judged in bins of one frame interval
    assert flag.detail.startswith(("the rear marker was hidden for a fifth of every stride",
                                   "the rear marker was hidden for a sixth of every stride"))
    assert "rider's leg" in flag.detail


def test_gaps_at_different_moments_of_each_stride_leave_no_phase_unmeasured():
    t = np.arange(0, 3 * PERIOD_S, 1 / FPS)
    measured = np.ones((t.size, 3), bool)
    measured[3:6, 2] = False  # one stride's gap only: the other strides measure that phase
    flags: list[Finding] = []
    assert unmeasured_phase(t, measured, _markers(t), PERIOD_S, flags)["share"] == 0.0
    assert not flags


def test_the_orders_tried_reach_a_sixth_harmonic_the_frame_rate_resolves():
    rng = np.random.default_rng(1)
    f0 = 1.4
    t = np.arange(0, 2 / f0, 1 / FPS)
    w = 2 * np.pi * f0
    y = (0.05 * np.cos(2 * w * t) + 0.002 * np.cos(w * t + 1) + 0.002 * np.cos(3 * w * t)
         + 0.0015 * np.cos(4 * w * t + 0.3) + 0.0006 * np.cos(6 * w * t + 2) + rng.normal(0, 0.0003, t.size))
    cut = fit_fourier(t, y, period_s=1 / f0, extra_orders=3, trend_degree=1)
    full = fit_fourier(t, y, period_s=1 / f0, extra_orders=3, trend_degree=1, up_to_frame_rate=True)
    assert cut.order == 4  # the extrema rule's range (2-5) stops short of it
    assert full.order >= 6
    assert np.hypot(full.a[5], full.b[5]) == pytest.approx(0.0006, rel=0.3)
    assert resolvable_order(t, 1 / f0) == 8  # 0.8 of 15 Hz over 1.4 Hz


def test_a_series_without_high_harmonics_keeps_its_order():
    rng = np.random.default_rng(2)
    f0 = 1.4
    t = np.arange(0, 2 / f0, 1 / FPS)
    y = 0.05 * np.cos(2 * 2 * np.pi * f0 * t) + rng.normal(0, 0.0003, t.size)
    assert fit_fourier(t, y, period_s=1 / f0, trend_degree=1, up_to_frame_rate=True).order <= 3

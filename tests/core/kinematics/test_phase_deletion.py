"""The phase-deletion test (issue 38): what a stride phase nobody measured costs this ride's indicators.

Fast: a saddle's vertical motion sampled at 30 fps with a fifth of every stride hidden, refitted by a plain
least-squares Fourier series (the analysis's own refit is core.saddle's; here only the test's logic).
"""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.kinematics.hidden_phase import (
    DELETION_KEYS,
    deletion_masks,
    harmonic_indicators,
    phase_deletion_test,
    unmeasured_phase,
)
from saddlescope.core.vibration.intervals import FLOORS, MAX_HALF_WIDTH_FRACTION

FPS, F0_HZ, ORDER = 30.0, 1.45, 4  # a trot's stride
AMPS_M = np.array([0.004, 0.03, 0.003, 0.002])  # the saddle's vertical displacement per harmonic
PHASES = np.array([0.3, -1.0, 2.0, 0.7])


def _position(t: np.ndarray) -> np.ndarray:
    k = np.arange(1, AMPS_M.size + 1)
    return np.sum(AMPS_M * np.cos(2 * np.pi * F0_HZ * np.outer(t, k) + PHASES), axis=1)


def _harmonics(t: np.ndarray, y: np.ndarray) -> dict:
    """Least-squares Fourier series of the displacement, its acceleration's amplitudes and phases."""
    w = 2 * np.pi * F0_HZ
    cols = [np.ones_like(t)] + [f(k * w * t) for k in range(1, ORDER + 1) for f in (np.cos, np.sin)]
    coef, *_ = np.linalg.lstsq(np.stack(cols, axis=1), y, rcond=None)
    a, b = coef[1::2], coef[2::2]
    k = np.arange(1, ORDER + 1)
    amp = np.hypot(a, b)
    dense = np.linspace(0, 1 / F0_HZ, 512, endpoint=False)
    y_dense = np.sum(amp * np.cos(w * np.outer(dense, k) + np.arctan2(-b, a)), axis=1)
    return {"f0_hz": F0_HZ, "amplitudes_m_s2": amp * (k * w) ** 2, "phases_rad": np.arctan2(-b, a) + np.pi,
            "amplitude_y_m": float(np.ptp(y_dense))}


def _ride(strides: float, hidden: tuple[float, float] = (0.36, 0.57), noise_m: float = 0.0002, seed: int = 1):
    """Times, the saddle's measured displacement and the frames where every marker was measured."""
    t = np.arange(0, strides / F0_HZ, 1 / FPS)
    phase = (t * F0_HZ) % 1.0
    seen = ~((phase >= hidden[0]) & (phase < hidden[1]))
    y = _position(t) + np.random.default_rng(seed).normal(0, noise_m, t.size)
    return t, y, seen


def _refit(t, y, seen):
    return lambda deleted: _harmonics(t[seen & ~deleted], y[seen & ~deleted])


def test_the_windows_are_as_wide_as_the_gap_and_lie_in_the_measured_part():
    t, _, seen = _ride(3.0)
    masks, reason = deletion_masks(t, seen, 1 / F0_HZ)
    assert reason == "" and len(masks) == 6
    for mask in masks:  # as much of the measured stride left out as the gap hides, outside the gap
        assert (mask & seen).sum() == pytest.approx((~seen).sum(), abs=3)
        assert (mask & ~seen).sum() <= 3
    assert deletion_masks(t, np.ones(t.size, bool), 1 / F0_HZ) == ([], "")


def test_a_smooth_stride_with_a_hidden_fifth_costs_little_where_the_fixed_cost_marked_it():
    # the field table's trots: a fifth of the stride hidden moved W_b by at most 4.7 %, while the share's
    # fixed cost (0.5 x share, ±20 %) marked them too uncertain
    t, y, seen = _ride(3.0)
    base = _harmonics(t[seen], y[seen])
    test = phase_deletion_test(t, seen, 1 / F0_HZ, _refit(t, y, seen), base)
    assert test.tested and set(test.changes) == set(DELETION_KEYS)
    truth = harmonic_indicators(_harmonics(t, _position(t)))
    error = abs(harmonic_indicators(base)["acc_y_wb_rms"] / truth["acc_y_wb_rms"] - 1)
    half_width = 1.96 * FLOORS["unmeasured_phase_deletion"] * test.median_change
    assert half_width < MAX_HALF_WIDTH_FRACTION / 2  # not marked for the boot
    assert 1.96 * FLOORS["unmeasured_phase"] * 0.2 > MAX_HALF_WIDTH_FRACTION  # the fixed cost marked it
    assert error < 2 * max(half_width, 0.01)


def test_a_gap_the_fits_cannot_bridge_costs_a_lot():
    # noisy samples of a high-order motion over two strides: leaving more out swings the refit
    t, y, seen = _ride(2.0, hidden=(0.3, 0.55), noise_m=0.006, seed=3)
    test = phase_deletion_test(t, seen, 1 / F0_HZ, _refit(t, y, seen), _harmonics(t[seen], y[seen]))
    assert test.tested
    assert 1.96 * FLOORS["unmeasured_phase_deletion"] * test.median_change > MAX_HALF_WIDTH_FRACTION


def test_too_few_strides_or_a_failing_refit_leave_the_test_undone():
    t, y, seen = _ride(1.1)
    test = phase_deletion_test(t, seen, 1 / F0_HZ, _refit(t, y, seen), _harmonics(t[seen], y[seen]))
    assert not test.tested and "1.1 strides" in test.reason
    assert test.as_quality()["median_change"] is None

    def broken(deleted):
        raise KinematicsError("the fit is singular")

    t, y, seen = _ride(3.0)
    test = phase_deletion_test(t, seen, 1 / F0_HZ, broken, _harmonics(t[seen], y[seen]))
    assert not test.tested and "could not be redone" in test.reason


def _markers(t: np.ndarray) -> np.ndarray:
    xyz = np.zeros((t.size, 3, 3))
    xyz[:, :, 0] = 4.0 * t[:, None] + np.array([0.4, 0.2, 0.0])
    return xyz


@pytest.mark.parametrize(("strides", "code"), [(3.0, "kinematics.stride_phase_unmeasured"),
                                                (1.1, "kinematics.stride_phase_untested")])
def test_the_finding_names_the_marker_and_says_what_the_test_found(strides, code):
    t, y, seen = _ride(strides)
    measured = np.ones((t.size, 3), bool)
    measured[:, 2] = seen  # the rear marker
    flags: list[Finding] = []
    out = unmeasured_phase(t, measured, _markers(t), 1 / F0_HZ, flags, refit=_refit(t, y, seen),
                           base=_harmonics(t[seen], y[seen]))
    (flag,) = flags
    assert flag.code == code
    # a sixth or a fifth: the phase is judged in bins of one frame interval
    assert flag.detail.startswith(("the rear marker was hidden for a fifth of every stride",
                                   "the rear marker was hidden for a sixth of every stride"))
    assert "rider's leg" in flag.detail
    assert out["deletion"]["tested"] == (code == "kinematics.stride_phase_unmeasured")
    if out["deletion"]["tested"]:
        assert flag.severity == "check" and "moved the indicators by" in flag.detail
    else:
        assert flag.severity == "problem" and "too uncertain" in flag.detail


def test_a_wholly_measured_stride_runs_no_refit_and_keeps_its_numbers():
    # rides without a hidden phase give exactly the numbers they gave before the test existed
    t, y, _ = _ride(3.0)

    def refit(deleted):
        raise AssertionError("no refit where every phase was measured")

    flags: list[Finding] = []
    out = unmeasured_phase(t, np.ones((t.size, 3), bool), _markers(t), 1 / F0_HZ, flags, refit=refit,
                           base=_harmonics(t, y))
    assert out["share"] == 0.0 and "deletion" not in out and not flags

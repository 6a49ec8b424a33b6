"""Recordings aligned in time and space before their shape is compared (core.similarity.recordings)."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.core.similarity import (
    align_recordings,
    align_signatures,
    recording_signature,
    remove_progression,
    stretch_differences,
)

RATE = 100.0


def _turn(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q * np.sign(np.linalg.det(q))


def _walker(t_s: np.ndarray, *, f_hz: float = 1.1, shape: float = 0.0, speed_mm_s: float = 1400.0) -> np.ndarray:
    """Four markers (N, 4, 3) mm of a periodic motion with travel along x; ``shape`` changes the loops."""
    p = 2 * np.pi * f_hz * t_s
    out = []
    for m, (x0, z0) in enumerate([(0, 0), (0, 250), (-100, 120), (300, 60)]):
        loop = np.column_stack([40 * np.cos(p + m) + 10 * np.cos(2 * p),
                                25 * np.sin(2 * p + 0.3 * m) + shape * np.sin(3 * p),
                                15 * np.sin(p + 0.5 * m)])
        out.append(loop + np.column_stack([x0 + speed_mm_s * t_s, np.full_like(t_s, 900.0), np.full_like(t_s, z0)]))
    return np.stack(out, axis=1)


def _smooth_path(n: int, seed: int) -> np.ndarray:
    """A non-periodic motion (n, 3, 3) mm: smoothed random walks."""
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, 3.0, (n + 60, 3, 3))
    kernel = np.hanning(31)[:, None, None] / np.hanning(31).sum()
    walk = np.cumsum(steps, axis=0)
    smooth = np.stack([np.convolve(walk[:, m, k], kernel[:, 0, 0], mode="valid")
                       for m in range(3) for k in range(3)], axis=1)
    return smooth[:n].reshape(n, 3, 3) * 10


def test_progression_is_removed_and_commutes_with_a_rigid_motion():
    t = np.arange(400) / RATE
    x = _walker(t)
    still = remove_progression(x)
    assert abs(np.polyfit(t, still.mean(axis=1)[:, 0], 1)[0]) < 1e-6  # no travel left
    turn = _turn(1)
    moved = remove_progression(x @ turn.T + [500.0, -20.0, 3.0])
    np.testing.assert_allclose(moved, still @ turn.T, atol=1e-6)


def test_periodic_recordings_are_compared_in_cycle_phase_whatever_start_length_frame_and_pace():
    a = _walker(np.arange(330) / RATE)  # 3.6 cycles
    t_b = 0.37 + np.arange(480) / RATE * 1.04  # another start, 5.5 cycles, 4 % faster
    b = _walker(t_b, f_hz=1.1) @ _turn(2).T + [1500.0, 80.0, -700.0]
    al = align_recordings(a, RATE, b, RATE)
    assert al.alignment == "cycle_phase" and al.closed
    assert al.cycles == (3, 5)
    assert al.period_s[0] == pytest.approx(1 / 1.1, rel=0.02)
    assert al.period_s[1] == pytest.approx(1 / 1.1 / 1.04, rel=0.02)
    assert np.sqrt(np.mean((al.a - al.b) ** 2)) < 1.5  # mm, against loops of tens of mm
    # B starts 0.37 s (0.407 cycles) later: its cycle is read from 0.593 of it on
    off_cycle = (al.phase_shift - (1.0 - 0.37 * 1.1) + 0.5) % 1.0 - 0.5
    assert abs(off_cycle) < 0.02


def test_a_cropped_periodic_copy_is_cut_in_the_others_cycles():
    a = _walker(np.arange(330) / RATE)
    crop = a[30:180]  # 1.65 cycles: too short to find its own period
    sig_crop = recording_signature(crop, RATE)
    assert sig_crop.period is None
    al = align_signatures(recording_signature(a, RATE), sig_crop)
    assert al.alignment == "cycle_phase" and al.cycles[1] == 1
    assert np.sqrt(np.mean((al.a - al.b) ** 2)) < 1.5


def test_non_periodic_recordings_find_a_cropped_match_by_subsequence_dtw():
    long = _smooth_path(400, 3)
    crop = long[120:300] @ _turn(4).T + [10.0, 20.0, 30.0]
    al = align_recordings(long, RATE, crop, RATE)
    assert al.alignment == "subsequence_dtw" and not al.closed
    assert al.span_a_s == pytest.approx((1.2, 2.99), abs=0.03)
    assert al.span_b_s == pytest.approx((0.0, 1.79), abs=1e-9)
    assert al.rotation_residual_mm < 0.5
    # and the other way round: the crop is always the one searched in the longer
    back = align_recordings(crop, RATE, long, RATE)
    assert back.span_b_s == pytest.approx((1.2, 2.99), abs=0.03)


def test_forced_alignment_and_bad_input():
    a = _walker(np.arange(330) / RATE)
    assert align_recordings(a, RATE, a, RATE, alignment="subsequence_dtw").alignment == "subsequence_dtw"
    with pytest.raises(InputError, match="cycle phase"):
        align_recordings(_smooth_path(300, 1), RATE, _smooth_path(300, 2), RATE, alignment="cycle_phase")
    with pytest.raises(InputError, match="markers"):
        align_recordings(a, RATE, a[:, :2], RATE)
    with pytest.raises(InputError, match="gaps"):
        align_recordings(np.where(np.arange(330)[:, None, None] == 5, np.nan, a), RATE, a, RATE)
    with pytest.raises(InputError, match="unknown alignment"):
        align_recordings(a, RATE, a, RATE, alignment="kabsch")


def test_differences_say_which_marker_and_which_stretch():
    t = np.arange(330) / RATE
    a = _walker(t)
    b = a.copy()
    phase = (1.1 * t) % 1.0
    bump = np.where((phase > 0.6) & (phase < 0.7), 30.0, 0.0)  # marker 2 lifted in 60-70 % of the cycle
    b[:, 2, 1] += bump
    al = align_recordings(a, RATE, b, RATE, up=1)
    per_stretch, per_marker = stretch_differences(al.a, al.b, 10)
    assert int(np.argmax(per_marker)) == 2
    assert int(np.argmax(per_stretch[2])) == 6
    assert per_stretch[2, 6] > 5 * np.median(per_stretch[2])
    with pytest.raises(InputError, match="one shape"):
        stretch_differences(al.a, al.b[:, :2])

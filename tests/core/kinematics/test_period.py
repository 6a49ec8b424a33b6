"""Stride period and analysis window on gait-like marker tracks."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import KinematicsError
from saddlescope.core.kinematics.period import analysis_window, estimate_period

FPS = 30.0
BODY_MM = np.array([[-250.0, 0.0, 0.0], [0.0, 30.0, 0.0], [250.0, -10.0, 0.0]])


def _rotation(rx, ry, rz):
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def gait_tracks(gait: str, stride_hz: float, *, duration_s: float = 6.0, noise_mm: float = 1.0,
                seed: int = 0):
    """Three markers in rig mm: travel + vertical + lateral + pitch, seen from a tilted camera."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * FPS)) / FPS
    w = 2 * np.pi * stride_hz
    if gait == "walk":  # vertical dominated by 2x stride, lateral and pitch at 1x
        vert = 15 * np.cos(2 * w * t) + 3 * np.cos(w * t + 0.3)
        lat = 10 * np.sin(w * t)
        pitch = np.deg2rad(1.5) * np.sin(w * t + 1.0)
        speed = 1500.0
    elif gait == "trot":
        vert = 50 * np.cos(2 * w * t) + 5 * np.cos(4 * w * t)
        lat = 12 * np.sin(w * t)
        pitch = np.deg2rad(1.0) * np.sin(2 * w * t)
        speed = 3000.0
    else:  # canter: vertical at 1x
        vert = 120 * np.cos(w * t) + 30 * np.cos(2 * w * t + 0.5)
        lat = 20 * np.sin(w * t + 0.2)
        pitch = np.deg2rad(4.0) * np.sin(w * t + 0.7)
        speed = 4500.0
    xyz = np.empty((t.size, 3, 3))
    for m, (bx, by, _) in enumerate(BODY_MM):
        xyz[:, m, 0] = speed * t + bx * np.cos(pitch) - by * np.sin(pitch)
        xyz[:, m, 1] = vert + bx * np.sin(pitch) + by * np.cos(pitch)
        xyz[:, m, 2] = lat
    xyz = xyz @ _rotation(0.2, 0.5, -0.1).T + np.array([100.0, 200.0, 7000.0])
    return t, xyz + rng.normal(0.0, noise_mm, xyz.shape)


@pytest.mark.parametrize(("gait", "stride_hz", "harmonic"),
                         [("walk", 0.9, 2), ("trot", 1.4, 2), ("canter", 1.65, 1)])
def test_stride_period_within_one_percent(gait, stride_hz, harmonic):
    t, xyz = gait_tracks(gait, stride_hz)
    period, details = estimate_period(t, xyz)
    assert period == pytest.approx(1 / stride_hz, rel=0.01)
    assert details["harmonic"] == harmonic  # stride = this many periods of the dominant line
    assert details["score"] > 0.8


def test_walk_period_with_gaps_and_short_ride():
    t, xyz = gait_tracks("walk", 0.88, duration_s=3.0, noise_mm=2.0, seed=4)  # 2.6 strides
    xyz[20:24, 1] = np.nan
    period, _ = estimate_period(t, xyz)
    assert period == pytest.approx(1 / 0.88, rel=0.01)


def test_too_short_ride_raises():
    t, xyz = gait_tracks("canter", 1.65, duration_s=0.5)
    with pytest.raises(KinematicsError, match="shorter than two periods"):
        estimate_period(t, xyz)


def test_markers_lost_raises():
    t, xyz = gait_tracks("canter", 1.65)
    xyz[: int(0.7 * t.size)] = np.nan
    with pytest.raises(KinematicsError, match="lost for most of the ride"):
        estimate_period(t, xyz)


def test_no_periodic_motion_raises():
    rng = np.random.default_rng(2)
    t = np.arange(180) / FPS
    xyz = rng.normal(0.0, 5.0, (180, 3, 3))
    xyz[..., 0] += 3000 * t[:, None]
    with pytest.raises(KinematicsError, match="no periodic motion"):
        estimate_period(t, xyz)


def test_analysis_window_two_periods_centred():
    t = np.arange(100) / FPS
    start, stop = analysis_window(t, np.ones(100, bool), 0.6)
    assert stop - start == 36  # 2 x 18 frames, as the thesis's canter example
    assert start == 32  # centred: (100 - 36) / 2


def test_analysis_window_avoids_gaps():
    t = np.arange(100) / FPS
    valid = np.ones(100, bool)
    valid[40:70] = False
    start, stop = analysis_window(t, valid, 0.6)
    assert valid[start:stop].all()
    assert stop - start == 36


def test_analysis_window_errors():
    t = np.arange(30) / FPS
    with pytest.raises(KinematicsError, match="shorter than 2 periods"):
        analysis_window(t, np.ones(30, bool), 0.6)
    t = np.arange(100) / FPS
    valid = np.zeros(100, bool)
    valid[::3] = True
    with pytest.raises(KinematicsError, match="lost for most of the ride"):
        analysis_window(t, valid, 0.6)


def test_dominant_line_at_the_band_edge_stays_in_the_band():
    """A strong drift just below the band makes the band's first bin its largest; the parabola
    through that bin and the (higher) one outside the band must not move the line out of the band
    (a wide-rig canter's 0.51 Hz edge bin once read as 0.28 Hz and the stride was lost)."""
    from saddlescope.core.kinematics.period import _dominant_frequency

    t = np.arange(0, 3.1, 1 / 60)
    drift = 200 * np.sin(2 * np.pi * 0.3 * t)
    stride = 5 * np.sin(2 * np.pi * 1.65 * t)
    comp = np.column_stack([drift + stride, 0.5 * drift])
    f, freqs, _ = _dominant_frequency(comp, 1 / 60, 0.5, 7.0)
    df = freqs[1] - freqs[0]
    assert 0.5 <= f <= 0.5 + 2 * df

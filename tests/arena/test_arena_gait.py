"""The synthetic arena's gait model against the literature ranges and its own exact derivatives."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.arena import (
    SADDLE_NAME,
    acceleration_harmonics,
    fourier_series,
    saddle_vertical_peak_to_peak,
    sample_gait,
)
from saddlescope.core.errors import InputError
from saddlescope.core.types import GAITS

LIT = {
    "walk": {"f": (0.85, 0.95), "v": (1.2, 1.8), "pp": (0.01, 0.05)},
    "sitting_trot": {"f": (1.3, 1.5), "v": (2.6, 3.6), "pp": (0.07, 0.16)},
    "rising_trot": {"f": (1.3, 1.5), "v": (2.6, 3.6), "pp": (0.07, 0.16)},
    "canter": {"f": (1.6, 1.7), "v": (3.4, 7.0), "pp": (0.15, 0.30)},
}


@pytest.mark.parametrize("gait", GAITS)
def test_gait_in_literature_ranges_for_several_seeds(gait):
    for seed in range(6):
        m = sample_gait(gait, np.random.default_rng(seed), camera_side=1.0)
        lit = LIT[gait]
        assert lit["f"][0] <= m.stride_hz <= lit["f"][1]
        assert lit["v"][0] <= m.speed_m_s <= lit["v"][1]
        pp = saddle_vertical_peak_to_peak(m)
        assert lit["pp"][0] <= pp <= lit["pp"][1], (gait, seed, pp)
        # dominant vertical harmonic of S: 2x stride in walk and trot, 1x in canter
        t = np.arange(256) * m.period_s / 256
        y = m.point(m.body_points_m[SADDLE_NAME], t)[:, 1]
        spec = np.abs(np.fft.rfft(y))
        assert int(np.argmax(spec[1:5])) + 1 == (1 if gait == "canter" else 2)
        # markers in a rough horizontal row 15-25 cm apart
        b = m.body_points_m
        for a, c in (("marker1", "marker2"), ("marker2", "marker3")):
            assert 0.15 <= np.linalg.norm(b[a] - b[c]) <= 0.25
        assert b[SADDLE_NAME][1] < min(b[f"marker{i}"][1] for i in (1, 2, 3))  # S above (y is down)


def test_fourier_series_derivatives_are_exact():
    rng = np.random.default_rng(0)
    a, p = rng.uniform(0, 1, 4), rng.uniform(-3, 3, 4)
    t, h = np.linspace(0, 2, 40), 1e-5
    f = lambda tt, d=0: fourier_series(tt, 1.3, a, p, derivative=d)  # noqa: E731
    np.testing.assert_allclose(f(t, 1), (f(t + h) - f(t - h)) / (2 * h), atol=1e-7)
    np.testing.assert_allclose(f(t, 2), (f(t + h, 1) - f(t - h, 1)) / (2 * h), atol=1e-6)
    with pytest.raises(InputError):
        fourier_series(t, 1.0, a, p, derivative=3)


@pytest.mark.parametrize("gait", GAITS)
def test_body_kinematics_exact(gait):
    m = sample_gait(gait, np.random.default_rng(3), camera_side=-1.0)
    t, h = np.linspace(0.1, 2.1, 30), 1e-5
    r = m.body_points_m[SADDLE_NAME]
    p = lambda tt: m.point(r, tt)  # noqa: E731
    v, a = m.point(r, t, derivative=1), m.point(r, t, derivative=2)
    np.testing.assert_allclose(v, (p(t + h) - p(t - h)) / (2 * h), atol=1e-8)
    np.testing.assert_allclose(
        a, (m.point(r, t + h, derivative=1) - m.point(r, t - h, derivative=1)) / (2 * h), atol=1e-7
    )
    omega, alpha = m.angular(t)
    np.testing.assert_allclose(alpha, (m.angular(t + h)[0] - m.angular(t - h)[0]) / (2 * h), atol=1e-7)
    # rigid-body formula a = a_O + alpha x r + omega x (omega x r) (eq. 6.38-6.39 form)
    rr = np.einsum("tij,j->ti", m.rotation(t)[0], r)
    a_rb = m.origin(t, derivative=2) + np.cross(alpha, rr) + np.cross(omega, np.cross(omega, rr))
    np.testing.assert_allclose(a, a_rb, atol=1e-12)
    # dR/dt = skew(omega) R
    R, dR, _ = m.rotation(t)
    w = omega
    skew = np.zeros((len(t), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    skew -= np.swapaxes(skew, 1, 2)
    np.testing.assert_allclose(dR, skew @ R, atol=1e-12)


def _stride_locked_share(m, name: str) -> float:
    # share of a marker's skin-motion power at the stride's harmonics, over 40 strides
    t = np.arange(0, 40 / m.stride_hz, 1 / 240)
    y = m.skin_offset(name, t)
    k = np.arange(1, 9)
    arg = np.multiply.outer(t, 2 * np.pi * m.stride_hz * k)
    basis = np.hstack([np.cos(arg), np.sin(arg)])
    fitted = basis @ np.linalg.lstsq(basis, y, rcond=None)[0]
    return float(np.sum(fitted**2) / np.sum((y - y.mean(axis=0)) ** 2))


def test_skin_models_slide_the_same_horse_differently():
    rng = lambda: np.random.default_rng(11)  # noqa: E731
    locked = sample_gait("walk", rng(), camera_side=1.0)  # the default
    noise = sample_gait("walk", rng(), camera_side=1.0, skin_model="noise")
    none = sample_gait("walk", rng(), camera_side=1.0, skin_model="none")
    for other in (noise, none):  # one seed, one horse: only the skin differs
        assert other.stride_hz == locked.stride_hz and other.speed_m_s == locked.speed_m_s
        for name, p in locked.body_points_m.items():
            np.testing.assert_array_equal(other.body_points_m[name], p)
        for ch, (a, ph) in locked.harmonics.items():
            np.testing.assert_array_equal(other.harmonics[ch][0], a)
            np.testing.assert_array_equal(other.harmonics[ch][1], ph)
    assert none.skin == {}
    t = np.linspace(0, 20, 4000)
    for name in ("marker1", "marker2", "marker3"):
        # stride-locked: most of the sliding at the stride's harmonics; noise: a few percent there
        assert _stride_locked_share(locked, name) > 0.6
        assert _stride_locked_share(noise, name) < 0.2
        rms = np.sqrt(np.mean(noise.skin_offset(name, t) ** 2, axis=0))
        assert np.all(rms[:2] > 0.0002) and np.all(rms < 0.0015)  # "small": below 1.5 mm r.m.s.
    with pytest.raises(InputError, match="skin model"):
        sample_gait("walk", rng(), camera_side=1.0, skin_model="sticky")


def test_the_triangle_layout_moves_only_the_middle_marker_of_the_same_horse():
    from saddlescope.core.kinematics.rigid_body import unobservable_axis

    rng = lambda: np.random.default_rng(5)  # noqa: E731
    thesis = sample_gait("canter", rng(), camera_side=1.0)  # the default
    triangle = sample_gait("canter", rng(), camera_side=1.0, marker_layout="triangle")
    assert triangle.stride_hz == thesis.stride_hz and triangle.skin.keys() == thesis.skin.keys()
    for name, p in thesis.body_points_m.items():
        drop = triangle.body_points_m[name] - p
        if name == "marker2":  # about 10 cm below the line of the others instead of 3-5 cm
            assert drop[0] == drop[2] == 0.0 and 0.05 < drop[1] < 0.07
        else:
            assert np.all(drop == 0.0), name
    ratio_thesis, ratio_triangle = (
        unobservable_axis(np.stack([m.body_points_m[f"marker{i}"] for i in (1, 2, 3)])[None], min_eig_ratio=0.0)[1]
        for m in (thesis, triangle))
    assert ratio_triangle > 3 * ratio_thesis  # the roll about the row is far better fixed
    with pytest.raises(InputError, match="marker layout"):
        sample_gait("walk", rng(), camera_side=1.0, marker_layout="square")


def test_the_skin_common_mode_is_the_markers_mean_sliding_and_its_derivatives():
    # what a rigid body fitted to the three markers cannot remove: their mean sliding, in the arena
    m = sample_gait("canter", np.random.default_rng(3), camera_side=1.0)
    t = np.linspace(0.0, 2.0, 2001)
    h = t[1] - t[0]
    rigid = sample_gait("canter", np.random.default_rng(3), camera_side=1.0, skin_model="none")
    mean_slide = np.mean(m.marker_positions(t)[:, :3] - rigid.marker_positions(t)[:, :3], axis=1)
    np.testing.assert_allclose(m.skin_common_mode(t), mean_slide, atol=1e-12)
    p, v, a = (m.skin_common_mode(t, derivative=d) for d in range(3))
    np.testing.assert_allclose((p[2:] - p[:-2]) / (2 * h), v[1:-1], atol=3e-4 * np.abs(v).max())
    np.testing.assert_allclose((p[2:] - 2 * p[1:-1] + p[:-2]) / h**2, a[1:-1], atol=2e-4 * np.abs(a).max())
    assert np.all(rigid.skin_common_mode(t, derivative=2) == 0.0)


def test_acceleration_harmonics_reproduce_the_exact_acceleration():
    m = sample_gait("sitting_trot", np.random.default_rng(5), camera_side=1.0)
    r = m.body_points_m[SADDLE_NAME]
    amps, phases = acceleration_harmonics(m, r, axis=1, n_harmonics=40)
    t = np.random.default_rng(1).uniform(-3, 7, 200)
    k = np.arange(1, 41)
    series = np.cos(np.multiply.outer(t, 2 * np.pi * m.stride_hz * k) + phases) @ amps
    np.testing.assert_allclose(series, m.point(r, t, derivative=2)[:, 1], atol=1e-10)

"""Frequency weightings, exact harmonic metrics, digital filters and exposure (core.vibration)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, signal

from saddlescope.core import vibration as vib
from saddlescope.core.errors import VibrationError

# ISO 2631-1:1997 Table 3 (W_k, W_d, W_f) and Table 4 (W_c, W_j): weighting factors x 1000 at
# the nominal one-third-octave frequencies, as printed (3 significant figures).
NOMINAL_HZ = [0.02, 0.025, 0.0315, 0.04, 0.05, 0.063, 0.08, 0.1, 0.125, 0.16, 0.2, 0.25, 0.315, 0.4,
              0.5, 0.63, 0.8, 1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0, 10.0, 12.5, 16.0,
              20.0, 25.0, 31.5, 40.0, 50.0, 63.0, 80.0, 100.0, 125.0, 160.0, 200.0, 250.0, 315.0,
              400.0]
ISO_2631_1 = {
    "Wk": {0.1: 31.2, 0.125: 48.6, 0.16: 79.0, 0.2: 121, 0.25: 182, 0.315: 263, 0.4: 352, 0.5: 418,
           0.63: 459, 0.8: 477, 1.0: 482, 1.25: 484, 1.6: 494, 2.0: 531, 2.5: 631, 3.15: 804,
           4.0: 967, 5.0: 1039, 6.3: 1054, 8.0: 1036, 10.0: 988, 12.5: 902, 16.0: 768, 20.0: 636,
           25.0: 513, 31.5: 405, 40.0: 314, 50.0: 246, 63.0: 186, 80.0: 132, 100.0: 88.7,
           125.0: 54.0, 160.0: 28.5, 200.0: 15.2, 250.0: 7.9, 315.0: 3.98, 400.0: 1.95},
    "Wd": {0.1: 62.4, 0.125: 97.3, 0.16: 158, 0.2: 243, 0.25: 365, 0.315: 530, 0.4: 713, 0.5: 853,
           0.63: 944, 0.8: 992, 1.0: 1011, 1.25: 1008, 1.6: 968, 2.0: 890, 2.5: 776, 3.15: 642,
           4.0: 512, 5.0: 409, 6.3: 323, 8.0: 253, 12.5: 161, 16.0: 125, 20.0: 100, 25.0: 80.0,
           31.5: 63.2, 40.0: 49.4, 50.0: 38.8, 63.0: 29.5, 80.0: 21.1, 100.0: 14.1, 125.0: 8.63,
           160.0: 4.55, 200.0: 2.43, 250.0: 1.26},
    "Wf": {0.02: 24.2, 0.025: 37.7, 0.0315: 59.7, 0.04: 97.1, 0.05: 157, 0.063: 267, 0.08: 461,
           0.1: 695, 0.125: 895, 0.16: 1006, 0.2: 992, 0.25: 854, 0.315: 619, 0.4: 384, 0.5: 224,
           0.63: 116, 0.8: 53.0, 1.0: 23.5, 1.25: 9.98, 1.6: 3.77, 2.0: 1.55},
    "Wc": {0.1: 62.4, 0.125: 97.2, 0.16: 158, 0.2: 243, 0.25: 364, 0.315: 527, 0.4: 708, 0.5: 843,
           0.63: 929, 0.8: 972, 1.0: 991, 1.25: 1000, 1.6: 1007, 2.0: 1012, 2.5: 1017, 3.15: 1022,
           4.0: 1024, 5.0: 1013, 6.3: 974, 8.0: 891, 10.0: 776, 12.5: 647, 16.0: 512, 20.0: 409,
           25.0: 325, 31.5: 256, 40.0: 199},
    "Wj": {0.1: 31.0, 0.125: 48.3, 0.16: 78.5, 0.2: 120, 0.25: 181, 0.315: 262, 0.4: 351, 0.5: 417,
           0.63: 458, 0.8: 478, 1.0: 484, 1.25: 485, 1.6: 483, 2.0: 482, 2.5: 489, 3.15: 524,
           4.0: 628, 5.0: 793, 6.3: 946, 8.0: 1017, 10.0: 1030, 12.5: 1026, 16.0: 1018, 20.0: 1012,
           25.0: 1007, 31.5: 1001, 40.0: 991, 50.0: 972, 63.0: 931},
}


@pytest.mark.parametrize("name", sorted(ISO_2631_1))
def test_weighting_factors_match_iso_2631_1_tables_at_nominal_frequencies(name):
    table = ISO_2631_1[name]
    f = np.array(list(table))
    printed = np.array(list(table.values())) / 1000
    computed = np.abs(vib.weighting_response(name, f))
    # Printed to 3 significant figures: half a unit in the third figure, plus a little.
    tolerance = 0.006 * printed + 0.5e-5
    assert np.all(np.abs(computed - printed) <= tolerance), list(zip(f, printed, computed, strict=True))


def test_tables_are_at_nominal_not_exact_band_frequencies():
    table = ISO_2631_1["Wk"]
    band = {f: n for n, f in enumerate(NOMINAL_HZ, start=-17)}
    nominal = np.array(list(table))
    exact = 10.0 ** (np.array([band[f] for f in nominal]) / 10)
    printed = np.array(list(table.values())) / 1000
    err_nominal = np.abs(np.abs(vib.weighting_response("Wk", nominal)) / printed - 1)
    err_exact = np.abs(np.abs(vib.weighting_response("Wk", exact)) / printed - 1)
    assert err_nominal.max() < 0.004
    # e.g. 0.16 Hz is 0.1585 Hz exactly: W_k ~ f^2 there, 1.9 % lower than printed.
    assert err_exact.max() > 0.015


def test_upward_step_is_monic_form_without_extra_factor():
    # The common bug multiplies the monic step by (f6/f5)^2 and doubles W_k below 2 Hz.
    wk_1hz = abs(vib.weighting_response("Wk", 1.0))
    assert wk_1hz == pytest.approx(0.482, abs=0.001)
    assert abs(vib.weighting_response("Wk", 0.8)) / abs(vib.weighting_response("Wk", 8.0)) == \
        pytest.approx(0.477 / 1.036, rel=0.005)


def test_wb_follows_the_bs6841_asymptotes_and_gain():
    # BS 6841 straight-line approximation of W_b: 0.4 (0.5-2 Hz), f/5 (2-5), 1 (5-16), 16/f (16-80).
    for f_hz, asymptote in [(0.8, 0.4), (1.0, 0.4), (1.25, 0.4), (8.0, 1.0), (10.0, 1.0),
                            (31.5, 16 / 31.5), (40.0, 0.4)]:
        assert abs(vib.weighting_response("Wb", f_hz)) == pytest.approx(asymptote, rel=0.06)
    # K = 1.024 lifts the pass band: peak near 6.3 Hz just above 1.05.
    f = np.linspace(4, 10, 601)
    assert np.abs(vib.weighting_response("Wb", f)).max() == pytest.approx(1.054, abs=0.004)


def test_weighting_response_phase_and_limits():
    f = np.array([0.0, 1e-6, 1e4])
    h = vib.weighting_response("Wk", f)
    assert abs(h[0]) == 0 and abs(h[1]) < 1e-9 and abs(h[2]) < 1e-3
    # Two high-pass poles: +180 degrees far below f1.
    assert np.angle(vib.weighting_response("Wd", 0.001)) == pytest.approx(np.pi, abs=0.01)
    assert vib.weighting_response("w_k", 4.0) == vib.weighting_response("Wk", 4.0)
    assert vib.weighting_response("Wk", [[1.0, 2.0]]).shape == (1, 2)


@pytest.mark.parametrize("bad", ["Wz", "Wh", 3])
def test_unknown_weighting_is_refused(bad):
    with pytest.raises(VibrationError, match="weighting"):
        vib.weighting_response(bad, 1.0)


# ---------------------------------------------------------------------------------------------
# Exact metrics of Fourier series


@pytest.mark.parametrize("name", ["Wb", "Wk", "Wd"])
def test_pure_tone_rms_peak_vdv(name):
    f0, amplitude, duration_s = 1.7, 3.0, 3 / 1.7
    h = abs(vib.weighting_response(name, f0))
    m = vib.harmonic_metrics(f0, [amplitude], [0.4], name, duration_s)
    assert m["rms"] == pytest.approx(amplitude * h / math.sqrt(2), rel=1e-12)
    assert m["peak"] == pytest.approx(amplitude * h, rel=1e-12)
    assert m["crest_factor"] == pytest.approx(math.sqrt(2), rel=1e-12)
    # integral of sin^4 over tau is 3 tau / 8.
    assert m["vdv"] == pytest.approx(amplitude * h * (3 * duration_s / 8) ** 0.25, rel=1e-12)
    # 1 s running mean of cos^2(w t): 1/2 + |sin(w W)| / (2 w W) at most (W = 1 s).
    w = 2 * np.pi * f0
    assert m["mtvv"] == pytest.approx(amplitude * h * math.sqrt(0.5 + abs(math.sin(w)) / (2 * w)), rel=1e-4)


def test_tone_on_a_higher_harmonic_uses_the_harmonic_frequency():
    m = vib.harmonic_metrics(1.5, [0.0, 0.0, 2.0], [0.0, 0.0, 0.0], "Wk", 2 / 1.5)
    assert m["rms"] == pytest.approx(2.0 * abs(vib.weighting_response("Wk", 4.5)) / math.sqrt(2))


def _canter_like():
    return 1.65, np.array([6.0, 3.5, 1.8, 0.6]), np.array([0.0, 2.2, -1.1, 0.9]), 2 / 1.65


def _series(t, f0, amps, phases):
    k = np.arange(1, len(amps) + 1)[:, None]
    return np.sum(amps[:, None] * np.cos(2 * np.pi * f0 * k * t + phases[:, None]), axis=0)


def test_multi_harmonic_metrics_match_brute_force_integration():
    f0, amps, phases, tau = _canter_like()
    h = vib.weighting_response("Wb", f0 * np.arange(1, 5))

    def aw(t):
        return np.real(np.sum(amps * h * np.exp(1j * (2 * np.pi * f0 * np.arange(1, 5) * t + phases))))

    m = vib.harmonic_metrics(f0, amps, phases, "Wb", tau)
    fourth, _ = integrate.quad(lambda t: aw(t) ** 4, 0, tau, limit=400, epsabs=1e-12, epsrel=1e-12)
    square, _ = integrate.quad(lambda t: aw(t) ** 2, 0, tau, limit=400, epsabs=1e-12, epsrel=1e-12)
    assert m["vdv"] == pytest.approx(fourth**0.25, rel=1e-9)
    assert m["rms"] == pytest.approx(math.sqrt(square / tau), rel=1e-9)
    t = np.linspace(0, 1 / f0, 200001)
    dense_peak = np.max(np.abs([aw(x) for x in t[::50]]))
    assert dense_peak <= m["peak"] * (1 + 1e-12)
    assert m["peak"] == pytest.approx(dense_peak, rel=1e-5)


def test_weighting_phase_changes_crest_factor_and_vdv():
    """Scaling each harmonic by |H| only (thesis eq. 7.1-7.2 read literally) is not the filter."""
    f0, amps, phases, tau = _canter_like()
    complex_w = vib.harmonic_metrics(f0, amps, phases, "Wk", tau)
    gains = np.abs(vib.weighting_response("Wk", f0 * np.arange(1, 5)))
    magnitude_only = vib.harmonic_metrics(f0, amps * gains, phases, None, tau)
    assert complex_w["rms"] == pytest.approx(magnitude_only["rms"], rel=1e-12)  # Parseval: same
    assert abs(complex_w["crest_factor"] / magnitude_only["crest_factor"] - 1) > 0.02
    assert abs(complex_w["vdv"] / magnitude_only["vdv"] - 1) > 0.005


def test_unweighted_and_none_agree():
    f0, amps, phases, tau = _canter_like()
    unweighted = vib.harmonic_metrics(f0, amps, phases, None, tau)
    assert unweighted == vib.harmonic_metrics(f0, amps, phases, "none", tau)


def test_duration_must_be_whole_periods():
    with pytest.raises(VibrationError, match="whole number of periods"):
        vib.harmonic_metrics(1.65, [1.0], [0.0], "Wk", 1.0)
    # Within the relative tolerance is accepted (floating-point periods).
    vib.harmonic_metrics(1.65, [1.0], [0.0], "Wk", 2 / 1.65 * (1 + 1e-9))


@pytest.mark.parametrize("kwargs, match", [
    ({"amplitudes": [1.0, 2.0], "phases": [0.0]}, "phases must match"),
    ({"amplitudes": [], "phases": []}, "non-empty"),
    ({"amplitudes": [np.nan], "phases": [0.0]}, "finite"),
    ({"f0": -1.0}, "f0"),
    ({"weighting": "W9"}, "unknown frequency weighting"),
])
def test_harmonic_metrics_validation(kwargs, match):
    args = {"f0": 1.0, "amplitudes": [1.0], "phases": [0.0], "weighting": "Wk", "duration_s": 2.0} | kwargs
    with pytest.raises(VibrationError, match=match):
        vib.harmonic_metrics(**args)


# ---------------------------------------------------------------------------------------------
# Digital filters


@pytest.mark.parametrize("fs_hz", [25.0, 30.0, 60.0, 120.0, 500.0])
@pytest.mark.parametrize("name", ["Wb", "Wk", "Wd", "Wc", "We", "Wj", "Wf"])
def test_causal_sos_follows_analog_response_in_its_band(name, fs_hz):
    lo, hi = vib.digital_band_hz(name, fs_hz)
    assert hi == pytest.approx(min(hi, fs_hz / 4))
    f = np.logspace(np.log10(max(lo, 0.02 if name == "Wf" else 0.5)), np.log10(min(hi, 60.0)), 300)
    _, h = signal.sosfreqz(vib.weighting_sos(name, fs_hz), worN=f, fs=fs_hz)
    rel = np.abs(h / vib.weighting_response(name, f) - 1)
    assert rel.max() < 0.02
    if fs_hz >= 500:
        assert rel.max() < 0.002


def test_causal_sos_band_at_thesis_rate_is_limited():
    assert vib.digital_band_hz("Wk", 30.0)[1] == pytest.approx(7.5)
    assert vib.digital_band_hz("Wk", 120.0)[1] == pytest.approx(30.0)
    sos = vib.weighting_sos("Wk", 30.0)
    assert sos.shape[1] == 6 and np.all(np.abs(signal.sos2zpk(sos)[1]) < 1)


def _tone(fs_hz, f_hz, n, phase=0.3):
    t = np.arange(n) / fs_hz
    return t, np.cos(2 * np.pi * f_hz * t + phase)


@pytest.mark.parametrize("fs_hz", [30.0, 60.0, 120.0])
@pytest.mark.parametrize("method", ["iir", "fft"])
def test_weight_signal_matches_analog_response_on_periodic_tones(fs_hz, method):
    """0.5-20 Hz, capped at 0.8 fs/2 (12 Hz at 30 Hz sampling: 20 Hz is above Nyquist)."""
    duration_s = 4.0
    n = int(fs_hz * duration_s)
    f_top = min(20.0, 0.8 * fs_hz / 2)
    freqs = np.unique(np.round(np.geomspace(0.5, f_top, 7) * duration_s) / duration_s)
    for name in ("Wb", "Wk", "Wd"):
        for f_hz in freqs:
            t, a = _tone(fs_hz, f_hz, n)
            y = vib.weight_signal(a, fs_hz, name, method=method)
            h = vib.weighting_response(name, f_hz)
            expected = np.real(h * np.exp(1j * (2 * np.pi * f_hz * t + 0.3)))
            assert np.abs(y - expected).max() / abs(h) < 0.02, (name, f_hz)


def test_start_up_transient_matters_on_short_records():
    fs_hz, f_hz, n = 30.0, 1.5, 60  # 2 s (3 cycles), the thesis's window length scale
    _, a = _tone(fs_hz, f_hz, n)
    exact = abs(vib.weighting_response("Wk", f_hz)) / math.sqrt(2)
    periodic = vib.weighted_rms(vib.weight_signal(a, fs_hz, "Wk", transient="periodic"))
    from_rest = vib.weighted_rms(vib.weight_signal(a, fs_hz, "Wk", transient="none"))
    assert periodic == pytest.approx(exact, rel=1e-3)
    assert abs(from_rest / exact - 1) > 0.03  # about 5 % here


def test_pad_transient_settles_for_non_periodic_records():
    fs_hz, n = 60.0, 600
    t, a = _tone(fs_hz, 1.37, n)  # not a whole number of cycles in 10 s
    h = vib.weighting_response("Wk", 1.37)
    y = vib.weight_signal(a, fs_hz, "Wk", transient="pad")
    expected = np.real(h * np.exp(1j * (2 * np.pi * 1.37 * t + 0.3)))
    interior = slice(int(3 * fs_hz), n - int(3 * fs_hz))
    assert np.abs(y - expected)[interior].max() / abs(h) < 0.01


def test_weight_signal_validation():
    with pytest.raises(VibrationError, match="too low"):
        vib.weight_signal(np.zeros(100), 20.0, "Wk")
    with pytest.raises(VibrationError, match="NaN"):
        vib.weight_signal(np.array([0.0, np.nan, 1.0, 2.0]), 30.0, "Wk")
    with pytest.raises(VibrationError, match="transient"):
        vib.weight_signal(np.zeros(100), 30.0, "Wk", transient="zeros")
    assert np.array_equal(vib.weight_signal([1.0, 2.0, 3.0, 4.0], 30.0, "none"), [1.0, 2.0, 3.0, 4.0])


def test_sampled_metrics_converge_to_exact_harmonic_metrics_at_30_fps():
    f0, amps, phases, tau = _canter_like()
    fs_hz = 30.0 * 1.65 / 1.5  # a whole number of samples per period: 33 per two strides
    n = int(round(tau * fs_hz))
    t = np.arange(n) / fs_hz
    a = _series(t, f0, amps, phases)
    for name in ("Wb", "Wk", None):
        exact = vib.harmonic_metrics(f0, amps, phases, name, tau)
        sampled = vib.sampled_metrics(a, fs_hz, name)
        for key in ("rms", "vdv", "peak", "crest_factor"):
            assert sampled[key] == pytest.approx(exact[key], rel=2e-3), (name, key)
        assert sampled["duration_s"] == pytest.approx(tau)


def test_raw_sample_metrics_are_worse_than_interpolated_ones_at_low_rates():
    f0, amps, phases, tau = _canter_like()
    fs_hz = 30.0 * 1.65 / 1.5
    t = np.arange(int(round(tau * fs_hz))) / fs_hz
    a = _series(t, f0, amps, phases)
    exact = vib.harmonic_metrics(f0, amps, phases, None, tau)
    assert vib.peak(a) < exact["peak"] * 0.999  # samples miss the true peak
    assert vib.sampled_metrics(a, fs_hz, None)["peak"] == pytest.approx(exact["peak"], rel=1e-3)


def test_sampled_metric_functions():
    fs_hz = 100.0
    t = np.arange(1000) / fs_hz
    a = 2.0 * np.sin(2 * np.pi * 5 * t)
    assert vib.weighted_rms(a) == pytest.approx(math.sqrt(2), rel=1e-9)
    assert vib.peak(a) == pytest.approx(2.0, rel=1e-3)
    assert vib.crest_factor(a) == pytest.approx(math.sqrt(2), rel=1e-3)
    assert vib.vdv(a, fs_hz) == pytest.approx(2.0 * (3 * 10 / 8) ** 0.25, rel=1e-9)
    assert vib.mtvv(a, fs_hz) == pytest.approx(math.sqrt(2), rel=1e-6)
    burst = np.where((t > 4) & (t < 5), a, 0.1 * a)
    assert vib.mtvv(burst, fs_hz) > 2.5 * vib.weighted_rms(burst)
    with pytest.raises(VibrationError, match="at least 1.0 s"):
        vib.mtvv(a[:50], fs_hz)
    assert vib.mtvv(a[:50], fs_hz, periodic=True) == pytest.approx(math.sqrt(2), rel=1e-6)
    assert math.isnan(vib.crest_factor(np.zeros(10)))


def test_a8_daily_exposure():
    assert vib.a8(1.0, 2.0) == pytest.approx(0.5)
    assert vib.a8(0.5, 8.0) == pytest.approx(0.5)


# ---------------------------------------------------------------------------------------------
# Exposure


def test_exposure_limits_definitions():
    e = vib.exposure_limits(1.0, 2.0, 10.0, 12.0)
    assert e["t_a8_action_h"] == pytest.approx(8 * 0.25)
    assert e["t_a8_limit_h"] == pytest.approx(8 * 1.15**2)
    assert e["t_vdv_action_h"] == pytest.approx(10.0 * (9.1 / 2.0) ** 4 / 3600)
    assert e["t_vdv_limit_h"] == pytest.approx(10.0 * (21.0 / 2.0) ** 4 / 3600)
    for key in ("a8_action", "a8_limit", "vdv_action", "vdv_limit"):
        assert e[f"d_{key}_km"] == pytest.approx(12.0 * e[f"t_{key}_h"])
    # Exposing for T_vdv really reaches the threshold: VDV scales with the fourth root of time.
    assert 2.0 * (e["t_vdv_action_h"] * 3600 / 10.0) ** 0.25 == pytest.approx(9.1)
    assert vib.a8(1.0, e["t_a8_limit_h"]) == pytest.approx(1.15)


def test_exposure_limits_of_no_vibration_and_bad_input():
    e = vib.exposure_limits(0.0, 0.0, 1.2, 10.0)
    assert all(math.isinf(v) for v in e.values())
    with pytest.raises(VibrationError, match="rms"):
        vib.exposure_limits(-1.0, 1.0, 1.2, 10.0)
    with pytest.raises(VibrationError, match="duration_s"):
        vib.exposure_limits(1.0, 1.0, 0.0, 10.0)


def test_per_axis_exposure_worst_axis_with_horizontal_factor():
    out = vib.per_axis_exposure({"x": 0.5, "y": 0.6, "z": 0.2}, {"x": 1.0, "y": 1.5, "z": 0.5}, 2.0, 10.0)
    assert out["rms_effective"] == pytest.approx({"x": 0.7, "y": 0.6, "z": 0.28})
    assert out["worst_axis_a8"] == "x" and out["worst_axis_vdv"] == "y"
    assert out["rms"] == pytest.approx(0.7) and out["vdv"] == pytest.approx(1.5)
    assert out["t_a8_action_h"] == pytest.approx(vib.exposure_limits(0.7, 1.5, 2.0, 10.0)["t_a8_action_h"])
    with pytest.raises(VibrationError, match="same axes"):
        vib.per_axis_exposure({"x": 1.0}, {"y": 1.0}, 1.0, 1.0)

"""The indicators' 95 % intervals (core/vibration/intervals.py): the bootstrap reproduces the indicators,
its intervals cover the truth at the stated rate when the noise model holds, and the too-uncertain rule."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from saddlescope.core.errors import VibrationError
from saddlescope.core.findings import Finding
from saddlescope.core.types import (
    AnalysisWindow,
    Camera,
    HorseMarkers,
    MotionFrameSummary,
    RideResult,
    Rig,
    SaddleKinematics,
    SaddleRotation,
    VerticalHarmonics,
)
from saddlescope.core.vibration import ride_indicators
from saddlescope.core.vibration.intervals import (
    COMFORT_BAND_EDGES_M_S2,
    FLOORS,
    INTERVAL_KEYS,
    MAX_HALF_WIDTH_FRACTION,
    SKIN_FLOORS,
    bootstrap_indicators,
    decision_uncertainty,
    interval_sources,
    ride_intervals,
)
from saddlescope.io.legacy_flags import findings_from_sentences

# a canter's vertical acceleration of S (m/s²), as the arena's rides give it
F0_HZ = 1.68
AMPS = np.array([12.9, 1.6, 2.0, 1.3, 0.05])
PHASES = np.array([-0.71, 1.65, 3.11, 2.90, -2.03])
ZERO = {"f0": 0.0, "gain": 0.0, "speed": 0.0, "shape": 0.0, "harmonic_m_s2": np.zeros(5)}


def _indicators(amps=AMPS, phases=PHASES, f0=F0_HZ, speed_kmh=14.2, amplitude_y_m=0.23):
    return ride_indicators(f0_hz=f0, acc_y_amplitudes_m_s2=amps, acc_y_phases_rad=phases, duration_s=2 / f0,
                           speed_kmh=speed_kmh, amplitude_y_m=amplitude_y_m, stride_frequency_hz=f0)


def _draws(sources, *, amps=AMPS, phases=PHASES, draws=400, seed=0):
    return bootstrap_indicators(f0_hz=F0_HZ, amplitudes_m_s2=amps, phases_rad=phases, n_periods=2, speed_kmh=14.2,
                                amplitude_y_m=0.23, sources=sources, draws=draws, rng=np.random.default_rng(seed))


def test_the_bootstraps_first_row_is_the_indicators_themselves():
    ind = _indicators()
    row0 = {k: v[0] for k, v in _draws(ZERO, draws=10).items()}
    for key in INTERVAL_KEYS:
        # peaks on a 320-point grid against Newton-refined ones: a few parts in 10^4
        assert row0[key] == pytest.approx(ind[key], rel=2e-4), key


def test_without_noise_every_interval_is_the_value():
    samples = _draws(ZERO, draws=20)
    for key in INTERVAL_KEYS:
        assert np.ptp(samples[key]) == pytest.approx(0.0, abs=1e-9 * abs(samples[key][0])), key


def test_a_common_gain_moves_rms_and_vdv_alike_and_leaves_the_crest_factor():
    samples = _draws({**ZERO, "gain": 0.05})
    rel = samples["acc_y_wb_rms"] / samples["acc_y_wb_rms"][0]
    assert np.std(rel) == pytest.approx(0.05, rel=0.15)
    np.testing.assert_allclose(samples["vdv_y_wb"] / samples["vdv_y_wb"][0], rel, rtol=1e-9)
    np.testing.assert_allclose(samples["crest_factor_y"], samples["crest_factor_y"][0], rtol=1e-9)
    # T_A(8) goes with 1/rms², T_VDV with 1/VDV^4 (eq. 7.10-7.17)
    np.testing.assert_allclose(samples["t_a8_action_wb_h"] / samples["t_a8_action_wb_h"][0], rel ** -2, rtol=1e-9)
    np.testing.assert_allclose(samples["t_vdv_action_wb_h"] / samples["t_vdv_action_wb_h"][0], rel ** -4, rtol=1e-9)


def test_the_peak_floor_widens_the_crest_factors_and_weighted_peaks_only():
    """The weighted peak is a tail statistic: skin motion moves it more than the harmonics' shape floor
    can (SKIN_FLOORS' third term). It widens the crest factors and W_b/W_k peaks, not the r.m.s., VDV
    or the unweighted peak."""
    base = {**ZERO, "shape": 0.02}
    without, with_peak = _draws(base), _draws({**base, "peak": 0.03})
    for key in ("crest_factor_y", "crest_factor_y_wk", "acc_y_wb_peak", "acc_y_wk_peak"):
        assert np.std(np.log(with_peak[key])) > 1.5 * np.std(np.log(without[key])), key
    for key in ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "acc_y_max", "amplitude_y_m"):
        np.testing.assert_allclose(with_peak[key], without[key], rtol=1e-12, err_msg=key)
    np.testing.assert_allclose(with_peak["crest_factor_y"] * with_peak["acc_y_wb_rms"], with_peak["acc_y_wb_peak"],
                               rtol=1e-12)


def test_every_gait_has_a_peak_floor_and_an_unknown_gait_the_widest():
    src = {g: interval_sources(replace(_result(), gait=g), depth_anisotropy=2.0) for g in SKIN_FLOORS}
    for gait, (_gain, shape, peak, displacement) in SKIN_FLOORS.items():
        assert src[gait]["peak"] == peak > 0 and src[gait]["shape"] == shape
        assert src[gait]["displacement"] == displacement
    # an unknown gait takes the widest floors
    unknown = interval_sources(replace(_result(), gait=None), depth_anisotropy=2.0)
    assert unknown["peak"] == max(f[2] for f in SKIN_FLOORS.values())
    assert unknown["displacement"] == max(f[3] for f in SKIN_FLOORS.values())


def test_the_displacement_floor_widens_the_amplitude_only_and_keeps_the_other_draws():
    base = {**ZERO, "gain": 0.02, "shape": 0.02}
    without, with_disp = _draws(base), _draws({**base, "displacement": 0.05})
    rel = with_disp["amplitude_y_m"] / without["amplitude_y_m"]
    assert rel[0] == 1.0 and np.std(rel) == pytest.approx(0.05, rel=0.15)
    for key in INTERVAL_KEYS:
        if key != "amplitude_y_m":
            np.testing.assert_array_equal(with_disp[key], without[key], err_msg=key)


def test_the_intervals_cover_the_truth_95_percent_of_the_time_when_the_noise_model_holds():
    """Measurements drawn from the model around a known truth: the intervals made from each measurement
    must hold the truth in 90-99 % of 150 trials (the nonlinear indicators included)."""
    rng = np.random.default_rng(11)
    sources = {"f0": 0.002, "gain": 0.04, "speed": 0.005, "shape": 0.03, "harmonic_m_s2": np.full(5, 0.15)}
    truth = _indicators()
    keys = ("acc_y_wb_rms", "vdv_y_wb", "crest_factor_y", "acc_y_max", "t_vdv_action_wb_h", "amplitude_y_m")
    hits = {k: 0 for k in keys}
    trials = 150
    for trial in range(trials):
        # one measurement: the truth seen through the noise model
        coef = AMPS * np.exp(1j * PHASES)
        z = rng.standard_normal(3 + 4 * AMPS.size)
        c = (coef * (1 + sources["gain"] * z[0] + sources["shape"] * (z[3:8] + 1j * z[8:13]) / np.sqrt(2))
             + 0.15 * (z[13:18] + 1j * z[18:23]))
        f0 = F0_HZ * (1 + sources["f0"] * z[1])
        est = {"amps": np.abs(c), "phases": np.angle(c), "f0": f0}
        samples = bootstrap_indicators(f0_hz=est["f0"], amplitudes_m_s2=est["amps"], phases_rad=est["phases"],
                                       n_periods=2, speed_kmh=14.2, amplitude_y_m=0.23, sources=sources, draws=200,
                                       rng=np.random.default_rng(trial))
        for k in keys:
            lo, hi = np.percentile(samples[k][1:], [2.5, 97.5])
            hits[k] += lo <= truth[k] <= hi
    for k in keys:
        # the displacement's truth here is the estimate's own scale (0.23 m): it checks the spread only
        if k == "amplitude_y_m":
            continue
        assert 0.90 <= hits[k] / trials <= 0.99, (k, hits[k] / trials)


def test_the_same_result_gives_the_same_intervals_and_the_estimate_lies_inside():
    result = _result()
    sources = {**ZERO, "gain": 0.03, "f0": 0.001, "speed": 0.004, "harmonic_m_s2": np.full(5, 0.05)}
    a = ride_intervals(result, sources=sources)
    b = ride_intervals(result, sources=sources)
    assert a == b
    assert set(a) == set(INTERVAL_KEYS)
    for key, (lo, hi) in a.items():
        assert lo <= result.indicators[key] <= hi, key
        assert lo < hi, key


def test_interval_sources_reads_what_the_result_knows():
    result = _result(square_error_pct=0.5, outside={"left": 0.4, "middle": 0.02})
    src = interval_sources(result, depth_anisotropy=40.0)
    parts = src["gain_parts"]
    assert parts["calibration_scale"] == pytest.approx(0.005)
    assert parts["depth_roll"] > 0  # depth 40 times worse than image position: roll unseen
    # 40 % of one camera's detections outside, squared, times the floor (0.08: 1.3 %)
    assert parts["lens_extrapolated"] == pytest.approx(0.08 * 0.4 ** 2)
    assert src["gain"] >= parts["lens_extrapolated"]
    # the fits' 95 % half-width 0.0004 m of each coefficient, times (kω)²
    omega = 2 * np.pi * F0_HZ
    k = np.arange(1, 4)
    np.testing.assert_allclose(src["harmonic_m_s2"][:3], 0.0004 / 1.959963984540054 * (k * omega) ** 2, rtol=1e-6)
    assert np.all(src["harmonic_m_s2"][3:] == 0)  # beyond the fits' order
    assert interval_sources(result, depth_anisotropy=2.0)["gain_parts"]["depth_roll"] == 0.0
    # one camera cannot fix depth at all; motion capture (no cameras) measures positions directly
    assert interval_sources(result)["gain_parts"]["depth_roll"] > 0
    mocap = replace(result, rig=Rig(cameras={}))
    assert interval_sources(mocap)["gain_parts"]["depth_roll"] == 0.0
    # a window of fewer strides than the indicators span: the stride frequency's floor is ten times wider
    one_stride = replace(result, window=replace(result.window, duration_s=1 / F0_HZ))
    assert interval_sources(one_stride, depth_anisotropy=2.0)["f0"] == pytest.approx(
        np.hypot(_f0_fit_part(src), 0.005), rel=1e-6)
    # without the per-camera shares, the coverage finding's number; an older result's (its sentence read
    # back without values by the legacy reader) gives it in its sentence only
    sentence = ("the left camera saw the markers outside the region the calibration board covered in 31 % of its "
                "detections: its lens distortion is extrapolated")
    coded = _result(outside=None, findings=(Finding("calibration.coverage", sentence, {"outside_share_pct": 27.0}),))
    assert interval_sources(coded, depth_anisotropy=2.0)["outside_board_share"] == pytest.approx(0.27)
    old = _result(outside=None, findings=tuple(findings_from_sentences([sentence])))
    assert interval_sources(old, depth_anisotropy=2.0)["outside_board_share"] == pytest.approx(0.31)


def test_a_lens_extrapolated_crossing_widens_the_speed_and_a_motion_that_is_not_periodic_the_gain_and_peaks():
    inside, outside = _result(outside={"left": 0.02}), _result(outside={"left": 0.7})
    s_in, s_out = (interval_sources(r, depth_anisotropy=2.0) for r in (inside, outside))
    # the scale where the lens is extrapolated is the lens's: 0.001 x 0.7² on the speed
    assert s_out["speed"] ** 2 - s_in["speed"] ** 2 == pytest.approx((0.001 * 0.49) ** 2 - (0.001 * 0.0004) ** 2)
    assert s_in["gain_parts"]["not_periodic"] == 0.0
    # S's vertical acceleration 30 % off its harmonic series (r.m.s.): a reconstruction that broke
    amps = np.asarray(inside.vertical_harmonics.amplitudes_m_s2)
    broken = replace(inside, quality={**inside.quality,
                                      "vertical_harmonic_fit_rms_m_s2": 0.3 * np.sqrt(np.sum(amps ** 2) / 2)})
    s_broken = interval_sources(broken, depth_anisotropy=2.0)
    assert s_broken["gain_parts"]["not_periodic"] == pytest.approx(0.3)
    assert s_broken["gain"] > 0.3 and s_broken["peak"] == pytest.approx(np.hypot(0.3, SKIN_FLOORS["canter"][2]))
    assert decision_uncertainty(broken.indicators, ride_intervals(broken, sources=s_broken)) is not None


def test_a_ride_with_much_of_its_crossing_beyond_the_board_is_too_uncertain():
    # the whole crossing where the lens is extrapolated: 8 % of gain (a third of it: under 1 %)
    result = _result(outside={"left": 1.0})
    intervals = ride_intervals(result, sources=interval_sources(result, depth_anisotropy=2.0))
    reason = decision_uncertainty(result.indicators, intervals)
    assert reason is not None and "W_b r.m.s. is known only to" in reason
    # the verdict names the largest part, in a club's words
    sources = interval_sources(result, depth_anisotropy=2.0)
    named = decision_uncertainty(result.indicators, intervals, sources)
    assert named.startswith(reason) and "where the calibration board never went" in named
    walk = replace(result, gait="walk", quality={**result.quality, "markers_outside_board_fraction": {}})
    walk_sources = interval_sources(walk, depth_anisotropy=2.0)
    assert max(walk_sources["gain_parts"], key=walk_sources["gain_parts"].get) == "skin_motion"
    verdict = decision_uncertainty(walk.indicators, ride_intervals(walk, sources=walk_sources), walk_sources)
    assert verdict is not None and "sliding on the skin" in verdict
    good = _result(outside={"left": 0.02})
    assert decision_uncertainty(good.indicators, ride_intervals(
        good, sources=interval_sources(good, depth_anisotropy=2.0))) is None


def test_the_too_uncertain_rule():
    ind = {"acc_y_wb_rms": 1.0}
    edge = MAX_HALF_WIDTH_FRACTION
    assert decision_uncertainty(ind, {"acc_y_wb_rms": (1 - 0.9 * edge, 1 + 0.9 * edge)}) is None
    assert "±11 %" in decision_uncertainty(ind, {"acc_y_wb_rms": (1 - 1.1 * edge, 1 + 1.1 * edge)})
    assert "no interval" in decision_uncertainty({"acc_y_wb_rms": 1.0}, {})


def test_an_interval_narrow_enough_never_spans_more_than_one_comfort_band():
    """docs/accuracy.md: the width rule implies the band rule, since a ±10 % interval spans a ratio of
    1.1 / 0.9 and ISO 2631-1's band edges two apart differ by more."""
    edges = np.array(COMFORT_BAND_EDGES_M_S2)
    widest = (1 + MAX_HALF_WIDTH_FRACTION) / (1 - MAX_HALF_WIDTH_FRACTION)
    assert np.all(edges[2:] / edges[:-2] > widest)
    assert np.all(edges[1:] / edges[:-1] > widest)  # it spans at most one edge


def test_bad_input_is_refused_with_what_was_expected():
    with pytest.raises(VibrationError, match="one length"):
        _draws(ZERO, amps=AMPS[:3])
    with pytest.raises(VibrationError, match="draws >= 10"):
        _draws(ZERO, draws=3)
    with pytest.raises(VibrationError, match="sources lack gain"):
        _draws({k: v for k, v in ZERO.items() if k != "gain"})
    with pytest.raises(VibrationError, match="harmonic_m_s2"):
        _draws({**ZERO, "harmonic_m_s2": np.zeros(2)})


def _fit_y(order: int = 3, half_width_m: float = 0.0004) -> dict:
    a = [0.01] * order
    return {"kind": "FourierFit", "omega_rad_s": 2 * np.pi * F0_HZ, "a": a, "b": a, "trend": [0.0],
            "ci95": {"a": [[v - half_width_m, v + half_width_m] for v in a],
                     "b": [[v - half_width_m, v + half_width_m] for v in a],
                     "omega_rad_s": [2 * np.pi * F0_HZ * 0.999, 2 * np.pi * F0_HZ * 1.001]}}


def _fit_x(speed_m_s: float = 3.95) -> dict:
    return {"kind": "FourierFit", "trend": [speed_m_s], "ci95": {"trend": [[speed_m_s - 0.005, speed_m_s + 0.005]]}}


def _f0_fit_part(src: dict) -> float:
    """The fits' own part of the stride frequency's sigma (the floor taken out)."""
    return float(np.sqrt(max(src["f0"] ** 2 - 0.0005 ** 2, 0.0)))


def _result(*, square_error_pct: float = 0.2, outside: dict | None = None, findings: tuple = ()) -> RideResult:
    n = 8
    cam = Camera("left", np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]]), np.zeros(5), (640, 480))
    quality = {"saddle_acceleration_spread_m_s2_median": 0.1}
    if outside is not None:
        quality["markers_outside_board_fraction"] = outside
    rng = np.random.default_rng(0)
    return RideResult(
        fps=30.0, gait="canter", direction="CCW",
        rig=Rig(cameras={"left": cam}, checks={"board_square_error_pct": square_error_pct}),
        sync_offsets={"motion": {"left": 0.0}}, period_s=1 / F0_HZ,
        window=AnalysisWindow(start_s=1.0, duration_s=2 / F0_HZ, start_frame=30, frames=n),
        saddle=SaddleKinematics(t_s=np.arange(n) / 30, position_m=rng.normal(size=(n, 3)),
                                velocity_m_s=rng.normal(size=(n, 3)), acceleration_m_s2=rng.normal(size=(n, 3)),
                                acceleration_spread_m_s2=np.full(n, 0.1), body_coordinates_m=np.zeros(3)),
        angular=SaddleRotation(omega_rad_s=np.zeros((n, 3)), alpha_rad_s2=np.zeros((n, 3)), singularity_index=0.5,
                               singularity_index_per_frame=np.zeros(n), omega_versions_rad_s=np.zeros((n, 6, 3)),
                               omega_versions_excluded=np.zeros((n, 6), bool), omega_spread_rad_s=np.zeros((n, 3)),
                               method="lsq_wiener"),
        markers=HorseMarkers(names=("M1", "M2", "M3"), position_m=np.zeros((n, 3, 3)), velocity_m_s=np.zeros((n, 3, 3)),
                             acceleration_m_s2=np.zeros((n, 3, 3)), rigidity_residual_mm=np.zeros(n),
                             fits={"x": [_fit_x()] * 3, "y": [_fit_y()] * 3, "z": []}),
        motion_frame=MotionFrameSummary(R_rig_to_motion=np.eye(3), origin_mm=np.array([0.0, 0.0, 7000.0]),
                                        gravity_source="plumb"),
        vertical_harmonics=VerticalHarmonics(f0_hz=F0_HZ, amplitudes_m_s2=AMPS, phases_rad=PHASES),
        indicators=_indicators(), quality=quality, params={"n_periods": 2}, timings_s={"total": 1.0},
        findings=findings)


def test_an_interval_grows_with_the_stride_phase_no_frame_measured_and_a_fifth_marks_the_ride():
    # issue 38: a boot over the rear marker for a fifth of every stride, in a result analysed before the
    # phase-deletion test (no quality["stride_phase_deletion"]): the share's fixed cost
    good = _result()
    base = interval_sources(good, depth_anisotropy=2.0)
    assert base["gain_parts"]["unmeasured_phase"] == 0.0
    assert decision_uncertainty(good.indicators, ride_intervals(good, sources=base)) is None
    widths = []
    for share in (0.05, 0.2):
        hidden = replace(good, quality={**good.quality, "stride_phase_unmeasured_share": share})
        src = interval_sources(hidden, depth_anisotropy=2.0)
        assert src["gain_parts"]["unmeasured_phase"] == pytest.approx(0.5 * share)
        lo, hi = ride_intervals(hidden, sources=src)["acc_y_wb_rms"]
        widths.append(hi - lo)
    assert widths[1] > widths[0]
    hidden = replace(good, quality={**good.quality, "stride_phase_unmeasured_share": 0.2})
    src = interval_sources(hidden, depth_anisotropy=2.0)
    verdict = decision_uncertainty(hidden.indicators, ride_intervals(hidden, sources=src), src)
    assert verdict is not None and "hidden at the same moment of every stride" in verdict


def test_a_hidden_fifth_costs_what_the_phase_deletion_test_measured_on_the_ride():
    # the field table's trots and canters: a fifth of the stride hidden moved W_b by at most 4.7 %, while
    # the share's fixed cost put ±20 % on them and marked them too uncertain
    good = _result()
    measured = {"tested": True, "median_change": 0.01, "max_change": 0.02, "deletions": 6}
    hidden = replace(good, quality={**good.quality, "stride_phase_unmeasured_share": 0.2,
                                    "stride_phase_deletion": measured})
    src = interval_sources(hidden, depth_anisotropy=2.0)
    assert src["gain_parts"]["unmeasured_phase"] == pytest.approx(FLOORS["unmeasured_phase_deletion"] * 0.01)
    assert decision_uncertainty(hidden.indicators, ride_intervals(hidden, sources=src), src) is None
    # a ride where leaving more of the stride out moves the indicators a lot is marked, naming the boot
    shaky = replace(hidden, quality={**hidden.quality, "stride_phase_deletion": {**measured, "median_change": 0.15}})
    src = interval_sources(shaky, depth_anisotropy=2.0)
    verdict = decision_uncertainty(shaky.indicators, ride_intervals(shaky, sources=src), src)
    assert verdict is not None and "hidden at the same moment of every stride" in verdict


def test_the_one_gap_test_carries_its_own_factor_and_stored_two_gap_tests_keep_theirs():
    # the test as it is now fills the hidden part with the analysis's fit (one gap per refit, method
    # "one_gap"), which measures about half what the two-gap test did: its factor is its own
    good = _result()
    one_gap = {"tested": True, "method": "one_gap", "median_change": 0.02, "max_change": 0.03, "deletions": 6}
    for test, factor in ((one_gap, FLOORS["unmeasured_phase_deletion_one_gap"]),
                         ({k: v for k, v in one_gap.items() if k != "method"}, FLOORS["unmeasured_phase_deletion"])):
        hidden = replace(good, quality={**good.quality, "stride_phase_unmeasured_share": 0.2,
                                        "stride_phase_deletion": test})
        src = interval_sources(hidden, depth_anisotropy=2.0)
        assert src["gain_parts"]["unmeasured_phase"] == pytest.approx(factor * 0.02)
    assert FLOORS["unmeasured_phase_deletion_one_gap"] > FLOORS["unmeasured_phase_deletion"]


def test_a_hidden_fifth_whose_cost_could_not_be_measured_marks_the_ride():
    # a one-stride canter with a boot over its rear marker (+88 % on W_b once): too few strides to refit
    good = _result()
    untested = {"tested": False, "median_change": None, "reason": "the fits saw 1.1 strides"}
    hidden = replace(good, quality={**good.quality, "stride_phase_unmeasured_share": 0.12,
                                    "stride_phase_deletion": untested})
    src = interval_sources(hidden, depth_anisotropy=2.0)
    assert src["gain_parts"]["unmeasured_phase"] == FLOORS["unmeasured_phase_untested"]
    assert decision_uncertainty(hidden.indicators, ride_intervals(hidden, sources=src), src) is not None

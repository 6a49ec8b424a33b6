"""Comfort indicators of a ride, comparisons and riders' grades (core.vibration)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from saddlescope.core import vibration as vib
from saddlescope.core.errors import InputError, VibrationError

# Thesis Table 8.7 (horse 2, CCW, canter): inputs and printed results.
TABLE_8_7_INPUTS = {"acc_y_wb_rms": 3.1906, "acc_y_wk_rms": 3.7007, "vdv_y_wb": 3.7932,
                    "vdv_y_wk": 4.3997, "vel_x_avg_kmh": 17.6376}
TABLE_8_7_TAU_S = 1.2  # two canter periods, 36 frames at 30 fps
TABLE_8_7 = {
    "t_a8_action_wb_h": 0.1965, "t_a8_action_wk_h": 0.1460, "t_a8_limit_wb_h": 1.0393,
    "t_a8_limit_wk_h": 0.7725, "t_vdv_action_wb_h": 0.0110, "t_vdv_action_wk_h": 0.0061,
    "t_vdv_limit_wb_h": 0.3131, "t_vdv_limit_wk_h": 0.1730, "d_a8_action_wb_km": 3.4653,
    "d_a8_action_wk_km": 2.5758, "d_a8_limit_wb_km": 18.3313, "d_a8_limit_wk_km": 13.6259,
    "d_vdv_action_wb_km": 0.1947, "d_vdv_action_wk_km": 0.1076, "d_vdv_limit_wb_km": 5.5228,
    "d_vdv_limit_wk_km": 3.0514,
}
HALF_UNIT = 0.00005  # Table 8.7 prints four decimals


def _table_value(rms, vdv, speed, key):
    out = vib.exposure_limits(rms, vdv, TABLE_8_7_TAU_S, speed)
    generic = key.replace("_wb", "").replace("_wk", "")
    return out[generic]


@pytest.mark.parametrize("key", sorted(TABLE_8_7))
def test_table_8_7_times_and_distances_are_reproduced(key):
    """Every time and distance from the printed r.m.s., VDV, tau = 1.2 s and 17.6376 km/h.

    The inputs are themselves rounded to four decimals, so the check is exact interval
    arithmetic: the printed value must lie within the range the rounded inputs allow.
    """
    w = "wb" if "_wb_" in key else "wk"
    rms, vdv = TABLE_8_7_INPUTS[f"acc_y_{w}_rms"], TABLE_8_7_INPUTS[f"vdv_y_{w}"]
    speed = TABLE_8_7_INPUTS["vel_x_avg_kmh"]
    corners = [_table_value(rms + dr, vdv + dv, speed + ds, key)
               for dr, dv, ds in itertools.product((-HALF_UNIT, HALF_UNIT), repeat=3)]
    assert min(corners) - HALF_UNIT <= TABLE_8_7[key] <= max(corners) + HALF_UNIT
    # And at the printed inputs themselves the times agree to the printed precision.
    if key.startswith("t_"):
        assert _table_value(rms, vdv, speed, key) == pytest.approx(TABLE_8_7[key], abs=HALF_UNIT)


def test_table_8_7_follows_fourth_power_vdv_time_not_printed_eq_7_14():
    corrected = vib.exposure_limits(3.1906, 3.7932, TABLE_8_7_TAU_S, 17.6376)["t_vdv_action_h"]
    assert corrected == pytest.approx(0.0110, abs=HALF_UNIT)
    linear_eq_7_14 = TABLE_8_7_TAU_S * (9.1 / 3.7932) / 3600
    assert abs(linear_eq_7_14 - 0.0110) > 0.01


def _canter():
    f0 = 1.65
    return {"f0_hz": f0, "acc_y_amplitudes_m_s2": [6.0, 3.5, 1.8, 0.6],
            "acc_y_phases_rad": [0.0, 2.2, -1.1, 0.9], "duration_s": 2 / f0, "speed_kmh": 17.6,
            "amplitude_y_m": 0.29, "stride_frequency_hz": f0}


def test_ride_indicators_has_every_contract_key_as_float():
    out = vib.ride_indicators(**_canter())
    assert set(vib.CONTRACT_KEYS) <= set(out)
    assert all(isinstance(v, float) for v in out.values())
    assert set(vib.COMFORT_INDICATORS) <= set(out)
    assert all(key in vib.INDICATORS for key in out)


def test_ride_indicators_are_consistent_with_the_metrics():
    args = _canter()
    out = vib.ride_indicators(**args)
    series = (args["f0_hz"], args["acc_y_amplitudes_m_s2"], args["acc_y_phases_rad"])
    wb = vib.harmonic_metrics(*series, "Wb", args["duration_s"])
    wk = vib.harmonic_metrics(*series, "Wk", args["duration_s"])
    raw = vib.harmonic_metrics(*series, None, args["duration_s"])
    assert out["acc_y_wb_rms"] == wb["rms"] and out["acc_y_wk_rms"] == wk["rms"]
    assert out["vdv_y_wb"] == wb["vdv"] and out["vdv_y_wk"] == wk["vdv"]
    assert out["acc_y_max"] == raw["peak"]
    assert out["crest_factor_y"] == pytest.approx(wb["peak"] / wb["rms"])
    assert out["crest_factor_y_wk"] == pytest.approx(wk["peak"] / wk["rms"])
    limits_wk = vib.exposure_limits(wk["rms"], wk["vdv"], args["duration_s"], args["speed_kmh"])
    assert out["t_vdv_limit_wk_h"] == limits_wk["t_vdv_limit_h"]
    assert out["d_a8_action_wk_km"] == limits_wk["d_a8_action_km"]
    assert (out["vel_x_avg_kmh"], out["amplitude_y_m"], out["stride_frequency_hz"]) == (17.6, 0.29, 1.65)
    # Below 4 Hz W_k weights more than W_b (0.48 against 0.39 at 1-2 Hz): same order as Table 8.7.
    assert out["acc_y_wk_rms"] > out["acc_y_wb_rms"] and out["vdv_y_wk"] > out["vdv_y_wb"]
    assert out["t_a8_limit_wb_h"] > out["t_a8_limit_wk_h"]
    assert out["acc_y_max"] > out["acc_y_wb_peak"]


def test_horizontal_axes_and_worst_axis_rule():
    args = _canter()
    acc_x = {"amplitudes_m_s2": [4.0, 1.0], "phases_rad": [0.3, 0.0]}
    acc_z = {"amplitudes_m_s2": [0.8], "phases_rad": [0.0], "f0_hz": args["f0_hz"] / 2}
    out = vib.ride_indicators(**args, acc_x=acc_x, acc_z=acc_z)
    wd_x = vib.harmonic_metrics(args["f0_hz"], [4.0, 1.0], [0.3, 0.0], "Wd", args["duration_s"])
    assert out["acc_x_wd_rms"] == wd_x["rms"]
    eff = {"x": 1.4 * wd_x["rms"], "y": out["acc_y_wk_rms"], "z": 1.4 * out["acc_z_wd_rms"]}
    worst = max(eff.values())
    assert worst == eff["x"]  # strong surge: the fore-aft axis dominates after the factor 1.4
    assert out["t_a8_limit_worst_h"] == pytest.approx(8 * (1.15 / worst) ** 2)
    assert out["t_a8_limit_worst_h"] < out["t_a8_limit_wk_h"]
    with pytest.raises(VibrationError, match="phases_rad"):
        vib.ride_indicators(**args, acc_x={"amplitudes_m_s2": [1.0]})


def test_sampled_twin_agrees_with_harmonic_indicators_at_30_fps():
    args = _canter()
    fs_hz = 33.0  # 40 samples in two strides at 1.65 Hz
    t = np.arange(40) / fs_hz
    amps, phases = np.array(args["acc_y_amplitudes_m_s2"]), np.array(args["acc_y_phases_rad"])
    k = np.arange(1, 5)[:, None]
    a = np.sum(amps[:, None] * np.cos(2 * np.pi * args["f0_hz"] * k * t + phases[:, None]), axis=0)
    exact = vib.ride_indicators(**args)
    sampled = vib.ride_indicators_sampled(a, fs_hz, speed_kmh=args["speed_kmh"],
                                          amplitude_y_m=args["amplitude_y_m"],
                                          stride_frequency_hz=args["stride_frequency_hz"])
    assert set(sampled) == set(exact)
    for key in vib.CONTRACT_KEYS:
        assert sampled[key] == pytest.approx(exact[key], rel=5e-3), key


@pytest.mark.parametrize("change, match", [
    ({"speed_kmh": -1.0}, "speed_kmh"),
    ({"duration_s": 1.0}, "whole number of periods"),
    ({"stride_frequency_hz": 0.0}, "stride_frequency_hz"),
    ({"acc_y_phases_rad": [0.0]}, "phases must match"),
])
def test_ride_indicators_validation(change, match):
    with pytest.raises(VibrationError, match=match):
        vib.ride_indicators(**(_canter() | change))


def test_comfort_indicators_and_units():
    out = vib.comfort_indicators(vib.ride_indicators(**_canter()))
    assert tuple(out) == vib.COMFORT_INDICATORS and len(out) == 8
    assert vib.indicator_unit("t_a8_limit_wb_h") == "h"
    assert vib.indicator_unit("vdv_y_wb") == "m/s^1.75"
    assert vib.indicator_unit("something_kmh") == "km/h"
    assert vib.INDICATORS["acc_y_wb_rms"].thesis_name == "acc_y_Wb_rms"
    with pytest.raises(InputError, match="acc_y_max"):
        vib.comfort_indicators({"acc_y_wb_rms": 1.0})


# ---------------------------------------------------------------------------------------------
# Comparisons


def _rides():
    rng = np.random.default_rng(7)
    rows = []
    base = {"walk": 0.8, "sitting_trot": 2.5, "rising_trot": 2.2, "canter": 3.2}
    for i, (horse, gait, rep) in enumerate(itertools.product(["Horse 1", "Horse 2", "Horse 3"],
                                                             ["canter", "walk", "sitting_trot"], range(3))):
        rms = base[gait] * (1 + 0.2 * int(horse[-1])) + rng.normal(0, 0.1)
        rows.append({"ride_id": i, "horse": horse, "rider": f"Rider {'ABC'[rep]}", "gait": gait,
                     "date": "2024-05-01", "acc_y_wb_rms": rms, "t_a8_limit_wb_h": 8 * (1.15 / rms) ** 2,
                     "vel_x_avg_kmh": 10.0 + rep})
    return rows


def test_compare_gaits_matches_numpy_statistics_in_gait_order():
    rows = _rides()
    out = vib.compare_gaits(rows, "acc_y_wb_rms", horse="Horse 2")
    assert [g["group"] for g in out] == ["walk", "sitting_trot", "canter"]
    for g in out:
        values = [r["acc_y_wb_rms"] for r in rows if r["horse"] == "Horse 2" and r["gait"] == g["group"]]
        assert g["n"] == 3
        assert g["mean"] == pytest.approx(np.mean(values))
        assert g["std"] == pytest.approx(np.std(values, ddof=1))
        assert (g["min"], g["max"]) == (min(values), max(values))


def test_compare_horses_reads_nested_indicators_and_skips_missing():
    rows = [{"horse": "A", "gait": "walk", "indicators": {"vdv_y_wb": 1.0}},
            {"horse": "A", "gait": "walk", "indicators": {"vdv_y_wb": 3.0}},
            {"horse": "B", "gait": "walk", "indicators": {"vdv_y_wb": None}},
            {"horse": "B", "gait": "walk", "vdv_y_wb": 2.0},
            {"horse": "C", "gait": "canter", "vdv_y_wb": 9.0}]
    out = vib.compare_horses(rows, "vdv_y_wb", gait="walk")
    assert [(g["group"], g["n"], g["mean"]) for g in out] == [("A", 2, 2.0), ("B", 1, 2.0)]
    assert math.isnan(out[1]["std"])


def test_leaderboard_ranks_by_comfort_direction_with_ties():
    rows = _rides()
    board = vib.leaderboard(rows, "acc_y_wb_rms", gait="canter")
    assert [b["horse"] for b in board] == ["Horse 1", "Horse 2", "Horse 3"]  # lower r.m.s. first
    assert [b["rank"] for b in board] == [1, 2, 3] and all(b["n"] == 3 for b in board)
    by_time = vib.leaderboard(rows, "t_a8_limit_wb_h", gait="canter")
    assert [b["horse"] for b in by_time] == ["Horse 1", "Horse 2", "Horse 3"]  # longer time first
    assert by_time[0]["spread"] == pytest.approx(by_time[0]["max"] - by_time[0]["min"])
    tied = [{"horse": h, "gait": "walk", "vdv_y_wb": v} for h, v in [("A", 2.0), ("B", 1.0), ("C", 1.0)]]
    assert [(b["rank"], b["horse"]) for b in vib.leaderboard(tied, "vdv_y_wb", gait="walk")] == \
        [(1, "B"), (1, "C"), (3, "A")]
    with pytest.raises(InputError, match="lower_is_better"):
        vib.leaderboard(rows, "vel_x_avg_kmh", gait="walk")
    fastest = vib.leaderboard(rows, "vel_x_avg_kmh", gait="walk", lower_is_better=False)
    assert fastest[0]["mean"] >= fastest[-1]["mean"]


def test_relative_comfort_as_in_thesis_8_5():
    assert vib.relative_comfort(1.5, 3.0) == pytest.approx(2.0)
    rows = [{"horse": "A", "gait": "canter", "t_a8_limit_wb_h": 1.5},
            {"horse": "B", "gait": "canter", "t_a8_limit_wb_h": 3.0},
            {"horse": "B", "gait": "canter", "t_a8_limit_wb_h": 3.0}]
    table = vib.relative_comfort_table(rows, gait="canter")
    assert table["reference_horse"] == "A"
    got = [(r["horse"], r["relative"], r["mean"]) for r in table["rows"]]
    assert got == [("B", 2.0, 3.0), ("A", 1.0, 1.5)]
    assert "passive" in table["caveat"]
    with pytest.raises(InputError, match="allowed times"):
        vib.relative_comfort_table(rows, gait="canter", indicator="acc_y_wb_rms")


# ---------------------------------------------------------------------------------------------
# Riders' grades: thesis Table 8.8

TABLE_8_8 = {  # gait -> rider -> grades for horses 1-4
    "walk": {"A": [3, 4, 4, 2], "B": [4, 5, 4, 3], "C": [4, 5, 5, 4], "D": [4, 4, 4, 2]},
    "sitting_trot": {"A": [2, 3, 4, 2], "B": [3, 4, 4, 2], "C": [3, 4, 4, 2], "D": [2, 5, 4, 2]},
    "rising_trot": {"A": [3, 4, 4, 3], "B": [3, 5, 4, 3], "C": [3, 4, 5, 3], "D": [3, 5, 4, 3]},
    "canter": {"A": [2, 5, 5, 3], "B": [3, 5, 5, 3], "C": [3, 5, 5, 2], "D": [3, 4, 5, 1]},
}
TABLE_8_8_AVG = {"walk": [3.75, 4.5, 4.25, 2.75], "sitting_trot": [2.5, 4, 4, 2],
                 "rising_trot": [3, 4.5, 4.25, 3], "canter": [2.75, 4.75, 5, 2.25]}


def _grade_rows():
    return [{"horse": f"Horse {h + 1}", "gait": gait, "rider": f"Rider {rider}", "grade": g}
            for gait, riders in TABLE_8_8.items() for rider, grades in riders.items()
            for h, g in enumerate(grades)]


def test_average_grades_reproduce_table_8_8():
    averages = vib.average_grades(_grade_rows())
    for gait, expected in TABLE_8_8_AVG.items():
        got = {a["horse"]: a["grade"] for a in averages if a["gait"] == gait}
        assert [got[f"Horse {h}"] for h in range(1, 5)] == expected
    assert {a["n"] for a in averages} == {4}
    overall = [np.mean([a["grade"] for a in averages if a["horse"] == f"Horse {h}"]) for h in range(1, 5)]
    assert overall == [3, 4.4375, 4.375, 2.5]  # "overall avg ccw"
    with pytest.raises(InputError, match="1-5"):
        vib.average_grades([{"horse": "H", "gait": "walk", "rider": "R", "grade": 6}])


@pytest.mark.parametrize("seed", [0, 1])
def test_grade_correlation_matches_scipy(seed):
    rng = np.random.default_rng(seed)
    grades = rng.integers(1, 6, 16).astype(float)  # ties, as real grades have
    values = 5.0 - 0.6 * grades + rng.normal(0, 0.8, 16)
    out = vib.grade_correlation(grades, values)
    pearson = stats.pearsonr(grades, values)
    spearman = stats.spearmanr(grades, values)
    assert out["n"] == 16
    assert out["pearson_r"] == pytest.approx(pearson.statistic, rel=1e-12)
    assert out["pearson_p"] == pytest.approx(pearson.pvalue, rel=1e-9)
    ci = pearson.confidence_interval(0.95)
    assert (out["pearson_ci_low"], out["pearson_ci_high"]) == pytest.approx((ci.low, ci.high), rel=1e-9)
    assert out["spearman_rho"] == pytest.approx(spearman.statistic, rel=1e-12)
    assert out["spearman_p"] == pytest.approx(spearman.pvalue, rel=1e-9)
    half = stats.norm.ppf(0.975) * math.sqrt(1.06 / 13)
    z = np.arctanh(spearman.statistic)
    assert out["spearman_ci_low"] == pytest.approx(np.tanh(z - half))
    assert out["spearman_ci_high"] == pytest.approx(np.tanh(z + half))
    assert out["pearson_ci_low"] < out["pearson_r"] < out["pearson_ci_high"]


def test_grade_correlation_of_table_8_8_averages_against_an_indicator():
    grades = TABLE_8_8_AVG["canter"]
    rms = [3.9, 3.2, 3.0, 4.4]
    out = vib.grade_correlation(grades, rms)
    assert out["pearson_r"] == pytest.approx(stats.pearsonr(grades, rms).statistic)
    assert out["spearman_rho"] == pytest.approx(-1.0)
    assert out["spearman_p"] == 0.0 and out["n"] == 4


def test_grade_correlation_degenerate_cases():
    constant = vib.grade_correlation([3, 3, 3, 3], [1.0, 2.0, 3.0, 4.0])
    assert math.isnan(constant["pearson_r"]) and math.isnan(constant["spearman_p"])
    three = vib.grade_correlation([1, 2, 4], [3.0, 2.0, 2.5])
    assert math.isnan(three["pearson_ci_low"]) and not math.isnan(three["pearson_p"])
    dropped = vib.grade_correlation([1, 2, np.nan, 4, 5], [1.0, 2.5, 3.0, np.nan, 4.0])
    assert dropped["n"] == 3
    with pytest.raises(InputError, match="paired"):
        vib.grade_correlation([1, 2], [1.0])


def test_grades_vs_indicators_pairs_average_grade_with_mean_indicator():
    grade_rows = _grade_rows()
    rms = {"Horse 1": 3.9, "Horse 2": 3.2, "Horse 3": 3.0, "Horse 4": 4.4}
    rides = [{"horse": h, "gait": "canter", "acc_y_wb_rms": v + d}
             for h, v in rms.items() for d in (-0.1, 0.1)]
    rides.append({"horse": "Horse 5", "gait": "canter", "acc_y_wb_rms": 1.0})  # never graded: left out
    out = vib.grades_vs_indicators(grade_rows, rides, ["acc_y_wb_rms"], gait="canter")["acc_y_wb_rms"]
    assert out["n"] == 4 and out["expected_sign"] == -1
    assert [p["horse"] for p in out["points"]] == list(rms)
    assert [p["grade"] for p in out["points"]] == [2.75, 4.75, 5.0, 2.25]
    assert [p["value"] for p in out["points"]] == pytest.approx(list(rms.values()))
    expected = stats.pearsonr([2.75, 4.75, 5, 2.25], list(rms.values())).statistic
    assert out["pearson_r"] == pytest.approx(expected)
    assert out["pearson_r"] < 0  # as the thesis expected for canter

"""Rider comfort indicators of a ride, and comparisons across gaits, horses and riders' grades.

Thesis Table 8.7 (the indicator set of one ride), section 8.5 (the eight comfort indicators,
gaits of one horse, horses in one gait, riders' 1-5 grades, Table 8.8, Figs 8.29-8.36).
Vertical = y axis of the motion frame, weighted with W_b (BS 6841) and W_k (ISO 2631-1);
horizontal axes x (travel) and z with W_d.  Times in hours, distances in km.

Everything here is a pure function of plain numbers, lists and dicts: no database.  A *row*
is a dict describing one ride: metadata ``ride_id``, ``horse``, ``rider``, ``gait``,
``date`` and the indicator values, either at the top level or under ``"indicators"``.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from saddlescope.core.errors import InputError, VibrationError
from saddlescope.core.vibration.weighting import (
    exposure_limits,
    harmonic_metrics,
    per_axis_exposure,
    sampled_metrics,
)

__all__ = [
    "GAITS",
    "CONTRACT_KEYS",
    "COMFORT_INDICATORS",
    "INDICATORS",
    "IndicatorInfo",
    "PASSIVE_SEATED_CAVEAT",
    "indicator_unit",
    "ride_indicators",
    "ride_indicators_sampled",
    "comfort_indicators",
    "relative_comfort",
    "relative_comfort_table",
    "summarize",
    "compare_gaits",
    "compare_horses",
    "leaderboard",
    "average_grades",
    "grade_correlation",
    "grades_vs_indicators",
]

GAITS = ("walk", "sitting_trot", "rising_trot", "canter")

PASSIVE_SEATED_CAVEAT = (
    "The EU 2002/44/EC action and limit values assume a passive, seated person who takes no "
    "counter-measures against the vibration. A rider compensates actively (the pelvis follows "
    "the saddle in sitting trot, the trunk swings in canter; in rising trot the rider is not in "
    "continuous contact with the saddle at all), so the allowed times and distances are far on "
    "the safe side: read them as relative comfort indicators between horses and gaits, not as "
    "absolute limits (thesis 8.5)."
)


@dataclass(frozen=True)
class IndicatorInfo:
    """What an indicator key means.

    Attributes
    ----------
    unit : str
        Unit of the value ("" for dimensionless).
    label : str
        Human-readable name.
    thesis_name : str or None
        Its name in thesis Table 8.7 (without the "_s_Horse2CCWcanter" suffix).
    better : {"lower", "higher"} or None
        Which way is more comfortable; None where the indicator has no comfort direction.
    """

    unit: str
    label: str
    thesis_name: str | None = None
    better: str | None = None


def _exposure_infos() -> dict[str, IndicatorInfo]:
    infos = {}
    for basis, basis_label in (("a8", "A(8)"), ("vdv", "VDV")):
        for level in ("action", "limit"):
            for w in ("wb", "wk"):
                tn = "TA_8" if basis == "a8" else "TVDV_T"
                infos[f"t_{basis}_{level}_{w}_h"] = IndicatorInfo(
                    "h", f"time to the {basis_label} exposure {level} value (W_{w[1]})",
                    f"{tn}_{level}_W{w[1]}", "higher")
                infos[f"d_{basis}_{level}_{w}_km"] = IndicatorInfo(
                    "km", f"distance to the {basis_label} exposure {level} value (W_{w[1]})",
                    f"Distance_{tn}_{level}_W{w[1]}", "higher")
    return infos


INDICATORS: dict[str, IndicatorInfo] = {
    "acc_y_wb_rms": IndicatorInfo("m/s^2", "vertical W_b weighted r.m.s. acceleration",
                                  "acc_y_Wb_rms", "lower"),
    "acc_y_wk_rms": IndicatorInfo("m/s^2", "vertical W_k weighted r.m.s. acceleration",
                                  "acc_y_Wk_rms", "lower"),
    "vdv_y_wb": IndicatorInfo("m/s^1.75", "vertical W_b vibration dose value", "VDV_y_Wb", "lower"),
    "vdv_y_wk": IndicatorInfo("m/s^1.75", "vertical W_k vibration dose value", "VDV_y_Wk", "lower"),
    "acc_y_max": IndicatorInfo("m/s^2", "peak unweighted vertical acceleration", "acc_y_max", "lower"),
    "crest_factor_y": IndicatorInfo("", "vertical crest factor (W_b)", "crest_factor", "lower"),
    **_exposure_infos(),
    "vel_x_avg_kmh": IndicatorInfo("km/h", "average speed in the direction of travel", "vel_x_avg"),
    "amplitude_y_m": IndicatorInfo("m", "peak-to-peak vertical displacement of the saddle point",
                                   "amplitude_y"),
    "stride_frequency_hz": IndicatorInfo("Hz", "stride frequency"),
    # Beyond Table 8.7.
    "crest_factor_y_wk": IndicatorInfo("", "vertical crest factor (W_k)", None, "lower"),
    "acc_y_wb_peak": IndicatorInfo("m/s^2", "vertical W_b weighted peak acceleration", None, "lower"),
    "acc_y_wk_peak": IndicatorInfo("m/s^2", "vertical W_k weighted peak acceleration", None, "lower"),
    "acc_y_rms": IndicatorInfo("m/s^2", "unweighted vertical r.m.s. acceleration", None, "lower"),
    "mtvv_y_wb": IndicatorInfo("m/s^2", "vertical W_b maximum transient vibration value", None, "lower"),
    "mtvv_y_wk": IndicatorInfo("m/s^2", "vertical W_k maximum transient vibration value", None, "lower"),
    "duration_s": IndicatorInfo("s", "analysed duration (whole number of periods)"),
}
for _axis, _name in (("x", "fore-aft"), ("z", "lateral")):
    INDICATORS[f"acc_{_axis}_wd_rms"] = IndicatorInfo(
        "m/s^2", f"{_name} W_d weighted r.m.s. acceleration", None, "lower")
    INDICATORS[f"vdv_{_axis}_wd"] = IndicatorInfo(
        "m/s^1.75", f"{_name} W_d vibration dose value", None, "lower")
    INDICATORS[f"acc_{_axis}_max"] = IndicatorInfo(
        "m/s^2", f"peak unweighted {_name} acceleration", None, "lower")
for _basis in ("a8", "vdv"):
    for _level in ("action", "limit"):
        INDICATORS[f"t_{_basis}_{_level}_worst_h"] = IndicatorInfo(
            "h", f"time to the {_basis.upper()} {_level} value, worst axis (1.4 W_d x, W_k y, 1.4 W_d z)",
            None, "higher")
        INDICATORS[f"d_{_basis}_{_level}_worst_km"] = IndicatorInfo(
            "km", f"distance to the {_basis.upper()} {_level} value, worst axis", None, "higher")

# The keys fixed by CONTRACTS section 2 (thesis Table 8.7), in the table's order.
CONTRACT_KEYS: tuple[str, ...] = (
    "acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vdv_y_wk", "acc_y_max", "crest_factor_y",
    "t_a8_action_wb_h", "t_a8_action_wk_h", "t_a8_limit_wb_h", "t_a8_limit_wk_h",
    "t_vdv_action_wb_h", "t_vdv_action_wk_h", "t_vdv_limit_wb_h", "t_vdv_limit_wk_h",
    "d_a8_action_wb_km", "d_a8_action_wk_km", "d_a8_limit_wb_km", "d_a8_limit_wk_km",
    "d_vdv_action_wb_km", "d_vdv_action_wk_km", "d_vdv_limit_wb_km", "d_vdv_limit_wk_km",
    "vel_x_avg_kmh", "amplitude_y_m", "stride_frequency_hz",
)

# Thesis 8.5: "the 8 comfort indicators (that may be used to evaluate horses)", all W_b.
COMFORT_INDICATORS: tuple[str, ...] = (
    "acc_y_max", "acc_y_wb_rms", "crest_factor_y", "d_a8_limit_wb_km", "t_a8_limit_wb_h",
    "vdv_y_wb", "vel_x_avg_kmh", "amplitude_y_m",
)

_SUFFIX_UNITS = (("_kmh", "km/h"), ("_km", "km"), ("_hz", "Hz"), ("_h", "h"), ("_s", "s"),
                 ("_m", "m"))


def indicator_unit(key: str) -> str:
    """Unit of an indicator key ("" if dimensionless or unknown)."""
    if key in INDICATORS:
        return INDICATORS[key].unit
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix):
            return unit
    return ""


# --------------------------------------------------------------------------------------------
# One ride


def _check_positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise VibrationError(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise VibrationError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {value}")
    return value


def _assemble(wb: Mapping[str, float], wk: Mapping[str, float], raw: Mapping[str, float], *,
              duration_s: float, speed_kmh: float, amplitude_y_m: float,
              stride_frequency_hz: float) -> dict[str, float]:
    """Table 8.7 keys (and extras) from the W_b, W_k and unweighted vertical metrics."""
    out: dict[str, float] = {
        "acc_y_wb_rms": wb["rms"],
        "acc_y_wk_rms": wk["rms"],
        "vdv_y_wb": wb["vdv"],
        "vdv_y_wk": wk["vdv"],
        "acc_y_max": raw["peak"],
        "crest_factor_y": wb["crest_factor"],
    }
    limits = {w: exposure_limits(m["rms"], m["vdv"], duration_s, speed_kmh)
              for w, m in (("wb", wb), ("wk", wk))}
    for kind in ("t", "d"):
        for basis in ("a8", "vdv"):
            for level in ("action", "limit"):
                unit = "h" if kind == "t" else "km"
                for w in ("wb", "wk"):
                    out[f"{kind}_{basis}_{level}_{w}_{unit}"] = limits[w][f"{kind}_{basis}_{level}_{unit}"]
    out.update({
        "vel_x_avg_kmh": speed_kmh,
        "amplitude_y_m": amplitude_y_m,
        "stride_frequency_hz": stride_frequency_hz,
        "crest_factor_y_wk": wk["crest_factor"],
        "acc_y_wb_peak": wb["peak"],
        "acc_y_wk_peak": wk["peak"],
        "acc_y_rms": raw["rms"],
        "mtvv_y_wb": wb["mtvv"],
        "mtvv_y_wk": wk["mtvv"],
        "duration_s": duration_s,
    })
    return {key: float(value) for key, value in out.items()}


def _add_horizontal(out: dict[str, float], horizontal: Mapping[str, tuple[Mapping, Mapping]],
                    wk: Mapping[str, float], duration_s: float, speed_kmh: float) -> None:
    """W_d metrics of the horizontal axes and the directive's worst-axis exposure."""
    if not horizontal:
        return
    rms_by_axis = {"y": wk["rms"]}
    vdv_by_axis = {"y": wk["vdv"]}
    for axis, (wd, raw) in horizontal.items():
        out[f"acc_{axis}_wd_rms"] = float(wd["rms"])
        out[f"vdv_{axis}_wd"] = float(wd["vdv"])
        out[f"acc_{axis}_max"] = float(raw["peak"])
        rms_by_axis[axis] = wd["rms"]
        vdv_by_axis[axis] = wd["vdv"]
    worst = per_axis_exposure(rms_by_axis, vdv_by_axis, duration_s, speed_kmh, vertical_axis="y")
    for basis in ("a8", "vdv"):
        for level in ("action", "limit"):
            out[f"t_{basis}_{level}_worst_h"] = float(worst[f"t_{basis}_{level}_h"])
            out[f"d_{basis}_{level}_worst_km"] = float(worst[f"d_{basis}_{level}_km"])


def _horizontal_harmonics(axis: str, spec, f0_default: float) -> tuple[float, np.ndarray, np.ndarray]:
    if not isinstance(spec, Mapping):
        raise VibrationError(
            f"acc_{axis} must be a dict with 'amplitudes_m_s2' and 'phases_rad' (and optionally "
            f"'f0_hz'), got {type(spec).__name__}"
        )
    missing = {"amplitudes_m_s2", "phases_rad"} - set(spec)
    if missing:
        raise VibrationError(f"acc_{axis} is missing {', '.join(sorted(missing))}")
    return float(spec.get("f0_hz", f0_default)), spec["amplitudes_m_s2"], spec["phases_rad"]


def ride_indicators(*, f0_hz: float, acc_y_amplitudes_m_s2: Sequence[float],
                    acc_y_phases_rad: Sequence[float], duration_s: float, speed_kmh: float,
                    amplitude_y_m: float, stride_frequency_hz: float,
                    acc_x: Mapping | None = None, acc_z: Mapping | None = None) -> dict[str, float]:
    """Every comfort indicator of one ride, from the Fourier series of the saddle point.

    The vertical acceleration of the saddle point S is
    a_y(t) = sum_k A_k cos(2 pi k f0 t + phi_k), k = 1..K (the analytic second derivative of
    the thesis's Fourier fit, eq. 5.23); it is weighted exactly with the complex W_b and W_k
    responses (:func:`saddlescope.core.vibration.harmonic_metrics`).

    Parameters
    ----------
    f0_hz : float
        Fundamental frequency of the vertical Fourier series (Hz); 2x stride in walk and trot.
    acc_y_amplitudes_m_s2, acc_y_phases_rad : sequence of float, shape (K,)
        A_k (m/s^2) and phi_k (rad).
    duration_s : float
        Analysed window tau, a whole number of periods 1/f0_hz (two strides in the thesis).
    speed_kmh : float
        Average speed in the direction of travel, v_x,avg (km/h).
    amplitude_y_m : float
        Peak-to-peak vertical displacement of S (m), passed through.
    stride_frequency_hz : float
        Stride frequency (Hz), passed through.
    acc_x, acc_z : dict, optional
        Horizontal accelerations as ``{"amplitudes_m_s2": [...], "phases_rad": [...],
        "f0_hz": f}`` (``f0_hz`` defaults to ``f0_hz``); weighted with W_d and combined with
        the worst-axis rule (1.4 W_d horizontal, W_k vertical).

    Returns
    -------
    dict of str -> float
        All keys of CONTRACTS section 2 (:data:`CONTRACT_KEYS`), plus ``crest_factor_y_wk``,
        ``acc_y_wb_peak``, ``acc_y_wk_peak``, ``acc_y_rms``, ``mtvv_y_wb``, ``mtvv_y_wk``,
        ``duration_s``; with horizontal axes also ``acc_x_wd_rms``, ``vdv_x_wd``,
        ``acc_x_max`` (same for z) and ``t_/d_{a8,vdv}_{action,limit}_worst_{h,km}``.
        The thesis's eight comfort indicators are the keys in :data:`COMFORT_INDICATORS`.
    """
    _check_positive("f0_hz", f0_hz)
    _check_positive("duration_s", duration_s)
    speed_kmh = _check_positive("speed_kmh", speed_kmh, allow_zero=True)
    amplitude_y_m = _check_positive("amplitude_y_m", amplitude_y_m, allow_zero=True)
    stride_frequency_hz = _check_positive("stride_frequency_hz", stride_frequency_hz)
    metrics = {w: harmonic_metrics(f0_hz, acc_y_amplitudes_m_s2, acc_y_phases_rad, w, duration_s)
               for w in ("Wb", "Wk", None)}
    out = _assemble(metrics["Wb"], metrics["Wk"], metrics[None], duration_s=duration_s,
                    speed_kmh=speed_kmh, amplitude_y_m=amplitude_y_m,
                    stride_frequency_hz=stride_frequency_hz)
    horizontal = {}
    for axis, spec in (("x", acc_x), ("z", acc_z)):
        if spec is None:
            continue
        f0_axis, amps, phases = _horizontal_harmonics(axis, spec, f0_hz)
        horizontal[axis] = (harmonic_metrics(f0_axis, amps, phases, "Wd", duration_s),
                            harmonic_metrics(f0_axis, amps, phases, None, duration_s))
    _add_horizontal(out, horizontal, metrics["Wk"], duration_s, speed_kmh)
    return out


def ride_indicators_sampled(acc_y_m_s2, fs_hz: float, *, speed_kmh: float, amplitude_y_m: float,
                            stride_frequency_hz: float, acc_x_m_s2=None, acc_z_m_s2=None,
                            transient: str = "periodic") -> dict[str, float]:
    """The same indicators as :func:`ride_indicators` from sampled accelerations.

    Parameters
    ----------
    acc_y_m_s2 : array_like of shape (n,)
        Vertical acceleration of the saddle point (m/s^2) sampled at ``fs_hz``; with the
        default ``transient="periodic"`` the record must be a whole number of periods.
    fs_hz : float
        Sampling rate (>= 25 Hz).
    speed_kmh, amplitude_y_m, stride_frequency_hz : float
        As in :func:`ride_indicators`.
    acc_x_m_s2, acc_z_m_s2 : array_like of shape (n,), optional
        Horizontal accelerations, weighted with W_d.
    transient : {"periodic", "pad"}
        See :func:`saddlescope.core.vibration.weight_signal`.

    Returns
    -------
    dict of str -> float
        Same keys as :func:`ride_indicators`; ``duration_s`` = n / fs_hz.
    """
    speed_kmh = _check_positive("speed_kmh", speed_kmh, allow_zero=True)
    amplitude_y_m = _check_positive("amplitude_y_m", amplitude_y_m, allow_zero=True)
    stride_frequency_hz = _check_positive("stride_frequency_hz", stride_frequency_hz)
    metrics = {w: sampled_metrics(acc_y_m_s2, fs_hz, w, transient=transient)
               for w in ("Wb", "Wk", None)}
    duration_s = metrics[None]["duration_s"]
    out = _assemble(metrics["Wb"], metrics["Wk"], metrics[None], duration_s=duration_s,
                    speed_kmh=speed_kmh, amplitude_y_m=amplitude_y_m,
                    stride_frequency_hz=stride_frequency_hz)
    horizontal = {}
    for axis, record in (("x", acc_x_m_s2), ("z", acc_z_m_s2)):
        if record is None:
            continue
        if np.asarray(record).shape != np.asarray(acc_y_m_s2).shape:
            raise VibrationError(
                f"acc_{axis}_m_s2 has shape {np.asarray(record).shape}, acc_y_m_s2 has "
                f"{np.asarray(acc_y_m_s2).shape}; the axes must be sampled together"
            )
        horizontal[axis] = (sampled_metrics(record, fs_hz, "Wd", transient=transient),
                            sampled_metrics(record, fs_hz, None, transient=transient))
    _add_horizontal(out, horizontal, metrics["Wk"], duration_s, speed_kmh)
    return out


def comfort_indicators(indicators: Mapping[str, float]) -> dict[str, float]:
    """The thesis's eight comfort indicators (8.5, all W_b) picked out of an indicator dict."""
    missing = [key for key in COMFORT_INDICATORS if key not in indicators]
    if missing:
        raise InputError(f"indicators lack the comfort indicator(s) {', '.join(missing)}")
    return {key: float(indicators[key]) for key in COMFORT_INDICATORS}


# --------------------------------------------------------------------------------------------
# Relative comfort


def relative_comfort(allowed_a_h: float, allowed_b_h: float) -> float:
    """How many times more comfortable horse B is than horse A (thesis 8.5).

    The ratio of their allowed exposure times (or distances): with T_A(8),limit,Wb of 1.5 h
    for A and 3 h for B, B is 2 times as comfortable.  Note that the ratio depends on the
    criterion: A(8) times scale with (a_rms,A / a_rms,B)^2, VDV times with
    (VDV_A / VDV_B)^4.  See :data:`PASSIVE_SEATED_CAVEAT`.
    """
    a = _check_positive("allowed_a_h", allowed_a_h)
    b = _check_positive("allowed_b_h", allowed_b_h, allow_zero=True)
    return b / a


def _value(row: Mapping, key: str) -> float:
    """Indicator value of a row (top level or under 'indicators'); NaN when absent."""
    source = row.get("indicators", row) if key not in row else row
    value = source.get(key, math.nan) if isinstance(source, Mapping) else math.nan
    if value is None:
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"ride {row.get('ride_id', '?')}: {key} = {value!r} is not a number") from exc


def _better(indicator: str, lower_is_better: bool | None) -> bool:
    if lower_is_better is not None:
        return bool(lower_is_better)
    info = INDICATORS.get(indicator)
    if info is None or info.better is None:
        raise InputError(
            f"{indicator!r} has no comfort direction; pass lower_is_better=True or False"
        )
    return info.better == "lower"


def relative_comfort_table(rows: Iterable[Mapping], *, gait: str,
                           indicator: str = "t_a8_limit_wb_h",
                           reference_horse: str | None = None) -> dict:
    """Relative comfort of the horses in one gait next to the absolute allowed times.

    Parameters
    ----------
    rows : iterable of dict
        Ride rows (``horse``, ``gait`` and the indicator).
    gait : str
        Gait to compare.
    indicator : str
        An allowed time or distance (``t_*_h`` or ``d_*_km``); default T_A(8),limit,Wb as in
        thesis 8.5.
    reference_horse : str, optional
        Horse whose relative comfort is 1; default the least comfortable (shortest time).

    Returns
    -------
    dict
        ``indicator``, ``unit``, ``gait``, ``reference_horse``, ``caveat`` and ``rows``: one
        dict per horse with ``horse``, ``n``, ``mean`` (absolute value) and ``relative``
        (mean / reference mean), most comfortable first.
    """
    if not (indicator.startswith(("t_", "d_")) and INDICATORS.get(indicator, IndicatorInfo("", "")).better
            == "higher"):
        raise InputError(
            f"relative comfort compares allowed times or distances (t_*_h, d_*_km), not {indicator!r}"
        )
    groups = summarize(rows, indicator, by="horse", where=lambda row: row.get("gait") == gait)
    if not groups:
        raise InputError(f"no rides in gait {gait!r} with a value for {indicator}")
    means = {g["group"]: g["mean"] for g in groups}
    if reference_horse is None:
        reference_horse = min(means, key=means.__getitem__)
    elif reference_horse not in means:
        raise InputError(f"reference horse {reference_horse!r} has no {gait} rides with {indicator}")
    ref = means[reference_horse]
    if not ref > 0:
        raise InputError(f"reference horse {reference_horse!r} has {indicator} = {ref}; cannot divide")
    table = [{"horse": g["group"], "n": g["n"], "mean": g["mean"], "relative": g["mean"] / ref}
             for g in groups]
    table.sort(key=lambda r: -r["relative"])
    return {"indicator": indicator, "unit": indicator_unit(indicator), "gait": gait,
            "reference_horse": reference_horse, "rows": table, "caveat": PASSIVE_SEATED_CAVEAT}


# --------------------------------------------------------------------------------------------
# Comparisons (thesis Figs 8.29-8.32)


def _group_order(key: str, names: Iterable[str]) -> list[str]:
    names = list(names)
    if key == "gait":
        known = [g for g in GAITS if g in names]
        return known + sorted(n for n in names if n not in GAITS)
    return sorted(names)


def summarize(rows: Iterable[Mapping], indicator: str, *, by: str,
              where: Callable[[Mapping], bool] | None = None) -> list[dict]:
    """Per-group statistics of one indicator.

    Parameters
    ----------
    rows : iterable of dict
        Ride rows.
    indicator : str
        Indicator key.
    by : str
        Row field to group by ("gait", "horse", "rider", ...).
    where : callable, optional
        Keep only rows for which it returns True.

    Returns
    -------
    list of dict
        One per group (gaits in walk, sitting trot, rising trot, canter order, others sorted):
        ``group``, ``n``, ``mean``, ``std`` (sample, ddof = 1; NaN for n = 1), ``min``,
        ``max``.  Rows without a finite-or-infinite value (missing or NaN) are skipped.
    """
    values: dict[str, list[float]] = defaultdict(list)
    for row in rows:
        if where is not None and not where(row):
            continue
        if by not in row:
            raise InputError(f"ride {row.get('ride_id', '?')} has no {by!r} to group by")
        value = _value(row, indicator)
        if not math.isnan(value):
            values[str(row[by])].append(value)
    out = []
    for group in _group_order(by, values):
        arr = np.asarray(values[group])
        out.append({
            "group": group,
            "n": int(arr.size),
            "mean": float(arr.mean()),
            "std": float(arr.std(ddof=1)) if arr.size > 1 else math.nan,
            "min": float(arr.min()),
            "max": float(arr.max()),
        })
    return out


def compare_gaits(rows: Iterable[Mapping], indicator: str, *, horse: str) -> list[dict]:
    """One horse across gaits (thesis Figs 8.29-8.32): :func:`summarize` by gait."""
    return summarize(rows, indicator, by="gait", where=lambda row: row.get("horse") == horse)


def compare_horses(rows: Iterable[Mapping], indicator: str, *, gait: str) -> list[dict]:
    """Horses within one gait (thesis 8.5.2): :func:`summarize` by horse."""
    return summarize(rows, indicator, by="horse", where=lambda row: row.get("gait") == gait)


def leaderboard(rows: Iterable[Mapping], indicator: str, *, gait: str,
                lower_is_better: bool | None = None) -> list[dict]:
    """Horses ranked by an indicator in one gait, most comfortable first.

    Parameters
    ----------
    rows : iterable of dict
        Ride rows.
    indicator : str
        Indicator key.
    gait : str
        Gait to rank in.
    lower_is_better : bool, optional
        Ranking direction; by default taken from :data:`INDICATORS` (raises for indicators
        such as speed that have no comfort direction).

    Returns
    -------
    list of dict
        ``rank`` (ties share the better rank), ``horse``, ``n`` (rides behind the mean),
        ``mean``, ``std``, ``min``, ``max``, ``spread`` (max - min).
    """
    lower = _better(indicator, lower_is_better)
    groups = compare_horses(rows, indicator, gait=gait)
    groups.sort(key=lambda g: (g["mean"] if lower else -g["mean"], g["group"]))
    out = []
    for i, g in enumerate(groups):
        tied = out and out[-1]["mean"] == g["mean"]
        out.append({
            "rank": out[-1]["rank"] if tied else i + 1,
            "horse": g["group"],
            "n": g["n"],
            "mean": g["mean"],
            "std": g["std"],
            "min": g["min"],
            "max": g["max"],
            "spread": g["max"] - g["min"],
        })
    return out


# --------------------------------------------------------------------------------------------
# Riders' grades (thesis Table 8.8, Figs 8.33-8.36)


def average_grades(grade_rows: Iterable[Mapping], *, gait: str | None = None) -> list[dict]:
    """Average of the riders' 1-5 grades per horse and gait (thesis Table 8.8 'avg' rows).

    Parameters
    ----------
    grade_rows : iterable of dict
        ``{"horse", "gait", "rider", "grade"}`` with grade in 1..5.
    gait : str, optional
        Keep only this gait.

    Returns
    -------
    list of dict
        ``horse``, ``gait``, ``grade`` (mean), ``n`` (number of grades), ``std``.
    """
    grades: dict[tuple[str, str], list[float]] = defaultdict(list)
    for row in grade_rows:
        for field in ("horse", "gait", "grade"):
            if field not in row:
                raise InputError(f"grade row {dict(row)!r} has no {field!r}")
        if gait is not None and row["gait"] != gait:
            continue
        grade = row["grade"]
        if isinstance(grade, bool) or not isinstance(grade, int | float | np.integer | np.floating) \
                or not 1 <= grade <= 5:
            raise InputError(
                f"grade of rider {row.get('rider', '?')} for {row['horse']} ({row['gait']}) must be "
                f"1-5, got {grade!r}"
            )
        grades[(str(row["horse"]), str(row["gait"]))].append(float(grade))
    gait_rank = {g: i for i, g in enumerate(GAITS)}
    keys = sorted(grades, key=lambda hg: (gait_rank.get(hg[1], len(GAITS)), hg[1], hg[0]))
    return [{"horse": h, "gait": g, "grade": float(np.mean(grades[(h, g)])), "n": len(grades[(h, g)]),
             "std": float(np.std(grades[(h, g)], ddof=1)) if len(grades[(h, g)]) > 1 else math.nan}
            for h, g in keys]


def _fisher_ci(r: float, n: int, se_scale: float, confidence: float) -> tuple[float, float]:
    if n <= 3 or math.isnan(r):
        return math.nan, math.nan
    if abs(r) >= 1:
        return r, r
    z = math.atanh(r)
    half = stats.norm.ppf(0.5 + confidence / 2) * se_scale / math.sqrt(n - 3)
    return math.tanh(z - half), math.tanh(z + half)


def _t_test_p(r: float, n: int) -> float:
    if math.isnan(r) or n < 3:
        return math.nan
    if abs(r) >= 1:
        return 0.0
    t = r * math.sqrt((n - 2) / (1 - r * r))
    return float(2 * stats.t.sf(abs(t), n - 2))


def _pearson(x: np.ndarray, y: np.ndarray) -> float:
    dx, dy = x - x.mean(), y - y.mean()
    denom = math.sqrt(float(dx @ dx) * float(dy @ dy))
    if denom == 0:
        return math.nan  # a constant variable has no correlation
    return float(np.clip((dx @ dy) / denom, -1.0, 1.0))


def grade_correlation(grades, values, *, confidence: float = 0.95) -> dict[str, float]:
    """Pearson and Spearman correlation of riders' grades with an indicator.

    Parameters
    ----------
    grades, values : array_like of shape (n,)
        Paired observations (e.g. average grade of a horse in a gait, and its indicator).
        Pairs with a NaN are dropped.
    confidence : float
        Confidence level of the intervals (default 0.95).

    Returns
    -------
    dict
        ``n``, ``pearson_r``, ``pearson_p`` (two-sided, t test with n - 2 degrees of freedom,
        as :func:`scipy.stats.pearsonr`), ``pearson_ci_low``, ``pearson_ci_high`` (Fisher z,
        standard error 1/sqrt(n - 3)), ``spearman_rho``, ``spearman_p`` (t approximation, as
        :func:`scipy.stats.spearmanr`), ``spearman_ci_low``, ``spearman_ci_high`` (Fisher z
        with the Fieller-Hartley-Pearson standard error sqrt(1.06 / (n - 3))).  NaN where
        undefined: a constant variable, fewer than 3 pairs (p) or 4 pairs (intervals).
    """
    x = np.asarray(grades, dtype=float).ravel()
    y = np.asarray(values, dtype=float).ravel()
    if x.shape != y.shape:
        raise InputError(f"{x.size} grades but {y.size} indicator values; they must be paired")
    if not 0 < confidence < 1:
        raise InputError(f"confidence must be between 0 and 1, got {confidence}")
    keep = ~(np.isnan(x) | np.isnan(y))
    x, y = x[keep], y[keep]
    n = int(x.size)
    r = _pearson(x, y) if n >= 2 else math.nan
    rho = _pearson(stats.rankdata(x), stats.rankdata(y)) if n >= 2 else math.nan
    p_lo, p_hi = _fisher_ci(r, n, 1.0, confidence)
    s_lo, s_hi = _fisher_ci(rho, n, math.sqrt(1.06), confidence)
    return {
        "n": n,
        "pearson_r": r,
        "pearson_p": _t_test_p(r, n),
        "pearson_ci_low": p_lo,
        "pearson_ci_high": p_hi,
        "spearman_rho": rho,
        "spearman_p": _t_test_p(rho, n),
        "spearman_ci_low": s_lo,
        "spearman_ci_high": s_hi,
    }


def grades_vs_indicators(grade_rows: Iterable[Mapping], indicator_rows: Iterable[Mapping],
                         indicators: Sequence[str] = COMFORT_INDICATORS, *,
                         gait: str | None = None, confidence: float = 0.95) -> dict[str, dict]:
    """Riders' grades against indicators (thesis Figs 8.33-8.36).

    As in the thesis, each point is one horse in one gait: the average of the riders'
    grades (:func:`average_grades`) against the mean indicator over that horse's rides in
    that gait.

    Parameters
    ----------
    grade_rows : iterable of dict
        ``{"horse", "gait", "rider", "grade"}``.
    indicator_rows : iterable of dict
        Ride rows with ``horse``, ``gait`` and the indicators.
    indicators : sequence of str
        Indicator keys; default the eight comfort indicators.
    gait : str, optional
        One gait (one figure of the thesis), or all gaits pooled.

    Returns
    -------
    dict of indicator -> dict
        The :func:`grade_correlation` result plus ``expected_sign`` (-1 where a lower value is
        more comfortable, +1 where higher is, 0 without direction) and ``points``: the list of
        ``{"horse", "gait", "grade", "value"}`` behind it.
    """
    mean_grades = {(g["horse"], g["gait"]): g["grade"] for g in average_grades(grade_rows, gait=gait)}
    indicator_rows = [row for row in indicator_rows if gait is None or row.get("gait") == gait]
    out = {}
    for indicator in indicators:
        per_pair: dict[tuple[str, str], list[float]] = defaultdict(list)
        for row in indicator_rows:
            value = _value(row, indicator)
            if not math.isnan(value):
                per_pair[(str(row.get("horse")), str(row.get("gait")))].append(value)
        points = [{"horse": h, "gait": g, "grade": mean_grades[(h, g)], "value": float(np.mean(v))}
                  for (h, g), v in per_pair.items() if (h, g) in mean_grades]
        points.sort(key=lambda p: (p["gait"], p["horse"]))
        result: dict = grade_correlation([p["grade"] for p in points], [p["value"] for p in points],
                                         confidence=confidence)
        better = INDICATORS.get(indicator, IndicatorInfo("", "")).better
        result["expected_sign"] = {"lower": -1, "higher": 1}.get(better, 0)
        result["points"] = points
        out[indicator] = result
    return out

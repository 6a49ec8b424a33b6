"""Rider comfort indicators of one ride from its saddle accelerations (thesis Table 8.7).

Vertical = y axis of the motion frame, weighted with W_b (BS 6841) and W_k (ISO 2631-1);
horizontal axes x (travel) and z with W_d.  Times in hours, distances in km.  The keys and their
meaning are in :mod:`saddlescope.core.vibration.indicator_keys`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from saddlescope.core.errors import InputError, VibrationError
from saddlescope.core.vibration.exposure import exposure_limits, per_axis_exposure
from saddlescope.core.vibration.indicator_keys import COMFORT_INDICATORS
from saddlescope.core.vibration.metrics import harmonic_metrics, sampled_metrics

__all__ = [
    "ride_indicators",
    "ride_indicators_sampled",
    "comfort_indicators",
]


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
        "vdv_ratio_y_wb": wb["vdv"] / (1.4 * wb["rms"] * duration_s ** 0.25),  # ISO 2631-1 6.3.3
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
    """The thesis's eight comfort indicators (8.5, all W_b) picked out of an indicator dict.

    Parameters
    ----------
    indicators : dict of str -> float
        A ride's indicators (:func:`ride_indicators`).

    Returns
    -------
    dict of str -> float
        The keys of :data:`COMFORT_INDICATORS`, in that order.
    """
    missing = [key for key in COMFORT_INDICATORS if key not in indicators]
    if missing:
        raise InputError(f"indicators lack the comfort indicator(s) {', '.join(missing)}")
    return {key: float(indicators[key]) for key in COMFORT_INDICATORS}

"""Daily exposure and the EU 2002/44/EC whole-body action and limit values (thesis 7.3, Table 7.2)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from saddlescope.core.errors import VibrationError

__all__ = [
    "A8_ACTION_M_S2",
    "A8_LIMIT_M_S2",
    "VDV_ACTION_M_S175",
    "VDV_LIMIT_M_S175",
    "HORIZONTAL_FACTOR",
    "a8",
    "exposure_limits",
    "per_axis_exposure",
]

# EU Physical Agents (Vibration) Directive 2002/44/EC, whole-body (thesis Table 7.2).
A8_ACTION_M_S2 = 0.5
A8_LIMIT_M_S2 = 1.15
VDV_ACTION_M_S175 = 9.1
VDV_LIMIT_M_S175 = 21.0
# Directive and ISO 2631-1 health factor k for the horizontal axes of a seated person.
HORIZONTAL_FACTOR = 1.4
_REFERENCE_DAY_H = 8.0


def a8(rms: float, exposure_h: float) -> float:
    """Daily exposure A(8) = a_w,rms sqrt(T / 8 h) for ``exposure_h`` hours a day.

    Parameters
    ----------
    rms : float
        Weighted r.m.s. acceleration a_w,rms (m/s^2).
    exposure_h : float
        Hours of exposure a day.

    Returns
    -------
    float
        A(8) in m/s^2.
    """
    _check_non_negative(rms=rms, exposure_h=exposure_h)
    return float(rms * math.sqrt(exposure_h / _REFERENCE_DAY_H))


def _check_non_negative(**values: float) -> None:
    for key, value in values.items():
        if not isinstance(value, int | float | np.floating | np.integer) or not math.isfinite(value):
            raise VibrationError(f"{key} must be a finite number, got {value!r}")
        if value < 0:
            raise VibrationError(f"{key} must be >= 0, got {value}")



def exposure_limits(rms: float, vdv: float, duration_s: float, speed_kmh: float) -> dict[str, float]:
    """Times and distances to the EU 2002/44/EC whole-body action and limit values.

    T_A(8) = 8 h (A8_threshold / a_w,rms)^2                      (eq. 7.10-7.13)
    T_VDV  = tau (VDV_threshold / VDV)^4                           (eq. 7.14-7.17, corrected:
             VDV grows with the fourth root of time; the thesis prints a linear ratio and uses
             the action value for the limit)
    D      = v_x,avg T                                             (eq. 7.18-7.25)

    Parameters
    ----------
    rms : float
        Weighted r.m.s. acceleration a_w,rms (m/s^2) over the analysed window.
    vdv : float
        VDV (m/s^1.75) of the analysed window.
    duration_s : float
        Duration tau of the analysed window (s) that produced ``vdv``.
    speed_kmh : float
        Average speed in the direction of travel (km/h).

    Returns
    -------
    dict
        ``t_a8_action_h``, ``t_a8_limit_h``, ``t_vdv_action_h``, ``t_vdv_limit_h`` (hours) and
        ``d_a8_action_km``, ``d_a8_limit_km``, ``d_vdv_action_km``, ``d_vdv_limit_km`` (km).
        Zero vibration gives infinite times.
    """
    _check_non_negative(rms=rms, vdv=vdv, duration_s=duration_s, speed_kmh=speed_kmh)
    if duration_s == 0:
        raise VibrationError("duration_s must be > 0 to scale a VDV to a daily exposure")

    def a8_time(threshold: float) -> float:
        return _REFERENCE_DAY_H * (threshold / rms) ** 2 if rms > 0 else math.inf

    def vdv_time(threshold: float) -> float:
        return duration_s * (threshold / vdv) ** 4 / 3600.0 if vdv > 0 else math.inf

    times = {
        "t_a8_action_h": a8_time(A8_ACTION_M_S2),
        "t_a8_limit_h": a8_time(A8_LIMIT_M_S2),
        "t_vdv_action_h": vdv_time(VDV_ACTION_M_S175),
        "t_vdv_limit_h": vdv_time(VDV_LIMIT_M_S175),
    }
    out = dict(times)
    for key, hours in times.items():
        out["d" + key[1:-2] + "_km"] = speed_kmh * hours if speed_kmh > 0 else 0.0
    return out


def per_axis_exposure(rms_by_axis: Mapping[str, float], vdv_by_axis: Mapping[str, float],
                      duration_s: float, speed_kmh: float, *, vertical_axis: str = "y",
                      horizontal_factor: float = HORIZONTAL_FACTOR) -> dict:
    """Exposure from several axes with the directive's worst-axis rule.

    2002/44/EC (Annex, B.1) and ISO 2631-1 (7.2.3): the daily exposure is the highest of
    1.4 a_wx, 1.4 a_wy, a_wz for a seated person (x, y horizontal with W_d, z vertical with
    W_k); the same for the VDV.  In the thesis's motion frame the vertical axis is y.

    Parameters
    ----------
    rms_by_axis, vdv_by_axis : mapping of axis name -> float
        Weighted r.m.s. (m/s^2) and VDV (m/s^1.75) per axis, same axes in both.
    duration_s, speed_kmh : float
        As in :func:`exposure_limits`.
    vertical_axis : str
        Axis that takes factor 1; every other axis takes ``horizontal_factor``.

    Returns
    -------
    dict
        ``rms_effective`` and ``vdv_effective`` (axis -> value after the factor),
        ``worst_axis_a8``, ``worst_axis_vdv`` (axis names), ``rms``, ``vdv`` (the worst
        effective values) and the eight keys of :func:`exposure_limits` computed from them.
    """
    if set(rms_by_axis) != set(vdv_by_axis) or not rms_by_axis:
        raise VibrationError(
            f"per-axis r.m.s. and VDV must name the same axes, got {sorted(rms_by_axis)} and "
            f"{sorted(vdv_by_axis)}"
        )
    if vertical_axis not in rms_by_axis:
        raise VibrationError(f"vertical axis {vertical_axis!r} is not among {sorted(rms_by_axis)}")
    factors = {axis: 1.0 if axis == vertical_axis else horizontal_factor for axis in rms_by_axis}
    for axis in rms_by_axis:
        _check_non_negative(**{f"rms_{axis}": rms_by_axis[axis], f"vdv_{axis}": vdv_by_axis[axis]})
    rms_eff = {axis: factors[axis] * float(rms_by_axis[axis]) for axis in rms_by_axis}
    vdv_eff = {axis: factors[axis] * float(vdv_by_axis[axis]) for axis in vdv_by_axis}
    worst_a8 = max(rms_eff, key=rms_eff.__getitem__)
    worst_vdv = max(vdv_eff, key=vdv_eff.__getitem__)
    out: dict = {
        "rms_effective": rms_eff,
        "vdv_effective": vdv_eff,
        "worst_axis_a8": worst_a8,
        "worst_axis_vdv": worst_vdv,
        "rms": rms_eff[worst_a8],
        "vdv": vdv_eff[worst_vdv],
    }
    out.update(exposure_limits(rms_eff[worst_a8], vdv_eff[worst_vdv], duration_s, speed_kmh))
    return out

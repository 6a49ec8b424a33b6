"""The comfort indicators' keys, units and meaning (thesis Table 8.7 and section 8.5).

:data:`INDICATORS` is the one table of every indicator key a ride's result holds (47), in the
order the exports list them; :data:`CONTRACT_KEYS` are the 25 of thesis Table 8.7 fixed by
CONTRACTS section 2, :data:`COMFORT_INDICATORS` the thesis's eight comfort indicators.
Vertical = y axis of the motion frame, weighted with W_b (BS 6841) and W_k (ISO 2631-1);
horizontal axes x (travel) and z with W_d.  Times in hours, distances in km.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

__all__ = [
    "GAITS",
    "CONTRACT_KEYS",
    "COMFORT_INDICATORS",
    "INDICATORS",
    "IndicatorInfo",
    "PASSIVE_SEATED_CAVEAT",
    "indicator_unit",
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
    better: Literal["lower", "higher"] | None = None


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


def _horizontal_infos() -> dict[str, IndicatorInfo]:
    """The W_d indicators of the fore-aft (x) and lateral (z) axes."""
    infos = {}
    for axis, name in (("x", "fore-aft"), ("z", "lateral")):
        infos[f"acc_{axis}_wd_rms"] = IndicatorInfo(
            "m/s^2", f"{name} W_d weighted r.m.s. acceleration", None, "lower")
        infos[f"vdv_{axis}_wd"] = IndicatorInfo(
            "m/s^1.75", f"{name} W_d vibration dose value", None, "lower")
        infos[f"acc_{axis}_max"] = IndicatorInfo(
            "m/s^2", f"peak unweighted {name} acceleration", None, "lower")
    return infos


def _worst_axis_infos() -> dict[str, IndicatorInfo]:
    """Times and distances to the exposure values on the worst axis (the directive's rule)."""
    infos = {}
    for basis in ("a8", "vdv"):
        for level in ("action", "limit"):
            infos[f"t_{basis}_{level}_worst_h"] = IndicatorInfo(
                "h", f"time to the {basis.upper()} {level} value, worst axis (1.4 W_d x, W_k y, 1.4 W_d z)",
                None, "higher")
            infos[f"d_{basis}_{level}_worst_km"] = IndicatorInfo(
                "km", f"distance to the {basis.upper()} {level} value, worst axis", None, "higher")
    return infos


# Every indicator key a ride's result may hold (47), in the order the exports list them.
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
    # ISO 2631-1 6.3.3: VDV over its estimate from the r.m.s., 1.4 a_w T^(1/4); above 1.75 the r.m.s. (and the
    # A(8) times built on it) understate the jolts, and the VDV's times are the ones to read
    "vdv_ratio_y_wb": IndicatorInfo("", "vertical W_b VDV over its r.m.s. estimate (ISO 2631-1 6.3.3)", None,
                                    "lower"),
    "duration_s": IndicatorInfo("s", "analysed duration (whole number of periods)"),
    **_horizontal_infos(),
    **_worst_axis_infos(),
}

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
    """Unit of an indicator key, from :data:`INDICATORS` or else from its suffix.

    Parameters
    ----------
    key : str
        Indicator key.

    Returns
    -------
    str
        The unit ("" if dimensionless or unknown).
    """
    if key in INDICATORS:
        return INDICATORS[key].unit
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix):
            return unit
    return ""

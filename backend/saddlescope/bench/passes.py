"""Rides of several passes against one (issue 38): how much pooling the passes' strides narrows the W_b interval.

The same horse (seed, rig, size, speed band) filmed passing the wide rig's cameras once and three times; both
rides analysed whole. Reported per ride: W_b r.m.s. against the truth, its 95 % interval's half-width and
whether it holds the truth, and the floor under that half-width (the interval's systematic parts alone:
calibration scale, the markers' skin sliding, the harmonics' shape, which more strides cannot remove); and the
three-pass / one-pass interval ratio (goal at most 0.65 where the floor allows).
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["floor_half_width", "passes_interval_ratio"]


def floor_half_width(doc: dict, key: str = "acc_y_wb_rms") -> float | None:
    """The half-width (fraction of the value) of ``key``'s interval from the result's systematic parts alone.

    The result's own noise model (``quality.interval_sources``) with the fits' noise and the stride
    frequency's random part set to nothing: what pooling any number of strides would leave.
    """
    import numpy as np

    from saddlescope.core.vibration.intervals import FLOORS, ride_intervals
    from saddlescope.io.result_document import result_from_document

    sources = dict((doc.get("quality") or {}).get("interval_sources") or {})
    if not sources or key not in doc.get("indicators", {}):
        return None
    sources["harmonic_m_s2"] = np.zeros(len(sources.get("harmonic_m_s2") or [0.0]))
    sources["f0"] = FLOORS["f0"]
    lo, hi = ride_intervals(result_from_document(doc), sources=sources)[key]
    return float(0.5 * (hi - lo) / doc["indicators"][key])


def _ride_row(doc: dict, truth: dict, key: str = "acc_y_wb_rms") -> dict:
    """One ride's W_b r.m.s. against the truth, its interval and the floor under it."""
    value, true = float(doc["indicators"][key]), float(truth["indicators"][key])
    lo, hi = doc["indicators_interval_95"][key]
    passes = doc.get("passes") or []
    return {**_speed_against_used(doc, truth),
            "wb_rms": value, "wb_rms_truth": true, "wb_rms_error_pct": 100 * (value / true - 1),
            "half_width_pct": 50 * (hi - lo) / value, "holds_truth": bool(lo <= true <= hi),
            "floor_half_width_pct": (None if (f := floor_half_width(doc, key)) is None else 100 * f),
            "strides_per_pass": [p["strides"] for p in passes if p.get("used")] or None,
            "too_uncertain": bool(((doc.get("quality") or {}).get("decision") or {}).get("too_uncertain"))}


def _speed_against_used(doc: dict, truth: dict) -> dict:
    """The speed's error against the truth of the passes the result used (all passes' mean when it used all).

    The passes' speeds differ (by design); a pass left out changes which mean the ride's speed estimates.
    """
    true_kmh = float(truth["indicators"]["vel_x_avg_kmh"])
    true_passes = (truth.get("truth") or {}).get("passes") or []
    used = [p for p in doc.get("passes") or [] if p.get("used")]
    if used and true_passes:
        def owner(p):  # the true pass whose crossing is nearest the pass's middle
            mid = 0.5 * (p["start_s"] + p["end_s"])
            return min(true_passes, key=lambda tp: abs(tp["t_cross_s"] - mid))
        true_kmh = sum(owner(p)["speed_kmh"] for p in used) / len(used)
    value = float(doc["indicators"]["vel_x_avg_kmh"])
    lo, hi = doc["indicators_interval_95"]["vel_x_avg_kmh"]
    return {"speed_error_pct": 100 * (value / true_kmh - 1), "speed_holds_truth": bool(lo <= true_kmh <= hi)}


def passes_interval_ratio(tmp: Path, *, seed: int = 3, size: tuple[int, int] = (1280, 720), fps: float = 30.0,
                          speed_range_m_s: tuple[float, float] | None = (5.5, 6.0),
                          calibration_poses: int = 40) -> dict:
    """The W_b r.m.s. interval of a three-pass canter on the wide rig over that of the same horse's one pass.

    ``speed_range_m_s`` (default a working canter, 5.5-6 m/s) makes each crossing of the common view hold
    1.3-1.5 s, one or two fitted strides: the case of issue 38. Returns the two rides' rows
    (:func:`_ride_row`), ``wb_interval_ratio_3_vs_1`` and the floors' ratio, or ``error`` on a failure.
    """
    from saddlescope.io.synth_writer import write_ride_bundle
    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    out: dict = {"seed": seed, "rig": "wide", "size": list(size), "fps": fps, "speed_range_m_s": speed_range_m_s}
    for passes in (1, 3):
        ride = tmp / f"passes_{passes}_canter_{seed}"
        try:
            write_ride_bundle(ride, gait="canter", seed=seed, rig="wide", size=size, fps=fps, passes=passes,
                              calibration_poses=calibration_poses, extras=False, speed_range_m_s=speed_range_m_s)
            out[f"passes_{passes}"] = _ride_row(analyze_bundle(ride), json.loads((ride / "truth.json").read_text()))
        except Exception as exc:  # noqa: BLE001 - a benchmark reports every failure and goes on
            out["error"] = f"{passes} pass(es): {type(exc).__name__}: {exc}"
            return out
    one, three = out["passes_1"], out["passes_3"]
    out["wb_interval_ratio_3_vs_1"] = three["half_width_pct"] / one["half_width_pct"]
    if one["floor_half_width_pct"]:
        # the best pooling can do: the three-pass floor over the one-pass interval
        out["wb_floor_ratio_3_vs_1"] = three["floor_half_width_pct"] / one["half_width_pct"]
    return out

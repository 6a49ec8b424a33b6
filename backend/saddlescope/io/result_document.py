"""The result document of CONTRACTS section 2, written from a :class:`RideResult` and read back.

This is the one place the result's JSON shape is written: the CLI's ``analyze --json``, the jobs'
stored ``result.json`` and the REST result all come from :func:`result_to_document`. Arrays are
rounded to 9 decimals (nanometres, nanoseconds) and missing values written as null.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from saddlescope.core.pipeline.result import rounded_list
from saddlescope.core.types import (
    AnalysisWindow,
    HorseMarkers,
    MotionFrameSummary,
    RidePass,
    RideResult,
    SaddleKinematics,
    SaddleRotation,
    VerticalHarmonics,
)
from saddlescope.io.findings_document import findings_of, findings_to_list
from saddlescope.io.result_schema import RESULT_FORMAT
from saddlescope.io.rig_document import rig_from_dict, rig_to_dict

__all__ = ["result_from_document", "result_to_document"]


def _nan_to_none(obj):
    """``obj`` with NaN and infinities as None and numpy scalars and arrays as Python values (JSON)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _nan_to_none(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_nan_to_none(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _nan_to_none(obj.tolist())
    if isinstance(obj, np.floating):
        return _nan_to_none(float(obj))
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _calibration(result: RideResult) -> dict:
    calibration = rig_to_dict(result.rig)
    if result.board_coverage_fraction is not None:  # computed from the ride's own calibration clips
        calibration["n_views"] = result.calibration_views
        calibration["board_coverage_fraction"] = dict(result.board_coverage_fraction)
    return calibration


def _angular(rot: SaddleRotation) -> dict:
    gain = rot.weak_axis_gain
    return {"omega_rad_s": rounded_list(rot.omega_rad_s), "alpha_rad_s2": rounded_list(rot.alpha_rad_s2),
            "singularity_index": rot.singularity_index,
            "singularity_index_per_frame": rounded_list(rot.singularity_index_per_frame),
            "omega_versions_rad_s": rounded_list(rot.omega_versions_rad_s),
            "omega_versions_excluded": np.asarray(rot.omega_versions_excluded).tolist(),
            "omega_spread_rad_s": rounded_list(rot.omega_spread_rad_s),
            "method": rot.method,
            "weak_axis_gain": None if gain is None else {"omega": gain[0], "alpha": gain[1]}}


def result_to_document(result: RideResult) -> dict[str, Any]:
    """The result document (CONTRACTS section 2) of a ride's analysis, JSON-ready."""
    s, m, w = result.saddle, result.markers, result.window
    doc = {
        "format": RESULT_FORMAT,
        "fps": result.fps,
        "gait": result.gait,
        "direction": result.direction,
        "calibration": _calibration(result),
        "sync": {kind: dict(off) for kind, off in result.sync_offsets.items()},
        "period_s": result.period_s,
        "window": {"start_s": w.start_s, "duration_s": w.duration_s, "start_frame": w.start_frame,
                   "frames": w.frames},
        "saddle": {"t_s": rounded_list(s.t_s), "position_m": rounded_list(s.position_m),
                   "velocity_m_s": rounded_list(s.velocity_m_s),
                   "acceleration_m_s2": rounded_list(s.acceleration_m_s2),
                   "acceleration_spread_m_s2": rounded_list(s.acceleration_spread_m_s2),
                   "body_coordinates_m": rounded_list(s.body_coordinates_m)},
        "angular": _angular(result.angular),
        "markers": {"names": list(m.names), "position_m": rounded_list(m.position_m),
                    "velocity_m_s": rounded_list(m.velocity_m_s),
                    "acceleration_m_s2": rounded_list(m.acceleration_m_s2),
                    "rigidity_residual_mm": rounded_list(m.rigidity_residual_mm), "fits": m.fits},
        "motion_frame": {"R_rig_to_motion": rounded_list(result.motion_frame.R_rig_to_motion),
                         "origin_mm": rounded_list(result.motion_frame.origin_mm),
                         "gravity_source": result.motion_frame.gravity_source},
        "vertical_harmonics": {"f0_hz": result.vertical_harmonics.f0_hz,
                               "amplitudes_m_s2": rounded_list(result.vertical_harmonics.amplitudes_m_s2),
                               "phases_rad": rounded_list(result.vertical_harmonics.phases_rad)},
        "indicators": dict(result.indicators),
        "indicators_interval_95": ({k: [float(lo), float(hi)] for k, (lo, hi) in result.indicators_interval_95.items()}
                                   if result.indicators_interval_95 is not None else None),
        # the findings as data, and their details as the first format's sentences (``flags``)
        "quality": {**result.quality, "flags": result.flags, "findings": findings_to_list(result.findings)},
        "params": dict(result.params),
        "timings_s": dict(result.timings_s),
    }
    if doc["indicators_interval_95"] is None:  # a result made before intervals: the key stays out
        del doc["indicators_interval_95"]
    if result.passes:  # a ride of several passes (issue 38); one pass: the key stays out
        doc["passes"] = [_pass_document(p) for p in result.passes]
    return _nan_to_none(doc)


def _pass_document(p: RidePass) -> dict:
    """One pass of the ride as the document's ``passes`` entry."""
    return {"start_s": p.start_s, "end_s": p.end_s, "start_frame": p.start_frame, "frames": p.frames,
            "strides": p.strides, "speed_m_s": p.speed_m_s, "stride_frequency_hz": p.stride_frequency_hz,
            "indicators": dict(p.indicators),
            "indicators_interval_95": {k: [float(lo), float(hi)] for k, (lo, hi) in p.intervals_95.items()},
            "used": p.used, "reason": p.reason}


def _passes(doc_passes: Any) -> tuple[RidePass, ...]:
    """The document's ``passes`` (absent: one pass, an empty tuple)."""
    if not isinstance(doc_passes, list):
        return ()
    return tuple(RidePass(start_s=float(p["start_s"]), end_s=float(p["end_s"]), start_frame=int(p["start_frame"]),
                          frames=int(p["frames"]), strides=int(p["strides"]),
                          speed_m_s=None if p.get("speed_m_s") is None else float(p["speed_m_s"]),
                          stride_frequency_hz=(None if p.get("stride_frequency_hz") is None
                                               else float(p["stride_frequency_hz"])),
                          indicators={k: _number(v) for k, v in (p.get("indicators") or {}).items()},
                          intervals_95={k: (float(lo), float(hi))
                                        for k, (lo, hi) in (p.get("indicators_interval_95") or {}).items()},
                          used=bool(p.get("used", True)), reason=p.get("reason"))
                 for p in doc_passes)


def _array(values: Any) -> np.ndarray:
    """A document's (nested) list as a float array, null as NaN."""
    return np.array(_none_to_nan(values), dtype=np.float64)


def _none_to_nan(values: Any) -> Any:
    if isinstance(values, list | tuple):
        return [_none_to_nan(v) for v in values]
    return np.nan if values is None else values


def _number(value: Any) -> float:
    return np.nan if value is None else float(value)


def result_from_document(doc: Mapping[str, Any]) -> RideResult:
    """The :class:`RideResult` of a result document (the inverse of :func:`result_to_document`)."""
    cal, s, a, m = doc["calibration"], doc["saddle"], doc["angular"], doc["markers"]
    w, mf, vh = doc["window"], doc["motion_frame"], doc["vertical_harmonics"]
    gain = a.get("weak_axis_gain")
    return RideResult(
        fps=float(doc["fps"]), gait=doc.get("gait"), direction=doc.get("direction"), rig=rig_from_dict(cal),
        sync_offsets={kind: dict(off) for kind, off in doc["sync"].items()},
        period_s=_number(doc["period_s"]),
        window=AnalysisWindow(start_s=w["start_s"], duration_s=w["duration_s"], start_frame=w["start_frame"],
                              frames=w["frames"]),
        saddle=SaddleKinematics(t_s=_array(s["t_s"]), position_m=_array(s["position_m"]),
                                velocity_m_s=_array(s["velocity_m_s"]),
                                acceleration_m_s2=_array(s["acceleration_m_s2"]),
                                acceleration_spread_m_s2=_array(s["acceleration_spread_m_s2"]),
                                body_coordinates_m=_array(s["body_coordinates_m"])),
        angular=SaddleRotation(omega_rad_s=_array(a["omega_rad_s"]), alpha_rad_s2=_array(a["alpha_rad_s2"]),
                               singularity_index=_number(a["singularity_index"]),
                               singularity_index_per_frame=_array(a["singularity_index_per_frame"]),
                               omega_versions_rad_s=_array(a["omega_versions_rad_s"]),
                               omega_versions_excluded=np.array(a["omega_versions_excluded"], dtype=bool),
                               omega_spread_rad_s=_array(a["omega_spread_rad_s"]), method=a["method"],
                               weak_axis_gain=None if gain is None else (gain["omega"], gain["alpha"])),
        markers=HorseMarkers(names=tuple(m["names"]), position_m=_array(m["position_m"]),
                             velocity_m_s=_array(m["velocity_m_s"]),
                             acceleration_m_s2=_array(m["acceleration_m_s2"]),
                             rigidity_residual_mm=_array(m["rigidity_residual_mm"]), fits=m["fits"]),
        motion_frame=MotionFrameSummary(R_rig_to_motion=_array(mf["R_rig_to_motion"]),
                                        origin_mm=_array(mf["origin_mm"]), gravity_source=mf["gravity_source"]),
        vertical_harmonics=VerticalHarmonics(f0_hz=_number(vh["f0_hz"]),
                                             amplitudes_m_s2=_array(vh["amplitudes_m_s2"]),
                                             phases_rad=_array(vh["phases_rad"])),
        indicators={k: _number(v) for k, v in doc["indicators"].items()},
        quality={k: v for k, v in (doc.get("quality") or {}).items() if k not in ("flags", "findings")},
        params=dict(doc.get("params") or {}),
        timings_s=dict(doc.get("timings_s") or {}),
        calibration_views=cal.get("n_views"),
        board_coverage_fraction=cal.get("board_coverage_fraction"),
        indicators_interval_95=_intervals(doc.get("indicators_interval_95")),
        findings=tuple(findings_of(doc.get("quality"))),
        passes=_passes(doc.get("passes")),
    )


def _intervals(doc_intervals: Any) -> dict[str, tuple[float, float]] | None:
    """The document's ``indicators_interval_95`` as (low, high) tuples, null as an unbounded end."""
    if not isinstance(doc_intervals, Mapping):
        return None
    return {k: (-math.inf if lo is None else float(lo), math.inf if hi is None else float(hi))
            for k, (lo, hi) in doc_intervals.items()}

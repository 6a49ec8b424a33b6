"""The ride's result assembled from what the stages found (CONTRACTS section 2).

``saddlescope.io.result_document`` writes it as the result document and reads it back.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from saddlescope.core.findings import Finding
from saddlescope.core.params import PipelineParams
from saddlescope.core.pipeline.detection import RideTracks, depth_uncertainty
from saddlescope.core.pipeline.setup import lens_coverage_of, outside_coverage
from saddlescope.core.saddle import SaddleAnalysis
from saddlescope.core.types import (
    AnalysisWindow,
    HorseMarkers,
    MarkerTracks,
    MotionFrameSummary,
    RideResult,
    Rig,
    SaddleKinematics,
    SaddleRotation,
    VerticalHarmonics,
)
from saddlescope.core.vibration.intervals import decision_uncertainty, interval_sources, ride_intervals

__all__ = ["assemble_result", "fits_document", "rounded_list", "with_intervals"]


def rounded_list(x) -> list:
    """An array as nested lists rounded to 9 decimals (nm, µs), NaN kept (the document writes None)."""
    arr = np.asarray(x, dtype=np.float64)
    return np.where(np.isfinite(arr), np.round(arr, 9), np.nan).tolist()


def _track_quality(tracks: MarkerTracks) -> dict:
    xyz = tracks.xyz_mm
    seen = np.all(np.isfinite(xyz), axis=2)
    out = {"frames": int(xyz.shape[0]), "markers_seen_fraction": rounded_list(seen.mean(axis=0))}
    if tracks.reprojection_error_px is not None:
        err = np.asarray(tracks.reprojection_error_px, dtype=np.float64)
        fin = err[np.isfinite(err)]
        out["reprojection_error_px_median"] = float(np.median(fin)) if fin.size else None
        out["reprojection_error_px_p95"] = float(np.percentile(fin, 95)) if fin.size else None
    return out


def _outside_board(motion2d, calib_report: Mapping | None) -> dict[str, float]:
    """Per camera, the share of its marker detections outside the region the calibration board (and wand) covered."""
    coverage = lens_coverage_of(calib_report)
    if not motion2d or not coverage:
        return {}
    return {cam: float(share) for cam, share in outside_coverage(motion2d, coverage).items()}


def _findings(rig: Rig, flags: Sequence[Finding], input_flags: Sequence[Finding]) -> tuple[Finding, ...]:
    """The result's findings: the input's first, then the rig's and the stages', each once."""
    return tuple(input_flags) + tuple(dict.fromkeys([*rig.flags, *flags]))


def _quality(rig: Rig, kin: SaddleAnalysis, harm: Mapping, tracks3d: Mapping[str, MarkerTracks],
             found_motion2d=None, calib_report: Mapping | None = None, depth: Mapping | None = None) -> dict:
    """The result's ``quality``: the checks and the figures behind the findings."""
    s, ang, reg, frame = kin.saddle, kin.angular, kin.registration, kin.frame
    return {
        "calibration_ok": not rig.flags,
        "gravity_source": frame.gravity_source,
        "angle_travel_gravity_deg": frame.angle_travel_gravity_deg,
        "rigidity_residual_mm": {"median": float(np.nanmedian(reg.rms_residual) * 1e3),
                                 "max": float(np.nanmax(reg.rms_residual) * 1e3)},
        "static_marker_mismatch_mm": kin.static_mismatch_mm,
        "singularity_index_median": ang.median_singularity_index,
        "omega_versions_excluded_fraction": float(np.mean(ang.excluded)),
        "saddle_acceleration_spread_m_s2_median": float(np.nanmedian(s.acceleration_spread)),
        "vertical_harmonic_fit_rms_m_s2": harm["fit_rms_residual_m_s2"],
        "tracks": {kind: _track_quality(tr) for kind, tr in tracks3d.items()},
        "long_gaps_s": [list(g) for g in kin.long_gaps],
        # the share of the stride no fitted frame measured (issue 38): the intervals grow with it
        "stride_phase_unmeasured_share": float(kin.unmeasured_phase.get("share", 0.0)),
        "stride_phase_unmeasured_per_marker": dict(kin.unmeasured_phase.get("per_marker", {})),
        # what that part costs this ride (core.kinematics.hidden_phase's phase-deletion test), or None
        "stride_phase_deletion": kin.unmeasured_phase.get("deletion"),
        "period_estimate_s": kin.period_estimate_s,
        # the frames the fits saw (the window's harmonics are estimated from every tracked stride)
        "fitted_frames": {"start_frame": int(kin.fitted[0]), "frames": int(kin.fitted[1] - kin.fitted[0])},
        # what the indicators' intervals read (core.vibration.intervals): where the lens was extrapolated
        # and how much worse than image position the rig fixes depth at the markers
        "markers_outside_board_fraction": _outside_board(found_motion2d, calib_report),
        "depth_anisotropy": (depth or {}).get("anisotropy"),
    }


def _rotation(kin: SaddleAnalysis) -> SaddleRotation:
    ang = kin.angular
    return SaddleRotation(omega_rad_s=ang.omega_rad_s, alpha_rad_s2=ang.alpha_rad_s2,
                          singularity_index=ang.median_singularity_index,
                          singularity_index_per_frame=ang.singularity_index, omega_versions_rad_s=ang.omega_versions,
                          omega_versions_excluded=np.asarray(ang.excluded), omega_spread_rad_s=ang.omega_spread,
                          method=ang.method, weak_axis_gain=ang.weak_axis_gain)


def assemble_result(meta: Mapping, rig: Rig, calib_report: Mapping, offsets: Mapping, found: RideTracks,
                    kin: SaddleAnalysis, harm: Mapping, indicators: Mapping, fps: float, timings_s: Mapping,
                    params: PipelineParams, flags: Sequence[Finding],
                    input_flags: Sequence[Finding] = ()) -> RideResult:
    """The :class:`RideResult` of a ride from its stages' outputs.

    ``flags`` are the stages' findings in order (the input's, then the rig's, are put first); ``harm`` is
    :func:`~saddlescope.core.saddle.vertical_harmonics`' output; ``fps`` the motion clip's rate.
    """
    s, fits, frame, t_s = kin.saddle, kin.fits, kin.frame, kin.t_s
    result = RideResult(
        fps=fps, gait=meta.get("gait"), direction=meta.get("direction"), rig=rig,
        sync_offsets={kind: {c: float(v) for c, v in off.items()} for kind, off in offsets.items()},
        period_s=kin.period_s,
        window=AnalysisWindow(start_s=float(t_s[0]), duration_s=float(len(t_s) / fps),
                              start_frame=int(kin.window[0]), frames=int(len(t_s))),
        saddle=SaddleKinematics(t_s=t_s, position_m=s.position_m, velocity_m_s=s.velocity_m_s,
                                acceleration_m_s2=s.acceleration_m_s2, acceleration_spread_m_s2=s.acceleration_spread,
                                body_coordinates_m=s.body_coordinates_m),
        angular=_rotation(kin),
        markers=HorseMarkers(names=("M1", "M2", "M3"), position_m=kin.markers_m, velocity_m_s=fits.velocity_m_s,
                             acceleration_m_s2=fits.acceleration_m_s2,
                             rigidity_residual_mm=kin.registration.rms_residual * 1e3, fits=fits_document(fits)),
        motion_frame=MotionFrameSummary(R_rig_to_motion=frame.R, origin_mm=frame.origin_mm,
                                        gravity_source=frame.gravity_source),
        vertical_harmonics=VerticalHarmonics(f0_hz=harm["f0_hz"], amplitudes_m_s2=harm["amplitudes_m_s2"],
                                             phases_rad=harm["phases_rad"]),
        indicators={k: float(v) for k, v in indicators.items()},
        quality=_quality(rig, kin, harm, found.tracks3d, found.motion2d, calib_report,
                         depth_uncertainty(rig, found.tracks3d["motion"]) if "motion" in found.tracks3d else None),
        findings=_findings(rig, flags, input_flags),
        params={"n_periods": params.n_periods, "triangulation": params.triangulation,
                "smoothing_span": params.smoothing_span, "angular_method": params.angular_method,
                "x_model": params.x_model, "omega_from": params.omega_from, "fit_span": params.fit_span,
                "smoothing": params.smoothing, "criterion": params.criterion},
        timings_s=dict(timings_s),
        calibration_views=calib_report.get("n_views") if calib_report else None,
        board_coverage_fraction=({c: v["area_fraction"] for c, v in calib_report.get("board_coverage", {}).items()}
                                 if calib_report else None),
    )
    return with_intervals(result)


def with_intervals(result: RideResult, *, sources: Mapping | None = None) -> RideResult:
    """``result`` with its indicators' 95 % intervals, and the too-uncertain verdict in its quality.

    The verdict (:func:`~saddlescope.core.vibration.intervals.decision_uncertainty`) joins the findings
    (``indicators.too_uncertain``) and ``quality["decision"]``; the noise model's parts go to
    ``quality["interval_sources"]``. ``sources`` replaces the noise model read from the result (a ride of
    several passes pools its passes', :func:`~saddlescope.core.pipeline.passes.pooled_sources`).
    """
    if sources is None:
        sources = interval_sources(result, depth_anisotropy=result.quality.get("depth_anisotropy"))
    intervals = ride_intervals(result, sources=sources)
    reason = decision_uncertainty(result.indicators, intervals, sources)
    quality = dict(result.quality)
    findings = [f for f in result.findings if f.code != "indicators.too_uncertain"]
    if reason:
        findings.append(Finding("indicators.too_uncertain",
                                f"too uncertain for a decision: {reason}; it is left out of leaderboards unless "
                                "asked for"))
    quality["decision"] = {"too_uncertain": reason is not None, "reason": reason}
    quality["interval_sources"] = {"gain": sources["gain"], "gain_parts": dict(sources["gain_parts"]),
                                   "harmonic_m_s2": [float(v) for v in sources["harmonic_m_s2"]],
                                   "shape": sources["shape"], "f0": sources["f0"], "speed": sources["speed"],
                                   "peak": float(sources.get("peak", 0.0)),
                                   "displacement": float(sources.get("displacement", 0.0))}
    return replace(result, quality=quality, indicators_interval_95=intervals, findings=tuple(findings))


def fits_document(fits) -> dict:
    """The result's ``markers.fits``: a summary of every marker's fit per axis.

    The result's ``markers.fits``: per axis (x, y, z) and marker, the fit's kind, goodness of fit
    (SSE, R², adjusted R², RMSE, the residuals' and the noise's lag-1 autocorrelation), order,
    fundamental, coefficients and their 95 % confidence intervals (thesis 5.5).
    """
    return {axis: [_fit_summary(f) for f in group]
            for axis, group in (("x", fits.fits_x), ("y", fits.fits_y), ("z", fits.fits_z))}


def _fit_summary(fit) -> dict:
    out: dict[str, Any] = {"kind": type(fit).__name__}
    gof = getattr(fit, "gof", None)
    if gof is not None:
        out.update({k: (float(v) if isinstance(v, int | float | np.floating) else v)
                    for k, v in gof.as_dict().items()})
    for attr in ("order", "f0_hz", "slope", "intercept", "omega_rad_s"):
        if hasattr(fit, attr):
            val = getattr(fit, attr)
            if isinstance(val, int | float | np.floating | np.integer):
                out[attr] = float(val)
    # the coefficients with their 95 % confidence intervals (correlated noise accounted for, see
    # fitting's module note): the slope's is the average speed's
    ci = getattr(fit, "ci", None)
    if isinstance(ci, np.ndarray):
        out["ci95"] = {"intercept": rounded_list(ci[0]), "slope": rounded_list(ci[1])}
    elif isinstance(ci, dict):
        # trend[0] of a Fourier x series is the average speed (m/s)
        out["a"], out["b"], out["trend"] = rounded_list(fit.a), rounded_list(fit.b), rounded_list(fit.trend)
        out["ci95"] = {k: rounded_list(ci[k]) for k in ("a0", "a", "b", "omega_rad_s", "trend") if k in ci}
    return out

"""Fake results for tests, in one place: a typed `RideResult` of a two-camera rig with every section
filled (tests/io), built from seeded random numbers. The result documents the API and page tests store are
made from ride.json (`tests/api/api_helpers.standin_result`) and from exact Fourier series
(`tests/e2e/dashboard_helpers.result_document`)."""

from __future__ import annotations

import numpy as np

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

SQUARES = Finding("calibration.square_error", "reconstructed board squares are off by 0.40 mm RMS",
                  {"square_error_mm": 0.4})
LOST = Finding("tracking.lost", "markers lost from 1.00 s to 1.20 s", {"gap_start_s": 1.0, "gap_end_s": 1.2})

K = np.array([[600.0, 0, 320], [0, 600, 240], [0, 0, 1]])


def two_camera_rig() -> Rig:
    """A calibrated left-right rig with its checks, a calibration finding and the pair's extrinsics."""
    right_R = np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])
    cams = {"left": Camera("left", K, np.array([-0.1, 0.01, 0, 0, 0]), (640, 480), rms_px=0.2,
                           K_std=np.diag([0.3, 0.3, 0.0]), dist_std=np.full(5, 0.001)),
            "right": Camera("right", K, np.zeros(5), (640, 480), R=right_R, t_mm=np.array([-500.0, 0, 300]),
                            rms_px=0.2)}
    pairs = {"left-right": {"R": right_R, "t_mm": cams["right"].t_mm, "rms_px": 0.21, "n_views": 12}}
    return Rig(cams, checks={"board_square_error_mm": np.float64(0.1), "views": np.int64(40)}, flags=(SQUARES,),
               pairs=pairs)



def ride_result(rng: np.random.Generator, *, calibrated: bool) -> RideResult:
    """A seven-frame result with every section (one NaN sample, an infinite indicator); `calibrated`: with
    the calibration's view counts and board coverage, as a ride calibrated from its own clip."""
    n = 7
    t = np.arange(n) / 30.0
    acc = rng.normal(size=(n, 3))
    acc[2, 1] = np.nan  # a sample with no value is written as null and read back as NaN
    return RideResult(
        fps=30.0, gait="canter", direction="CCW", rig=two_camera_rig(),
        sync_offsets={"motion": {"left": 0.0, "right": 12.25}}, period_s=0.6,
        window=AnalysisWindow(start_s=1.0, duration_s=n / 30.0, start_frame=30, frames=n),
        saddle=SaddleKinematics(t_s=t, position_m=rng.normal(size=(n, 3)), velocity_m_s=rng.normal(size=(n, 3)),
                                acceleration_m_s2=acc, acceleration_spread_m_s2=rng.random(n),
                                body_coordinates_m=rng.normal(size=3)),
        angular=SaddleRotation(omega_rad_s=rng.normal(size=(n, 3)), alpha_rad_s2=rng.normal(size=(n, 3)),
                               singularity_index=0.4, singularity_index_per_frame=rng.random(n),
                               omega_versions_rad_s=rng.normal(size=(n, 6, 3)),
                               omega_versions_excluded=rng.random((n, 6)) > 0.8,
                               omega_spread_rad_s=rng.random((n, 3)), method="lsq_wiener", weak_axis_gain=(0.5, 0.25)),
        markers=HorseMarkers(names=("M1", "M2", "M3"), position_m=rng.normal(size=(n, 3, 3)),
                             velocity_m_s=rng.normal(size=(n, 3, 3)), acceleration_m_s2=rng.normal(size=(n, 3, 3)),
                             rigidity_residual_mm=rng.random(n), fits={"x": [], "y": [], "z": []}),
        motion_frame=MotionFrameSummary(R_rig_to_motion=np.eye(3), origin_mm=np.array([1.0, 2.0, 3.0]),
                                        gravity_source="plumb"),
        vertical_harmonics=VerticalHarmonics(f0_hz=1.6, amplitudes_m_s2=rng.random(4), phases_rad=rng.random(4)),
        indicators={"acc_y_wb_rms": 4.5, "t_a8_action_wb_h": float("inf")},
        quality={"singularity_index_median": np.float64(0.4)}, findings=(SQUARES, LOST),
        params={"n_periods": 2}, timings_s={"total": 1.5},
        calibration_views={"left": 40, "right": 38} if calibrated else None,
        board_coverage_fraction={"left": 0.4, "right": 0.5} if calibrated else None)

"""A small ride bundle calibrated by a wand and close-up boards, analysed end to end (issue 35 item 3)."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytestmark = pytest.mark.slow


def test_a_wand_calibrated_ride_is_analysed_end_to_end(tmp_path):
    from rendered_rides import cached_ride_bundle

    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    # The wide rig, at 960x540. On the thesis rig (cameras 0.22 m apart, 640x480) the same ride passed at the
    # last stop and failed in 3 of 3 encodes on 2026-11-29 (libx264's output is not the same from run to run):
    # the wand's rig checked 0.11 px on its own clips while the motion markers reprojected 18-50 px off
    # ("the cameras moved"); so short a baseline leaves the wand's extrinsics at the mercy of the encode.
    ride = cached_ride_bundle(tmp_path / "wand", gait="canter", seed=4, rig="wide", size=(960, 540), duration_s=3.0,
                              extras=False, calibration_poses=4, calibration="wand", wand_s=16.0, close_up_poses=25)
    meta = json.loads((ride / "ride.json").read_text())
    assert meta["calibration"] == {"method": "wand", "wand_length_m": 1.0}
    assert "calibration" not in meta["clips"] and {"wand", "close_up"} <= set(meta["clips"])
    result = analyze_bundle(ride)
    truth = json.loads((ride / "truth.json").read_text())
    checks = result["calibration"]["checks"]
    # the wand's length, triangulated freely by the calibrated cameras about its 1000 mm (flagged above 5 mm
    # r.m.s.); a broken calibration is off by metres
    assert checks["wand_length_mm"] == 1000.0
    assert checks["wand_length_rms_mm"] < 30.0
    # the cameras' baselines against the arena's (+0.2 % and +0.8 % with 16 s of wand; +1.6 % for the middle
    # camera's 237 mm with 12 s)
    for cam in ("middle", "right"):
        got = np.linalg.norm(result["calibration"]["extrinsics"][cam]["t_mm"])
        want = np.linalg.norm(truth["calibration"]["extrinsics"][cam]["t_mm"])
        assert abs(got - want) < 0.02 * want, cam
    assert abs(result["indicators"]["vel_x_avg_kmh"] / truth["truth"]["speed_kmh"] - 1) < 0.02
    assert abs(result["period_s"] / truth["period_s"] - 1) < 0.01

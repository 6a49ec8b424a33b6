"""'The cameras moved since the rig was calibrated': the markers' reprojection against the rig's own check."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import CalibrationError, CamerasMovedError
from saddlescope.core.findings import FINDING_KINDS
from saddlescope.core.pipeline.consistency import MOVED_MIN_PX, cameras_moved_finding, rig_reprojection_px
from saddlescope.core.types import Camera, MarkerTracks, Rig


def _rig(rms_px: float = 0.3, checks: dict | None = None) -> Rig:
    cams = {name: Camera(name, np.eye(3), np.zeros(5), (640, 480), rms_px=rms_px)
            for name in ("left", "middle", "right")}
    return Rig(cams, checks=checks or {})


def _tracks(err_px: float, n: int = 60) -> MarkerTracks:
    rng = np.random.default_rng(1)
    err = np.abs(rng.normal(err_px, 0.1 * err_px, (n, 3)))
    return MarkerTracks(("M1", "M2", "M3"), np.arange(n) / 30.0, np.zeros((n, 3, 3)), reprojection_error_px=err)


def test_markers_far_off_a_good_rig_say_the_cameras_moved():
    finding = cameras_moved_finding(_rig(0.3), _tracks(25.0))
    assert finding is not None and finding.code == "calibration.cameras_moved"
    assert finding.detail.startswith("the cameras moved since the rig was calibrated")
    assert finding.severity == "problem"
    assert finding.values["rig_check_px"] == pytest.approx(0.3)
    assert "calibrate the rig again" in FINDING_KINDS["calibration.cameras_moved"].advice


def test_markers_consistent_with_the_rig_say_nothing():
    assert cameras_moved_finding(_rig(0.3), _tracks(1.2)) is None
    # a few px is normal for blob centroids even on a perfect rig
    assert cameras_moved_finding(_rig(0.05), _tracks(MOVED_MIN_PX * 0.9)) is None
    # a rig whose own check is poor is judged against that check
    assert cameras_moved_finding(_rig(3.0), _tracks(20.0)) is None


def test_the_rig_check_prefers_its_triangulation_check_and_too_little_data_says_nothing():
    assert rig_reprojection_px(_rig(0.3, {"triangulation_rms_px": 0.8})) == pytest.approx(0.8)
    assert cameras_moved_finding(_rig(0.3), _tracks(25.0, n=5)) is None
    unknown = Rig({"left": Camera("left", np.eye(3), np.zeros(5), (640, 480))})
    assert cameras_moved_finding(unknown, _tracks(25.0)) is None


def test_the_error_is_a_calibration_error():
    assert issubclass(CamerasMovedError, CalibrationError)

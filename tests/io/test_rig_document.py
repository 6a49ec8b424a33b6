"""The one serialiser of a rig and of a ride's result: JSON out, the same objects back."""

from __future__ import annotations

import json

import numpy as np
import pytest

from saddlescope.core.errors import InputError
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
from saddlescope.io.result_document import result_from_document, result_to_document
from saddlescope.io.rig_document import rig_from_dict, rig_to_dict

K = np.array([[600.0, 0, 320], [0, 600, 240], [0, 0, 1]])


def _rig() -> Rig:
    right_R = np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])
    cams = {"left": Camera("left", K, np.array([-0.1, 0.01, 0, 0, 0]), (640, 480), rms_px=0.2,
                           K_std=np.diag([0.3, 0.3, 0.0]), dist_std=np.full(5, 0.001)),
            "right": Camera("right", K, np.zeros(5), (640, 480), R=right_R, t_mm=np.array([-500.0, 0, 300]),
                            rms_px=0.2)}
    pairs = {"left-right": {"R": right_R, "t_mm": cams["right"].t_mm, "rms_px": 0.21, "n_views": 12}}
    return Rig(cams, checks={"board_square_error_mm": np.float64(0.1), "views": np.int64(40)}, flags=(SQUARES,),
               pairs=pairs)


SQUARES = Finding("calibration.square_error", "reconstructed board squares are off by 0.40 mm RMS",
                  {"square_error_mm": 0.4})
LOST = Finding("tracking.lost", "markers lost from 1.00 s to 1.20 s", {"gap_start_s": 1.0, "gap_end_s": 1.2})


def test_rig_dict_round_trip_is_json():
    rig = _rig()
    d = json.loads(json.dumps(rig_to_dict(rig)))
    assert list(d["cameras"]) == ["left", "right"] and list(d["extrinsics"]) == ["right"]
    assert d["checks"] == {"board_square_error_mm": 0.1, "views": 40}  # numpy scalars as JSON numbers
    assert len(d["cameras"]["left"]["dist"]) == 5 and d["cameras"]["left"]["image_size"] == [640, 480]
    back = rig_from_dict(d)
    for n in rig.cameras:
        a, b = rig.cameras[n], back.cameras[n]
        assert np.allclose(a.K, b.K) and np.allclose(a.R, b.R) and np.allclose(a.t_mm, b.t_mm)
        assert b.rms_px == 0.2
    assert np.allclose(back.cameras["left"].K_std, rig.cameras["left"].K_std)
    assert back.flags == (SQUARES,)  # code, detail and values
    assert d["flags"] == [SQUARES.detail]  # the sentences still written for readers of the first format
    assert d["findings"][0]["severity"] == "problem" and d["findings"][0]["stage"] == "calibration"
    assert np.allclose(back.pairs["left-right"]["t_mm"], rig.cameras["right"].t_mm)
    with pytest.raises(InputError, match="camera right has no extrinsics"):
        rig_from_dict({"cameras": d["cameras"], "extrinsics": {}})
    with pytest.raises(InputError, match="camera left K"):
        rig_from_dict({"cameras": {"left": {**d["cameras"]["left"], "K": [[1, 2]]}}})


def _result(rng: np.random.Generator, *, calibrated: bool) -> RideResult:
    n = 7
    t = np.arange(n) / 30.0
    acc = rng.normal(size=(n, 3))
    acc[2, 1] = np.nan  # a sample with no value is written as null and read back as NaN
    return RideResult(
        fps=30.0, gait="canter", direction="CCW", rig=_rig(),
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


@pytest.mark.parametrize("calibrated", [True, False])
def test_result_document_round_trip(calibrated):
    result = _result(np.random.default_rng(3), calibrated=calibrated)
    doc = json.loads(json.dumps(result_to_document(result), allow_nan=False))  # strict JSON: no NaN, no inf
    assert doc["format"] == "saddlescope.result/1"
    assert doc["saddle"]["acceleration_m_s2"][2][1] is None
    assert doc["indicators"]["t_a8_action_wb_h"] is None
    assert ("n_views" in doc["calibration"]) == calibrated
    assert doc["angular"]["weak_axis_gain"] == {"omega": 0.5, "alpha": 0.25}
    back = result_from_document(doc)
    assert np.isnan(back.saddle.acceleration_m_s2[2, 1])
    assert np.allclose(back.saddle.position_m, result.saddle.position_m, atol=1e-9)
    assert np.array_equal(back.angular.omega_versions_excluded, result.angular.omega_versions_excluded)
    assert back.rig.names == ["left", "right"] and back.findings == (SQUARES, LOST)
    assert doc["quality"]["flags"] == [SQUARES.detail, LOST.detail]
    assert [f["code"] for f in doc["quality"]["findings"]] == ["calibration.square_error", "tracking.lost"]
    assert result_to_document(back) == doc  # written again, byte for byte the same document


def test_a_calibration_stored_with_sentences_only_reads_back_as_coded_findings():
    """A rig calibration stored before findings were data (``flags`` only) keeps its codes."""
    d = rig_to_dict(_rig())
    del d["findings"]
    d["flags"] = ["the joint adjustment moved every camera's principal point by about 9 px (x +9, y -1) from where",
                  "something a later version will not say"]
    back = rig_from_dict(d)
    assert [f.code for f in back.flags] == ["calibration.principal_point", "other"]
    assert [f.detail for f in back.flags] == d["flags"] and all(not f.values for f in back.flags)

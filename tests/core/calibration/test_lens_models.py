"""Lenses fitted by the evidence (issue 35, item 2): lens models, a joint lens its own views reject, given lenses."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.calibration import (
    calibrate_intrinsics,
    calibrate_rig,
    make_board,
    simulate_board_views,
    thesis_like_views,
)
from saddlescope.core.calibration.rig import _joint_lens_test
from saddlescope.core.errors import InputError
from saddlescope.core.findings import FINDING_KINDS
from saddlescope.core.types import Camera, LensModel, Rig


def _scene(n=40, seed=3, noise_px=0.1):
    truth, board, views, sizes = thesis_like_views(n, rng=np.random.default_rng(seed), noise_px=noise_px)
    return truth, board, views, sizes


def test_a_fixed_lens_model_holds_what_it_fixes():
    truth, board, views, sizes = _scene()
    w, h = sizes["left"]
    cam, rep = calibrate_intrinsics(views["left"], board, sizes["left"],
                                    model=LensModel(equal_focal=True, principal_point=False, tangential=False))
    assert cam.K[0, 0] == cam.K[1, 1]
    assert cam.K[0, 2] == pytest.approx((w - 1) / 2) and cam.K[1, 2] == pytest.approx((h - 1) / 2)
    assert np.all(cam.dist[2:] == 0)
    assert abs(cam.K[0, 0] / truth.cameras["left"].K[0, 0] - 1) < 0.02


def test_a_consistent_rig_keeps_every_joint_lens_and_reports_the_models():
    truth, board, views, sizes = _scene()
    rig, report = calibrate_rig(views, board, sizes)
    assert set(rig.lens_models) == set(rig.cameras)
    for name, model in rig.lens_models.items():
        assert model.joint and not model.given, (name, model)
        assert "kept" in model.reason and model.label.startswith("fx fy")
        assert not report["lens_choice"][name]["held"]
    assert "calibration.lens_model" not in [f.code for f in rig.flags]
    assert "calibration.lens_model" in FINDING_KINDS


def _three_cameras_one_late(late_by: float, seed: int = 1):
    """Three parallel cameras 100 mm apart, 40 board poses at 0.8 m; the middle one sees each pose ``late_by`` nearer.

    As views that are not quite simultaneous: the cameras disagree about where the board was, and the joint
    adjustment bends the middle camera's lens to absorb it.
    """
    rng = np.random.default_rng(seed)
    board = make_board("checkerboard", (8, 6), 30.0)
    K = np.array([[600.0, 0, 320], [0, 600, 240], [0, 0, 1]])
    rig = Rig({f"c{i}": Camera(f"c{i}", K + np.diag([4.0 * i, 4.0 * i, 0]), np.array([-0.15, 0.05, 0, 0, 0]),
                               (640, 480), t_mm=np.array([-100.0 * i, 0, 0])) for i in range(3)})
    half = np.array([3.5 * 30, 2.5 * 30, 0])
    rvecs = np.radians(np.column_stack([rng.uniform(-30, 30, 40), rng.uniform(-30, 30, 40), rng.uniform(-15, 15, 40)]))
    centres = np.column_stack([100 + rng.uniform(-100, 100, 40), rng.uniform(-70, 70, 40),
                               800 + rng.uniform(-100, 150, 40)])
    ts = centres - np.einsum("nij,j->ni", np.array([cv2.Rodrigues(r)[0] for r in rvecs]), half)
    views = simulate_board_views(rig, board, rvecs, ts, noise_px=0.1, rng=rng)
    eye = rig.cameras["c1"].center_mm
    views["c1"] = simulate_board_views(rig, board, rvecs, eye + (ts - eye) * (1 - late_by), noise_px=0.1, rng=rng)["c1"]
    return rig, board, views, {n: (640, 480) for n in views}


def test_a_joint_lens_its_own_views_reject_is_held():
    truth, board, views, sizes = _three_cameras_one_late(0.08)
    own, _ = calibrate_intrinsics(views["c1"], board, sizes["c1"])
    rig, report = calibrate_rig(views, board, sizes)
    test = report["lens_choice"]["c1"]
    assert test["held"] and test["bic_own"] < test["bic_joint"]
    assert test["joint_lens_rms_px"] > 1.5 * test["own_views_rms_px"]
    assert not report["lens_choice"]["c0"]["held"] and not report["lens_choice"]["c2"]["held"]
    assert not rig.lens_models["c1"].joint and rig.lens_models["c0"].joint
    # the lens from its own views, in the model they support: the truth's square pixels, its principal point
    # half a pixel from the image centre and no tangential term are what the criterion fixes
    model = rig.lens_models["c1"]
    assert (model.equal_focal, model.principal_point, model.tangential) == (True, False, False)
    assert "one focal length for x and y, the principal point at the image centre" in model.reason
    chosen, _ = calibrate_intrinsics(views["c1"], board, sizes["c1"], guess=own, model=model, max_rounds=0)
    assert np.allclose(rig.cameras["c1"].K, chosen.K)
    bic, label = test["lens_test"]["bic"], model.label.split(";")[0]
    assert test["lens_test"]["chosen"] == label and min(bic.values()) == bic[label]
    assert len(bic) == 8 and bic["fx=fy, centre, k1 k2"] < bic["fx fy, cx cy, k1 k2, p1 p2"] - 10
    assert abs(rig.cameras["c1"].K[0, 0] / truth.cameras["c1"].K[0, 0] - 1) < 0.01
    found = [f for f in rig.flags if f.code == "calibration.lens_model"]
    assert len(found) == 1 and "camera c1" in found[0].detail and "own lens was kept" in found[0].detail
    assert found[0].values["joint_lens_rms_px"] == pytest.approx(test["joint_lens_rms_px"])
    # with the cameras in agreement, nothing is held
    _, board, views, sizes = _three_cameras_one_late(0.0)
    _, report = calibrate_rig(views, board, sizes)
    assert not any(t["held"] for t in report["lens_choice"].values())


def test_the_joint_lens_test_counts_views_not_corners():
    own = {"rms_px": 0.20, "n_points": 600}
    assert not _joint_lens_test(own, {"rms_px": 0.22, "n_points": 600, "n_views": 50}, 8)["held"]
    assert _joint_lens_test(own, {"rms_px": 0.43, "n_points": 600, "n_views": 50}, 8)["held"]
    assert not _joint_lens_test(own, {"rms_px": 0.9, "n_points": 40, "n_views": 4}, 8)["held"]  # too few views


def test_given_intrinsics_are_held_and_only_poses_fitted():
    truth, board, views, sizes = _scene()
    known = {"right": Camera("right", truth.cameras["right"].K * [[1.01], [1.01], [1]], truth.cameras["right"].dist,
                             truth.cameras["right"].image_size)}
    rig, report = calibrate_rig(views, board, sizes, given_intrinsics=known)
    assert np.allclose(rig.cameras["right"].K, known["right"].K)
    assert np.allclose(rig.cameras["right"].dist, known["right"].dist)
    assert rig.lens_models["right"].given and rig.lens_models["right"].label == "given"
    assert "given" in rig.lens_models["right"].reason
    assert not rig.lens_models["left"].given
    with pytest.raises(InputError, match=r"camera\(s\) nowhere"):
        calibrate_rig(views, board, sizes, given_intrinsics={"nowhere": known["right"]})
    small = {"right": Camera("right", known["right"].K, known["right"].dist, (320, 240))}
    with pytest.raises(InputError, match="320x240"):
        calibrate_rig(views, board, sizes, given_intrinsics=small)


def test_partial_views_count_for_the_board_pose():
    truth, board, views, sizes = _scene()
    cut = {}
    for name, vs in views.items():
        cut[name] = [type(v)(v.frame, v.corners_px[:4], v.ids[:4]) if name == "right" and i % 5 == 0 else v
                     for i, v in enumerate(vs)]
    rig, report = calibrate_rig(cut, board, sizes)
    assert report["n_partial_views"]["right"] > 0
    assert report["bundle"]["n_observations"] > sum(len(v.ids) for vs in cut.values() for v in vs if len(v.ids) >= 6)

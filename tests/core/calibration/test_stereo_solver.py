"""The stereo pair's solver reaches cv2.stereoCalibrate's answer (CALIB_FIX_INTRINSIC), with a sparse step."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.calibration.stereo import stereo_extrinsics
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.errors import CalibrationError
from saddlescope.core.types import Board, Camera


def _pair_views(n_views: int, *, noise_px: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    board = Board("checkerboard", (9, 6), 30.0)
    obj = board.object_points_mm()
    K = np.array([[800.0, 0, 320], [0, 790.0, 240], [0, 0, 1]])
    cam_a = Camera("a", K, np.array([-0.2, 0.05, 0.001, -0.001, 0.0]), (640, 480))
    cam_b = Camera("b", K * [[1.02], [1.02], [1]], np.array([-0.15, 0.02, 0.0, 0.001, 0.0]), (640, 480))
    R_ab = cv2.Rodrigues(np.array([0.05, 0.3, 0.02]))[0]
    t_ab = np.array([-500.0, 10.0, 50.0])
    va, vb = [], []
    for frame in range(n_views):
        rvec = rng.normal(0, 0.3, 3)
        tvec = np.array([rng.normal(-100, 60), rng.normal(-80, 60), 2000 + rng.normal(0, 200)])
        keep = np.sort(rng.choice(len(obj), 40, replace=False))  # some corners hidden, not the same in a and b
        a = cv2.projectPoints(obj, rvec, tvec, cam_a.K, cam_a.dist)[0].reshape(-1, 2)
        rb = cv2.Rodrigues(R_ab @ cv2.Rodrigues(rvec)[0])[0]
        b = cv2.projectPoints(obj, rb, R_ab @ tvec + t_ab, cam_b.K, cam_b.dist)[0].reshape(-1, 2)
        keep_b = np.sort(np.union1d(keep[:30], rng.choice(len(obj), 10, replace=False)))
        va.append(BoardView(frame, a[keep] + rng.normal(0, noise_px, (keep.size, 2)), keep))
        vb.append(BoardView(frame, b[keep_b] + rng.normal(0, noise_px, (keep_b.size, 2)), keep_b))
    return board, obj, cam_a, cam_b, va, vb, R_ab, t_ab


def _opencv_pair(board_obj, cam_a, cam_b, va, vb):
    obj, img_a, img_b = [], [], []
    for a, b in zip(va, vb, strict=True):
        common, ia, ib = np.intersect1d(a.ids, b.ids, return_indices=True)
        obj.append(board_obj[common].astype(np.float32))
        img_a.append(a.corners_px[ia].astype(np.float32).reshape(-1, 1, 2))
        img_b.append(b.corners_px[ib].astype(np.float32).reshape(-1, 1, 2))
    out = cv2.stereoCalibrate(obj, img_a, img_b, cam_a.K, cam_a.dist, cam_b.K, cam_b.dist, (640, 480),
                              flags=cv2.CALIB_FIX_INTRINSIC,
                              criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-9))
    return out[0], out[5], out[6].ravel()


@pytest.mark.parametrize("n_views", [5, 60, 90])  # OpenCV's own below 60 shared views, the sparse solver from 60
def test_the_pair_matches_opencv_stereo_calibrate(n_views):
    board, obj, cam_a, cam_b, va, vb, R_true, t_true = _pair_views(n_views, noise_px=0.2)
    got = stereo_extrinsics(va, vb, cam_a, cam_b, board)
    assert got["n_views"] == n_views and got["frames"] == list(range(n_views))
    rms_cv, R_cv, t_cv = _opencv_pair(obj, cam_a, cam_b, va, vb)
    assert got["rms_px"] <= rms_cv * (1 + 1e-6)  # the same objective: its minimum, or lower
    assert np.degrees(np.linalg.norm(cv2.Rodrigues(got["R"] @ R_cv.T)[0])) < 1e-4
    assert np.linalg.norm(got["t_mm"] - t_cv) < 0.01
    assert np.linalg.norm(got["t_mm"] - t_true) < 5.0  # and near the truth


@pytest.mark.parametrize("n_views", [12, 70])  # OpenCV's solver below 60 shared views, the sparse one from 60
def test_exact_corners_give_the_exact_pose(n_views):
    board, _, cam_a, cam_b, va, vb, R_true, t_true = _pair_views(n_views, noise_px=0.0, seed=3)
    got = stereo_extrinsics(va, vb, cam_a, cam_b, board)
    assert got["rms_px"] < 1e-3
    assert np.linalg.norm(got["t_mm"] - t_true) < 1e-2
    assert np.degrees(np.linalg.norm(cv2.Rodrigues(got["R"] @ R_true.T)[0])) < 1e-5


def test_too_few_shared_views_is_a_clear_error():
    board, _, cam_a, cam_b, va, vb, _, _ = _pair_views(2, noise_px=0.2)
    with pytest.raises(CalibrationError, match="see the board together in only 2 frame"):
        stereo_extrinsics(va, vb, cam_a, cam_b, board)

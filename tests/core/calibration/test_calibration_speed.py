"""Issue 28's cheaper calibration steps give the answers of the costly ones they stand in for."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.calibration import calibrate_intrinsics, calibrate_rig, make_board, simulate_board_views
from saddlescope.core.calibration.intrinsics import _bic_pair, _linearised_k3_test
from saddlescope.core.calibration.rig import _spread
from saddlescope.core.types import Camera, Rig


def _small_rig(n_cams: int) -> Rig:
    cams = {}
    for i in range(n_cams):
        R = cv2.Rodrigues(np.array([0.0, np.radians(8.0 * i), 0.0]))[0]  # turned towards the board
        K = np.array([[600.0 + 5 * i, 0, 320], [0, 600.0 + 5 * i, 240], [0, 0, 1]])
        cams[f"c{i}"] = Camera(f"c{i}", K, np.array([-0.15, 0.05, 0.0005, -0.0003, 0.0]), (640, 480), R=R,
                               t_mm=-R @ np.array([150.0 * i, 0.0, 0.0]))
    return Rig(cams)


def _random_poses(n: int, rng, board) -> tuple[np.ndarray, np.ndarray]:
    cols, rows = board.inner_corners
    half = np.array([(cols - 1) * board.square_mm / 2, (rows - 1) * board.square_mm / 2, 0.0])
    rvecs, ts = [], []
    for _ in range(n):
        rv = np.radians([rng.uniform(-35, 35), rng.uniform(-35, 35), rng.uniform(-20, 20)])
        c = np.array([75.0, 0.0, 700.0]) + [rng.uniform(-150, 150), rng.uniform(-100, 100), rng.uniform(-100, 150)]
        rvecs.append(rv)
        ts.append(c - cv2.Rodrigues(rv)[0] @ half)
    return np.array(rvecs), np.array(ts)


@pytest.mark.parametrize("k3", [0.0, -0.3])
def test_the_linearised_k3_test_agrees_with_the_full_free_fit(k3):
    rng = np.random.default_rng(5)
    board = make_board("checkerboard", (9, 6), 25.0)
    cam = _small_rig(1).cameras["c0"]
    truth = Rig({"c0": Camera("c0", cam.K, np.array([-0.15, 0.05, 0.0005, -0.0003, k3]), cam.image_size)})
    views = simulate_board_views(truth, board, *_random_poses(40, rng, board), noise_px=0.2, rng=rng)["c0"]
    fixed, report = calibrate_intrinsics(views, board, (640, 480), camera="c0")
    lin = _linearised_k3_test(fixed, report, views, board)
    free, free_rep = calibrate_intrinsics(views, board, (640, 480), camera="c0", fix_k3=False, guess=fixed,
                                          max_rounds=0)
    z_full = abs(free.dist[4]) / free.dist_std[4]
    assert lin["k3"] == pytest.approx(free.dist[4], abs=0.1 * free.dist_std[4])
    assert lin["z"] == pytest.approx(z_full, abs=0.1)
    assert lin["bic_free"] == pytest.approx(_bic_pair(report, free_rep)[1], abs=0.5)
    if k3:
        assert lin["z"] > 3  # a k3 that matters is never screened out


def test_stereo_pairs_use_at_most_fifty_spread_instants_and_the_adjusted_rig_does_not_care():
    rng = np.random.default_rng(3)
    board = make_board("checkerboard", (9, 6), 25.0)
    truth = _small_rig(2)
    views = simulate_board_views(truth, board, *_random_poses(80, rng, board), noise_px=0.2, rng=rng)
    a, b = _spread(views["c0"], views["c1"], 50)
    assert len(a) == len(b) == 50 and [v.frame for v in a] == [v.frame for v in b]
    assert a[0].frame == views["c0"][0].frame and a[-1].frame == views["c0"][-1].frame  # spread end to end
    rig, _ = calibrate_rig(views, board, {"c0": (640, 480), "c1": (640, 480)})
    assert rig.pairs["c0-c1"]["n_views"] == 50
    assert np.allclose(rig.cameras["c1"].t_mm, truth.cameras["c1"].t_mm, atol=1.0)

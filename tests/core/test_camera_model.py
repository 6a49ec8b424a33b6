"""The camera model: numpy projection against OpenCV's, and the exact inverse of the distortion."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.camera_model import project_points, undistort_normalized
from saddlescope.core.types import Camera


def scene_points(rng, n):
    """Points in a 5 m wide, 3 m high slab 6.5-8.5 m in front of the rig (mm)."""
    return np.column_stack([rng.uniform(-2500, 2500, n), rng.uniform(-1500, 1500, n),
                            rng.uniform(6500, 8500, n)])


@pytest.fixture
def cam() -> Camera:
    """The middle camera of a thesis-like rig: 640x480, f ~730 px, 0.23 m right of the left one."""
    K = np.array([[731.0, 0, 322], [0, 727.0, 239], [0, 0, 1]])
    dist = np.array([-0.11, 0.15, 0.0005, -0.0003, 0.0])
    R = cv2.Rodrigues(np.array([0.002, -0.01, 0.001]))[0]
    centre = np.array([230.0, 3.0, 0.0])
    return Camera("middle", K, dist, (640, 480), R, -R @ centre)


def test_undistort_inverts_the_camera_model(cam):
    rng = np.random.default_rng(0)
    X = scene_points(rng, 50)
    px = cam.project(X)  # OpenCV's projection
    np.testing.assert_allclose(project_points(cam, X), px, atol=1e-9)
    xn = undistort_normalized(cam, px)
    xc = X @ cam.R.T + cam.t_mm
    np.testing.assert_allclose(xn, xc[:, :2] / xc[:, 2:], atol=1e-13)


def test_camera_undistorts_to_ideal_pixels(cam):
    rng = np.random.default_rng(1)
    X = scene_points(rng, 20)
    xc = X @ cam.R.T + cam.t_mm
    ideal = xc[:, :2] / xc[:, 2:] @ cam.K[:2, :2].T + cam.K[:2, 2]
    np.testing.assert_allclose(cam.undistort_points(cam.project(X)), ideal, atol=1e-8)

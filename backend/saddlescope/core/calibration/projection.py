"""Projection model, vectorised over observations.

OpenCV's 5-coefficient model: thesis eq. 3.4-3.10, with the standard tangential terms instead of the
typo in eq. 3.8.
"""

from __future__ import annotations

import cv2
import numpy as np

from saddlescope.core.types import Camera

__all__: list[str] = []  # helpers of the package's other modules only

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)


def _rotation_matrices(rvecs: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of rotation vectors (N, 3) (Rodrigues' formula)."""
    theta = np.linalg.norm(rvecs, axis=1)
    small = theta < 1e-12
    k = rvecs / np.where(small, 1.0, theta)[:, None]
    kx = np.zeros((len(rvecs), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx -= kx.transpose(0, 2, 1)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    R = np.eye(3) + s * kx + (1 - c) * (kx @ kx)
    R[small] = np.eye(3)
    return R


def _distorted(xc: np.ndarray, intr: np.ndarray) -> tuple[np.ndarray, ...]:
    """The Brown-Conrady model on camera-frame points (M, 3); intr (M, 9) = fx fy cx cy k1 k2 p1 p2 k3.

    Returns the ideal normalised x, y, r², the radial factor and the distorted normalised xd, yd (each (M,)).
    """
    z = xc[:, 2]
    x, y = xc[:, 0] / z, xc[:, 1] / z
    _, _, _, _, k1, k2, p1, p2, k3 = intr.T
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return x, y, r2, radial, xd, yd


def _distort_project(xc: np.ndarray, intr: np.ndarray) -> np.ndarray:
    """Camera-frame points (M, 3) -> distorted px (M, 2); intr (M, 9) = fx fy cx cy k1 k2 p1 p2 k3."""
    *_, xd, yd = _distorted(xc, intr)
    fx, fy, cx, cy = intr[:, :4].T
    return np.column_stack([fx * xd + cx, fy * yd + cy])


def _intr_vector(cam: Camera) -> np.ndarray:
    K, d = cam.K, np.asarray(cam.dist, np.float64).ravel()
    d = np.pad(d, (0, max(0, 5 - len(d))))[:5]
    return np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2], *d])


def _camera_from_vector(name, intr, rvec, t, image_size, **kw) -> Camera:
    K = np.array([[intr[0], 0, intr[2]], [0, intr[1], intr[3]], [0, 0, 1.0]])
    R = cv2.Rodrigues(np.asarray(rvec, np.float64))[0]
    return Camera(name, K, np.asarray(intr[4:9], np.float64), tuple(image_size), R=R,
                  t_mm=np.asarray(t, np.float64), **kw)

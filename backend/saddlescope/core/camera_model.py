"""The pinhole camera with OpenCV's 5-coefficient lens distortion, vectorised in double precision.

Rig points in mm map to camera coordinates ``x_cam = R @ x_rig + t_mm``, to ideal normalised
coordinates (x/z, y/z), through the distortion (k1, k2, p1, p2, k3) to distorted normalised
coordinates, and through K to distorted pixels (the detected image points). This module holds that
model and its exact inverse; it sits below :mod:`saddlescope.core.types` (whose ``Camera`` uses it)
and reads a camera only through the attributes of :class:`CameraModel`.
"""

from __future__ import annotations

from typing import Protocol

import cv2
import numpy as np

from saddlescope.core.errors import InputError

__all__ = [
    "CameraModel",
    "distort_normalized",
    "undistort_normalized",
    "project_points",
]

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)


class CameraModel(Protocol):
    """What the camera model reads of a camera (``saddlescope.core.types.Camera`` has it all).

    name : camera name, used in errors; K : ndarray of shape (3, 3); dist : ndarray of shape (5,)
    (more coefficients only if the extra ones are zero); R : ndarray of shape (3, 3) and t_mm :
    ndarray of shape (3,) mapping rig coordinates in mm into the camera's.
    """

    # Read-only properties: a frozen dataclass (Camera) satisfies them.
    @property
    def name(self) -> str:
        """Camera name."""
    @property
    def K(self) -> np.ndarray:
        """Intrinsic matrix (3, 3)."""
    @property
    def dist(self) -> np.ndarray:
        """Distortion coefficients (5,)."""
    @property
    def R(self) -> np.ndarray:
        """Rotation rig -> camera (3, 3)."""
    @property
    def t_mm(self) -> np.ndarray:
        """Translation rig -> camera in mm (3,)."""


def _dist5(camera: CameraModel) -> np.ndarray:
    """The camera's (k1, k2, p1, p2, k3), zero-padded; raise for models this module does not handle."""
    d = np.asarray(camera.dist, dtype=np.float64).ravel()
    if d.size > 5 and np.any(d[5:] != 0):
        raise InputError(f"camera {camera.name!r}: only the 5-coefficient OpenCV distortion model "
                         f"(k1, k2, p1, p2, k3) is supported, got {d.size} non-zero coefficients")
    out = np.zeros(5)
    out[: min(d.size, 5)] = d[:5]
    return out


def distort_normalized(xy_n: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Apply the OpenCV distortion model to normalised points.

    Parameters
    ----------
    xy_n : ndarray of shape (..., 2)
        Ideal normalised image coordinates (x/z, y/z).
    dist : ndarray of shape (5,)
        (k1, k2, p1, p2, k3).

    Returns
    -------
    ndarray of shape (..., 2)
        Distorted normalised coordinates.
    """
    k1, k2, p1, p2, k3 = dist
    x, y = xy_n[..., 0], xy_n[..., 1]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], axis=-1)


def _distortion_jacobian(xy_n: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """d(distorted)/d(ideal) of the OpenCV model, shape (..., 2, 2)."""
    k1, k2, p1, p2, k3 = dist
    x, y = xy_n[..., 0], xy_n[..., 1]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
    jac = np.empty(xy_n.shape[:-1] + (2, 2))
    jac[..., 0, 0] = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x
    jac[..., 0, 1] = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
    jac[..., 1, 0] = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y
    jac[..., 1, 1] = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x
    return jac


def undistort_normalized(camera: CameraModel, xy_px: np.ndarray) -> np.ndarray:
    """Distorted pixels -> ideal normalised coordinates, to double precision.

    OpenCV's iterative ``undistortPoints`` gives the start; three Newton steps on the exact
    distortion model then make the result exact to rounding (triangulation over a 0.23 m baseline
    at 7.5 m turns 1e-6 px of disparity into ~3e-4 mm of depth).

    Parameters
    ----------
    camera : CameraModel
    xy_px : ndarray of shape (..., 2)
        Distorted pixel coordinates; NaN rows stay NaN.

    Returns
    -------
    ndarray of shape (..., 2)
        Ideal normalised coordinates (x/z, y/z).
    """
    pts = np.asarray(xy_px, dtype=np.float64)
    shape = pts.shape
    flat = pts.reshape(-1, 2)
    out = np.full_like(flat, np.nan)
    ok = np.all(np.isfinite(flat), axis=1)
    if not ok.any():
        return out.reshape(shape)
    K = np.asarray(camera.K, dtype=np.float64)
    dist = _dist5(camera)
    target = flat[ok]
    xn = cv2.undistortPoints(target.reshape(-1, 1, 2), K, dist, criteria=_UNDISTORT_CRITERIA).reshape(-1, 2)
    # Observed point in distorted normalised coordinates (inverse of K's affine part).
    Kinv = np.linalg.inv(K)
    obs = target @ Kinv[:2, :2].T + Kinv[:2, 2]
    if np.any(dist != 0):
        for _ in range(3):
            res = distort_normalized(xn, dist) - obs
            jac = _distortion_jacobian(xn, dist)
            xn = xn - np.linalg.solve(jac, res[..., None])[..., 0]
    else:
        xn = obs
    out[ok] = xn
    return out.reshape(shape)


def project_points(camera: CameraModel, points_mm: np.ndarray) -> np.ndarray:
    """Project rig points in mm to distorted pixels; NaN in, NaN out.

    Same model as ``Camera.project`` (OpenCV's), vectorised in numpy so it can run on millions of
    points; points behind the camera give NaN.

    Parameters
    ----------
    camera : CameraModel
    points_mm : ndarray of shape (..., 3)
        Rig coordinates in mm.

    Returns
    -------
    ndarray of shape (..., 2)
        Distorted pixel coordinates.
    """
    pts = np.asarray(points_mm, dtype=np.float64)
    R = np.asarray(camera.R, dtype=np.float64)
    t = np.asarray(camera.t_mm, dtype=np.float64).reshape(3)
    xc = pts @ R.T + t
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(xc[..., 2] > 0, xc[..., 2], np.nan)
        xn = xc[..., :2] / z[..., None]
    xd = distort_normalized(xn, _dist5(camera))
    K = np.asarray(camera.K, dtype=np.float64)
    return xd @ K[:2, :2].T + K[:2, 2]

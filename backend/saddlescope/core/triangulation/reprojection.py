"""Reprojection errors of triangulated points, and the checks every triangulation makes on its views.

Image points are distorted pixels as detected, NaN where a camera did not see a marker; 3-D points are
in millimetres in rig coordinates.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from saddlescope.core.camera_model import project_points
from saddlescope.core.errors import InputError
from saddlescope.core.types import Camera, Rig

__all__ = ["reprojection_errors"]


def reprojection_errors(rig: Rig, xyz_mm: np.ndarray,
                        xy_by_camera: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per-camera reprojection error in pixels.

    Parameters
    ----------
    rig : Rig
    xyz_mm : ndarray of shape (..., 3)
    xy_by_camera : dict of camera name -> ndarray of shape (..., 2)
        Observed distorted pixels; NaN where not seen.

    Returns
    -------
    dict of camera name -> ndarray of shape (...,)
        Euclidean distance between the projection and the observation, NaN where either is NaN.
    """
    out = {}
    for name, xy in xy_by_camera.items():
        proj = project_points(_camera(rig, name), xyz_mm)
        out[name] = np.linalg.norm(proj - np.asarray(xy, dtype=np.float64), axis=-1)
    return out


def _camera(rig: Rig, name: str) -> Camera:
    try:
        return rig.cameras[name]
    except KeyError:
        raise InputError(f"camera {name!r} is not in the rig (cameras: {', '.join(rig.names)})") from None


def _stack_views(rig: Rig, xy_by_camera: Mapping[str, np.ndarray]):
    """Validate and flatten the views: names, shape (...), observations (C, P, 2)."""
    if not xy_by_camera:
        raise InputError("no camera views given to triangulate")
    names = list(xy_by_camera)
    arrays = []
    shape = None
    for name in names:
        _camera(rig, name)
        xy = np.asarray(xy_by_camera[name], dtype=np.float64)
        if xy.ndim < 1 or xy.shape[-1] != 2:
            raise InputError(f"camera {name!r}: image points must have shape (..., 2), got {xy.shape}")
        if shape is None:
            shape = xy.shape[:-1]
        elif xy.shape[:-1] != shape:
            raise InputError(f"camera {name!r}: image points have shape {xy.shape}, expected "
                             f"{shape + (2,)} like camera {names[0]!r}")
        arrays.append(xy.reshape(-1, 2))
    return names, shape, np.stack(arrays)


def _rms_over(err: np.ndarray, use: np.ndarray) -> np.ndarray:
    """RMS over the cameras ``use`` (C, P) of the errors (C, P), shape (P,); NaN where none is used."""
    n = use.sum(axis=0)
    sq = np.where(use, err, 0.0) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(sq.sum(axis=0) / np.maximum(n, 1)), np.nan)

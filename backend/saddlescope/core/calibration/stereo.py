"""Stereo pairs (thesis 3.5: L-M, L-R, M-R): the pose of one camera relative to another."""

from __future__ import annotations

import cv2
import numpy as np

from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.calibration.intrinsics import _CALIB_CRITERIA
from saddlescope.core.calibration.views import MIN_CORNERS, BoardView
from saddlescope.core.errors import CalibrationError
from saddlescope.core.types import Board, Camera

__all__ = ["stereo_extrinsics"]


def _shared(views_a: list[BoardView], views_b: list[BoardView]):
    """Per shared instant: common ids, their corners in a and b."""
    by_frame = {v.frame: v for v in views_b}
    out = []
    for va in views_a:
        vb = by_frame.get(va.frame)
        if vb is None:
            continue
        common, ia, ib = np.intersect1d(va.ids, vb.ids, return_indices=True)
        if len(common) >= MIN_CORNERS:
            out.append((va.frame, common, va.corners_px[ia], vb.corners_px[ib]))
    return out


def stereo_extrinsics(views_a: list[BoardView], views_b: list[BoardView], cam_a: Camera, cam_b: Camera,
                      board: Board, *, min_shared: int = 3) -> dict:
    """Pose of camera b relative to camera a from instants both see (thesis 3.5, Table 8.4).

    ``cv2.stereoCalibrate`` with both cameras' intrinsics fixed.

    Returns
    -------
    dict with ``R`` (3, 3) and ``t_mm`` (3,) such that ``x_b = R @ x_a + t_mm``, ``rms_px``,
    ``n_views`` and ``frames``.

    Raises
    ------
    CalibrationError
        Fewer than ``min_shared`` instants where both cameras see at least 6 common corners.
    """
    shared = _shared(views_a, views_b)
    if len(shared) < min_shared:
        raise CalibrationError(f"cameras {cam_a.name} and {cam_b.name} see the board together in only "
                               f"{len(shared)} frame(s); need at least {min_shared}")
    obj_all = object_points_mm(board).astype(np.float32)
    obj = [obj_all[ids] for _, ids, _, _ in shared]
    img_a = [a.astype(np.float32).reshape(-1, 1, 2) for _, _, a, _ in shared]
    img_b = [b.astype(np.float32).reshape(-1, 1, 2) for _, _, _, b in shared]
    try:
        out = cv2.stereoCalibrate(obj, img_a, img_b, cam_a.K, cam_a.dist, cam_b.K, cam_b.dist,
                                  tuple(cam_a.image_size), flags=cv2.CALIB_FIX_INTRINSIC,
                                  criteria=_CALIB_CRITERIA)
    except cv2.error as exc:
        raise CalibrationError(f"stereo calibration of {cam_a.name}-{cam_b.name} failed in OpenCV: "
                               f"{str(exc).strip().splitlines()[-1]}") from None
    rms, R, T = out[0], out[5], out[6]
    return {"R": np.asarray(R, np.float64), "t_mm": np.asarray(T, np.float64).ravel(), "rms_px": float(rms),
            "n_views": len(shared), "frames": [int(f) for f, _, _, _ in shared]}

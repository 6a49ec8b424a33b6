"""Stereo pairs (thesis 3.5: L-M, L-R, M-R): the pose of one camera relative to another."""

from __future__ import annotations

import cv2
import numpy as np

from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.calibration.bundle_adjustment import _NCAM, _Bundle, _levenberg_marquardt, _pose_of_view
from saddlescope.core.calibration.intrinsics import _CALIB_CRITERIA
from saddlescope.core.calibration.projection import _intr_vector
from saddlescope.core.calibration.views import MIN_CORNERS, BoardView
from saddlescope.core.errors import CalibrationError
from saddlescope.core.types import Board, Camera

__all__ = ["stereo_extrinsics"]

# shared views from which the sparse solver is used: with the adjustment's analytic Jacobians and per-view
# normal equations it costs about OpenCV's from 30 views and less above (50 views, 1080p wide rig: 0.07-0.09
# CPU-s a pair against OpenCV's 0.10-0.75, whose threads spin on a loaded machine), the pose the same to 0.004 mm
SPARSE_STEREO_MIN_VIEWS = 30


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

    The objective of ``cv2.stereoCalibrate`` with both cameras' intrinsics fixed (:func:`_stereo_fit`).

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
    obj_all = object_points_mm(board).astype(np.float64)
    try:
        # OpenCV's dense solve is cheaper for few views; its O(views^3) overtakes near 30 (SPARSE_STEREO_MIN_VIEWS)
        fit = _stereo_opencv if len(shared) < SPARSE_STEREO_MIN_VIEWS else _stereo_fit
        R, t_mm, rms = fit(shared, obj_all, cam_a, cam_b)
    except (cv2.error, np.linalg.LinAlgError) as exc:
        raise CalibrationError(f"stereo calibration of {cam_a.name}-{cam_b.name} failed: "
                               f"{str(exc).strip().splitlines()[-1]}") from None
    if R is None:
        raise CalibrationError(f"stereo calibration of {cam_a.name}-{cam_b.name} failed: a shared view's board "
                               "pose could not be found")
    return {"R": R, "t_mm": t_mm, "rms_px": rms, "n_views": len(shared), "frames": [int(f) for f, _, _, _ in shared]}


def _stereo_opencv(shared, obj_all: np.ndarray, cam_a: Camera, cam_b: Camera):
    """(R, t_mm, RMS px) from ``cv2.stereoCalibrate`` with CALIB_FIX_INTRINSIC."""
    obj = [obj_all[ids].astype(np.float32) for _, ids, _, _ in shared]
    img_a = [a.astype(np.float32).reshape(-1, 1, 2) for _, _, a, _ in shared]
    img_b = [b.astype(np.float32).reshape(-1, 1, 2) for _, _, _, b in shared]
    out = cv2.stereoCalibrate(obj, img_a, img_b, cam_a.K, cam_a.dist, cam_b.K, cam_b.dist,
                              tuple(cam_a.image_size), flags=cv2.CALIB_FIX_INTRINSIC, criteria=_CALIB_CRITERIA)
    return np.asarray(out[5], np.float64), np.asarray(out[6], np.float64).ravel(), float(out[0])


def _stereo_fit(shared, obj_all: np.ndarray, cam_a: Camera, cam_b: Camera):
    """(R, t_mm, RMS px) minimising both cameras' reprojection errors over b's pose and every board pose.

    The objective of ``cv2.stereoCalibrate`` with CALIB_FIX_INTRINSIC (thesis 3.5), solved by the
    bundle adjustment's Levenberg-Marquardt with the Schur complement over the board poses (plain
    least squares, intrinsics held): a step costs O(views) where OpenCV's dense normal equations
    cost O(views^3) (150 shared views: 0.9 CPU-s a pair). Started, like OpenCV, from each view's PnP
    poses: the median of the per-view relative poses. (None, None, nan) when a view's pose is not found.
    """
    n = len(shared)
    poses_a, rel_r, rel_t = [], [], []
    for _, ids, a, b in shared:
        ok_a, ra, ta = _pose_of_view(cam_a, obj_all[ids], a.astype(np.float64))
        ok_b, rb, tb = _pose_of_view(cam_b, obj_all[ids], b.astype(np.float64))
        if not (ok_a and ok_b):
            return None, None, float("nan")
        R_ab = cv2.Rodrigues(rb)[0] @ cv2.Rodrigues(ra)[0].T  # x_b = R_ab x_a + t_ab in this view
        poses_a.append(np.concatenate([ra, ta]))
        rel_r.append(cv2.Rodrigues(R_ab)[0].ravel())
        rel_t.append(tb - R_ab @ ta)
    cams = np.zeros((2, _NCAM))
    cams[0, :9], cams[1, :9] = _intr_vector(cam_a), _intr_vector(cam_b)
    cams[1, 9:12], cams[1, 12:] = np.median(rel_r, axis=0), np.median(rel_t, axis=0)
    counts = [len(ids) for _, ids, _, _ in shared]
    inst = np.repeat(np.arange(n), counts)
    bundle = _Bundle(obj_all, np.concatenate([np.zeros(inst.size, int), np.ones(inst.size, int)]),
                     np.concatenate([inst, inst]), np.concatenate([ids for _, ids, _, _ in shared] * 2),
                     np.concatenate([a for _, _, a, _ in shared] + [b for _, _, _, b in shared]).astype(np.float64),
                     2, n)
    free = np.arange(_NCAM + 9, 2 * _NCAM)  # camera b's pose alone: a is the frame, intrinsics held
    cams, _, r, _, _ = _levenberg_marquardt(bundle, cams, np.array(poses_a), free, loss="linear", f_scale_px=1.0,
                                            max_iterations=100)
    rms = float(np.sqrt(np.mean(np.sum(r * r, axis=1))))  # as OpenCV's: over both cameras' corners
    return cv2.Rodrigues(cams[1, 9:12])[0], cams[1, 12:].copy(), rms

"""The whole rig: intrinsics, stereo pairs, chained poses, bundle adjustment and metric checks."""

from __future__ import annotations

import itertools
from collections.abc import Mapping

import cv2
import numpy as np

from saddlescope.core.calibration.bundle_adjustment import _pose_of_view, bundle_adjust
from saddlescope.core.calibration.checks import metric_checks
from saddlescope.core.calibration.intrinsics import _choose_k3, calibrate_intrinsics
from saddlescope.core.calibration.stereo import stereo_extrinsics
from saddlescope.core.calibration.views import MIN_VIEWS, BoardView
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.types import Board, Camera, Rig

__all__ = ["calibrate_rig", "principal_point_common_shift"]


def _initial_poses(names, pairs, ref) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Chain pair poses from the reference along the pairs with most shared views (spanning tree)."""
    poses = {ref: (np.eye(3), np.zeros(3))}
    while len(poses) < len(names):
        best = None
        for (a, b), p in pairs.items():
            for src, dst, R, t in ((a, b, p["R"], p["t_mm"]), (b, a, p["R"].T, -p["R"].T @ p["t_mm"])):
                if src in poses and dst not in poses and (best is None or p["n_views"] > best[0]):
                    best = (p["n_views"], src, dst, R, t)
        if best is None:
            missing = [n for n in names if n not in poses]
            raise CalibrationError(f"camera(s) {', '.join(missing)} never see the board together with "
                                   f"camera {ref} or a camera linked to it: cannot place them in the rig")
        _, src, dst, R, t = best
        Rs, ts = poses[src]
        poses[dst] = (R @ Rs, R @ ts + t)
    return poses


def _fix_flipped_views(cameras, views_by_camera, board, *, max_px=20.0):
    """Relabel (180-degree) or drop views inconsistent with the board pose the other cameras see.

    Symmetric checkerboards can be labelled from the opposite corner in one camera; this finds such
    views from the initial rig and tries the rotated labels.
    """
    names = list(cameras)
    obj_all = board.object_points_mm()
    n = len(obj_all)
    cols, rows = board.inner_corners
    symmetric = board.kind == "checkerboard" and (cols + rows) % 2 == 0
    by_inst: dict[int, dict[str, BoardView]] = {}
    for cam in names:
        for v in views_by_camera.get(cam, []):
            by_inst.setdefault(v.frame, {})[cam] = v
    out = {cam: [] for cam in names}
    n_fixed = n_dropped = 0
    for per_cam in by_inst.values():
        if len(per_cam) < 2:
            for cam, v in per_cam.items():
                out[cam].append(v)
            continue
        poses = {}
        for cam, v in per_cam.items():
            c = cameras[cam]
            ok, rvec, tvec = _pose_of_view(c, obj_all[v.ids], v.corners_px)
            if ok:
                Rb = c.R.T @ cv2.Rodrigues(rvec)[0]
                poses[cam] = (Rb, c.R.T @ (tvec - c.t_mm))

        def err_of(cam, v, pose):
            Rb, tb = pose
            pts = obj_all[v.ids] @ Rb.T + tb
            proj = cameras[cam].project(pts)
            return float(np.sqrt(np.mean(np.sum((proj - v.corners_px) ** 2, axis=1))))

        # the pose most cameras agree with
        best_pose, best_votes = None, -1
        for pose in poses.values():
            votes = sum(err_of(c2, v2, pose) < max_px for c2, v2 in per_cam.items())
            if votes > best_votes:
                best_pose, best_votes = pose, votes
        for cam, v in per_cam.items():
            if best_pose is None or err_of(cam, v, best_pose) < max_px:
                out[cam].append(v)
                continue
            if symmetric:
                flipped = BoardView(v.frame, v.corners_px, n - 1 - v.ids)
                if err_of(cam, flipped, best_pose) < max_px:
                    out[cam].append(flipped)
                    n_fixed += 1
                    continue
            n_dropped += 1
    for cam in names:
        out[cam].sort(key=lambda v: v.frame)
    return out, n_fixed, n_dropped


def principal_point_common_shift(single: Mapping[str, Camera], joint: Mapping[str, Camera]) -> np.ndarray:
    """The mean over cameras of (joint - single-camera) principal point, (2,) px.

    With the board held in a band across the images (a person carrying it at chest height) a common
    shift of every principal point and a common tilt of the rig fit the views almost equally well:
    each camera alone still finds its principal point within a few pixels, but in the joint
    adjustment a hundredth of a pixel of disagreement between the cameras' corners moved all three
    together by 10-40 px (50-60 fps synthetic thesis-rig rides), bending the markers' heights by
    3-4 mm across the view. Each camera's own estimate scatters; their mean shift does not."""
    names = [n for n in joint if n in single]
    d = [np.asarray(joint[n].K)[:2, 2] - np.asarray(single[n].K)[:2, 2] for n in names]
    return np.mean(d, axis=0) if d else np.zeros(2)


def calibrate_rig(views_by_camera: Mapping[str, list[BoardView]], board: Board,
                  image_sizes: Mapping[str, tuple[int, int]], *, fix_k3: bool | None = None,
                  bundle: bool = True, loss: str = "soft_l1", min_views: int = MIN_VIEWS, min_shared: int = 3,
                  max_square_error_pct: float = 1.0, max_square_error_mm: float | None = None,
                  max_distance_rms_mm: float | None = None, max_principal_point_shift: float = 0.02,
                  clip: str | None = "calibration") -> tuple[Rig, dict]:
    """Calibrate one or more cameras into a :class:`Rig` (first camera = reference, identity pose).

    Steps: intrinsics per camera (:func:`calibrate_intrinsics`); stereo pairs for every pair of cameras
    that see the board together (:func:`stereo_extrinsics`, thesis 3.5); initial poses chained from
    the reference; joint bundle adjustment (:func:`bundle_adjust`); metric checks in mm
    (:func:`metric_checks`), whose failures become ``Rig.flags``.

    Parameters
    ----------
    views_by_camera : dict name -> list of BoardView
        Frame keys are synchronised instants (apply the sync offsets before).
    board : Board
    image_sizes : dict name -> (width, height)
    fix_k3 : bool or None
        Keep k3 = 0 for every camera (True), fit it for every camera (False), or (None, default) fit
        it for the cameras whose views call for it (:func:`_choose_k3`).
    max_principal_point_shift : float
        Flag the rig when the bundle adjustment moves all principal points together by more than
        this fraction of the smaller image side (:func:`principal_point_common_shift`).

    Returns
    -------
    rig : Rig
        ``checks`` holds the metric numbers, ``flags`` their failures, ``pairs`` the stereo results
        {"a-b": {"R", "t_mm", "rms_px", "n_views"}}.
    report : dict
        ``intrinsics`` {name: report}, ``bundle`` report (or None), ``per_pair_checks``,
        ``n_relabelled_views``, ``n_dropped_views``.
    """
    names = list(views_by_camera)
    if not names:
        raise InputError("no cameras to calibrate")
    missing = [n for n in names if n not in image_sizes]
    if missing:
        raise InputError(f"image size missing for camera(s) {', '.join(missing)}")
    intrinsics: dict[str, Camera] = {}
    intr_reports: dict[str, dict] = {}
    for name in names:
        intrinsics[name], intr_reports[name] = calibrate_intrinsics(
            views_by_camera[name], board, image_sizes[name], camera=name, clip=clip,
            fix_k3=True if fix_k3 is None else fix_k3, min_views=min_views)
        if fix_k3 is None:
            intrinsics[name], intr_reports[name] = _choose_k3(intrinsics[name], intr_reports[name],
                                                              views_by_camera[name], board, image_sizes[name],
                                                              camera=name, clip=clip, min_views=min_views)
    k3_fixed = {n: intr_reports[n]["fix_k3"] for n in names}
    # views kept by the intrinsic step (outlier views dropped)
    views = {n: [v for v in views_by_camera[n] if v.frame in intr_reports[n]["per_view_rms_px"]]
             for n in names}
    report: dict = {"intrinsics": intr_reports, "bundle": None, "per_pair_checks": {},
                    "n_relabelled_views": 0, "n_dropped_views": 0}
    if len(names) == 1:
        return Rig({names[0]: intrinsics[names[0]]}), report

    pairs_cv: dict[tuple[str, str], dict] = {}
    for a, b in itertools.combinations(names, 2):
        try:
            pairs_cv[(a, b)] = stereo_extrinsics(views[a], views[b], intrinsics[a], intrinsics[b], board,
                                                 min_shared=min_shared)
        except CalibrationError:
            continue  # the pair may be linked through other cameras
    init = _initial_poses(names, pairs_cv, names[0])
    cams = {n: Camera(n, intrinsics[n].K, intrinsics[n].dist, intrinsics[n].image_size, R=init[n][0],
                      t_mm=init[n][1], rms_px=intrinsics[n].rms_px, K_std=intrinsics[n].K_std,
                      dist_std=intrinsics[n].dist_std) for n in names}
    views, n_fixed, n_dropped = _fix_flipped_views(cams, views, board)
    report["n_relabelled_views"], report["n_dropped_views"] = n_fixed, n_dropped
    if bundle:
        cams, report["bundle"] = bundle_adjust(cams, views, board, fix_k3=k3_fixed, loss=loss)
    pairs = {}
    for (a, b), p in pairs_cv.items():
        pairs[f"{a}-{b}"] = {"R": p["R"], "t_mm": p["t_mm"], "rms_px": p["rms_px"], "n_views": p["n_views"]}
    rig = Rig(cams, pairs=pairs)
    checks, flags, per_pair = metric_checks(rig, views, board, max_square_error_pct=max_square_error_pct,
                                            max_square_error_mm=max_square_error_mm,
                                            max_distance_rms_mm=max_distance_rms_mm)
    for key, p in pairs.items():
        p.update({f"check_{k}": v for k, v in per_pair.get(key, {}).items()})
    if report["bundle"] is not None:
        checks["bundle_rms_px"] = report["bundle"]["rms_px"]
        shift = principal_point_common_shift(intrinsics, cams)
        checks["principal_point_common_shift_px"] = float(np.hypot(*shift))
        limit = max_principal_point_shift * min(min(image_sizes[n]) for n in names)
        if checks["principal_point_common_shift_px"] > limit:
            flags.append(
                f"the joint adjustment moved every camera's principal point by about "
                f"{checks['principal_point_common_shift_px']:.0f} px (x {shift[0]:+.0f}, y {shift[1]:+.0f}) from where "
                "each camera's own views put it: the board's positions do not tell the cameras' aim from their "
                "principal points, so heights and depths may bend by millimetres across the view; carry the board "
                "higher and lower and tilt it towards and away from the cameras")
    report["per_pair_checks"] = per_pair
    return Rig(cams, checks=checks, flags=tuple(flags), pairs=pairs), report

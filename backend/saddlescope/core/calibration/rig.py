"""The whole rig: intrinsics, stereo pairs, chained poses, bundle adjustment and metric checks."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import cv2
import numpy as np

from saddlescope.core.calibration.boards import board_type, object_points_mm
from saddlescope.core.calibration.bundle_adjustment import _pose_of_view, bundle_adjust
from saddlescope.core.calibration.checks import metric_checks
from saddlescope.core.calibration.intrinsics import (
    _choose_k3,
    _given_intrinsics,
    calibrate_intrinsics,
    choose_lens_model,
)
from saddlescope.core.calibration.stereo import stereo_extrinsics
from saddlescope.core.calibration.views import MIN_CORNERS, MIN_POSE_CORNERS, MIN_VIEWS, BoardView
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.findings import Finding
from saddlescope.core.types import Board, Camera, LensModel, Rig

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


def _board_poses(cameras, per_cam, obj_all) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The board pose (R (3, 3), t_mm (3,)) in the rig that each camera's view of one instant gives."""
    poses = {}
    for cam, v in per_cam.items():
        c = cameras[cam]
        ok, rvec, tvec = _pose_of_view(c, obj_all[v.ids], v.corners_px)
        if ok:
            Rb = c.R.T @ cv2.Rodrigues(rvec)[0]
            poses[cam] = (Rb, c.R.T @ (tvec - c.t_mm))
    return poses


def _view_error_px(camera: Camera, obj_all: np.ndarray, view: BoardView, pose) -> float:
    """R.m.s. reprojection error (px) of a view's corners for a board pose in the rig."""
    Rb, tb = pose
    pts = obj_all[view.ids] @ Rb.T + tb
    proj = camera.project(pts)
    return float(np.sqrt(np.mean(np.sum((proj - view.corners_px) ** 2, axis=1))))


def _agreed_pose(cameras, per_cam, obj_all, poses, max_px):
    """Of the cameras' board poses, the one most of their views agree with (None without poses)."""
    best_pose, best_votes = None, -1
    for pose in poses.values():
        votes = sum(_view_error_px(cameras[c2], obj_all, v2, pose) < max_px for c2, v2 in per_cam.items())
        if votes > best_votes:
            best_pose, best_votes = pose, votes
    return best_pose


def _fix_instant(cameras, per_cam, board, obj_all, max_px) -> tuple[dict[str, BoardView], int, int]:
    """The views of one instant that are kept, and how many were relabelled and dropped.

    A view is relabelled after a half turn where that fits the pose the other cameras see.
    """
    best_pose = _agreed_pose(cameras, per_cam, obj_all, _board_poses(cameras, per_cam, obj_all), max_px)
    kept: dict[str, BoardView] = {}
    n_fixed = n_dropped = 0
    for cam, v in per_cam.items():
        if best_pose is None or _view_error_px(cameras[cam], obj_all, v, best_pose) < max_px:
            kept[cam] = v
            continue
        turned_ids = board_type(board.kind).half_turn_ids(board, v.ids)
        if turned_ids is not None:
            flipped = BoardView(v.frame, v.corners_px, turned_ids)
            if _view_error_px(cameras[cam], obj_all, flipped, best_pose) < max_px:
                kept[cam] = flipped
                n_fixed += 1
                continue
        n_dropped += 1
    return kept, n_fixed, n_dropped


def _fix_flipped_views(cameras, views_by_camera, board, *, max_px=20.0):
    """Relabel (180-degree) or drop views inconsistent with the board pose the other cameras see.

    Symmetric checkerboards can be labelled from the opposite corner in one camera; this finds such
    views from the initial rig and tries the rotated labels.
    """
    names = list(cameras)
    obj_all = object_points_mm(board)
    by_inst: dict[int, dict[str, BoardView]] = {}
    for cam in names:
        for v in views_by_camera.get(cam, []):
            by_inst.setdefault(v.frame, {})[cam] = v
    out = {cam: [] for cam in names}
    n_fixed = n_dropped = 0
    for per_cam in by_inst.values():
        kept = per_cam
        if len(per_cam) >= 2:
            kept, fixed, dropped = _fix_instant(cameras, per_cam, board, obj_all, max_px)
            n_fixed += fixed
            n_dropped += dropped
        for cam, v in kept.items():
            out[cam].append(v)
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
    3-4 mm across the view. Each camera's own estimate scatters; their mean shift does not.
    """
    names = [n for n in joint if n in single]
    d = [np.asarray(joint[n].K)[:2, 2] - np.asarray(single[n].K)[:2, 2] for n in names]
    return np.mean(d, axis=0) if d else np.zeros(2)


def calibrate_rig(views_by_camera: Mapping[str, list[BoardView]], board: Board,
                  image_sizes: Mapping[str, tuple[int, int]], *, fix_k3: bool | None = None,
                  bundle: bool = True, loss: str = "soft_l1", min_views: int = MIN_VIEWS, min_shared: int = 3,
                  max_square_error_pct: float = 1.0, max_square_error_mm: float | None = None,
                  max_distance_rms_mm: float | None = None, max_principal_point_shift: float = 0.02,
                  clip: str | None = "calibration", threads: int | None = 1,
                  given_intrinsics: Mapping[str, Camera] | None = None) -> tuple[Rig, dict]:
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
    threads : int or None
        Intrinsics and pairs fitted this many at once (None: all); each fit uses its own views alone.
    given_intrinsics : dict name -> Camera, optional
        Intrinsics known for some cameras (an earlier calibration of the same camera, a lens profile):
        held as given, only their poses fitted.

    Returns
    -------
    rig : Rig
        ``checks`` holds the metric numbers, ``flags`` their failures, ``pairs`` the stereo results
        {"a-b": {"R", "t_mm", "rms_px", "n_views"}}.
    report : dict
        ``intrinsics`` {name: report}, ``bundle`` report (or None), ``per_pair_checks``,
        ``n_relabelled_views``, ``n_dropped_views``, ``n_partial_views`` {name: views of 4-5 corners used for
        the board's pose}, ``lens_choice`` {name: :func:`_joint_lens_test`'s numbers}.

    Each camera's lens comes from the joint adjustment unless its own views reject it
    (:func:`_joint_lens_test`); ``rig.lens_models`` and a ``calibration.lens_model`` finding per camera say which.
    """
    names, given = _check_rig_inputs(views_by_camera, image_sizes, given_intrinsics)
    intrinsics, intr_reports = _all_intrinsics(views_by_camera, board, image_sizes, fix_k3=fix_k3, clip=clip,
                                               min_views=min_views, threads=threads, given=given)
    k3_fixed = {n: intr_reports[n]["fix_k3"] for n in names}
    views = {n: _pose_views(views_by_camera[n], intr_reports[n]) for n in names}
    partial = {n: sum(len(v.ids) < MIN_CORNERS for v in views[n]) for n in names}
    report: dict = {"intrinsics": intr_reports, "bundle": None, "per_pair_checks": {},
                    "n_relabelled_views": 0, "n_dropped_views": 0, "lens_choice": {},
                    "n_partial_views": partial}
    models = {n: LensModel(k3=not k3_fixed[n], given=n in given) for n in names}
    if len(names) == 1:
        return Rig({names[0]: intrinsics[names[0]]}, lens_models=models), report

    pairs_cv = _stereo_pairs(views, intrinsics, board, min_shared=min_shared, threads=threads)
    init = _initial_poses(names, pairs_cv, names[0])
    cams = {n: Camera(n, intrinsics[n].K, intrinsics[n].dist, intrinsics[n].image_size, R=init[n][0],
                      t_mm=init[n][1], rms_px=intrinsics[n].rms_px, K_std=intrinsics[n].K_std,
                      dist_std=intrinsics[n].dist_std) for n in names}
    views, n_fixed, n_dropped = _fix_flipped_views(cams, views, board)
    report["n_relabelled_views"], report["n_dropped_views"] = n_fixed, n_dropped
    lens_flags: list[Finding] = []
    if bundle:
        cams, report["bundle"], models, report["lens_choice"], lens_flags = _adjust_with_lens_choice(
            cams, intrinsics, intr_reports, views, views_by_camera, board, models, loss=loss, clip=clip,
            min_views=min_views)
    pairs = {f"{a}-{b}": {"R": p["R"], "t_mm": p["t_mm"], "rms_px": p["rms_px"], "n_views": p["n_views"]}
             for (a, b), p in pairs_cv.items()}
    checks, flags, report["per_pair_checks"] = _rig_checks(
        cams, pairs, views, board, intrinsics, report["bundle"], image_sizes,
        metric_limits={"max_square_error_pct": max_square_error_pct, "max_square_error_mm": max_square_error_mm,
                       "max_distance_rms_mm": max_distance_rms_mm},
        max_principal_point_shift=max_principal_point_shift)
    return Rig(cams, checks=checks, flags=tuple(flags) + tuple(lens_flags), pairs=pairs, lens_models=models), report


def _check_rig_inputs(views_by_camera: Mapping[str, list[BoardView]], image_sizes: Mapping[str, tuple[int, int]],
                      given_intrinsics: Mapping[str, Camera] | None) -> tuple[list[str], dict[str, Camera]]:
    """The cameras to calibrate and the intrinsics given; refuse none, a missing size or a stranger's lens."""
    names = list(views_by_camera)
    if not names:
        raise InputError("no cameras to calibrate")
    missing = [n for n in names if n not in image_sizes]
    if missing:
        raise InputError(f"image size missing for camera(s) {', '.join(missing)}")
    given = dict(given_intrinsics or {})
    unknown = [n for n in given if n not in names]
    if unknown:
        raise InputError(f"intrinsics given for camera(s) {', '.join(unknown)} that are not calibrated here")
    return names, given


def _pose_views(views: list[BoardView], intr_report: dict) -> list[BoardView]:
    """Return the views kept by the intrinsic step (outliers dropped) and the partial ones.

    Partial views have too few corners for a lens but enough for the board's pose (4 or more): they count
    in the joint adjustment.
    """
    return [v for v in views if v.frame in intr_report["per_view_rms_px"]
            or (MIN_POSE_CORNERS <= len(v.ids) < MIN_CORNERS and v.frame not in intr_report["dropped_frames"])]


def _rig_checks(cams: dict[str, Camera], pairs: dict, views: dict, board: Board, intrinsics: dict,
                bundle_report: dict | None, image_sizes: Mapping[str, tuple[int, int]], *,
                metric_limits: dict, max_principal_point_shift: float) -> tuple[dict, list, dict]:
    """The rig's metric checks in mm, each pair's own, and whether the adjustment moved every principal point."""
    checks, flags, per_pair = metric_checks(Rig(cams, pairs=pairs), views, board, **metric_limits)
    for key, p in pairs.items():
        p.update({f"check_{k}": v for k, v in per_pair.get(key, {}).items()})
    if bundle_report is not None:
        checks["bundle_rms_px"] = bundle_report["rms_px"]
        limit = max_principal_point_shift * min(min(image_sizes[n]) for n in cams)
        checks["principal_point_common_shift_px"], flag = _principal_point_check(intrinsics, cams, limit)
        if flag is not None:
            flags.append(flag)
    return checks, flags, per_pair


JOINT_LENS_MIN_VIEWS = 6  # fewer own views than this cannot overrule the joint adjustment


def _joint_lens_test(own_report: dict, joint_report: dict, n_intrinsics: int) -> dict:
    """Whether a camera's own views reject the lens the joint adjustment gave it (Bayesian information criterion).

    Two models of the camera's own views, each view with its own board pose: its own lens fit (``n_intrinsics``
    more parameters) and the joint adjustment's lens (fixed). The criterion counts each view as one observation
    (its corners' errors move together: a board a little off in time or bent, a corner detector's bias), so
    ``bic_own - bic_joint = n_views ln(rss_own / rss_joint) + n_intrinsics ln(n_views)``; counting every
    corner instead would reject any lens but the camera's own, down to a hundredth of a pixel.
    """
    n_views = int(joint_report["n_views"])
    rss_own = own_report["rms_px"] ** 2 * own_report["n_points"] / n_views
    rss_joint = joint_report["rms_px"] ** 2 * joint_report["n_points"] / n_views
    bic_joint = n_views * float(np.log(max(rss_joint, 1e-300)))
    bic_own = n_views * float(np.log(max(rss_own, 1e-300))) + n_intrinsics * float(np.log(max(n_views, 1)))
    return {"own_views_rms_px": float(own_report["rms_px"]), "joint_lens_rms_px": float(joint_report["rms_px"]),
            "n_views": n_views, "bic_own": bic_own, "bic_joint": bic_joint,
            "held": bool(n_views >= JOINT_LENS_MIN_VIEWS and bic_own < bic_joint)}


def _adjust_with_lens_choice(cams: dict[str, Camera], intrinsics: Mapping[str, Camera],
                             intr_reports: Mapping[str, dict],
                             views: Mapping[str, list[BoardView]], views_by_camera: Mapping[str, list[BoardView]],
                             board: Board, models: dict[str, LensModel], *, loss: str, clip: str | None,
                             min_views: int = MIN_VIEWS):
    """The joint adjustment, repeated with the lens of each camera whose own views reject the joint one held.

    The joint adjustment fits every camera's lens to all cameras' views at once; where the cameras disagree
    by more than each sees alone (a real rig's views are not exactly simultaneous; caliscope's four webcams
    disagree by 1.2 px where each camera's own fit leaves 0.2 px), a lens seen mostly in its middle absorbs
    the disagreement: its focal length came out 23 % long, its principal point 140 px aside. Such a lens fits
    its own camera's views far worse than the camera's own fit; :func:`_joint_lens_test` decides, once for
    all cameras after the first adjustment, and the adjustment is repeated with those lenses held, each in
    the lens model its own views support (:func:`choose_lens_model`: fx = fy, the principal point at the
    centre, no tangential term where the views do not pay for them).

    Returns cameras, the bundle report, the lens models, the tests' numbers and one finding per camera.
    """
    names = list(cams)
    first, bundle_report = bundle_adjust(cams, views, board, lens_models=models, loss=loss)
    choice: dict[str, dict] = {}
    for n in names:
        if models[n].given:
            continue
        own_views = [v for v in views_by_camera[n] if v.frame in intr_reports[n]["per_view_rms_px"]]
        joint_rep = _given_intrinsics(own_views, board, first[n], camera=n, clip=clip,
                                      model=LensModel(given=True))[1]
        choice[n] = _joint_lens_test(intr_reports[n], joint_rep, models[n].n_intrinsics)
    held = [n for n in choice if choice[n]["held"]]
    out = first
    if held:
        own = {n: choose_lens_model(intrinsics[n], intr_reports[n], views_by_camera[n], board,
                                    intrinsics[n].image_size, camera=n, clip=clip, min_views=min_views)
               for n in held}
        for n, (_, rep, model) in own.items():
            models[n] = replace(model, given=models[n].given)
            choice[n]["lens_test"] = rep["lens_test"]
        start = {n: (Camera(n, own[n][0].K, own[n][0].dist, own[n][0].image_size, R=first[n].R,
                            t_mm=first[n].t_mm) if n in held else first[n]) for n in names}
        ba_models = {n: replace(models[n], given=True) if n in held else models[n] for n in names}
        out, bundle_report = bundle_adjust(start, views, board, lens_models=ba_models, loss=loss)
        for n in held:  # the own fit's uncertainty, not the adjustment's zero for a held lens
            out[n] = replace(out[n], K_std=own[n][0].K_std, dist_std=own[n][0].dist_std)
    models = {n: replace(m, joint=n not in held, reason=_lens_reason(n, m, choice.get(n)))
              for n, m in models.items()}
    return out, bundle_report, models, choice, [_lens_finding(n, models[n], choice[n], first[n], out[n])
                                                for n in held]


def _fixed_in_words(model: LensModel) -> str:
    """Which lens parameters a model fixes, in words ("every lens parameter fitted" where none)."""
    fixed = [words for held, words in ((model.equal_focal, "one focal length for x and y"),
                                       (not model.principal_point, "the principal point at the image centre"),
                                       (not model.tangential, "no tangential distortion"),
                                       (not model.k3, "k3 at zero")) if held]
    if not fixed:
        return "every lens parameter fitted"
    return ", ".join(fixed[:-1]) + (" and " if len(fixed) > 1 else "") + fixed[-1]


def _lens_reason(name: str, model: LensModel, test: dict | None) -> str:
    """Why the camera's lens is what it is, in words."""
    if model.given:
        return "intrinsics given (an earlier calibration or a lens profile); only the camera's pose was fitted"
    if test is None:
        return "fitted by the joint adjustment of all cameras"
    if test["held"]:
        return (f"the joint adjustment's lens fits this camera's own views with {test['joint_lens_rms_px']:.2f} px "
                f"against {test['own_views_rms_px']:.2f} px for its own fit, more than its lens parameters explain "
                f"over {test['n_views']} views: the lens from its own views was kept ({_fixed_in_words(model)}, "
                "the model its views support by the Bayesian information criterion) and only its pose adjusted "
                "with the other cameras")
    return (f"the joint adjustment's lens fits this camera's own views with {test['joint_lens_rms_px']:.2f} px "
            f"(its own fit {test['own_views_rms_px']:.2f} px over {test['n_views']} views): kept")


def _lens_finding(name: str, model: LensModel, test: dict, joint: Camera, final: Camera) -> Finding:
    """A ``calibration.lens_model`` finding for a camera whose lens the joint adjustment was not allowed to bend."""
    values = {"n_lens_parameters": float(model.n_intrinsics), "focal_x_px": float(final.K[0, 0]),
              "focal_y_px": float(final.K[1, 1]), "joint_focal_x_px": float(joint.K[0, 0]),
              "joint_focal_y_px": float(joint.K[1, 1]), "own_views_rms_px": test["own_views_rms_px"],
              "joint_lens_rms_px": test["joint_lens_rms_px"], "n_views": float(test["n_views"]),
              "bic_own": test["bic_own"], "bic_joint": test["bic_joint"]}
    return Finding("calibration.lens_model", (
        f"camera {name}: the joint adjustment of all cameras would have made its focal length "
        f"{joint.K[0, 0]:.0f}/{joint.K[1, 1]:.0f} px, which fits its own views with {test['joint_lens_rms_px']:.2f} px "
        f"against {test['own_views_rms_px']:.2f} px for its own lens ({final.K[0, 0]:.0f}/{final.K[1, 1]:.0f} px): "
        "its own lens was kept and only its pose adjusted with the other cameras"), values)


def _all_intrinsics(views_by_camera: Mapping[str, list[BoardView]], board: Board,
                    image_sizes: Mapping[str, tuple[int, int]], *, fix_k3: bool | None, clip: str | None,
                    min_views: int, threads: int | None = 1,
                    given: Mapping[str, Camera] | None = None) -> tuple[dict[str, Camera], dict[str, dict]]:
    """Each camera's intrinsics and report (:func:`calibrate_intrinsics`), ``threads`` cameras at once.

    Where ``fix_k3`` is None, k3 is chosen per camera (:func:`_choose_k3`); ``given`` intrinsics are held.
    """
    def one(name: str) -> tuple[Camera, dict]:
        if given and name in given:
            known = given[name]
            if tuple(known.image_size) != tuple(image_sizes[name]):
                raise InputError(f"intrinsics given for camera {name} are for {known.image_size[0]}x"
                                 f"{known.image_size[1]} px images but its clip is {image_sizes[name][0]}x"
                                 f"{image_sizes[name][1]} px")
            return calibrate_intrinsics(views_by_camera[name], board, image_sizes[name], camera=name, clip=clip,
                                        guess=known, model=LensModel(k3=bool(np.asarray(known.dist).ravel()[4:5].any()),
                                                                     given=True))
        cam, rep = calibrate_intrinsics(views_by_camera[name], board, image_sizes[name], camera=name, clip=clip,
                                        fix_k3=True if fix_k3 is None else fix_k3, min_views=min_views)
        if fix_k3 is None:
            cam, rep = _choose_k3(cam, rep, views_by_camera[name], board, image_sizes[name], camera=name,
                                  clip=clip, min_views=min_views)
        return cam, rep

    fitted = _in_threads(list(views_by_camera), one, threads)
    return {n: c for n, (c, _) in fitted.items()}, {n: r for n, (_, r) in fitted.items()}


def _in_threads(keys: list, work: Callable, threads: int | None) -> dict:
    """``{key: work(key)}`` in ``keys``' order, ``threads`` at once (None: all); the first error is raised."""
    workers = len(keys) if threads is None else max(1, min(len(keys), threads))
    if workers <= 1:
        return {k: work(k) for k in keys}
    with ThreadPoolExecutor(max_workers=workers) as pool:
        return dict(zip(keys, pool.map(work, keys), strict=True))


STEREO_MAX_VIEWS = 50  # shared instants a pair's pose is fitted from (evenly spread through the clip)


def _spread(shared_a: list[BoardView], shared_b: list[BoardView], most: int) -> tuple[list, list]:
    """At most ``most`` of the instants both lists hold, evenly spread (every one when there are fewer)."""
    frames = sorted({v.frame for v in shared_a} & {v.frame for v in shared_b})
    if len(frames) <= most:
        return shared_a, shared_b
    keep = {frames[i] for i in np.unique(np.linspace(0, len(frames) - 1, most).round().astype(int))}
    return [v for v in shared_a if v.frame in keep], [v for v in shared_b if v.frame in keep]


def _stereo_pairs(views: Mapping[str, list[BoardView]], intrinsics: Mapping[str, Camera], board: Board, *,
                  min_shared: int, max_views: int = STEREO_MAX_VIEWS,
                  threads: int | None = 1) -> dict[tuple[str, str], dict]:
    """:func:`stereo_extrinsics` of every pair of cameras that see the board together often enough.

    A pair's pose only starts the bundle adjustment (which then fits every view of every camera), so it is
    fitted from at most ``max_views`` shared instants spread through the clip: on a default synthetic
    ride's 150 instants the three pairs cost 6 CPU-s, two fifths of the calibration's solve, and the
    adjusted rig is the same. ``threads`` pairs at once.
    """
    def one(pair: tuple[str, str]) -> dict | None:
        a, b = pair
        try:
            return stereo_extrinsics(*_spread(views[a], views[b], max_views), intrinsics[a], intrinsics[b], board,
                                     min_shared=min_shared)
        except CalibrationError:
            return None  # the pair may be linked through other cameras

    fitted = _in_threads(list(itertools.combinations(list(views), 2)), one, threads)
    return {pair: p for pair, p in fitted.items() if p is not None}


def _principal_point_check(single: Mapping[str, Camera], joint: Mapping[str, Camera],
                           limit_px: float) -> tuple[float, Finding | None]:
    """The principal points' common shift (px) by the joint adjustment, and a flag when over ``limit_px``."""
    shift = principal_point_common_shift(single, joint)
    shift_px = float(np.hypot(*shift))
    if not shift_px > limit_px:
        return shift_px, None
    return shift_px, Finding("calibration.principal_point", (
        f"the joint adjustment moved every camera's principal point by about "
        f"{shift_px:.0f} px (x {shift[0]:+.0f}, y {shift[1]:+.0f}) from where "
        "each camera's own views put it: the board's positions do not tell the cameras' aim from their "
        "principal points, so heights and depths may bend by millimetres across the view; carry the board "
        "higher and lower and tilt it towards and away from the cameras"),
        {"shift_px": shift_px, "shift_x_px": float(shift[0]), "shift_y_px": float(shift[1]), "limit_px": limit_px})

"""Intrinsics of one camera from board views (Zhang / Bouguet; thesis 3.4, Tables 8.1-8.3)."""

from __future__ import annotations

import cv2
import numpy as np

from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.calibration.views import MIN_CORNERS, MIN_VIEWS, BoardView
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.types import Board, Camera, LensModel

__all__ = ["calibrate_intrinsics", "choose_lens_model"]

_CALIB_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-9)


def _check_views(views: list[BoardView], board: Board, camera: str, clip: str | None, *,
                 min_views: int) -> list[BoardView]:
    where = f"{clip} clip of the {camera} camera" if clip else f"camera {camera}"
    n_points = len(object_points_mm(board))
    good = []
    for v in views:
        corners = np.asarray(v.corners_px, np.float64)
        ids = np.asarray(v.ids, np.int64)
        if corners.ndim != 2 or corners.shape[1] != 2 or len(ids) != len(corners):
            raise InputError(f"{where}, frame {v.frame}: corners must have shape (N, 2) and ids (N,), "
                             f"got {corners.shape} and {ids.shape}")
        if ids.size and (ids.min() < 0 or ids.max() >= n_points):
            raise InputError(f"{where}, frame {v.frame}: corner ids outside the board's 0..{n_points - 1}")
        if len(ids) >= MIN_CORNERS and np.all(np.isfinite(corners)):
            good.append(BoardView(int(v.frame), corners, ids))
    if not good:
        raise CalibrationError(f"no calibration board found in the {where}")
    if len(good) < min_views:
        raise CalibrationError(f"calibration board found in only {len(good)} frame(s) of the {where}; "
                               f"need at least {min_views} views")
    return good


def _calib_flags(fix_k3: bool, model: LensModel | None = None) -> int:
    """OpenCV's calibration flags for a lens model (None: fx, fy, cx, cy, k1, k2, p1, p2 and k3 unless fixed)."""
    if model is None:
        return cv2.CALIB_FIX_K3 if fix_k3 else 0
    return ((0 if model.k3 else cv2.CALIB_FIX_K3) | (cv2.CALIB_FIX_ASPECT_RATIO if model.equal_focal else 0)
            | (0 if model.principal_point else cv2.CALIB_FIX_PRINCIPAL_POINT)
            | (0 if model.tangential else cv2.CALIB_ZERO_TANGENT_DIST))


def _model_start(guess: Camera | None, model: LensModel | None, image_size: tuple[int, int]):
    """The K and distortion OpenCV starts from (None, None: its own estimate), held where the model fixes them.

    A fixed principal point is the image centre, an equal focal length the mean of the guess's two, a
    fixed tangential term or k3 zero.
    """
    if guess is None and (model is None or (model.principal_point and not model.equal_focal)):
        return None, None  # OpenCV's distortion-free start (the centre, fx = fy from the views)
    w, h = image_size
    if guess is None:
        K, dist = np.array([[w, 0.0, (w - 1) / 2], [0.0, w, (h - 1) / 2], [0, 0, 1]]), np.zeros(5)
    else:
        K, dist = np.array(guess.K, np.float64), np.array(guess.dist, np.float64).ravel()[:5].copy()
    if model is not None and not model.given:
        if model.equal_focal:
            K[0, 0] = K[1, 1] = float(np.sqrt(K[0, 0] * K[1, 1]))
        if not model.principal_point:
            K[0, 2], K[1, 2] = (w - 1) / 2, (h - 1) / 2
        if not model.tangential:
            dist[2:4] = 0.0
        if not model.k3:
            dist[4] = 0.0
    return K, dist


def calibrate_intrinsics(views: list[BoardView], board: Board, image_size: tuple[int, int], *,
                         camera: str = "camera", clip: str | None = None, fix_k3: bool = True,
                         min_views: int = MIN_VIEWS, outlier_factor: float = 3.0,
                         min_outlier_px: float = 0.5, max_rounds: int = 3,
                         guess: Camera | None = None, model: LensModel | None = None) -> tuple[Camera, dict]:
    """Intrinsics of one camera from board views (Zhang / Bouguet; thesis 3.4, Tables 8.1-8.3).

    Parameters
    ----------
    views : list of BoardView
    board : Board
    image_size : (width, height) px
    camera, clip : str
        Names used in error messages.
    fix_k3 : bool
        Keep k3 = 0 (narrow lenses: k3 is poorly determined and trades off against k1, k2).
    outlier_factor, min_outlier_px : float
        A view whose RMS error exceeds ``max(outlier_factor * median, min_outlier_px)`` is dropped and
        the calibration repeated (at most ``max_rounds`` times).
    guess : Camera, optional
        Start from these intrinsics instead of OpenCV's distortion-free initial estimate.
    model : LensModel, optional
        Fit only the parameters it names (``fix_k3`` is then ignored): fx = fy as one focal length, the
        principal point held at the image centre, the tangential term or k3 held at zero; ``given``
        intrinsics (``guess``) are held whole and only the views' poses fitted.

    Returns
    -------
    camera : Camera
        At identity pose, with ``K_std``, ``dist_std`` (one standard deviation) and ``rms_px``.
    report : dict
        ``rms_px``, ``residual_std_px`` (x, y), ``per_view_rms_px`` {frame: px}, ``dropped_frames``,
        ``n_views``, ``n_points``, ``fix_k3``, ``poses`` {frame: (rvec (3,), tvec_mm (3,))}.

    Raises
    ------
    CalibrationError
        No board, fewer than ``min_views`` views, or OpenCV failing to converge.
    """
    if model is not None and model.given:
        if guess is None:
            raise InputError(f"camera {camera}: intrinsics marked as given but none were given")
        return _given_intrinsics(views, board, guess, camera=camera, clip=clip, model=model)
    views = _check_views(views, board, camera, clip, min_views=min_views)
    obj_all = object_points_mm(board).astype(np.float32)
    dropped: list[int] = []
    w, h = (int(v) for v in image_size)
    start = _model_start(guess, model, (w, h))
    flags = _calib_flags(fix_k3, model) | (0 if start[0] is None else cv2.CALIB_USE_INTRINSIC_GUESS)
    for round_ in range(max_rounds + 1):
        obj = [obj_all[v.ids] for v in views]
        img = [v.corners_px.astype(np.float32).reshape(-1, 1, 2) for v in views]
        try:
            rms, K, dist, rvecs, tvecs, std_intr, _, per_view = cv2.calibrateCameraExtended(  # type: ignore[call-overload]  # cv2's stubs: None K/dist are allowed
                obj, img, (w, h), *start, flags=flags, criteria=_CALIB_CRITERIA)
        except cv2.error as exc:
            raise CalibrationError(f"calibration of camera {camera} failed in OpenCV: "
                                   f"{str(exc).strip().splitlines()[-1]}") from None
        per_view = per_view.ravel()
        limit = max(outlier_factor * float(np.median(per_view)), min_outlier_px)
        bad = per_view > limit
        if not bad.any() or len(views) - bad.sum() < min_views or round_ == max_rounds:
            break  # (views are dropped only where a round follows to fit without them)
        dropped += [v.frame for v, b in zip(views, bad, strict=True) if b]
        views = [v for v, b in zip(views, bad, strict=True) if not b]
    fix_k3_used = bool(fix_k3) if model is None else not model.k3
    return _intrinsics_result(camera, views, obj_all, (w, h), (rms, K, dist, rvecs, tvecs, std_intr, per_view),
                              dropped=dropped, fix_k3=fix_k3_used)


def _intrinsics_result(camera: str, views: list[BoardView], obj_all: np.ndarray, size: tuple[int, int],
                       fit: tuple, *, dropped: list[int], fix_k3: bool) -> tuple[Camera, dict]:
    """The camera and the report of OpenCV's fit ``(rms, K, dist, rvecs, tvecs, std_intr, per_view)``."""
    rms, K, dist, rvecs, tvecs, std_intr, per_view = fit
    w, h = size
    residuals = []
    for v, rv, tv in zip(views, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(obj_all[v.ids], rv, tv, K, dist)
        residuals.append(proj.reshape(-1, 2) - v.corners_px)
    res = np.concatenate(residuals)
    std_intr = std_intr.ravel()
    dist = dist.ravel()[:5]
    cam = Camera(camera, K, np.pad(dist, (0, 5 - len(dist))), (w, h), rms_px=float(rms),
                 K_std=np.array([[std_intr[0], 0, std_intr[2]], [0, std_intr[1], std_intr[3]], [0, 0, 0]]),
                 dist_std=std_intr[4:9].copy())
    report = {
        "rms_px": float(rms),
        "residual_std_px": res.std(axis=0).tolist(),
        "per_view_rms_px": {int(v.frame): float(e) for v, e in zip(views, per_view, strict=True)},
        "dropped_frames": sorted(dropped),
        "n_views": len(views),
        "n_points": int(len(res)),
        "fix_k3": fix_k3,
        "poses": {int(v.frame): (np.asarray(rv, np.float64).ravel(), np.asarray(tv, np.float64).ravel())
                  for v, rv, tv in zip(views, rvecs, tvecs, strict=True)},
    }
    return cam, report


def _view_pose(cam: Camera, obj: np.ndarray, img: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The board's pose (rvec, tvec_mm) in one view for fixed intrinsics (IPPE, then Levenberg-Marquardt)."""
    K, dist = np.asarray(cam.K, np.float64), np.asarray(cam.dist, np.float64)
    try:
        ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
        if not ok:
            ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist)
        if not ok:
            return None
        rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
    except cv2.error:
        return None
    return rvec.ravel(), tvec.ravel()


def _given_intrinsics(views: list[BoardView], board: Board, given: Camera, *, camera: str, clip: str | None,
                      model: LensModel) -> tuple[Camera, dict]:
    """Given intrinsics with the report :func:`calibrate_intrinsics` gives: only each view's pose is fitted."""
    views = _check_views(views, board, camera, clip, min_views=1)
    obj_all = object_points_mm(board).astype(np.float64)
    kept, residuals, per_view, poses = [], [], {}, {}
    for v in views:
        pose = _view_pose(given, obj_all[v.ids], v.corners_px)
        if pose is None:
            continue
        proj, _ = cv2.projectPoints(obj_all[v.ids], pose[0], pose[1], given.K, given.dist)
        res = proj.reshape(-1, 2) - v.corners_px
        kept.append(v)
        residuals.append(res)
        per_view[int(v.frame)] = float(np.sqrt(np.mean(np.sum(res ** 2, axis=1))))
        poses[int(v.frame)] = pose
    if not kept:
        raise CalibrationError(f"no board pose could be fitted in the views of camera {camera}")
    res = np.concatenate(residuals)
    rms = float(np.sqrt(np.mean(np.sum(res ** 2, axis=1))))
    cam = Camera(camera, np.array(given.K, np.float64), np.asarray(given.dist, np.float64).ravel()[:5].copy(),
                 (int(given.image_size[0]), int(given.image_size[1])), rms_px=rms, K_std=np.zeros((3, 3)),
                 dist_std=np.zeros(5))
    return cam, {"rms_px": rms, "residual_std_px": res.std(axis=0).tolist(), "per_view_rms_px": per_view,
                 "dropped_frames": [], "n_views": len(kept), "n_points": int(len(res)), "fix_k3": not model.k3,
                 "poses": poses}


K3_SCREEN_SIGMAS = 2.0  # a linearised k3 nearer zero than this (in standard deviations; the full test asks 3) ...
K3_SCREEN_BIC = 3.0  # ... and a BIC this much worse than the fixed model's (the full test asks better) settle it


def _bic_pair(fixed: dict, free: dict) -> tuple[float, float]:
    """The Bayesian information criterion of the fixed-k3 and free-k3 fits' reprojection residuals."""
    n_fixed, n_free = 2 * fixed["n_points"], 2 * free["n_points"]
    return (n_fixed * np.log(fixed["rms_px"] ** 2) + 8 * np.log(n_fixed),
            n_free * np.log(free["rms_px"] ** 2) + 9 * np.log(n_free))


def _linearised_k3_test(cam: Camera, report: dict, views: list[BoardView], board: Board) -> dict | None:
    """The free-k3 fit's k3, its standard deviation and BIC, from Gauss-Newton steps off the fixed-k3 fit.

    OpenCV's fit costs the cube of the views (its normal equations are dense: over a second for 140 views);
    here the board poses are eliminated view by view (Schur complement, as the bundle adjustment does), so a
    step costs in proportion to the views. Starting at the fixed-k3 optimum, where the model is nearly
    linear in k3, two steps land within a small fraction of a deviation of the full fit (synthetic rigs:
    k3 z-scores 1.47, 2.92 and 0.06 from the full fit, the same to 0.05 here). None if a view's pose is
    missing.
    """
    from saddlescope.core.calibration.bundle_adjustment import _NCAM, _Bundle, _schur_solve

    poses = report.get("poses", {})
    if any(v.frame not in poses for v in views):
        return None
    obj = object_points_mm(board).astype(np.float64)
    counts = [len(v.ids) for v in views]
    inst = np.repeat(np.arange(len(views)), counts)
    bundle = _Bundle(obj, np.zeros(inst.size, int), inst, np.concatenate([v.ids for v in views]),
                     np.concatenate([v.corners_px for v in views]).astype(np.float64), 1, len(views))
    cams = np.zeros((1, _NCAM))
    cams[0, :4] = cam.K[0, 0], cam.K[1, 1], cam.K[0, 2], cam.K[1, 2]
    cams[0, 4:9] = np.asarray(cam.dist, np.float64).ravel()[:5]
    boards = np.array([np.concatenate(poses[v.frame]) for v in views], np.float64)
    free = np.arange(9)  # fx fy cx cy k1 k2 p1 p2 k3; the camera is the frame
    r = bundle.residuals(cams, boards)
    for _ in range(2):
        A, B = bundle.jacobians(cams, boards, r)
        U, V, W, gc, gb = bundle.normal_equations(A, B, r, np.ones(len(r)))
        try:
            dc, db, S = _schur_solve(U, V, W, gc, gb, free, 0.0)
        except np.linalg.LinAlgError:
            return None
        cams, boards = cams + dc, boards + db
        r = bundle.residuals(cams, boards)
    n_points = len(r)
    sq = float(np.sum(r * r))
    try:
        cov = np.linalg.inv(S[np.ix_(free, free)])  # the intrinsics' block of (J^T J)^-1, as OpenCV's
    except np.linalg.LinAlgError:
        return None
    sigma2 = sq / max(2 * n_points - len(free) - 6 * len(views), 1)
    k3, k3_std = float(cams[0, 8]), float(np.sqrt(max(cov[8, 8], 0.0) * sigma2))
    bic_fixed, bic_free = _bic_pair(report, {"n_points": n_points, "rms_px": np.sqrt(sq / n_points)})
    return {"k3": k3, "k3_std": k3_std, "z": abs(k3) / k3_std if k3_std > 0 else np.inf,
            "bic_fixed": float(bic_fixed), "bic_free": float(bic_free)}


def _choose_k3(cam: Camera, report: dict, views: list[BoardView], board: Board, image_size, *,
               camera: str, clip: str | None, min_views: int) -> tuple[Camera, dict]:
    """Keep k3 = 0 unless the views call for it.

    The free k3 must lower the Bayesian information criterion of the reprojection residuals and stand
    three standard deviations from zero.

    A wide-angle lens whose k3 is fixed at zero bends the rest: on the synthetic wide rig (k3 about
    -0.02) the left camera's principal point came out 10 px off and its markers 50 mm aside. A narrow
    lens's k3 is not determined and trades off against k1 and k2, so it stays at zero there.
    """
    dropped = set(report["dropped_frames"])
    kept = [v for v in views if v.frame not in dropped]  # both models judged on the same corners
    screen = _linearised_k3_test(cam, report, kept, board)
    if (screen is not None and screen["z"] < K3_SCREEN_SIGMAS
            and screen["bic_free"] - screen["bic_fixed"] > K3_SCREEN_BIC):
        # far from both bars of the full test below: k3 stays fixed without fitting it (a narrow lens)
        report["k3_test"] = {"k3_free": screen["k3"], "k3_std": screen["k3_std"], "bic_fixed": screen["bic_fixed"],
                             "bic_free": screen["bic_free"], "chosen": "fixed", "linearised": True}
        return cam, report
    try:
        # From the fixed-k3 fit: from OpenCV's distortion-free start, a wide lens's free fit stopped
        # in a wrong minimum (action camera, exact corners: f 5 % long, k3 = -0.005 for -0.013).
        free_cam, free_rep = calibrate_intrinsics(kept, board, image_size, camera=camera, clip=clip,
                                                  fix_k3=False, min_views=min_views, guess=cam, max_rounds=0)
    except CalibrationError:
        return cam, report
    free_rep["dropped_frames"] = report["dropped_frames"]
    n_fixed, n_free = 2 * report["n_points"], 2 * free_rep["n_points"]
    bic_fixed, bic_free = _bic_pair(report, free_rep)
    k3, k3_std = float(free_cam.dist[4]), float(free_cam.dist_std[4]) if free_cam.dist_std is not None else np.inf
    significant = np.isfinite(k3_std) and abs(k3) > 3.0 * k3_std
    free = significant and bic_free < bic_fixed and n_free == n_fixed
    report["k3_test"] = {"k3_free": k3, "k3_std": k3_std, "bic_fixed": float(bic_fixed),
                         "bic_free": float(bic_free), "chosen": "free" if free else "fixed"}
    if free:
        free_rep["k3_test"] = report["k3_test"]
        return free_cam, free_rep
    return cam, report


def _lens_candidates(k3: bool) -> list[LensModel]:
    """The lens models a camera's views choose from, the full model first.

    fx = fy or not, the principal point fitted or at the centre, a tangential term or not (k3 as already chosen).
    """
    return [LensModel(equal_focal=eq, principal_point=pp, tangential=tg, k3=k3)
            for eq in (False, True) for pp in (True, False) for tg in (True, False)]


def _lens_bic(report: dict, model: LensModel) -> float:
    """The Bayesian information criterion of a fit's reprojection residuals (every corner's x and y counted).

    The views' poses (6 per view) are common to every candidate and left out.
    """
    n = 2 * report["n_points"]
    return float(n * np.log(max(report["rms_px"], 1e-12) ** 2) + model.n_intrinsics * np.log(n))


def choose_lens_model(cam: Camera, report: dict, views: list[BoardView], board: Board, image_size, *,
                      camera: str, clip: str | None, min_views: int) -> tuple[Camera, dict, LensModel]:
    """The lens model the camera's own views support: the lowest Bayesian information criterion.

    Each of fx = fy, the principal point at the image centre and no tangential term is fixed where the views
    do not pay for it: the eight combinations (k3 as :func:`_choose_k3` chose it) are fitted on the same
    corners, each from the full fit, and the one with the lowest criterion kept. A lens seen mostly in its
    middle cannot tell its principal point from its aim, nor its tangential term from the board's tilt; left
    free there, they absorb whatever else disagrees (caliscope's webcam 1: principal point 140 px aside).

    Returns the camera and report of the chosen model (``lens_test`` in the report: every candidate's
    criterion by its label and the chosen label) and the model.
    """
    k3 = not report["fix_k3"]
    dropped = set(report["dropped_frames"])
    kept = [v for v in views if v.frame not in dropped and v.frame in report["per_view_rms_px"]]
    fits: list[tuple[float, LensModel, Camera, dict]] = []
    for model in _lens_candidates(k3):
        if model == LensModel(k3=k3):
            fit_cam, fit_rep = cam, report
        else:
            try:
                fit_cam, fit_rep = calibrate_intrinsics(kept, board, image_size, camera=camera, clip=clip,
                                                        min_views=min_views, guess=cam, model=model, max_rounds=0)
            except CalibrationError:
                continue
        fits.append((_lens_bic(fit_rep, model), model, fit_cam, fit_rep))
    bic, model, best_cam, best_rep = min(fits, key=lambda f: f[0])
    best_rep = {**best_rep, "dropped_frames": report["dropped_frames"], "fix_k3": report["fix_k3"]}
    if "k3_test" in report:
        best_rep["k3_test"] = report["k3_test"]
    best_rep["lens_test"] = {"bic": {m.label: b for b, m, _, _ in fits}, "chosen": model.label,
                             "n_points": int(report["n_points"]),
                             "model": {"equal_focal": model.equal_focal, "principal_point": model.principal_point,
                                       "tangential": model.tangential}}
    return best_cam, best_rep, model


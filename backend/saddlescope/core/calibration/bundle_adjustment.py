"""Bundle adjustment: all cameras and all board poses refined jointly."""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.calibration.projection import (
    _camera_from_vector,
    _distort_project,
    _distorted,
    _intr_vector,
    _rotation_matrices,
)
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.types import Board, Camera, LensModel

__all__ = ["bundle_adjust"]


def _pose_of_view(cam: Camera, view_obj, view_img):
    ok, rvec, tvec = cv2.solvePnP(view_obj, view_img, cam.K, cam.dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        ok, rvec, tvec = cv2.solvePnP(view_obj, view_img, cam.K, cam.dist)
    return ok, rvec.ravel(), tvec.ravel()


def _robust_weights(sq_err: np.ndarray, loss: str, f_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """IRLS weights rho'(s) and costs rho(s) of squared residual norms s (per observation)."""
    z = sq_err / f_scale ** 2
    if loss == "linear":
        return np.ones_like(z), sq_err
    if loss == "soft_l1":
        root = np.sqrt(1 + z)
        return 1 / root, 2 * f_scale ** 2 * (root - 1)
    if loss == "huber":
        r = np.sqrt(z)
        w = np.where(r <= 1, 1.0, 1 / np.maximum(r, 1e-300))
        return w, f_scale ** 2 * np.where(r <= 1, z, 2 * r - 1)
    raise InputError(f"unknown bundle-adjustment loss {loss!r} (linear, soft_l1, huber)")


_NCAM = 15  # per camera: fx fy cx cy k1 k2 p1 p2 k3 | rvec (3) t_mm (3)


def _rotations_with_derivatives(rvecs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation matrices (N, 3, 3) of rotation vectors (N, 3) and their derivatives (N, 3, 3, 3): [n, k] = dR/dr_k."""
    R = np.empty((len(rvecs), 3, 3))
    dR = np.empty((len(rvecs), 3, 3, 3))
    for i, rv in enumerate(rvecs):
        R[i], jac = cv2.Rodrigues(rv)
        dR[i] = jac.reshape(3, 3, 3)
    return R, dR


def _projection_derivatives(xc: np.ndarray, intr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Derivatives of :func:`_distort_project`'s pixels (M, 2): w.r.t. the intrinsics (M, 2, 9), the point (M, 2, 3)."""
    x, y, r2, radial, xd, yd = _distorted(xc, intr)
    fx, fy, _, _, k1, k2, p1, p2, k3 = intr.T
    J = np.zeros((len(x), 2, 9))
    J[:, 0, 0], J[:, 1, 1], J[:, 0, 2], J[:, 1, 3] = xd, yd, 1.0, 1.0
    for k, rk in ((4, r2), (5, r2 * r2), (8, r2 * r2 * r2)):
        J[:, 0, k], J[:, 1, k] = fx * x * rk, fy * y * rk
    J[:, 0, 6], J[:, 1, 6] = fx * 2 * x * y, fy * (r2 + 2 * y * y)
    J[:, 0, 7], J[:, 1, 7] = fx * (r2 + 2 * x * x), fy * 2 * x * y
    d_radial = 2 * (k1 + r2 * (2 * k2 + 3 * k3 * r2))  # d radial / d x = x times this
    dxd_dx = radial + x * x * d_radial + 2 * p1 * y + 6 * p2 * x
    dxd_dy = x * y * d_radial + 2 * p1 * x + 2 * p2 * y
    dyd_dx = x * y * d_radial + 2 * p1 * x + 2 * p2 * y
    dyd_dy = radial + y * y * d_radial + 6 * p1 * y + 2 * p2 * x
    D = np.stack([np.stack([fx * dxd_dx, fx * dxd_dy], axis=1), np.stack([fy * dyd_dx, fy * dyd_dy], axis=1)],
                 axis=1)  # (M, 2, 2): pixels by normalised coordinates
    z = xc[:, 2]
    P = np.zeros((len(z), 2, 3))
    P[:, 0, 0] = P[:, 1, 1] = 1 / z
    P[:, 0, 2], P[:, 1, 2] = -x / z, -y / z
    return J, D @ P


class _Bundle:
    """Observations and the residual model of the joint bundle adjustment."""

    def __init__(self, obj, obs_cam, obs_inst, obs_pt, obs_xy, n_cams, n_inst, equal_focal=None):
        self.obj, self.cam, self.inst, self.pt, self.xy = obj, obs_cam, obs_inst, obs_pt, obs_xy
        self.C, self.I = n_cams, n_inst
        # cameras whose fx and fy are one parameter (square pixels): fy follows fx
        self.equal_focal = np.zeros(n_cams, bool) if equal_focal is None else np.asarray(equal_focal, bool)
        self._tied_obs = self.equal_focal[self.cam]
        self._views()

    def tie(self, cams: np.ndarray) -> np.ndarray:
        """Cameras (C, 15) with fy set to fx where the focal lengths are one parameter."""
        if not self.equal_focal.any():
            return cams
        cams = cams.copy()
        cams[self.equal_focal, 1] = cams[self.equal_focal, 0]
        return cams

    def _views(self) -> None:
        """The observations grouped by view (one camera at one instant), padded to the largest view.

        The normal equations' blocks are sums over each view's corners: as one batched matrix product per
        block over (views, 2 x corners) arrays they cost a fraction of per-corner outer products summed
        through sparse matrices (the joint adjustment's step was mostly that).
        """
        key = self.cam.astype(np.int64) * self.I + self.inst
        order = np.argsort(key, kind="stable")
        keys, start, count = np.unique(key[order], return_index=True, return_counts=True)
        self.view_cam, self.view_inst = keys // self.I, keys % self.I
        slot = np.arange(count.max())
        take = start[:, None] + slot[None, :]
        self.view_mask = slot[None, :] < count[:, None]  # (P, L): a real corner, not padding
        self.view_obs = order[np.where(self.view_mask, take, 0)]  # (P, L) observation index (padding: any)
        # views one after another and all of one size (whole boards, the usual case): a reshape, no gather
        self._in_order = bool(self.view_mask.all() and np.array_equal(self.view_obs.ravel(), np.arange(len(key))))

    def _by_view(self, X: np.ndarray) -> np.ndarray:
        """Per-observation rows X (M, 2, k) as (P, 2 L, k), zero in the padding."""
        if self._in_order:
            return X.reshape(len(self.view_obs), -1, X.shape[-1])
        Xp = X[self.view_obs] * self.view_mask[:, :, None, None]
        return Xp.reshape(len(Xp), -1, X.shape[-1])

    def board_points(self, boards: np.ndarray) -> np.ndarray:
        """Corners in the reference frame (M, 3) for board poses (I, 6)."""
        R = _rotation_matrices(boards[:, :3])
        return np.einsum("mij,mj->mi", R[self.inst], self.obj[self.pt]) + boards[self.inst, 3:]

    def camera_points(self, cams: np.ndarray, xr: np.ndarray) -> np.ndarray:
        R = _rotation_matrices(cams[:, 9:12])
        return np.einsum("mij,mj->mi", R[self.cam], xr) + cams[self.cam, 12:]

    def project(self, cams: np.ndarray, xc: np.ndarray) -> np.ndarray:
        return _distort_project(xc, cams[self.cam, :9]) - self.xy

    def residuals(self, cams: np.ndarray, boards: np.ndarray) -> np.ndarray:
        """(M, 2) px for cams (C, 15) and boards (I, 6)."""
        return self.project(cams, self.camera_points(cams, self.board_points(boards)))

    def jacobians(self, cams, boards, r0=None):
        """Analytic blocks: A (M, 2, 15) w.r.t. the observing camera, B (M, 2, 6) w.r.t. the board pose.

        The chain rule through the projection (:func:`_projection_derivatives`), the camera's and the board's
        rigid motions and Rodrigues' formula (``cv2.Rodrigues``' derivative of each rotation): forward
        differences cost 21 projections of every corner a step, most of the adjustment's time. ``r0``, the
        residuals there, is not needed (kept for the callers).
        """
        Rb, dRb = _rotations_with_derivatives(boards[:, :3])
        Rc, dRc = _rotations_with_derivatives(cams[:, 9:12])
        p = self.obj[self.pt]
        xr = np.einsum("mij,mj->mi", Rb[self.inst], p) + boards[self.inst, 3:]
        Rcm = Rc[self.cam]
        xc = np.einsum("mij,mj->mi", Rcm, xr) + cams[self.cam, 12:]
        J_intr, J_xc = _projection_derivatives(xc, cams[self.cam, :9])
        M = len(self.cam)
        A = np.empty((M, 2, _NCAM))
        A[:, :, :9] = J_intr
        A[:, :, 9:12] = J_xc @ np.einsum("mkij,mj->mik", dRc[self.cam], xr)
        A[:, :, 12:] = J_xc
        J_xr = J_xc @ Rcm
        B = np.empty((M, 2, 6))
        B[:, :, :3] = J_xr @ np.einsum("mkij,mj->mik", dRb[self.inst], p)
        B[:, :, 3:] = J_xr
        if self._tied_obs.any():  # one focal length f = fx = fy: d/df = d/dfx + d/dfy, fy's column unused
            A[self._tied_obs, :, 0] += A[self._tied_obs, :, 1]
            A[self._tied_obs, :, 1] = 0.0
        return A, B

    def normal_equations(self, A, B, r, w):
        """Blocks of J^T W J and J^T W r: U (C, 15, 15), V (I, 6, 6), W (C, I, 15, 6), gc, gb."""
        # every block is a sum over each view's (camera, instant) corners: one batched product per block over
        # the views' rows (boolean selections per camera and outer products per corner cost more)
        Awp, Ap, Bwp, Bp, rp = (self._by_view(X) for X in (A * w[:, None, None], A, B * w[:, None, None], B,
                                                           r[:, :, None]))
        AwT, BwT = Awp.transpose(0, 2, 1), Bwp.transpose(0, 2, 1)
        U = np.zeros((self.C, _NCAM, _NCAM))
        np.add.at(U, self.view_cam, AwT @ Ap)
        gc = np.zeros((self.C, _NCAM))
        np.add.at(gc, self.view_cam, (AwT @ rp)[:, :, 0])
        BtB = BwT @ Bp
        AtB = AwT @ Bp
        Btr = (BwT @ rp)[:, :, 0]
        V = np.zeros((self.I, 6, 6))
        np.add.at(V, self.view_inst, BtB)
        W = np.zeros((self.C, self.I, _NCAM, 6))
        W[self.view_cam, self.view_inst] = AtB  # one view per camera and instant
        gb = np.zeros((self.I, 6))
        np.add.at(gb, self.view_inst, Btr)
        return U, V, W, gc, gb


def _schur_solve(U, V, W, gc, gb, free, lam):
    """Damped Gauss-Newton step by the Schur complement over the board poses.

    Returns (dc (C, 15), db (I, 6), S) where S is the reduced camera system on the free parameters.
    """
    C, I = W.shape[:2]
    n = C * _NCAM
    Ufull = np.zeros((n, n))
    for c in range(C):
        Ufull[c * _NCAM:(c + 1) * _NCAM, c * _NCAM:(c + 1) * _NCAM] = U[c]
    Vd = V + lam * np.einsum("ijj->ij", V)[:, :, None] * np.eye(6) + 1e-12 * np.eye(6)
    # inverted scaled to a unit diagonal (rotations in rad, translations in mm: 10^4 apart in the diagonal)
    d = 1.0 / np.sqrt(np.maximum(np.einsum("ijj->ij", Vd), 1e-300))
    Vinv = np.linalg.inv(Vd * d[:, :, None] * d[:, None, :]) * d[:, :, None] * d[:, None, :]
    Wi = W.transpose(1, 0, 2, 3).reshape(I, n, 6)  # per instant, all cameras stacked
    WV = np.einsum("iaj,ijk->iak", Wi, Vinv)
    S = Ufull - np.einsum("iak,ibk->ab", WV, Wi)
    rhs = -(gc.ravel() - np.einsum("iak,ik->a", WV, gb))
    Sf = S[np.ix_(free, free)]
    Sf = Sf + lam * np.diag(np.diag(Sf)) + 1e-12 * np.eye(len(free))
    dc = np.zeros(n)
    # scaled to a unit diagonal first: the parameters' units differ by 10^4 (focal px, distortion), which
    # unscaled cost the solve enough digits to make Gauss-Newton converge only linearly
    scale = 1.0 / np.sqrt(np.maximum(np.diag(Sf), 1e-300))
    dc[free] = scale * np.linalg.solve(Sf * scale[:, None] * scale[None, :], rhs[free] * scale)
    db = np.einsum("ijk,ik->ij", Vinv, -gb - np.einsum("iaj,a->ij", Wi, dc))
    return dc.reshape(C, _NCAM), db, S


def bundle_adjust(cameras: Mapping[str, Camera], views_by_camera: Mapping[str, list[BoardView]],
                  board: Board, *, fix_k3: bool | Mapping[str, bool] = True, loss: str = "soft_l1",
                  f_scale_px: float = 1.0, outlier_px: float = 5.0, max_iterations: int = 60,
                  lens_models: Mapping[str, LensModel] | None = None) -> tuple[dict[str, Camera], dict]:
    """Refine all cameras (intrinsics, distortion, pose) and all board poses jointly.

    The first camera is the reference (identity pose). Board poses are parameters per instant (a
    frame key shared by all cameras). Each residual is a corner's reprojection error in px; the loss
    is robust (``soft_l1`` or ``huber`` with scale ``f_scale_px``, solved by reweighting). The solver
    is Levenberg-Marquardt on the normal equations with the board poses eliminated by the Schur
    complement (the classic sparse bundle adjustment), so a step costs one small dense solve.

    Parameters
    ----------
    cameras : dict name -> Camera
        Initial values: intrinsics and poses relative to the first camera.
    views_by_camera : dict name -> list of BoardView
        Frame keys must be synchronised instants.
    outlier_px : float
        After a first pass, corners reprojecting worse than this are dropped and the fit repeated.
    lens_models : dict name -> LensModel, optional
        Which intrinsics each camera fits (``fix_k3`` is then ignored): parameters it does not fit stay
        where they start (the caller starts them at the image centre and zero), fx = fy are fitted as
        one focal length, and given intrinsics are not touched (only the pose is fitted).

    Returns
    -------
    cameras : dict name -> Camera, refined, with ``K_std``/``dist_std`` (one standard deviation) from
        the Gauss-Newton covariance with the board poses marginalised
    report : dict with ``rms_px`` (all), ``rms_px_by_camera``, ``n_observations``, ``n_dropped``,
        ``n_instants``, ``iterations``, ``pose_std`` {camera: (rvec std (3,), t std mm (3,))},
        ``board_poses`` {instant: (6,) rvec and t_mm in the reference camera}.
    """
    names = list(cameras)
    obj_all = object_points_mm(board)
    if without := [n for n in names if not views_by_camera.get(n)]:
        raise CalibrationError(f"bundle adjustment: camera {without[0]} has no board view")
    inst_pose = _initial_board_poses(cameras, views_by_camera, obj_all)
    instants = sorted(inst_pose)
    if not instants:
        raise CalibrationError("bundle adjustment: no board pose could be initialised")
    inst_index = {f: i for i, f in enumerate(instants)}
    obs_cam, obs_inst, obs_pt, obs_xy = _observations(names, views_by_camera, inst_index)

    C, I = len(names), len(instants)
    cams = np.array([np.concatenate([_intr_vector(cameras[n]), cameras[n].rvec, cameras[n].t_mm])
                     for n in names])
    boards = np.array([inst_pose[f] for f in instants])
    free = _free_parameters(names, fix_k3, lens_models)
    equal_focal = np.array([bool(lens_models and lens_models.get(n, LensModel()).equal_focal) for n in names])
    cams[equal_focal, 1] = cams[equal_focal, 0] = np.sqrt(cams[equal_focal, 0] * cams[equal_focal, 1])

    keep = np.ones(len(obs_cam), bool)
    n_dropped = 0
    iterations = 0
    for _pass in range(2):
        bundle = _Bundle(obj_all, obs_cam[keep], obs_inst[keep], obs_pt[keep], obs_xy[keep], C, I,
                         equal_focal=equal_focal)
        cams, boards, r, w, n_iterations = _levenberg_marquardt(bundle, cams, boards, free, loss=loss,
                                                                f_scale_px=f_scale_px,
                                                                max_iterations=max_iterations)
        iterations += n_iterations
        err = np.full(len(keep), np.inf)
        err[keep] = np.hypot(r[:, 0], r[:, 1])
        new_keep = keep & (err <= outlier_px)
        if new_keep.sum() == keep.sum() or new_keep.sum() < 0.5 * keep.sum():
            break
        n_dropped = int((~new_keep).sum())
        keep = new_keep

    std = _camera_std(bundle, cams, boards, r, w, free)
    out, pose_std, rms_by_cam = _refined_cameras(names, cameras, cams, std, bundle, r)
    report = {"rms_px": float(np.sqrt(np.mean(np.sum(r ** 2, axis=1)))), "rms_px_by_camera": rms_by_cam,
              "n_observations": int(keep.sum()), "n_dropped": n_dropped, "n_instants": I, "iterations": iterations,
              "pose_std": pose_std, "board_poses": {f: boards[inst_index[f]].copy() for f in instants}}
    return out, report


def _initial_board_poses(cameras: Mapping[str, Camera], views_by_camera: Mapping[str, list[BoardView]],
                         obj_all: np.ndarray) -> dict[int, np.ndarray]:
    """Per instant, the board pose (rvec, t_mm) (6,) in the reference camera's frame.

    From the camera seeing most of its corners; instants where its PnP fails are left out.
    """
    inst_pose: dict[int, np.ndarray] = {}
    by_inst: dict[int, list[tuple[str, BoardView]]] = {}
    for cam in cameras:
        for v in views_by_camera.get(cam, []):
            by_inst.setdefault(v.frame, []).append((cam, v))
    for inst, entries in by_inst.items():
        cam, v = max(entries, key=lambda e: len(e[1].ids))
        c = cameras[cam]
        ok, rvec, tvec = _pose_of_view(c, obj_all[v.ids], v.corners_px)
        if ok:
            Rb = c.R.T @ cv2.Rodrigues(rvec)[0]
            inst_pose[inst] = np.concatenate([cv2.Rodrigues(Rb)[0].ravel(), c.R.T @ (tvec - c.t_mm)])
    return inst_pose


def _observations(names: list[str], views_by_camera: Mapping[str, list[BoardView]],
                  inst_index: Mapping[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every corner seen at an initialised instant.

    Returns its camera index, instant index and corner id (M,) each, and its pixel coordinates (M, 2).
    """
    parts = [(ci, inst_index[v.frame], v) for ci, cam in enumerate(names)
             for v in views_by_camera.get(cam, []) if v.frame in inst_index]
    obs_cam = np.concatenate([np.full(len(v.ids), ci) for ci, _, v in parts])
    obs_inst = np.concatenate([np.full(len(v.ids), ii) for _, ii, v in parts])
    obs_pt = np.concatenate([v.ids for _, _, v in parts])
    obs_xy = np.concatenate([v.corners_px for _, _, v in parts])
    return obs_cam, obs_inst, obs_pt, obs_xy


def _free_parameters(names: list[str], fix_k3: bool | Mapping[str, bool],
                     lens_models: Mapping[str, LensModel] | None = None) -> np.ndarray:
    """Indices into the cameras' parameters (C * 15) that the adjustment may change.

    Not the reference camera's pose, which defines the rig frame, nor a k3 kept at zero; with
    ``lens_models``, only the intrinsics each camera's model fits (fy never alone where fx = fy).
    """
    free_mask = np.ones((len(names), _NCAM), bool)
    free_mask[0, 9:] = False  # the reference camera defines the rig frame
    k3_fixed = fix_k3 if isinstance(fix_k3, Mapping) else {n: bool(fix_k3) for n in names}
    for i, n in enumerate(names):
        if lens_models is None:
            free_mask[i, 8] = not k3_fixed.get(n, True)
            continue
        model = lens_models.get(n, LensModel())
        free_mask[i, :9] = not model.given
        if not model.given:
            free_mask[i, 1] = not model.equal_focal
            free_mask[i, 2:4] = model.principal_point
            free_mask[i, 6:8] = model.tangential
            free_mask[i, 8] = model.k3
    return np.flatnonzero(free_mask.ravel())


def _levenberg_marquardt(bundle: _Bundle, cams: np.ndarray, boards: np.ndarray, free: np.ndarray, *,
                         loss: str, f_scale_px: float, max_iterations: int):
    """Robust Levenberg-Marquardt from cameras (C, 15) and board poses (I, 6).

    Returns the refined cams and boards, the residuals (M, 2) px and weights (M,) there, and the number
    of iterations.
    """
    r = bundle.residuals(cams, boards)
    w, rho = _robust_weights(np.sum(r ** 2, axis=1), loss, f_scale_px)
    cost = float(rho.sum())
    lam = 1e-4
    iterations = 0
    for _ in range(max_iterations):
        iterations += 1
        A, B = bundle.jacobians(cams, boards, r)
        normal = bundle.normal_equations(A, B, r, w)
        step = _damped_step(bundle, normal, cams, boards, free, cost, lam, loss, f_scale_px)
        if step is None:
            break
        c_new, b_new, r_new, w_new, cost_new, lam = step
        rel = (cost - cost_new) / max(cost, 1e-300)
        cams, boards, r, w, cost = c_new, b_new, r_new, w_new, cost_new
        lam = max(lam / 10, 1e-9)
        if rel < 1e-10:
            break
    return cams, boards, r, w, iterations


def _damped_step(bundle: _Bundle, normal, cams, boards, free, cost: float, lam: float, loss: str,
                 f_scale_px: float):
    """The first damped Gauss-Newton step that lowers the cost, or None.

    The damping grows tenfold after each step that does not (at most ten tries). Returns cams (C, 15),
    boards (I, 6), residuals (M, 2), weights (M,), cost and damping after the step.
    """
    U, V, W, gc, gb = normal
    for _try in range(10):
        dc, db, _ = _schur_solve(U, V, W, gc, gb, free, lam)
        c_new, b_new = bundle.tie(cams + dc), boards + db
        r_new = bundle.residuals(c_new, b_new)
        w_new, rho_new = _robust_weights(np.sum(r_new ** 2, axis=1), loss, f_scale_px)
        cost_new = float(rho_new.sum())
        if np.isfinite(cost_new) and cost_new < cost:
            return c_new, b_new, r_new, w_new, cost_new, lam
        lam *= 10
    return None


def _camera_std(bundle: _Bundle, cams: np.ndarray, boards: np.ndarray, r: np.ndarray, w: np.ndarray,
                free: np.ndarray) -> np.ndarray:
    """One standard deviation (C, 15) of the camera parameters.

    From sigma^2 S^-1 with the board poses marginalised; 0 for fixed parameters, NaN where S is singular.
    """
    A, B = bundle.jacobians(cams, boards, r)
    U, V, W, gc, gb = bundle.normal_equations(A, B, r, w)
    _, _, S = _schur_solve(U, V, W, gc, gb, free, 0.0)
    dof = max(2 * len(r) - len(free) - 6 * bundle.I, 1)
    sigma2 = float(np.sum(w * np.sum(r ** 2, axis=1)) / dof)
    std = np.zeros(bundle.C * _NCAM)
    try:
        std[free] = np.sqrt(np.clip(np.diag(np.linalg.inv(S[np.ix_(free, free)])), 0, None) * sigma2)
    except np.linalg.LinAlgError:
        std[free] = np.nan
    std = std.reshape(bundle.C, _NCAM)
    std[bundle.equal_focal, 1] = std[bundle.equal_focal, 0]  # fy is fx
    return std


def _refined_cameras(names: list[str], cameras: Mapping[str, Camera], cams: np.ndarray, std: np.ndarray,
                     bundle: _Bundle, r: np.ndarray):
    """The refined cameras, the standard deviations of their poses, and their r.m.s. errors (px).

    Pose standard deviations are (rvec (3,), t_mm (3,)) for every camera but the reference.
    """
    out, pose_std, rms_by_cam = {}, {}, {}
    for ci, name in enumerate(names):
        sel = bundle.cam == ci
        rms_c = float(np.sqrt(np.mean(np.sum(r[sel] ** 2, axis=1)))) if sel.any() else float("nan")
        rms_by_cam[name] = rms_c
        s = std[ci]
        K_std = np.array([[s[0], 0, s[2]], [0, s[1], s[3]], [0, 0, 0]])
        out[name] = _camera_from_vector(name, cams[ci, :9], cams[ci, 9:12], cams[ci, 12:],
                                        cameras[name].image_size, rms_px=rms_c, K_std=K_std,
                                        dist_std=s[4:9].copy())
        if ci > 0:
            pose_std[name] = (s[9:12].copy(), s[12:].copy())
    return out, pose_std, rms_by_cam

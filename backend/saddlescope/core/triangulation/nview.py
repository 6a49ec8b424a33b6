"""N-view least-squares triangulation with per-point reprojection error and outlier rejection.

A linear (DLT) solution on undistorted normalised points refined by Gauss-Newton on the reprojection
error; a camera whose error is an outlier is left out (thesis 5.1 uses stereo pairs instead, see
:mod:`saddlescope.core.triangulation.pairs`). Image points are distorted pixels as detected, NaN where a
camera did not see a marker; 3-D points are in millimetres in rig coordinates (the left camera's frame,
``x_cam = R @ x_left + t_mm``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from saddlescope.core.camera_model import project_points
from saddlescope.core.triangulation.lens_reach import reach_radius, undistort_within_reach
from saddlescope.core.triangulation.reprojection import _camera, _rms_over, _stack_views
from saddlescope.core.types import Rig

__all__ = ["triangulate_nview"]


class _Views:
    """Per-camera arrays for the vectorised solver: poses, K's 2x2 part, normalised observations."""

    def __init__(self, rig: Rig, names: Sequence[str], obs_px: np.ndarray,
                 lens_reach_px: Mapping[str, float] | None = None):
        self.names = list(names)
        self.cameras = [_camera(rig, n) for n in names]
        self.R = np.stack([np.asarray(c.R, dtype=np.float64) for c in self.cameras])          # (C, 3, 3)
        self.t = np.stack([np.asarray(c.t_mm, dtype=np.float64).reshape(3) for c in self.cameras])
        self.A = np.stack([np.asarray(c.K, dtype=np.float64)[:2, :2] for c in self.cameras])  # (C, 2, 2)
        self.obs_px = obs_px                                                                   # (C, P, 2)
        reach_given = lens_reach_px or {}
        reach = {n: reach_given[n] for n in self.names if n in reach_given}
        limited = [undistort_within_reach(c, o, reach.get(n)) for n, c, o in zip(self.names, self.cameras, obs_px,
                                                                                  strict=True)]
        self.obs_n = np.stack([xy for xy, _ in limited])
        self.beyond = np.stack([b for _, b in limited])  # (C, P): seen beyond the board's reach
        # the tangent there turns ideal-pixel residuals into (about) distorted ones
        self.slope = np.array([reach_radius(c, reach[n])[2] if n in reach else 1.0
                               for n, c in zip(self.names, self.cameras, strict=True)])
        self.seen = np.all(np.isfinite(self.obs_n), axis=-1)                                  # (C, P)
        # Centre and scale the unknowns (camera centres ~ 0..1e3 mm, points ~ 1e3..1e4 mm) for the DLT.
        centres = -np.einsum("cji,cj->ci", self.R, self.t)
        self.origin = centres.mean(axis=0)
        spread = float(np.max(np.linalg.norm(centres - self.origin, axis=1))) if len(names) > 1 else 0.0
        self.scale = max(spread, 1.0)

    def dlt(self, use: np.ndarray) -> np.ndarray:
        """Linear triangulation of every point from the views in ``use`` (C, P); (P, 3), NaN if < 2."""
        C, P = use.shape
        # P_c' = [R_c | (R_c o + t_c) / s] acting on X' = (X - o) / s.
        Pm = np.concatenate([self.R, ((self.R @ self.origin + self.t) / self.scale)[:, :, None]], axis=2)
        x = np.where(use, self.obs_n[..., 0], 0.0)  # (C, P)
        y = np.where(use, self.obs_n[..., 1], 0.0)
        w = use.astype(np.float64)
        rows_x = (x[..., None] * Pm[:, None, 2, :] - Pm[:, None, 0, :]) * w[..., None]  # (C, P, 4)
        rows_y = (y[..., None] * Pm[:, None, 2, :] - Pm[:, None, 1, :]) * w[..., None]
        A = np.concatenate([rows_x, rows_y], axis=0).transpose(1, 0, 2)  # (P, 2C, 4)
        _, _, vt = np.linalg.svd(A, full_matrices=False)
        h = vt[:, -1, :]
        with np.errstate(invalid="ignore", divide="ignore"):
            X = h[:, :3] / h[:, 3:4] * self.scale + self.origin
        X[use.sum(axis=0) < 2] = np.nan
        X[~np.all(np.isfinite(X), axis=1)] = np.nan
        return X

    def linearise(self, X: np.ndarray, use: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (C, P, 2) in ideal pixels and their Jacobians (C, P, 2, 3) w.r.t. X (mm).

        Entries of cameras not in ``use`` are zero.
        """
        w = use.astype(np.float64)[..., None]
        xc = np.einsum("cij,pj->cpi", self.R, X) + self.t[:, None, :]  # (C, P, 3)
        z = xc[..., 2]
        zsafe = np.where(np.abs(z) > 1e-9, z, 1e-9)
        proj = xc[..., :2] / zsafe[..., None]
        res_n = np.where(use[..., None], proj - self.obs_n, 0.0)
        res = np.einsum("cij,cpj->cpi", self.A, res_n) * w
        # d(proj)/d(xc) = [[1/z, 0, -x/z^2], [0, 1/z, -y/z^2]]
        dproj = np.zeros(xc.shape[:2] + (2, 3))
        dproj[..., 0, 0] = 1 / zsafe
        dproj[..., 1, 1] = 1 / zsafe
        dproj[..., 0, 2] = -proj[..., 0] / zsafe
        dproj[..., 1, 2] = -proj[..., 1] / zsafe
        J = np.einsum("cij,cpjk,ckl->cpil", self.A, dproj, self.R) * w[..., None]
        return np.nan_to_num(res), np.nan_to_num(J)

    def refine(self, X: np.ndarray, use: np.ndarray, iterations: int) -> np.ndarray:
        """Gauss-Newton on the reprojection error in ideal pixels (K's 2x2 part times normalised)."""
        for _ in range(iterations):
            res, J = self.linearise(X, use)
            H = np.einsum("cpki,cpkj->pij", J, J)
            g = np.einsum("cpki,cpk->pi", J, res)
            ok = np.all(np.isfinite(X), axis=1) & (np.linalg.det(H) > 0)
            if not ok.any():
                break
            step = np.zeros_like(X)
            step[ok] = np.linalg.solve(H[ok], g[ok][..., None])[..., 0]
            X = X - step
            if np.nanmax(np.abs(step)) < 1e-12 * max(1.0, float(np.nanmax(np.abs(X)))):
                break
        return X

    def predicted_error(self, X: np.ndarray, use: np.ndarray, c: int) -> np.ndarray:
        """Camera c's error against the solution X of the cameras ``use`` (c not among them), in px.

        The error is normalised by how well those cameras pin down the point's image in camera c:
        r^T (I + J_c H^-1 J_c^T)^-1 r with H = sum of J^T J over the cameras used: a leave-one-out
        prediction error per unit (1 px) image noise, so a camera that the others see from a weak
        angle is not blamed for the geometry's weakness.
        """
        one = np.zeros_like(use)
        one[c] = True
        _, J = self.linearise(X, use)
        H = np.einsum("cpki,cpkj->pij", J, J)
        res_c, J_c = self.linearise(X, one)
        r, Jc = res_c[c], J_c[c]  # (P, 2), (P, 2, 3)
        out = np.full(X.shape[0], np.nan)
        ok = np.all(np.isfinite(X), axis=1) & (np.linalg.det(H) > 0)
        if ok.any():
            S = np.eye(2) + Jc[ok] @ np.linalg.solve(H[ok], np.swapaxes(Jc[ok], 1, 2))
            out[ok] = np.sqrt(np.einsum("pi,pi->p", r[ok], np.linalg.solve(S, r[ok][..., None])[..., 0]))
        return out

    def solve(self, use: np.ndarray, iterations: int) -> np.ndarray:
        X = self.dlt(use)
        if iterations > 0:
            X = self.refine(X, use, iterations)
        return X

    def errors_px(self, X: np.ndarray) -> np.ndarray:
        """Reprojection error of each camera and point in distorted pixels, shape (C, P).

        Beyond the board's reach the lens model is not the fitted polynomial but its tangent: there the
        error is measured on that model (ideal pixels times the tangent's slope).
        """
        err = np.stack([np.linalg.norm(project_points(c, X) - o, axis=-1)
                        for c, o in zip(self.cameras, self.obs_px, strict=True)])
        if self.beyond.any():
            xc = np.einsum("cij,pj->cpi", self.R, X) + self.t[:, None, :]
            with np.errstate(invalid="ignore", divide="ignore"):
                res = np.einsum("cij,cpj->cpi", self.A, xc[..., :2] / xc[..., 2:3] - self.obs_n)
            ideal = np.linalg.norm(res, axis=-1) * self.slope[:, None]
            err = np.where(self.beyond, ideal, err)
        return err



def triangulate_nview(rig: Rig, xy_by_camera: Mapping[str, np.ndarray], *, refine_iterations: int = 8,
                      outlier_ratio: float = 3.0, outlier_px: float = 2.0, outlier_sigmas: float = 5.0,
                      reject_outliers: bool = True, lens_reach_px: Mapping[str, float] | None = None,
                      return_used: bool = False):
    """N-view least-squares triangulation with per-point reprojection error and outlier rejection.

    A DLT on undistorted normalised points (centred and scaled) gives the start; Gauss-Newton steps
    then minimise the sum of squared reprojection errors (in ideal pixels).

    Outliers: the limit is ``max(outlier_px, outlier_sigmas * sigma)`` with sigma the robust spread
    (1.4826 x median) of the reprojection errors of all over-determined points in the call, so a
    calibration's few-pixel systematic disagreements are not mistaken for gross errors (on the
    caliscope 4-camera data a fixed 2 px limit dropped 104 views and made inter-corner distances
    worse). Where three or more cameras see a point and the worst camera's error exceeds the limit,
    each camera in turn is left out and the point re-solved with the rest: a camera is dropped when
    its error against the others' solution, normalised by how well the others predict its image
    (leave-one-out prediction error per pixel of noise), is above the limit, its plain error is above
    ``outlier_ratio`` times the largest error of the cameras kept, and no other camera qualifies as
    well (with three nearly collinear cameras an error along the baseline cannot be pinned on one
    camera; then nothing is dropped and the point keeps a large reprojection error). This repeats
    while at least three cameras remain.

    Parameters
    ----------
    rig : Rig
    xy_by_camera : dict of camera name -> ndarray of shape (..., 2)
        Distorted pixel coordinates, NaN where the camera did not see the point. All the same shape.
    refine_iterations : int, keyword-only
        Gauss-Newton steps after the DLT (0 keeps the linear solution).
    outlier_ratio, outlier_px, outlier_sigmas : float, keyword-only
        The rejection rule above.
    reject_outliers : bool, keyword-only
    lens_reach_px : dict of camera name -> float, keyword-only
        How far from the principal point (px) the calibration board reached in each camera
        (:func:`~saddlescope.core.triangulation.lens_reach.board_reach_px`): beyond it the lens model
        is continued by its tangent instead of extrapolating the polynomial
        (:func:`~saddlescope.core.triangulation.lens_reach.undistort_within_reach`). None: the fitted
        model everywhere.
    return_used : bool, keyword-only
        Also return the boolean mask of the cameras used, shape (C, ...), in ``xy_by_camera``'s order.

    Returns
    -------
    xyz_mm : ndarray of shape (..., 3)
        NaN where fewer than two cameras saw the point.
    reprojection_error_px : ndarray of shape (...,)
        RMS over the cameras used of the distance between projection and observation.
    views : ndarray of shape (...,), int
        Number of cameras used (0 where the point was not triangulated).
    used : ndarray of shape (C, ...), bool
        Only with ``return_used=True``.
    """
    names, shape, obs = _stack_views(rig, xy_by_camera)
    views = _Views(rig, names, obs, lens_reach_px)
    use = views.seen.copy()
    X = views.solve(use, refine_iterations)
    err = views.errors_px(X)
    if reject_outliers and len(names) >= 3:
        limit_px = _outlier_limit_px(err, use, outlier_px, outlier_sigmas)
        for _ in range(len(names) - 2):
            if not _drop_outliers(views, use, X, err, limit_px, outlier_ratio, refine_iterations):
                break
    rms = _rms_over(err, use)
    n_use = use.sum(axis=0)
    rms[n_use < 2] = np.nan
    X[n_use < 2] = np.nan
    use[:, n_use < 2] = False
    n_use[n_use < 2] = 0  # nothing triangulated, nothing used
    out = (X.reshape(shape + (3,)), rms.reshape(shape), n_use.reshape(shape).astype(int))
    if return_used:
        return out + (use.reshape((len(names),) + shape),)
    return out


def _outlier_limit_px(err: np.ndarray, use: np.ndarray, outlier_px: float, outlier_sigmas: float) -> float:
    """The rejection limit in px: the batch's own error level, at least ``outlier_px``.

    The level is ``outlier_sigmas`` robust sigmas of all residuals of over-determined points, so that
    a calibration's systematic few-pixel disagreements are not mistaken for gross errors.
    """
    over = use & (use.sum(axis=0) >= 3)
    sigma_px = 1.4826 * float(np.median(err[over])) if over.any() else 0.0
    return max(outlier_px, outlier_sigmas * sigma_px)


def _drop_outliers(views: _Views, use: np.ndarray, X: np.ndarray, err: np.ndarray, limit_px: float,
                   outlier_ratio: float, refine_iterations: int) -> bool:
    """One round of the rejection of :func:`triangulate_nview`.

    Where three or more cameras see a point and the worst is over the limit, the one camera the others
    single out is dropped. ``use`` (C, P), ``X`` (P, 3) and ``err`` (C, P) are updated in place; False when nothing was
    dropped (the rounds end).
    """
    n_use = use.sum(axis=0)
    worst = np.max(np.where(use, err, -np.inf), axis=0)
    todo = np.flatnonzero((n_use >= 3) & (worst > limit_px))
    if todo.size == 0:
        return False
    candidate, solutions = _leave_one_out(_subset(views, todo), use[:, todo], limit_px, outlier_ratio,
                                          refine_iterations)
    unique = candidate.sum(axis=0) == 1
    if not unique.any():
        return False
    cols = np.flatnonzero(unique)
    drop_cam = np.argmax(candidate[:, cols], axis=0)
    pts = todo[cols]
    use[drop_cam, pts] = False
    X[pts] = solutions[drop_cam, cols]
    err[:, pts] = _subset(views, pts).errors_px(X[pts])
    return True


def _leave_one_out(sub_views: _Views, sub_use: np.ndarray, limit_px: float, outlier_ratio: float,
                   refine_iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Each camera in turn left out and the points re-solved with the rest.

    Returns whether each camera qualifies as the outlier of each point (C, P) (its prediction error
    over the limit and its plain error over ``outlier_ratio`` times the largest of the cameras kept)
    and the solutions without it (C, P, 3).
    """
    candidate = np.zeros(sub_use.shape, dtype=bool)
    solutions = np.full(sub_use.shape + (3,), np.nan)
    for c in range(sub_use.shape[0]):
        loo = sub_use.copy()
        loo[c] = False
        Xc = sub_views.solve(loo, refine_iterations)
        ec = sub_views.errors_px(Xc)
        kept_max = np.max(np.where(loo, ec, -np.inf), axis=0)
        pred = sub_views.predicted_error(Xc, loo, c)
        candidate[c] = (sub_use[c] & (pred > limit_px) & (ec[c] > outlier_ratio * kept_max)
                        & np.all(np.isfinite(Xc), axis=1))
        solutions[c] = Xc
    return candidate, solutions


def _subset(views: _Views, cols: np.ndarray) -> _Views:
    """A shallow copy of ``views`` restricted to the points ``cols``."""
    sub = object.__new__(_Views)
    sub.__dict__.update(views.__dict__)
    sub.obs_px = views.obs_px[:, cols]
    sub.obs_n = views.obs_n[:, cols]
    sub.seen = views.seen[:, cols]
    sub.beyond = views.beyond[:, cols]
    return sub

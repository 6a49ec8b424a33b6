"""Triangulation of marker image points into rig coordinates (thesis 5.1).

Two methods:

- :func:`triangulate_thesis_pairs`, the thesis's method: triangulate with each stereo pair
  (L-M, L-R, M-R) with ``cv2.triangulatePoints`` on undistorted points, move the pair results that
  live in another camera's frame into the left frame (eq. 5.3-5.4) and average them (eq. 5.5).
- :func:`triangulate_nview`, N-view least squares: a linear (DLT) solution on undistorted normalised
  points refined by Gauss-Newton on the reprojection error, with per-point reprojection error and
  rejection of a camera whose error is an outlier.

Image points are distorted pixels as detected, NaN where a camera did not see a marker; 3-D points are
in millimetres in rig coordinates (the left camera's frame, ``x_cam = R @ x_left + t_mm``).
:func:`triangulate_tracks` resamples each camera's 2-D tracks onto the left camera's frame times with
the sub-frame synchronisation offsets, then triangulates them into ``MarkerTracks``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from saddlescope.core.errors import InputError, TriangulationError
from saddlescope.core.sync import clip_frames_at
from saddlescope.core.types import Camera, ImageTracks, MarkerTracks, Rig

__all__ = [
    "distort_normalized",
    "undistort_normalized",
    "project_points",
    "reprojection_errors",
    "triangulate_nview",
    "triangulate_thesis_pairs",
    "match_markers_across_cameras",
    "resample_tracks",
    "triangulate_tracks",
]

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)


# --------------------------------------------------------------------------------------------------
# Camera model helpers (vectorised, double precision)
# --------------------------------------------------------------------------------------------------

def _dist5(camera: Camera) -> np.ndarray:
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


def undistort_normalized(camera: Camera, xy_px: np.ndarray) -> np.ndarray:
    """Distorted pixels -> ideal normalised coordinates, to double precision.

    OpenCV's iterative ``undistortPoints`` gives the start; three Newton steps on the exact
    distortion model then make the result exact to rounding (triangulation over a 0.23 m baseline
    at 7.5 m turns 1e-6 px of disparity into ~3e-4 mm of depth).

    Parameters
    ----------
    camera : Camera
    xy_px : ndarray of shape (..., 2)
        Distorted pixel coordinates; NaN rows stay NaN.

    Returns
    -------
    ndarray of shape (..., 2)
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


def project_points(camera: Camera, points_mm: np.ndarray) -> np.ndarray:
    """Project rig points (..., 3) in mm to distorted pixels (..., 2); NaN in, NaN out.

    Same model as ``Camera.project`` (OpenCV's), vectorised in numpy so it can run on millions of
    points; points behind the camera give NaN.
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


# --------------------------------------------------------------------------------------------------
# N-view least squares
# --------------------------------------------------------------------------------------------------

class _Views:
    """Per-camera arrays for the vectorised solver: poses, K's 2x2 part, normalised observations."""

    def __init__(self, rig: Rig, names: Sequence[str], obs_px: np.ndarray):
        self.names = list(names)
        self.cameras = [_camera(rig, n) for n in names]
        self.R = np.stack([np.asarray(c.R, dtype=np.float64) for c in self.cameras])          # (C, 3, 3)
        self.t = np.stack([np.asarray(c.t_mm, dtype=np.float64).reshape(3) for c in self.cameras])
        self.A = np.stack([np.asarray(c.K, dtype=np.float64)[:2, :2] for c in self.cameras])  # (C, 2, 2)
        self.obs_px = obs_px                                                                   # (C, P, 2)
        self.obs_n = np.stack([undistort_normalized(c, o) for c, o in zip(self.cameras, obs_px, strict=True)])
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
        """Camera c's error against the solution X of the cameras ``use`` (c not among them), in px,
        normalised by how well those cameras pin down the point's image in camera c.

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
        """Reprojection error of each camera and point in distorted pixels, shape (C, P)."""
        return np.stack([np.linalg.norm(project_points(c, X) - o, axis=-1)
                         for c, o in zip(self.cameras, self.obs_px, strict=True)])


def _rms_over(err: np.ndarray, use: np.ndarray) -> np.ndarray:
    n = use.sum(axis=0)
    sq = np.where(use, err, 0.0) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sqrt(sq.sum(axis=0) / np.maximum(n, 1)), np.nan)


def triangulate_nview(rig: Rig, xy_by_camera: Mapping[str, np.ndarray], *, refine_iterations: int = 8,
                      outlier_ratio: float = 3.0, outlier_px: float = 2.0, outlier_sigmas: float = 5.0,
                      reject_outliers: bool = True,
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
    views = _Views(rig, names, obs)
    use = views.seen.copy()
    X = views.solve(use, refine_iterations)
    err = views.errors_px(X)
    if reject_outliers and len(names) >= 3:
        # The batch's own error level (robust sigma of all residuals of over-determined points) so that
        # a calibration's systematic few-pixel disagreements are not mistaken for gross errors.
        over = use & (use.sum(axis=0) >= 3)
        sigma_px = 1.4826 * float(np.median(err[over])) if over.any() else 0.0
        limit_px = max(outlier_px, outlier_sigmas * sigma_px)
        for _ in range(len(names) - 2):
            n_use = use.sum(axis=0)
            worst = np.max(np.where(use, err, -np.inf), axis=0)
            todo = np.flatnonzero((n_use >= 3) & (worst > limit_px))
            if todo.size == 0:
                break
            sub_use = use[:, todo]
            sub_views = _subset(views, todo)
            candidate = np.zeros(sub_use.shape, dtype=bool)
            solutions = np.full(sub_use.shape + (3,), np.nan)
            for c in range(len(names)):
                loo = sub_use.copy()
                loo[c] = False
                Xc = sub_views.solve(loo, refine_iterations)
                ec = sub_views.errors_px(Xc)
                kept_max = np.max(np.where(loo, ec, -np.inf), axis=0)
                pred = sub_views.predicted_error(Xc, loo, c)
                candidate[c] = (sub_use[c] & (pred > limit_px) & (ec[c] > outlier_ratio * kept_max)
                                & np.all(np.isfinite(Xc), axis=1))
                solutions[c] = Xc
            unique = candidate.sum(axis=0) == 1
            if not unique.any():
                break
            cols = np.flatnonzero(unique)
            drop_cam = np.argmax(candidate[:, cols], axis=0)
            pts = todo[cols]
            use[drop_cam, pts] = False
            X[pts] = solutions[drop_cam, cols]
            err[:, pts] = _subset(views, pts).errors_px(X[pts])
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


def _subset(views: _Views, cols: np.ndarray) -> _Views:
    """A shallow copy of ``views`` restricted to the points ``cols``."""
    sub = object.__new__(_Views)
    sub.__dict__.update(views.__dict__)
    sub.obs_px = views.obs_px[:, cols]
    sub.obs_n = views.obs_n[:, cols]
    sub.seen = views.seen[:, cols]
    return sub


# --------------------------------------------------------------------------------------------------
# The thesis's pairwise method
# --------------------------------------------------------------------------------------------------

def _pair_pose(rig: Rig, a: str, b: str, use_pair_extrinsics: bool) -> tuple[np.ndarray, np.ndarray]:
    """Pose of camera b relative to camera a: x_b = R_ba x_a + t_ba (eq. 5.1)."""
    pair = rig.pairs.get(f"{a}-{b}") if use_pair_extrinsics else None
    if pair is not None and "R" in pair and "t_mm" in pair:
        return np.asarray(pair["R"], dtype=np.float64), np.asarray(pair["t_mm"], dtype=np.float64).reshape(3)
    ca, cb = _camera(rig, a), _camera(rig, b)
    Ra, ta = np.asarray(ca.R, dtype=np.float64), np.asarray(ca.t_mm, dtype=np.float64).reshape(3)
    Rb, tb = np.asarray(cb.R, dtype=np.float64), np.asarray(cb.t_mm, dtype=np.float64).reshape(3)
    R_ba = Rb @ Ra.T
    return R_ba, tb - R_ba @ ta


def triangulate_thesis_pairs(rig: Rig, xy_by_camera: Mapping[str, np.ndarray], *,
                             pairs: Sequence[tuple[str, str]] | None = None,
                             use_pair_extrinsics: bool = True):
    """The thesis's triangulation: each stereo pair on its own, moved into the rig frame, averaged.

    For each pair (a, b), ``cv2.triangulatePoints`` on the undistorted pixels gives the point in camera
    a's frame; it is moved into the rig (left camera) frame with x_rig = R_a^-1 (x_a - t_a) (eq. 5.3-5.4)
    and the pair results are averaged (eq. 5.5). Where a point is seen by only some cameras, the
    pairs that see it are averaged.

    Parameters
    ----------
    rig : Rig
        With ``rig.pairs["a-b"] = {"R", "t_mm"}`` (a pair's own stereo calibration) used for the pair's
        relative pose when ``use_pair_extrinsics``; otherwise the relative pose follows from the cameras'
        rig poses.
    xy_by_camera : dict of camera name -> ndarray of shape (..., 2)
        Distorted pixels, NaN where not seen.
    pairs : sequence of (a, b), keyword-only
        Default: every pair of the given cameras in order (L-M, L-R, M-R for a thesis rig).
    use_pair_extrinsics : bool, keyword-only

    Returns
    -------
    xyz_mm : ndarray of shape (..., 3)
    reprojection_error_px : ndarray of shape (...,)
        RMS over the cameras of the pairs used.
    views : ndarray of shape (...,), int
        Number of distinct cameras in the pairs used.
    """
    names, shape, obs = _stack_views(rig, xy_by_camera)
    index = {n: i for i, n in enumerate(names)}
    if pairs is None:
        pairs = list(itertools.combinations(names, 2))
    if not pairs:
        raise TriangulationError("the thesis method needs at least two cameras (one stereo pair)")
    ideal = []
    for name, o in zip(names, obs, strict=True):
        cam = _camera(rig, name)
        xn = undistort_normalized(cam, o)
        K = np.asarray(cam.K, dtype=np.float64)
        ideal.append(xn @ K[:2, :2].T + K[:2, 2])
    P = obs.shape[1]
    total = np.zeros((P, 3))
    count = np.zeros(P)
    used = np.zeros((len(names), P), dtype=bool)
    for a, b in pairs:
        if a not in index or b not in index:
            raise InputError(f"pair {a}-{b}: no image points given for camera {a if a not in index else b!r}")
        ia, ib = index[a], index[b]
        ok = np.all(np.isfinite(ideal[ia]), axis=1) & np.all(np.isfinite(ideal[ib]), axis=1)
        if not ok.any():
            continue
        ca, cb = _camera(rig, a), _camera(rig, b)
        R_ba, t_ba = _pair_pose(rig, a, b, use_pair_extrinsics)
        Pa = np.asarray(ca.K, dtype=np.float64) @ np.hstack([np.eye(3), np.zeros((3, 1))])
        Pb = np.asarray(cb.K, dtype=np.float64) @ np.hstack([R_ba, t_ba[:, None]])
        h = cv2.triangulatePoints(Pa, Pb, ideal[ia][ok].T.copy(), ideal[ib][ok].T.copy())
        x_a = (h[:3] / h[3]).T
        Ra = np.asarray(ca.R, dtype=np.float64)
        ta = np.asarray(ca.t_mm, dtype=np.float64).reshape(3)
        x_rig = (x_a - ta) @ Ra  # eq. 5.3: R^-1 (x - t), R^-1 = R^T
        good = np.all(np.isfinite(x_rig), axis=1)
        rows = np.flatnonzero(ok)[good]
        total[rows] += x_rig[good]
        count[rows] += 1
        used[ia, rows] = True
        used[ib, rows] = True
    with np.errstate(invalid="ignore", divide="ignore"):
        X = total / count[:, None]  # eq. 5.5
    X[count == 0] = np.nan
    err = np.stack([np.linalg.norm(project_points(_camera(rig, n), X) - o, axis=-1)
                    for n, o in zip(names, obs, strict=True)])
    rms = _rms_over(err, used)
    rms[count == 0] = np.nan
    n_used = used.sum(axis=0)
    return X.reshape(shape + (3,)), rms.reshape(shape), n_used.reshape(shape).astype(int)


# --------------------------------------------------------------------------------------------------
# Cross-camera correspondence
# --------------------------------------------------------------------------------------------------

def match_markers_across_cameras(rig: Rig, xy_by_camera: Mapping[str, np.ndarray], *,
                                 reference: str | None = None, cap_px: float = 50.0,
                                 max_combinations: int = 2_000_000) -> dict[str, np.ndarray]:
    """Which marker of each camera is which marker of the reference camera.

    Brute force over label permutations (M <= 5 markers): every tuple of one detection per camera is
    triangulated once (N-view, no outlier rejection) and costs its RMS reprojection error, capped at
    ``cap_px`` (also the cost of a point behind a camera) so that one bad instant cannot outvote the
    others; the permutations minimising the cost summed over markers and instants win. Ties keep the
    cameras' own labels.

    Parameters
    ----------
    rig : Rig
    xy_by_camera : dict of camera name -> ndarray of shape (M, 2) or (T, M, 2)
        Detections of one instant (or T instants) per camera, in each camera's own label order; NaN
        rows allowed (a marker a camera did not see costs nothing).
    reference : str, keyword-only
        The camera whose labels are kept (default: "left" if given, else the first camera).
    cap_px : float, keyword-only
    max_combinations : int, keyword-only
        Guard against an exhaustive search that would not finish.

    Returns
    -------
    dict of camera name -> ndarray of shape (M,), int
        ``perm`` with ``xy_by_camera[name][..., perm[m], :]`` being reference marker ``m``; the
        identity for the reference camera.
    """
    names = list(xy_by_camera)
    if reference is None:
        reference = "left" if "left" in names else names[0]
    if reference not in names:
        raise InputError(f"reference camera {reference!r} has no image points")
    arrays = {n: np.asarray(xy_by_camera[n], dtype=np.float64) for n in names}
    ref = arrays[reference]
    if ref.ndim == 2:
        arrays = {n: a[None] for n, a in arrays.items()}
    T, M = arrays[reference].shape[:2]
    for n, a in arrays.items():
        if a.shape != (T, M, 2):
            raise InputError(f"camera {n!r}: expected marker image points of shape {ref.shape}, got "
                             f"{np.asarray(xy_by_camera[n]).shape}")
    others = [n for n in names if n != reference]
    if not others:
        return {reference: np.arange(M)}
    n_perm = math.factorial(M) ** len(others)
    if n_perm > max_combinations or T * M ** len(names) > max_combinations:
        raise InputError(f"too many label permutations to try ({n_perm}) for {M} markers in "
                         f"{len(names)} cameras")
    order = [reference] + others
    # Cost of every tuple (i_ref, i_1, ..., i_k) at every instant: one triangulation of T M^C points.
    grids = np.meshgrid(*[np.arange(M)] * len(order), indexing="ij")
    idx = [g.ravel() for g in grids]
    xy = {n: arrays[n][:, i] for n, i in zip(order, idx, strict=True)}  # (T, M^C, 2)
    X, rms, nviews = triangulate_nview(rig, xy, reject_outliers=False)
    behind = np.zeros(X.shape[:-1], dtype=bool)
    for n in order:
        cam = _camera(rig, n)
        R, t = np.asarray(cam.R, dtype=np.float64), np.asarray(cam.t_mm, dtype=np.float64).reshape(3)
        behind |= (X @ R.T + t)[..., 2] <= 0
    cost = np.where(np.isfinite(rms) & ~behind, np.minimum(rms, cap_px), cap_px)
    # A tuple with a missing detection costs nothing extra: the gap stays a gap either way.
    cost = np.where(nviews < len(order), np.where(np.isfinite(rms) & ~behind, np.minimum(rms, cap_px), 0.0),
                    cost)
    cost = cost.sum(axis=0).reshape((M,) * len(order))
    perms = np.array(list(itertools.permutations(range(M))))  # (M!, M), the identity first
    best_total, best = np.inf, None
    # Sum over m of cost[m, p1[m], p2[m], ...] for every combination of permutations (chunks of the first).
    rest = list(itertools.product(range(len(perms)), repeat=len(others) - 1))
    rest_idx = np.array(rest, dtype=int).reshape(len(rest), len(others) - 1)
    m = np.arange(M)
    for p1 in range(len(perms)):
        index = [m[None, :].repeat(len(rest), 0), perms[p1][None, :].repeat(len(rest), 0)]
        for k in range(len(others) - 1):
            index.append(perms[rest_idx[:, k]])
        totals = cost[tuple(index)].sum(axis=1)
        j = int(np.argmin(totals))
        if totals[j] < best_total - 1e-9:
            best_total = float(totals[j])
            best = [perms[p1]] + [perms[rest_idx[j, k]] for k in range(len(others) - 1)]
    result = {reference: np.arange(M)}
    for n, p in zip(others, best, strict=True):
        result[n] = np.asarray(p, dtype=int)
    return {n: result[n] for n in names}


# --------------------------------------------------------------------------------------------------
# Tracks
# --------------------------------------------------------------------------------------------------

def resample_tracks(tracks: ImageTracks, frames: np.ndarray, *, kind: str = "cubic",
                    frame_times_s: np.ndarray | None = None) -> np.ndarray:
    """Sample a camera's 2-D tracks at fractional frame positions of its own clip.

    ``kind="cubic"``: the cubic through the four nearest frames (two each side), where all four are
    tracked, else linear between the two neighbours; ``"linear"``: always linear. Linear interpolation
    misses the curvature of the motion by a Δt²/8 (0.4 px half way between frames for a saddle
    bobbing at 3 px/frame², which over a 0.23 m baseline at 7.5 m is a decimetre in depth); the cubic
    is exact up to third-order motion. A gap (NaN) in either neighbour, or a position outside the
    tracked frames, gives NaN; integer positions take the frame as it is.

    Parameters
    ----------
    tracks : ImageTracks
        ``xy_px`` of shape (F, M, 2) at ``frame_index`` (F,) (need not be contiguous).
    frames : ndarray of shape (N,)
        Wanted positions in this clip's frame numbers.
    kind : {"cubic", "linear"}, keyword-only
    frame_times_s : ndarray of shape (F_clip,), keyword-only
        Each clip frame's timestamp, for a variable-rate clip: the cubic then goes through the four
        frames at their own instants (a dropped frame leaves a double interval), and a fractional
        position means that fraction of the time between its two frames.

    Returns
    -------
    ndarray of shape (N, M, 2)
    """
    if kind not in ("cubic", "linear"):
        raise InputError(f"unknown interpolation {kind!r} (use 'cubic' or 'linear')")
    xy = np.asarray(tracks.xy_px, dtype=np.float64)
    fi = np.asarray(tracks.frame_index, dtype=np.int64)
    if xy.ndim != 3 or xy.shape[-1] != 2 or xy.shape[0] != fi.shape[0]:
        raise InputError(f"camera {tracks.camera!r}: tracks must be (F, M, 2) with F frame indices, got "
                         f"{xy.shape} and {fi.shape}")
    frames = np.asarray(frames, dtype=np.float64)
    out = np.full((frames.size, xy.shape[1], 2), np.nan)
    if fi.size == 0:
        return out
    first = int(fi.min())
    # Dense frames with a NaN frame before and two after, so every neighbour index exists.
    dense = np.full((int(fi.max()) - first + 4, xy.shape[1], 2), np.nan)
    dense[fi - first + 1] = xy
    pos = frames - first + 1
    base = np.floor(pos)
    frac = pos - base
    snap = frac < 1e-9
    inside = (base >= 1) & (base <= dense.shape[0] - 3) & np.isfinite(pos)
    b = np.where(inside, base, 1).astype(np.int64)
    p0, p1 = dense[b], dense[b + 1]
    t = frac[:, None, None]
    val = np.where(snap[:, None, None], p0, (1 - t) * p0 + t * p1)  # NaN in p1 poisons only real blends
    if kind == "cubic":
        pm, p2 = dense[b - 1], dense[b + 2]
        if frame_times_s is None:
            # Lagrange weights of the cubic through frames -1, 0, 1, 2 at t in [0, 1).
            cubic = (-t * (t - 1) * (t - 2) / 6 * pm + (t + 1) * (t - 1) * (t - 2) / 2 * p0
                     - (t + 1) * t * (t - 2) / 2 * p1 + (t + 1) * t * (t - 1) / 6 * p2)
        else:
            # the same cubic through the four frames at their stamped instants (uneven nodes)
            tn = _dense_frame_times(frame_times_s, first, dense.shape[0])
            nodes = np.stack([tn[b - 1], tn[b], tn[b + 1], tn[b + 2]], axis=1)  # (N, 4)
            tq = nodes[:, 1] + frac * (nodes[:, 2] - nodes[:, 1])
            cubic = 0.0
            for j, pj in enumerate((pm, p0, p1, p2)):
                w = np.ones_like(tq)
                for m in range(4):
                    if m != j:
                        w *= (tq - nodes[:, m]) / (nodes[:, j] - nodes[:, m])
                cubic = cubic + w[:, None, None] * pj
        use = ~snap[:, None, None] & np.isfinite(cubic)
        val = np.where(use, cubic, val)
    out[inside] = val[inside]
    return out


def _dense_frame_times(frame_times_s: np.ndarray, first: int, n_dense: int) -> np.ndarray:
    """Timestamps of the dense rows of :func:`resample_tracks` (frame ``first - 1 + j``), extended
    evenly at the median interval beyond the clip's stamped frames."""
    times = np.asarray(frame_times_s, dtype=np.float64)
    dt = float(np.median(np.diff(times))) if times.size > 1 else 1.0
    fnum = first - 1 + np.arange(n_dense, dtype=np.float64)
    last = times.size - 1
    tn = np.interp(fnum, np.arange(times.size, dtype=np.float64), times)
    tn = np.where(fnum < 0, times[0] + fnum * dt, tn)
    return np.where(fnum > last, times[-1] + (fnum - last) * dt, tn)


def triangulate_tracks(rig: Rig, tracks: Mapping[str, ImageTracks], offsets_frames: Mapping[str, float],
                       fps: float, *, reference: str | None = None, method: str = "nview",
                       match_labels: bool = True, names: Sequence[str] | None = None,
                       interpolation: str = "cubic",
                       clocks: Mapping[str, tuple[np.ndarray, float]] | None = None, **kwargs) -> MarkerTracks:
    """2-D tracks of several cameras -> 3-D marker tracks on the reference camera's clock.

    Camera c's clip frame ``k + offsets_frames[c]`` shows the same instant as the reference clip's frame
    ``k`` (CONTRACTS: frame k of the left clip is frame k + offset of another camera's clip); offsets
    may be fractional (sub-frame sync). Each camera's tracks are resampled there (cubic where four
    frames around are tracked, else linear; a gap stays a gap), then triangulated.

    Parameters
    ----------
    rig : Rig
    tracks : dict of camera name -> ImageTracks
        ``xy_px`` (F_c, M, 2) with the same M in every camera.
    offsets_frames : dict of camera name -> float
        Missing cameras (and the reference) default to 0.
    fps : float
        Frame rate of the reference clip; ``t_s = frame_index / fps``.
    reference : str, keyword-only
        Default "left" if present, else the first camera.
    method : {"nview", "thesis_pairs"}, keyword-only
    match_labels : bool, keyword-only
        Relabel the other cameras' markers to the reference's with
        :func:`match_markers_across_cameras` on up to 12 instants where every camera sees every marker.
    names : sequence of str, keyword-only
        Marker names (default "1", "2", ...).
    interpolation : {"cubic", "linear"}, keyword-only
        How tracks are resampled between frames (see :func:`resample_tracks`).
    clocks : dict of camera name -> (frame times (F_clip,) s, anchor frame), keyword-only
        For variable-rate clips: each frame's timestamp and the frame (sub-frame) where the offsets
        were measured. Offsets then count nominal frames at ``fps`` from that anchor, and the camera's
        tracks are sampled at the stamped instants (:func:`clip_frames_at`); the reference's too, so
        ``t_s`` stays even.
    **kwargs
        Passed to the triangulation function.

    Returns
    -------
    MarkerTracks
        ``xyz_mm`` (F, M, 3), ``reprojection_error_px`` (F, M), ``views`` (F, M), ``t_s`` (F,) with F
        the reference camera's tracked frames.
    """
    if not tracks:
        raise InputError("no camera tracks to triangulate")
    if method not in ("nview", "thesis_pairs"):
        raise InputError(f"unknown triangulation method {method!r} (use 'nview' or 'thesis_pairs')")
    if not (fps > 0 and math.isfinite(fps)):
        raise InputError(f"frame rate must be positive, got {fps}")
    cams = list(tracks)
    if reference is None:
        reference = "left" if "left" in cams else cams[0]
    if reference not in tracks:
        raise InputError(f"reference camera {reference!r} has no tracks")
    M = np.asarray(tracks[reference].xy_px).shape[1]
    for c in cams:
        shape = np.asarray(tracks[c].xy_px).shape
        if len(shape) != 3 or shape[1] != M:
            raise InputError(f"camera {c!r}: tracks have shape {shape}, expected (F, {M}, 2) like "
                             f"camera {reference!r}")
    if len(cams) < 2:
        raise TriangulationError(f"triangulation needs at least two cameras, got only {reference!r}")
    ref_frames = np.asarray(tracks[reference].frame_index, dtype=np.float64)
    base = float(offsets_frames.get(reference, 0.0))
    xy = {}
    clocks = clocks or {}
    for c in cams:
        offset = float(offsets_frames.get(c, 0.0)) - base
        wanted = ref_frames + offset
        times = None
        if c in clocks:
            times, anchor = clocks[c]
            wanted = clip_frames_at(wanted, times, anchor, fps)
        xy[c] = resample_tracks(tracks[c], wanted, kind=interpolation, frame_times_s=times)
    if match_labels and M > 1:
        full = np.all(np.stack([np.all(np.isfinite(v), axis=(1, 2)) for v in xy.values()]), axis=0)
        hits = np.flatnonzero(full)
        if hits.size:
            # A dozen instants spread over the clip, so that one odd frame cannot decide the labels.
            pick = hits[np.unique(np.linspace(0, hits.size - 1, min(hits.size, 12)).round().astype(int))]
            perms = match_markers_across_cameras(rig, {c: xy[c][pick] for c in cams}, reference=reference)
            xy = {c: xy[c][:, perms[c]] for c in cams}
    if method == "nview":
        X, err, views = triangulate_nview(rig, xy, **kwargs)
    else:
        X, err, views = triangulate_thesis_pairs(rig, xy, **kwargs)
    if names is None:
        names = tuple(str(i + 1) for i in range(M))
    elif len(names) != M:
        raise InputError(f"{len(names)} marker names given for {M} markers")
    return MarkerTracks(names=tuple(names), t_s=ref_frames / fps, xyz_mm=X, reprojection_error_px=err,
                        views=views)


# --------------------------------------------------------------------------------------------------
# Depth uncertainty of a rig
# --------------------------------------------------------------------------------------------------

def position_uncertainty(rig: Rig, point_mm: np.ndarray, *, sigma_px: float = 1.0) -> dict:
    """How well the rig fixes a point: the covariance of its least-squares triangulation.

    Every camera that sees ``point_mm`` (3,) adds its projection Jacobian (pinhole, distortion
    ignored) to the information matrix; image noise ``sigma_px`` per coordinate. With cameras close
    together (thesis rig: 0.23 m apart at 7.5 m) the point is fixed ~30 times worse along the
    viewing direction than across it.

    Returns
    -------
    dict with ``std_mm`` (3,) standard deviations along the principal axes, largest first,
    ``worst_axis`` (3,) unit vector of the largest, ``anisotropy`` (largest / smallest std), and
    ``ray_origin_mm`` (3,), the mean centre of the cameras used.
    """
    x = np.asarray(point_mm, dtype=np.float64).reshape(3)
    info = np.zeros((3, 3))
    centres = []
    for cam in rig.cameras.values():
        R = np.asarray(cam.R, dtype=np.float64)
        t = np.asarray(cam.t_mm, dtype=np.float64).reshape(3)
        xc = R @ x + t
        if xc[2] <= 0:
            continue
        K = np.asarray(cam.K, dtype=np.float64)
        u, v = xc[0] / xc[2], xc[1] / xc[2]
        # d(pixel)/d(x_rig) = diag(fx, fy) / z [[1, 0, -u], [0, 1, -v]] R
        j = (np.diag([K[0, 0], K[1, 1]]) / xc[2]) @ np.array([[1.0, 0.0, -u], [0.0, 1.0, -v]]) @ R
        info += j.T @ j
        centres.append(cam.center_mm)
    if len(centres) < 2:
        raise TriangulationError("fewer than two cameras see the point; its uncertainty is unbounded")
    w, vecs = np.linalg.eigh(info)
    if w[0] <= 0:
        raise TriangulationError("the cameras' rays are parallel at the point; depth is unbounded")
    std = sigma_px / np.sqrt(w)  # ascending information = descending std
    return {"std_mm": std, "worst_axis": vecs[:, 0], "anisotropy": float(std[0] / std[-1]),
            "ray_origin_mm": np.mean(centres, axis=0)}

"""Triangulation for checks and the rig's metric quality (thesis Table 8.5)."""

from __future__ import annotations

import itertools
from collections.abc import Mapping

import cv2
import numpy as np

from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.calibration.projection import _UNDISTORT_CRITERIA
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.errors import InputError
from saddlescope.core.types import Board, Camera, Rig

__all__ = ["board_distance_errors", "metric_checks", "triangulate_dlt"]


def _normalized(cam: Camera, xy_px: np.ndarray) -> np.ndarray:
    """Distorted px (N, 2) -> undistorted normalised image coordinates (N, 2), NaN kept."""
    out = np.full(xy_px.shape, np.nan)
    ok = np.all(np.isfinite(xy_px), axis=1)
    if ok.any():
        und = cv2.undistortPoints(xy_px[ok].reshape(-1, 1, 2).astype(np.float64), cam.K, cam.dist,
                                  criteria=_UNDISTORT_CRITERIA)
        out[ok] = und.reshape(-1, 2)
    return out


def triangulate_dlt(cameras: list[Camera], xy_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear N-view triangulation (DLT on undistorted normalised coordinates).

    Parameters
    ----------
    cameras : list of C Camera (poses relative to a common frame, mm)
    xy_px : ndarray of shape (C, N, 2)
        Distorted pixel coordinates, NaN where a camera does not see the point.

    Returns
    -------
    xyz_mm : ndarray of shape (N, 3), NaN where fewer than two cameras see the point
    reprojection_error_px : ndarray of shape (N,), RMS over the cameras that see the point
    """
    xy_px = np.asarray(xy_px, np.float64)
    C, N = xy_px.shape[:2]
    if len(cameras) != C:
        raise InputError(f"{len(cameras)} cameras but points for {C}")
    A = np.zeros((N, 2 * C, 4))
    seen = np.zeros((C, N), bool)
    for c, cam in enumerate(cameras):
        xn = _normalized(cam, xy_px[c])
        ok = np.all(np.isfinite(xn), axis=1)
        seen[c] = ok
        P = np.hstack([cam.R, np.reshape(cam.t_mm, (3, 1)) / 1000.0])  # metres: better conditioned
        xn0 = np.where(ok[:, None], xn, 0.0)
        A[:, 2 * c] = (xn0[:, :1] * P[2] - P[0]) * ok[:, None]
        A[:, 2 * c + 1] = (xn0[:, 1:] * P[2] - P[1]) * ok[:, None]
    _, _, vt = np.linalg.svd(A)
    X = vt[:, -1, :]
    n_seen = seen.sum(axis=0)
    w = np.where((n_seen >= 2) & (np.abs(X[:, 3]) > 1e-15), X[:, 3], np.nan)
    xyz = X[:, :3] / w[:, None] * 1000.0
    sq = np.zeros(N)
    for c, cam in enumerate(cameras):
        proj = cam.project(xyz)
        d2 = np.sum((proj - xy_px[c]) ** 2, axis=1)
        sq += np.where(seen[c] & np.isfinite(d2), d2, 0.0)
    err = np.sqrt(sq / np.maximum(n_seen, 1))
    err[n_seen < 2] = np.nan
    return xyz, err


def _instant_points(views_by_camera, names):
    """Corners per instant seen by two cameras or more: {instant: (ids (K,), xy (C, K, 2) with NaN)}."""
    frames = sorted({v.frame for n in names for v in views_by_camera.get(n, [])})
    by = {n: {v.frame: v for v in views_by_camera.get(n, [])} for n in names}
    out = {}
    for f in frames:
        ids = np.unique(np.concatenate([by[n][f].ids for n in names if f in by[n]]))
        xy = np.full((len(names), len(ids), 2), np.nan)
        for c, n in enumerate(names):
            v = by[n].get(f)
            if v is not None:
                xy[c, np.searchsorted(ids, v.ids)] = v.corners_px
        if np.sum(np.any(np.isfinite(xy[..., 0]), axis=1)) >= 2:
            out[f] = (ids, xy)
    return out


def _triangulated_instants(cams: list[Camera], points: Mapping[int, tuple[np.ndarray, np.ndarray]]):
    """(ids, xyz (K, 3) mm, reprojection error (K,) px) per instant of :func:`_instant_points`.

    Every instant's corners in one :func:`triangulate_dlt` (each point is triangulated on its own): one call
    per instant cost more in its per-call work (undistortion, projection) than in the triangulation.
    """
    parts = list(points.values())
    if not parts:
        return
    xyz, err = triangulate_dlt(cams, np.concatenate([xy for _, xy in parts], axis=1))
    bounds = np.cumsum([0] + [len(ids) for ids, _ in parts])
    for (ids, _), lo, hi in zip(parts, bounds[:-1], bounds[1:], strict=True):
        yield ids, xyz[lo:hi], err[lo:hi]


def _similarity_fit(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray]:
    """Scale s and residuals (K, 3) of the best dst ~ s R src + t (Umeyama's closed form)."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_s, dst - mu_d
    U, sv, Vt = np.linalg.svd(b.T @ a / len(src))
    d = np.ones(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        d[-1] = -1
    R = U @ np.diag(d) @ Vt
    var_a = np.mean(np.sum(a ** 2, axis=1))
    s = float(np.sum(sv * d) / var_a)
    return s, b - s * a @ R.T


def board_distance_errors(rig: Rig, views_by_camera: Mapping[str, list[BoardView]], board: Board, *,
                          cameras: list[str] | None = None, max_pair_corners: int = 60) -> dict:
    """Metric errors of the triangulated board (thesis Table 8.5, for every corner pair).

    For each instant, corners seen by two or more of ``cameras`` are triangulated. Then (1) the true
    board is fitted to them by a similarity transform (rotation, translation, scale): the scale
    times the square size is the reconstructed square length, averaged over the whole board so that
    it measures the calibration's systematic scale error rather than one corner's noise; (2) every
    pair of neighbouring corners and every pair among up to ``max_pair_corners`` corners spread over
    the board is compared with its true distance (noise and systematic error together).

    Returns
    -------
    dict with ``scales`` (I,) fitted scale per instant, ``fit_residuals_mm`` (P,) point distances to
    the fitted board, ``adjacent_errors_mm`` (S,) neighbouring-corner distance errors,
    ``distance_errors_mm`` (D,) and ``true_distances_mm`` (D,) for all corner pairs,
    ``reprojection_error_px`` (P,), ``n_instants``, ``n_points``.
    """
    names = list(cameras or rig.cameras)
    cams = [rig.cameras[n] for n in names]
    obj = object_points_mm(board)
    cols = board.inner_corners[0]
    scales, fit_res, adj_err, d_err, d_true, reproj = [], [], [], [], [], []
    n_pts = 0
    for ids, xyz, err in _triangulated_instants(cams, _instant_points(views_by_camera, names)):
        ok = np.isfinite(xyz[:, 0])
        if ok.sum() < 4:
            continue
        ids, xyz = ids[ok], xyz[ok]
        rows_cols = np.column_stack(np.divmod(ids, cols))
        if np.linalg.matrix_rank(rows_cols - rows_cols.mean(axis=0)) < 2:
            continue  # collinear corners fix no plane
        s, res = _similarity_fit(obj[ids], xyz)
        scales.append(s)
        fit_res.append(np.linalg.norm(res, axis=1))
        reproj.append(err[ok])
        n_pts += len(ids)
        # neighbours: all of them
        pos = {int(k): n for n, k in enumerate(ids)}
        right = [(pos[k], pos[k + 1]) for k in pos if (k % cols) + 1 < cols and k + 1 in pos]
        below = [(pos[k], pos[k + cols]) for k in pos if k + cols in pos]
        nb = np.array(right + below, dtype=np.int64).reshape(-1, 2)
        adj_err.append(np.linalg.norm(xyz[nb[:, 0]] - xyz[nb[:, 1]], axis=1) - board.square_mm)
        # all pairs among at most max_pair_corners evenly spread corners (a large board has 10^5 pairs)
        sub = np.unique(np.linspace(0, len(ids) - 1, min(len(ids), max_pair_corners)).round().astype(int))
        iu, ju = np.triu_indices(len(sub), 1)
        iu, ju = sub[iu], sub[ju]
        meas = np.linalg.norm(xyz[iu] - xyz[ju], axis=1)
        true = np.linalg.norm(obj[ids[iu]] - obj[ids[ju]], axis=1)
        d_err.append(meas - true)
        d_true.append(true)
    cat = lambda parts: np.concatenate(parts) if parts else np.zeros(0)
    return {"scales": np.asarray(scales), "fit_residuals_mm": cat(fit_res),
            "adjacent_errors_mm": cat(adj_err),
            "distance_errors_mm": cat(d_err), "true_distances_mm": cat(d_true),
            "reprojection_error_px": cat(reproj), "n_instants": len(scales), "n_points": n_pts}


def _summary(err: np.ndarray, prefix: str) -> dict[str, float]:
    if err.size == 0:
        return {}
    return {f"{prefix}_mean_mm": float(np.mean(err)), f"{prefix}_rms_mm": float(np.sqrt(np.mean(err ** 2))),
            f"{prefix}_max_mm": float(np.max(np.abs(err)))}


def metric_checks(rig: Rig, views_by_camera: Mapping[str, list[BoardView]], board: Board, *,
                  max_square_error_pct: float = 1.0, max_square_error_mm: float | None = None,
                  max_distance_rms_mm: float | None = None) -> tuple[dict[str, float], list[str], dict]:
    """Metric quality of a rig in mm (thesis Table 8.5), overall and per camera pair.

    Returns
    -------
    checks : dict of float
        ``board_square_error_mm``: RMS over instants of the reconstructed square length (from the
        board's fitted scale, :func:`board_distance_errors`) minus the true one; ``board_square_error_pct``;
        ``board_scale_error_pct``: mean signed scale error (the systematic part);
        ``board_fit_rms_mm``: RMS distance of the triangulated corners to the fitted board (point
        noise); ``adjacent_distance_error_{mean,rms,max}_mm`` (neighbouring corners) and
        ``corner_distance_error_{mean,rms,max}_mm`` (all corner pairs within an instant);
        ``corner_distance_error_pct`` (RMS error / RMS true distance); ``triangulation_rms_px``;
        ``check_instants``; ``check_points``.
    flags : list of str
        A sentence per threshold exceeded: square error over ``max_square_error_pct`` percent or over
        ``max_square_error_mm``; corner-distance RMS over ``max_distance_rms_mm`` (None: not checked,
        since on a narrow-baseline rig it is dominated by each corner's depth noise, not the
        calibration).
    per_pair : dict "a-b" -> dict of the same numbers using only those two cameras.
    """
    names = list(rig.cameras)
    if len(names) < 2:
        return {}, [], {}

    def numbers(errs):
        out: dict[str, float] = {}
        scales = errs["scales"]
        if scales.size:
            out["board_square_error_mm"] = float(np.sqrt(np.mean((scales - 1) ** 2)) * board.square_mm)
            out["board_square_error_pct"] = 100.0 * out["board_square_error_mm"] / board.square_mm
            out["board_scale_error_pct"] = float(100 * np.mean(scales - 1))
            out["board_fit_rms_mm"] = float(np.sqrt(np.mean(errs["fit_residuals_mm"] ** 2)))
        out.update(_summary(errs["adjacent_errors_mm"], "adjacent_distance_error"))
        d, true = errs["distance_errors_mm"], errs["true_distances_mm"]
        if d.size:
            out.update(_summary(d, "corner_distance_error"))
            out["corner_distance_error_pct"] = float(100 * np.sqrt(np.mean(d ** 2) / np.mean(true ** 2)))
        if errs["reprojection_error_px"].size:
            out["triangulation_rms_px"] = float(np.sqrt(np.mean(errs["reprojection_error_px"] ** 2)))
        out["check_instants"] = float(errs["n_instants"])
        out["check_points"] = float(errs["n_points"])
        return out

    checks = numbers(board_distance_errors(rig, views_by_camera, board))
    per_pair = {f"{a}-{b}": numbers(board_distance_errors(rig, views_by_camera, board, cameras=[a, b]))
                for a, b in itertools.combinations(names, 2)}
    flags: list[str] = []
    if "board_square_error_mm" not in checks:
        flags.append("no board was seen by two cameras at once: the rig's metric accuracy is unchecked")
        return checks, flags, per_pair
    sq_mm, sq_pct = checks["board_square_error_mm"], checks["board_square_error_pct"]
    if sq_pct > max_square_error_pct or (max_square_error_mm is not None and sq_mm > max_square_error_mm):
        limit = f"{max_square_error_pct:g} %"
        if max_square_error_mm is not None:
            limit += f" / {max_square_error_mm:g} mm"
        flags.append(f"reconstructed board squares are off by {sq_mm:.2f} mm RMS ({sq_pct:.2f} % of "
                     f"{board.square_mm:g} mm, over the {limit} limit): recalibrate before trusting "
                     f"distances")
    rms = checks.get("corner_distance_error_rms_mm", 0.0)
    if max_distance_rms_mm is not None and rms > max_distance_rms_mm:
        flags.append(f"distances between triangulated board corners are off by {rms:.2f} mm RMS, over the "
                     f"{max_distance_rms_mm:g} mm limit")
    return checks, flags, per_pair

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
from saddlescope.core.findings import Finding
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
    obj = object_points_mm(board)
    cols = board.inner_corners[0]
    points = _instant_points(views_by_camera, names)
    empty = {"scales": np.zeros(0), "fit_residuals_mm": np.zeros(0), "adjacent_errors_mm": np.zeros(0),
             "distance_errors_mm": np.zeros(0), "true_distances_mm": np.zeros(0),
             "reprojection_error_px": np.zeros(0), "n_instants": 0, "n_points": 0}
    if not points:
        return empty
    # Every instant's corners at once (one triangulation, per-instant sums by bincount, one batched SVD):
    # the instant-by-instant loop cost more in numpy's per-call work than in the arithmetic (issue 28).
    parts = list(points.values())
    xyz, err = triangulate_dlt([rig.cameras[n] for n in names], np.concatenate([xy for _, xy in parts], axis=1))
    ids = np.concatenate([i for i, _ in parts]).astype(np.int64)
    inst = np.repeat(np.arange(len(parts)), [len(i) for i, _ in parts])
    ok = np.isfinite(xyz[:, 0])
    ids, xyz, err, inst = ids[ok], xyz[ok], err[ok], inst[ok]
    valid = _plane_instants(ids, inst, len(parts), cols)
    keep = valid[inst]
    ids, xyz, err, inst = ids[keep], xyz[keep], err[keep], inst[keep]
    if not ids.size:
        return empty
    used = np.flatnonzero(valid)  # the instants checked, in order
    inst = np.searchsorted(used, inst)  # 0..I-1
    count = np.bincount(inst, minlength=used.size).astype(np.float64)
    starts = np.concatenate([[0], np.cumsum(count).astype(np.int64)[:-1]])
    scales, res = _board_fits(obj[ids], xyz, inst, count, starts)
    p, q = _neighbours(ids, inst, cols, obj.shape[0])
    adjacent = np.linalg.norm(xyz[p] - xyz[q], axis=1) - board.square_mm
    # all pairs among at most max_pair_corners evenly spread corners of each instant (a large board has 10^5)
    pair_i, pair_j = [], []
    for lo, k in zip(starts.tolist(), count.astype(np.int64).tolist(), strict=True):
        sub = np.unique(np.linspace(0, k - 1, min(k, max_pair_corners)).round().astype(int))
        iu, ju = np.triu_indices(len(sub), 1)
        pair_i.append(lo + sub[iu])
        pair_j.append(lo + sub[ju])
    pi, pj = np.concatenate(pair_i), np.concatenate(pair_j)
    meas = np.linalg.norm(xyz[pi] - xyz[pj], axis=1)
    true = np.linalg.norm(obj[ids[pi]] - obj[ids[pj]], axis=1)
    return {"scales": scales, "fit_residuals_mm": np.linalg.norm(res, axis=1), "adjacent_errors_mm": adjacent,
            "distance_errors_mm": meas - true, "true_distances_mm": true, "reprojection_error_px": err,
            "n_instants": int(used.size), "n_points": int(ids.size)}


def _per_instant_sums(values: np.ndarray, inst: np.ndarray, n_inst: int) -> np.ndarray:
    """Column sums (n_inst, k) of ``values`` (P, k) over the points of each instant."""
    return np.stack([np.bincount(inst, weights=v, minlength=n_inst) for v in values.T], axis=1)


def _plane_instants(ids: np.ndarray, inst: np.ndarray, n_inst: int, cols: int) -> np.ndarray:
    """Per instant (n_inst,), whether its corners fix a plane: four or more, not all on one line.

    Collinear corners leave the grid positions' 2 x 2 scatter singular (exact in integers).
    """
    n = np.bincount(inst, minlength=n_inst).astype(np.float64)
    r, c = (v.astype(np.float64) for v in np.divmod(ids, cols))
    s_r, s_c, s_rr, s_cc, s_rc = _per_instant_sums(np.column_stack([r, c, r * r, c * c, r * c]), inst, n_inst).T
    det = (n * s_rr - s_r ** 2) * (n * s_cc - s_c ** 2) - (n * s_rc - s_r * s_c) ** 2
    return (n >= 4) & (det != 0)


def _board_fits(src: np.ndarray, dst: np.ndarray, inst: np.ndarray, count: np.ndarray,
                starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Umeyama's closed form per instant, dst ~ s R src + t: scales (I,) and residuals (P, 3) mm.

    Points are grouped by instant (``inst`` ascending, ``count`` each, from ``starts``); R comes from the
    SVD of each instant's cross-covariance, all instants in one batched call.
    """
    n_inst = count.size
    mu_s = _per_instant_sums(src, inst, n_inst) / count[:, None]
    mu_d = _per_instant_sums(dst, inst, n_inst) / count[:, None]
    a, b = src - mu_s[inst], dst - mu_d[inst]
    cov = np.add.reduceat(b[:, :, None] * a[:, None, :], starts, axis=0) / count[:, None, None]
    U, sv, Vt = np.linalg.svd(cov)
    d = np.ones((n_inst, 3))
    d[np.linalg.det(U) * np.linalg.det(Vt) < 0, -1] = -1
    R = U @ (d[:, :, None] * Vt)
    var_a = _per_instant_sums(np.sum(a ** 2, axis=1)[:, None], inst, n_inst)[:, 0] / count
    scales = np.sum(sv * d, axis=1) / var_a
    return scales, b - scales[inst, None] * np.einsum("kj,kij->ki", a, R[inst])


def _neighbours(ids: np.ndarray, inst: np.ndarray, cols: int, n_corners: int) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (p, q) of neighbouring corners seen at the same instant.

    Per instant the right-hand neighbours come first, then the lower ones, each in corner order.
    """
    key = inst * (n_corners + cols + 1) + ids  # room for a corner's lower neighbour within its instant
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]

    def partner(step: int, allowed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        at = np.minimum(np.searchsorted(sorted_key, key + step), sorted_key.size - 1)
        has = allowed & (sorted_key[at] == key + step)
        return np.flatnonzero(has), order[at[has]]

    right_p, right_q = partner(1, (ids % cols) + 1 < cols)
    below_p, below_q = partner(cols, np.ones(ids.size, bool))
    p, q = np.concatenate([right_p, below_p]), np.concatenate([right_q, below_q])
    kind = np.concatenate([np.zeros(right_p.size, int), np.ones(below_p.size, int)])
    nb = np.lexsort((ids[p], kind, inst[p]))
    return p[nb], q[nb]


def _summary(err: np.ndarray, prefix: str) -> dict[str, float]:
    if err.size == 0:
        return {}
    return {f"{prefix}_mean_mm": float(np.mean(err)), f"{prefix}_rms_mm": float(np.sqrt(np.mean(err ** 2))),
            f"{prefix}_max_mm": float(np.max(np.abs(err)))}


def metric_checks(rig: Rig, views_by_camera: Mapping[str, list[BoardView]], board: Board, *,
                  max_square_error_pct: float = 1.0, max_square_error_mm: float | None = None,
                  max_distance_rms_mm: float | None = None) -> tuple[dict[str, float], list[Finding], dict]:
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
    flags : list of Finding
        A finding per threshold exceeded: square error over ``max_square_error_pct`` percent or over
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
    flags: list[Finding] = []
    if "board_square_error_mm" not in checks:
        flags.append(Finding("calibration.no_shared_view",
                             "no board was seen by two cameras at once: the rig's metric accuracy is unchecked"))
        return checks, flags, per_pair
    sq_mm, sq_pct = checks["board_square_error_mm"], checks["board_square_error_pct"]
    if sq_pct > max_square_error_pct or (max_square_error_mm is not None and sq_mm > max_square_error_mm):
        limit = f"{max_square_error_pct:g} %"
        if max_square_error_mm is not None:
            limit += f" / {max_square_error_mm:g} mm"
        flags.append(Finding("calibration.square_error",
                             f"reconstructed board squares are off by {sq_mm:.2f} mm RMS ({sq_pct:.2f} % of "
                             f"{board.square_mm:g} mm, over the {limit} limit): recalibrate before trusting "
                             f"distances",
                             {"square_error_mm": sq_mm, "square_error_pct": sq_pct,
                              "limit_pct": max_square_error_pct, "square_mm": board.square_mm}))
    rms = checks.get("corner_distance_error_rms_mm", 0.0)
    if max_distance_rms_mm is not None and rms > max_distance_rms_mm:
        flags.append(Finding("calibration.corner_distances",
                             f"distances between triangulated board corners are off by {rms:.2f} mm RMS, over "
                             f"the {max_distance_rms_mm:g} mm limit",
                             {"distance_error_rms_mm": rms, "limit_mm": max_distance_rms_mm}))
    return checks, flags, per_pair

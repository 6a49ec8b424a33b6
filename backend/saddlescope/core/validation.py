"""The thesis's validation experiments (8.2-8.3), repeatable on any rig.

- Free fall (thesis 8.3): a ball thrown up and falling; a parabola fitted to its 3-D track gives the
  gravitational acceleration, whose error against 9.81 m/s^2 measures the whole chain (calibration,
  synchronisation, detection, triangulation, differentiation). The thesis found 9.5 m/s^2 (3.6 %).
  Finding the ball among look-alikes and fitting its flight to every camera's pixels:
  :mod:`saddlescope.core.freefall`.
- Board distances (thesis Fig. 8.6, Table 8.5): points A-D on a board held in several places; their
  triangulated distances against the board's geometry (thesis: 2.2-4.6 % error).
"""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from saddlescope.core.calibration import BoardView
from saddlescope.core.camera_model import project_points, undistort_normalized
from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.triangulation import triangulate_nview
from saddlescope.core.types import Board, Camera, Rig

G_STANDARD_M_S2 = 9.80665


def gravity_from_freefall(t_s: np.ndarray, xyz_mm: np.ndarray, *, min_frames: int = 8,
                          max_residual_mm: float = 8.0, select_axes: tuple[int, ...] = (0, 1),
                          min_acceleration_m_s2: float = 0.25 * G_STANDARD_M_S2, min_significance: float = 5.0) -> dict:
    """Gravitational acceleration from a ball's free-fall track.

    Parameters
    ----------
    t_s : ndarray of shape (F,)
    xyz_mm : ndarray of shape (F, 3), NaN where the ball was not seen

    The flight is the longest run of frames where a parabola (x(t) = p + v t + a t^2 / 2 in every
    coordinate) fits within ``max_residual_mm`` on the ``select_axes`` (the image-plane axes of the
    reference camera, precise where depth is not) and accelerates on them at least
    ``min_acceleration_m_s2`` and ``min_significance`` standard errors (noise on a short run can fake an
    acceleration): the throw and the catch are left out, and so is the ball held still before the throw
    (a parabola too, and often the longer run). The acceleration is then fitted on all three axes
    over that flight (depth noise adds only to its second order).

    Returns
    -------
    dict with ``g_m_s2`` (|a|), ``direction`` (unit vector of a, rig axes), ``frames`` used,
    ``rms_residual_mm``, ``first``/``last`` frame indices.
    """
    t = np.asarray(t_s, dtype=np.float64)
    x = np.asarray(xyz_mm, dtype=np.float64)
    ok = np.all(np.isfinite(x), axis=1)
    idx = np.flatnonzero(ok)
    if idx.size < min_frames:
        raise KinematicsError(f"the ball is seen in only {idx.size} frames; at least {min_frames} are needed")

    axes = list(select_axes)

    def fit(sel: np.ndarray, cols=None) -> tuple[np.ndarray, float]:
        tt = t[sel] - t[sel].mean()
        design = np.stack([np.ones_like(tt), tt, 0.5 * tt ** 2], axis=1)
        y = x[sel] if cols is None else x[sel][:, cols]
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        resid = y - design @ coef
        return coef, float(np.sqrt(np.mean(np.sum(resid ** 2, axis=1))))

    best = None
    # grow windows from every seed of min_frames consecutive seen frames; keep the longest that fits
    for start in range(idx.size - min_frames + 1):
        sel = idx[start: start + min_frames]
        if sel[-1] - sel[0] != min_frames - 1:
            continue
        _, rms = fit(sel, axes)
        if rms > max_residual_mm:
            continue
        lo, hi = start, start + min_frames
        while True:
            grown = False
            for cand in ((lo - 1, hi), (lo, hi + 1)):
                a, b = cand
                if a < 0 or b > idx.size or idx[b - 1] - idx[a] != b - 1 - a:
                    continue
                if fit(idx[a:b], axes)[1] <= max_residual_mm:
                    lo, hi, grown = a, b, True
                    break
            if not grown:
                break
        if hi - lo <= (best[1] - best[0] if best else 0):
            continue
        # falling: accelerating on the precise axes, clearly more than the noise could fake
        coef, rms = fit(idx[lo:hi], axes)
        tt = t[idx[lo:hi]] - t[idx[lo:hi]].mean()
        design = np.stack([np.ones_like(tt), tt, 0.5 * tt ** 2], axis=1)
        acc_std = rms * np.sqrt(np.linalg.inv(design.T @ design)[2, 2] * (hi - lo) / max(1, hi - lo - 3))
        acc = float(np.linalg.norm(coef[2]))
        if acc / 1000.0 >= min_acceleration_m_s2 and acc >= min_significance * acc_std:
            best = (lo, hi)
    if best is None:
        raise KinematicsError("no stretch of the ball's track follows a parabola; was it in free fall?")
    sel = idx[best[0]: best[1]]
    coef, rms = fit(sel)
    acc = coef[2] / 1000.0
    g = float(np.linalg.norm(acc))
    return {"g_m_s2": g, "error_pct": 100 * (g / G_STANDARD_M_S2 - 1), "direction": (acc / g).tolist(),
            "frames": int(sel.size), "first": int(sel[0]), "last": int(sel[-1]), "rms_residual_mm": rms}


def grid_points_px(camera: Camera, view: BoardView, board: Board, ids: np.ndarray, *,
                   min_corners: int = 12) -> np.ndarray:
    """Image positions (distorted px) of board corners ``ids`` from every corner the view found.

    The inner corners of a flat board lie on an evenly spaced grid, so in the undistorted image they
    follow one homography of their (column, row) indices; fitted to all the corners found, it places
    each wanted corner with the detection errors of a hundred corners averaged out (the board's size
    is not used: the grid indices are unitless). Returns ndarray (len(ids), 2), NaN if fewer than
    ``min_corners`` corners were found.
    """
    ids = np.asarray(ids, dtype=np.int64)
    out = np.full((ids.size, 2), np.nan)
    if len(view.ids) < min_corners:
        return out
    cols = board.inner_corners[0]
    found = np.asarray(view.ids, dtype=np.int64)
    grid = np.stack([found % cols, found // cols], axis=1).astype(np.float64)
    H, _ = cv2.findHomography(grid, undistort_normalized(camera, np.asarray(view.corners_px, np.float64)), 0)
    if H is None:
        return out
    wanted = np.stack([ids % cols, ids // cols], axis=1).astype(np.float64)
    xy_n = cv2.perspectiveTransform(wanted[None], H)[0]
    # back to distorted pixels through the camera model: a point on each ray, in rig coordinates
    x_cam = 1000.0 * np.column_stack([xy_n, np.ones(len(xy_n))])
    R, t = np.asarray(camera.R, np.float64), np.asarray(camera.t_mm, np.float64).ravel()
    return project_points(camera, (x_cam - t) @ R)


def board_point_distances(rig: Rig, views_by_camera: Mapping[str, list[BoardView]], board: Board,
                          points: Mapping[str, tuple[int, int]], *, method: str = "grid") -> dict:
    """Distances between named inner corners of a board, triangulated at every instant all cameras
    see it, against the board's geometry (thesis Table 8.5).

    ``points`` maps a name to an inner corner (col, row); views carry synchronised instants.

    ``method="corners"`` triangulates the named corners as detected (the thesis). Their detection
    errors (about 0.1 px on a board of 5 px squares) stay the same while the board is held still, so
    averaging the still frames does not remove them, and the thesis rig turns 0.1 px of disparity into
    some 17 mm of depth at 7.5 m: up to 2 % on a 0.6 m distance of a turned board. ``method="grid"``
    (default) places them with :func:`grid_points_px`, from all the corners each camera found
    (0.02-0.05 px; a few tenths of a per cent on the thesis rig, 0.05 % on a wide one).

    Returns per pair: true_mm, mean_mm, std_mm, error_pct (of the mean), max_abs_error_pct, n.
    """
    if method not in ("grid", "corners"):
        raise InputError(f"unknown board distance method {method!r} (use 'grid' or 'corners')")
    cols = board.inner_corners[0]
    ids = {name: int(r * cols + c) for name, (c, r) in points.items()}
    obj = board.object_points_mm()
    names = list(points)
    wanted = np.array([ids[n] for n in names])
    cams = [c for c in rig.names if c in views_by_camera]
    by_instant: dict[int, dict[str, BoardView]] = {}
    for cam in cams:
        for v in views_by_camera[cam]:
            by_instant.setdefault(v.frame, {})[cam] = v
    measured: dict[str, list[float]] = {f"{a}{b}": [] for i, a in enumerate(names) for b in names[i + 1:]}
    for views in by_instant.values():
        if len(views) < 2:
            continue
        xy = {}
        for cam, v in views.items():
            if method == "grid":
                xy[cam] = grid_points_px(rig.cameras[cam], v, board, wanted)
            else:
                pos = {int(i): k for k, i in enumerate(v.ids)}
                xy[cam] = np.array([v.corners_px[pos[i]] if i in pos else [np.nan, np.nan] for i in wanted])
        xyz, _, _ = triangulate_nview(Rig({c: rig.cameras[c] for c in xy}), xy)
        for i, a in enumerate(names):
            for j in range(i + 1, len(names)):
                d = float(np.linalg.norm(xyz[i] - xyz[j]))
                if np.isfinite(d):
                    measured[f"{a}{names[j]}"].append(d)
    out = {}
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            true = float(np.linalg.norm(obj[ids[a]] - obj[ids[b]]))
            m = np.asarray(measured[f"{a}{b}"])
            if not m.size:
                continue
            out[f"{a}{b}"] = {"true_mm": true, "mean_mm": float(m.mean()), "std_mm": float(m.std()),
                              "error_pct": float(100 * (m.mean() / true - 1)),
                              "max_abs_error_pct": float(100 * np.max(np.abs(m / true - 1))), "n": int(m.size)}
    return out

"""The thesis's validation experiments (8.2-8.3), repeatable on any rig.

- Free fall (thesis 8.3): a ball thrown up and falling; a parabola fitted to its 3-D track gives the
  gravitational acceleration, whose error against 9.81 m/s^2 measures the whole chain (calibration,
  synchronisation, detection, triangulation, differentiation). The thesis found 9.5 m/s^2 (3.6 %).
- Board distances (thesis Fig. 8.6, Table 8.5): points A-D on a board held in several places; their
  triangulated distances against the board's geometry (thesis: 2.2-4.6 % error).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from saddlescope.core.calibration import BoardView
from saddlescope.core.errors import KinematicsError
from saddlescope.core.triangulation import triangulate_nview
from saddlescope.core.types import Board, Rig

G_STANDARD_M_S2 = 9.80665


def gravity_from_freefall(t_s: np.ndarray, xyz_mm: np.ndarray, *, min_frames: int = 8,
                          max_residual_mm: float = 8.0, select_axes: tuple[int, ...] = (0, 1)) -> dict:
    """Gravitational acceleration from a ball's free-fall track.

    Parameters
    ----------
    t_s : ndarray of shape (F,)
    xyz_mm : ndarray of shape (F, 3), NaN where the ball was not seen

    The flight is the longest run of frames where a parabola (x(t) = p + v t + a t^2 / 2 in every
    coordinate) fits within ``max_residual_mm`` on the ``select_axes`` (the image-plane axes of the
    reference camera, precise where depth is not): the throw and the catch are left out. The
    acceleration is then fitted on all three axes over that flight (depth noise adds only to
    its second order).

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
        if best is None or hi - lo > best[1] - best[0]:
            best = (lo, hi)
    if best is None:
        raise KinematicsError("no stretch of the ball's track follows a parabola; was it in free fall?")
    sel = idx[best[0]: best[1]]
    coef, rms = fit(sel)
    acc = coef[2] / 1000.0
    g = float(np.linalg.norm(acc))
    return {"g_m_s2": g, "error_pct": 100 * (g / G_STANDARD_M_S2 - 1), "direction": (acc / g).tolist(),
            "frames": int(sel.size), "first": int(sel[0]), "last": int(sel[-1]), "rms_residual_mm": rms}


def board_point_distances(rig: Rig, views_by_camera: Mapping[str, list[BoardView]], board: Board,
                          points: Mapping[str, tuple[int, int]]) -> dict:
    """Distances between named inner corners of a board, triangulated at every instant all cameras
    see it, against the board's geometry (thesis Table 8.5).

    ``points`` maps a name to an inner corner (col, row); views carry synchronised instants.
    Returns per pair: true_mm, mean_mm, std_mm, error_pct (of the mean), max_abs_error_pct, n.
    """
    cols = board.inner_corners[0]
    ids = {name: int(r * cols + c) for name, (c, r) in points.items()}
    obj = board.object_points_mm()
    names = list(points)
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
            pos = {int(i): k for k, i in enumerate(v.ids)}
            xy[cam] = np.array([v.corners_px[pos[ids[n]]] if ids[n] in pos else [np.nan, np.nan] for n in names])
        xyz, _, _ = triangulate_nview(Rig({c: rig.cameras[c] for c in xy}), xy)
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                d = float(np.linalg.norm(xyz[i] - xyz[names.index(b)]))
                if np.isfinite(d):
                    measured[f"{a}{b}"].append(d)
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

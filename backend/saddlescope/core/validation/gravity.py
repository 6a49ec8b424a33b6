"""Gravity from a ball's free-fall track (thesis 8.3): the parabola's acceleration.

A ball thrown up and falling; a parabola fitted to its 3-D track gives the gravitational
acceleration, whose error against 9.81 m/s^2 measures the whole chain (calibration, synchronisation,
detection, triangulation, differentiation). The thesis found 9.5 m/s^2 (3.6 %).
"""

from __future__ import annotations

import numpy as np

from saddlescope.core.errors import KinematicsError

__all__ = ["G_STANDARD_M_S2", "gravity_from_freefall"]

G_STANDARD_M_S2 = 9.80665  # standard gravity, m/s^2


def gravity_from_freefall(t_s: np.ndarray, xyz_mm: np.ndarray, *, min_frames: int = 8,
                          max_residual_mm: float = 8.0, select_axes: tuple[int, ...] = (0, 1),
                          min_acceleration_m_s2: float = 0.25 * G_STANDARD_M_S2, min_significance: float = 5.0) -> dict:
    """Gravitational acceleration from a ball's free-fall track.

    The flight is the longest run of frames where a parabola (x(t) = p + v t + a t^2 / 2 in every
    coordinate) fits within ``max_residual_mm`` on the ``select_axes`` (the image-plane axes of the
    reference camera, precise where depth is not) and accelerates on them at least
    ``min_acceleration_m_s2`` and ``min_significance`` standard errors (noise on a short run can fake an
    acceleration): the throw and the catch are left out, and so is the ball held still before the throw
    (a parabola too, and often the longer run). The acceleration is then fitted on all three axes
    over that flight (depth noise adds only to its second order).

    Parameters
    ----------
    t_s : ndarray of shape (F,)
    xyz_mm : ndarray of shape (F, 3)
        NaN where the ball was not seen.

    Returns
    -------
    dict
        ``g_m_s2`` (|a|), ``error_pct`` (against standard gravity), ``direction`` (unit vector of a,
        rig axes), ``frames`` used, ``rms_residual_mm``, ``first``/``last`` frame indices.

    Raises
    ------
    KinematicsError
        The ball seen on fewer than ``min_frames`` frames, or no stretch of its track in free fall.
    """
    t = np.asarray(t_s, dtype=np.float64)
    x = np.asarray(xyz_mm, dtype=np.float64)
    ok = np.all(np.isfinite(x), axis=1)
    idx = np.flatnonzero(ok)
    if idx.size < min_frames:
        raise KinematicsError(f"the ball is seen in only {idx.size} frames; at least {min_frames} are needed")
    axes = list(select_axes)
    best = None
    # grow windows from every seed of min_frames consecutive seen frames; keep the longest that fits
    for start in range(idx.size - min_frames + 1):
        sel = idx[start: start + min_frames]
        if sel[-1] - sel[0] != min_frames - 1:
            continue
        _, rms = _fit_parabola(t, x, sel, axes)
        if rms > max_residual_mm:
            continue
        lo, hi = _grown_run(t, x, idx, axes, start, start + min_frames, max_residual_mm)
        if hi - lo <= (best[1] - best[0] if best else 0):
            continue
        if _falls(t, x, idx[lo:hi], axes, min_acceleration_m_s2, min_significance):
            best = (lo, hi)
    if best is None:
        raise KinematicsError("no stretch of the ball's track follows a parabola; was it in free fall?")
    sel = idx[best[0]: best[1]]
    coef, rms = _fit_parabola(t, x, sel)
    acc = coef[2] / 1000.0
    g = float(np.linalg.norm(acc))
    return {"g_m_s2": g, "error_pct": 100 * (g / G_STANDARD_M_S2 - 1), "direction": (acc / g).tolist(),
            "frames": int(sel.size), "first": int(sel[0]), "last": int(sel[-1]), "rms_residual_mm": rms}


def _fit_parabola(t: np.ndarray, x: np.ndarray, sel: np.ndarray, cols=None) -> tuple[np.ndarray, float]:
    """Least-squares parabola through the frames ``sel`` of x (F, 3) (or its columns ``cols``).

    Returns the coefficients (3, D) (position, velocity, acceleration at the frames' mean time) and
    the RMS residual distance in mm.
    """
    tt = t[sel] - t[sel].mean()
    design = np.stack([np.ones_like(tt), tt, 0.5 * tt ** 2], axis=1)
    y = x[sel] if cols is None else x[sel][:, cols]
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    resid = y - design @ coef
    return coef, float(np.sqrt(np.mean(np.sum(resid ** 2, axis=1))))


def _grown_run(t: np.ndarray, x: np.ndarray, idx: np.ndarray, axes: list[int], lo: int, hi: int,
               max_residual_mm: float) -> tuple[int, int]:
    """The run idx[lo:hi] grown a frame at a time, either side, while the parabola still fits.

    The run stays contiguous and the parabola within ``max_residual_mm``; returns the grown (lo, hi).
    """
    while True:
        grown = False
        for cand in ((lo - 1, hi), (lo, hi + 1)):
            a, b = cand
            if a < 0 or b > idx.size or idx[b - 1] - idx[a] != b - 1 - a:
                continue
            if _fit_parabola(t, x, idx[a:b], axes)[1] <= max_residual_mm:
                lo, hi, grown = a, b, True
                break
        if not grown:
            return lo, hi


def _falls(t: np.ndarray, x: np.ndarray, sel: np.ndarray, axes: list[int], min_acceleration_m_s2: float,
           min_significance: float) -> bool:
    """Whether the ball falls over the frames ``sel``.

    It accelerates on the precise axes at least ``min_acceleration_m_s2``, clearly more than the noise
    could fake (``min_significance`` standard errors).
    """
    coef, rms = _fit_parabola(t, x, sel, axes)
    tt = t[sel] - t[sel].mean()
    design = np.stack([np.ones_like(tt), tt, 0.5 * tt ** 2], axis=1)
    n = sel.size
    acc_std = rms * np.sqrt(np.linalg.inv(design.T @ design)[2, 2] * n / max(1, n - 3))
    acc = float(np.linalg.norm(coef[2]))
    return bool(acc / 1000.0 >= min_acceleration_m_s2 and acc >= min_significance * acc_std)

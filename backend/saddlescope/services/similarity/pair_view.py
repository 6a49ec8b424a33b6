"""What the pair view draws of two analysed rides: their saddle-point paths and their mean strides aligned.

For display only (the similarity itself is `saddlescope.services.similarity.compare`'s): each ride's saddle
point S in the motion frame, with the travel (a least-squares straight line per coordinate) and the
mean removed, so the two paths overlay; and each ride's mean stride over stride phase, the second
shifted in phase to line up with the first by circular cross-correlation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["MAX_PATH_POINTS", "STRIDE_SAMPLES", "detrended_path", "mean_stride", "pair_paths"]

MAX_PATH_POINTS = 600
STRIDE_SAMPLES = 100


def detrended_path(position_m: np.ndarray) -> np.ndarray:
    """A track without its travel and mean.

    Parameters
    ----------
    position_m : ndarray of shape (N, 3)
        Positions (m), N >= 2.

    Returns
    -------
    ndarray of shape (N, 3)
        The positions minus a least-squares straight line per coordinate (mean zero).
    """
    n = position_m.shape[0]
    idx = np.arange(n, dtype=np.float64)
    basis = np.column_stack([np.ones(n), idx - idx.mean()])
    coef, *_ = np.linalg.lstsq(basis, position_m, rcond=None)
    return position_m - basis @ coef


def mean_stride(position_m: np.ndarray, period_samples: float, n_samples: int = STRIDE_SAMPLES) -> np.ndarray | None:
    """The mean stride of a detrended track over stride phase, or None when it has no whole stride.

    Parameters
    ----------
    position_m : ndarray of shape (N, 3)
        Detrended positions (m).
    period_samples : float
        Stride period in samples.
    n_samples : int, optional
        Phase samples of the stride.

    Returns
    -------
    ndarray of shape (n_samples, 3) or None
        Averaged over the whole strides, mean zero.
    """
    n = position_m.shape[0]
    if not np.isfinite(period_samples) or period_samples < 4 or period_samples > n - 1:
        return None
    strides = int((n - 1) // period_samples)
    t = (np.arange(strides)[:, None] * period_samples
         + np.arange(n_samples)[None, :] * (period_samples / n_samples)).ravel()
    idx = np.arange(n, dtype=np.float64)
    folded = np.column_stack([np.interp(t, idx, position_m[:, k]) for k in range(3)])
    stride = folded.reshape(strides, n_samples, 3).mean(axis=0)
    return stride - stride.mean(axis=0)


def _phase_shift(a: np.ndarray, b: np.ndarray) -> int:
    """Shift s maximising the circular cross-correlation of `a` with ``np.roll(b, -s)`` over all axes."""
    spectrum = np.sum(np.conj(np.fft.rfft(a, axis=0)) * np.fft.rfft(b, axis=0), axis=1)
    return int(np.argmax(np.fft.irfft(spectrum, n=a.shape[0])))


def _saddle(doc: dict[str, Any]) -> tuple[np.ndarray | None, float | None]:
    try:
        xyz = np.asarray(doc["saddle"]["position_m"], dtype=np.float64)
        period = float(doc["period_s"]) * float(doc["fps"])
    except (KeyError, TypeError, ValueError):
        return None, None
    if xyz.ndim != 2 or xyz.shape[0] < 2 or xyz.shape[1] != 3 or not np.all(np.isfinite(xyz)):
        return None, None
    return xyz, period


def _mm(values: np.ndarray) -> list:
    return np.round(values * 1000.0, 3).tolist()


def pair_paths(doc_first: dict[str, Any], doc_second: dict[str, Any]) -> dict[str, Any]:
    """The pair view's data of two result documents (positions in mm, motion frame).

    Returns ``{"paths_mm": [first (M, 3), second (M', 3)], "strides": {"phase": (n,), "first_mm",
    "second_mm" (aligned), "second_unaligned_mm", "shift_phase"} or None, "reason": why not}``; the
    paths are decimated to at most `MAX_PATH_POINTS` points.
    """
    (xa, pa), (xb, pb) = _saddle(doc_first), _saddle(doc_second)
    if xa is None or xb is None or pa is None or pb is None:
        return {"paths_mm": [], "strides": None, "reason": "a result has no saddle-point track"}
    da, db = detrended_path(xa), detrended_path(xb)
    paths = [_mm(d[:: max(1, int(np.ceil(d.shape[0] / MAX_PATH_POINTS)))]) for d in (da, db)]
    sa, sb = mean_stride(da, pa), mean_stride(db, pb)
    if sa is None or sb is None:
        return {"paths_mm": paths, "strides": None, "reason": "a ride is shorter than one whole stride"}
    shift = _phase_shift(sa, sb)
    return {
        "paths_mm": paths,
        "strides": {"phase": (np.arange(STRIDE_SAMPLES) / STRIDE_SAMPLES).round(4).tolist(),
                    "first_mm": _mm(sa), "second_mm": _mm(np.roll(sb, -shift, axis=0)),
                    "second_unaligned_mm": _mm(sb), "shift_phase": shift / STRIDE_SAMPLES},
        "reason": None,
    }

"""Dynamic time warping of raw trajectories, plain numpy (dissertation 4.1): the reference."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from saddlescope.core.errors import InputError

__all__ = [
    "dtw_distance_reference",
]


def _as_series(x: ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] < 1:
        raise InputError(f"{name} must be a (N,) or (N, D) series, got shape {np.shape(x)}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or infinite values")
    return arr


def dtw_distance_reference(a: ArrayLike, b: ArrayLike, *, window: int | None = None) -> float:
    """Dynamic time warping distance, plain numpy (the reference for tests and small inputs).

    ``DTW^2(i, j) = |a_i - b_j|^2 + min(DTW^2(i-1, j-1), DTW^2(i-1, j), DTW^2(i, j-1))`` (dissertation
    4.1) and the distance is ``sqrt(DTW^2(n, m))``: the same convention and window as
    ``dtaidistance`` (squared Euclidean cost per sample pair, square root of the total). Filled by
    anti-diagonals, O(n m) time (O(n window) with a window) and O(n + m) memory.

    Parameters
    ----------
    a, b : array_like of shape (n,) or (n, D), (m,) or (m, D)
        Series; D-dimensional samples use the squared Euclidean distance.
    window : int, optional
        Sakoe-Chiba window as in dtaidistance: cell (i, j) is allowed when
        ``i - max(0, n - m) - (window - 1) <= j <= i + max(0, m - n) + (window - 1)``.

    Returns
    -------
    distance : float
    """
    x = _as_series(a, "a")
    y = _as_series(b, "b")
    if x.shape[1] != y.shape[1]:
        raise InputError(f"series have different dimensions: {x.shape[1]} and {y.shape[1]}")
    n, m = x.shape[0], y.shape[0]
    if window is None:
        w_lo = w_hi = max(n, m)
    else:
        if window < 1:
            raise InputError(f"window must be at least 1, got {window}")
        w_lo = max(0, n - m) + window - 1
        w_hi = max(0, m - n) + window - 1
    inf = np.inf
    y_rev = y[::-1]  # cells (i, s - i) for increasing i read y backwards: a slice of y_rev
    # Three rotating buffers over anti-diagonals s - 2, s - 1, s; buf[i + 1] holds cell (i, s - i)
    # and index 0 stays infinite so that i - 1 = -1 needs no special case.
    d2, d1, cur = (np.full(n + 2, inf) for _ in range(3))
    ranges = [(0, -1), (0, -1), (0, -1)]  # (i_lo, i_hi) written in d2, d1, cur
    for s in range(n + m - 1):
        # i - w_lo <= s - i <= i + w_hi  and  0 <= s - i <= m - 1
        i_lo = max(0, s - m + 1, -((w_hi - s) // 2))
        i_hi = min(n - 1, s, (s + w_lo) // 2)
        old_lo, old_hi = ranges[2]
        cur[old_lo + 1: old_hi + 2] = inf
        if i_lo <= i_hi:
            diff = x[i_lo: i_hi + 1] - y_rev[m - 1 - s + i_lo: m - s + i_hi]
            cost = np.einsum("ij,ij->i", diff, diff)
            if s == 0:
                cur[1] = cost[0]
            else:
                best = np.minimum(np.minimum(d2[i_lo: i_hi + 1], d1[i_lo: i_hi + 1]), d1[i_lo + 1: i_hi + 2])
                cur[i_lo + 1: i_hi + 2] = cost + best
        ranges = [ranges[1], (i_lo, i_hi), ranges[0]]
        d2, d1, cur = d1, cur, d2
    total = d1[n]
    if not np.isfinite(total):
        raise InputError(f"the DTW window {window} leaves no warping path between lengths {n} and {m}")
    return float(np.sqrt(total))

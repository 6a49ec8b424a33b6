"""Robust local regression ("rloess") and gap bridging of marker coordinates (thesis 5.2).

The thesis smoothed every coordinate of every marker with MATLAB's ``smooth(y, 0.1, 'rloess')``:
a local quadratic fit over the nearest 10 % of the samples with tricube distance weights, made
robust by bisquare weights on the residuals scaled by six median absolute residuals. MATLAB runs
one ordinary pass and then four robustness passes (five in all); ``iterations`` counts the
robustness passes, so the default reproduces that.

Everything here is vectorised: the neighbour windows of all samples are gathered as one index
array and all the 3x3 weighted normal equations are solved at once (in chunks of rows to bound
memory on long records).
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from saddlescope.core.errors import InputError

# Rows of the (n_eval, k) neighbour arrays handled at once; bounds memory to ~ a few MB per array.
_CHUNK_ELEMENTS = 2_000_000


def _as_time(t, n: int | None = None, *, name: str = "t") -> np.ndarray:
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1:
        raise InputError(f"{name} must be a 1-D array of times, got shape {t.shape}")
    if n is not None and t.shape[0] != n:
        raise InputError(f"{name} has {t.shape[0]} samples but the data have {n}")
    if not np.all(np.isfinite(t)):
        raise InputError(f"{name} contains NaN or infinite times")
    if t.shape[0] > 1 and np.any(np.diff(t) <= 0):
        raise InputError(f"{name} must be strictly increasing")
    return t


def span_points(n: int, span: float) -> int:
    """Number of neighbours used by each local fit.

    Parameters
    ----------
    n : int
        Number of (finite) samples.
    span : float
        Fraction of the samples in (0, 1], or a number of samples if >= 1 (as MATLAB's ``smooth``).

    Returns
    -------
    k : int
        Window size, at least 5 (a local quadratic with zero weight at the window edge needs 4)
        and at most ``n``.
    """
    if not np.isfinite(span) or span <= 0:
        raise InputError(f"span must be positive, got {span}")
    k = int(round(span * n)) if span < 1 else int(round(span))
    return int(min(max(k, 5), n))


def _window_starts(t_fit: np.ndarray, t_eval: np.ndarray, k: int) -> np.ndarray:
    """First index of the k nearest fit samples of each evaluation time (a contiguous window).

    Moving the window one step right (drop t[s], add t[s+k]) brings it closer to t_e exactly when
    t[s] + t[s+k] < 2 t_e, and that sum grows with s, so the best start is a searchsorted count.
    """
    n = t_fit.shape[0]
    if k >= n:
        return np.zeros(t_eval.shape[0], dtype=np.intp)
    pair_sum = t_fit[: n - k] + t_fit[k:]
    return np.searchsorted(pair_sum, 2.0 * t_eval, side="left").astype(np.intp)


def _local_quadratic(t_fit: np.ndarray, y_fit: np.ndarray, robust_w: np.ndarray, t_eval: np.ndarray,
                     k: int, *, degree: int = 2) -> np.ndarray:
    """Weighted local polynomial value at each evaluation time.

    t_fit : (n,), y_fit : (n,), robust_w : (n,), t_eval : (m,) -> (m,).
    """
    n_eval = t_eval.shape[0]
    out = np.empty(n_eval)
    starts = _window_starts(t_fit, t_eval, k)
    offsets = np.arange(k)
    rows = max(1, _CHUNK_ELEMENTS // max(k, 1))
    n_coef = degree + 1
    for lo in range(0, n_eval, rows):
        hi = min(lo + rows, n_eval)
        idx = starts[lo:hi, None] + offsets[None, :]  # (r, k)
        dt = t_fit[idx] - t_eval[lo:hi, None]
        dist = np.abs(dt)
        dmax = dist.max(axis=1, keepdims=True)
        dmax = np.where(dmax > 0, dmax, 1.0)
        u = dist / dmax
        # Tricube distance weights (zero at the furthest neighbour, as MATLAB's lowess).
        w = (1.0 - np.clip(u, 0.0, 1.0) ** 3) ** 3 * robust_w[idx]
        x = dt / dmax  # centred and scaled abscissa keeps the normal equations well conditioned
        basis = np.stack([x**p for p in range(n_coef)], axis=-1)  # (r, k, c)
        wb = basis * w[..., None]
        A = np.einsum("rkc,rkd->rcd", wb, basis)
        b = np.einsum("rkc,rk->rc", wb, y_fit[idx])
        # A window may lose its support when robust weights zero most of it: fall back to pinv.
        det = np.linalg.det(A)
        scale = np.einsum("rcc->r", A) ** n_coef
        good = np.abs(det) > 1e-12 * np.maximum(scale, 1e-300)
        coef = np.empty((hi - lo, n_coef))
        if np.any(good):
            coef[good] = np.linalg.solve(A[good], b[good][..., None])[..., 0]
        if np.any(~good):
            coef[~good] = np.einsum("rcd,rd->rc", np.linalg.pinv(A[~good]), b[~good])
        out[lo:hi] = coef[:, 0]
    return out


def _bisquare(residual: np.ndarray) -> np.ndarray:
    """Bisquare robustness weights from residuals scaled by six median absolute residuals."""
    mad = np.median(np.abs(residual))
    if mad <= 1e-12 * max(np.max(np.abs(residual)), 1e-300) or mad == 0.0:
        return np.ones_like(residual)
    u = residual / (6.0 * mad)
    return np.where(np.abs(u) < 1.0, (1.0 - u**2) ** 2, 0.0)


def _rloess_1d(t: np.ndarray, y: np.ndarray, k_span: float, iterations: int,
               t_eval: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Smooth one finite series; optionally also evaluate the final local fit at t_eval."""
    n = t.shape[0]
    k = span_points(n, k_span)
    robust_w = np.ones(n)
    fit = _local_quadratic(t, y, robust_w, t, k)
    for _ in range(iterations):
        robust_w = _bisquare(y - fit)
        fit = _local_quadratic(t, y, robust_w, t, k)
    extra = None
    if t_eval is not None and t_eval.size:
        extra = _local_quadratic(t, y, robust_w, t_eval, k)
    return fit, extra


def rloess(t, y, *, span: float = 0.10, iterations: int = 4) -> np.ndarray:
    """Robust local quadratic regression of each column of ``y`` (MATLAB ``smooth(..., 'rloess')``).

    Parameters
    ----------
    t : ndarray of shape (N,)
        Strictly increasing sample times (s); uneven spacing is allowed.
    y : ndarray of shape (N,) or (N, D)
        Values; NaN marks a missing sample (ignored by the fits and left NaN in the output).
    span : float, optional
        Fraction of the finite samples in each local fit (10 % as in the thesis), or a number of
        samples if >= 1.
    iterations : int, optional
        Number of bisquare robustness passes after the first ordinary pass (MATLAB: 4, five
        passes in all). 0 gives plain loess.

    Returns
    -------
    y_smooth : ndarray of the shape of ``y``
        Smoothed values, NaN where ``y`` is NaN.
    """
    y = np.asarray(y, dtype=np.float64)
    if y.ndim not in (1, 2):
        raise InputError(f"y must have shape (N,) or (N, D), got {y.shape}")
    t = _as_time(t, y.shape[0])
    if iterations < 0:
        raise InputError(f"iterations must be >= 0, got {iterations}")
    cols = y.reshape(y.shape[0], -1)
    out = np.full_like(cols, np.nan)
    for c in range(cols.shape[1]):
        ok = np.isfinite(cols[:, c])
        if ok.sum() < 5:
            raise InputError(f"column {c} has {int(ok.sum())} finite samples; rloess needs at least 5")
        out[ok, c], _ = _rloess_1d(t[ok], cols[ok, c], span, iterations)
    return out.reshape(y.shape)


def _nan_runs(missing: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True in a 1-D bool array as (first, last) inclusive index pairs."""
    if not missing.any():
        return []
    padded = np.concatenate([[False], missing, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _merge_intervals(intervals: list[tuple[float, float]]) -> list[tuple[float, float]]:
    merged: list[tuple[float, float]] = []
    for start, end in sorted(intervals):
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], end))
        else:
            merged.append((start, end))
    return merged


def bridge_gaps(t, y, *, max_gap_s: float, span: float = 0.10, iterations: int = 4,
                method: str = "loess") -> tuple[np.ndarray, np.ndarray, list[tuple[float, float]]]:
    """Fill short interior gaps (NaN runs) and report the long ones.

    A gap's duration is counted as its number of missing samples times the median sampling
    interval, so a single lost frame at 30 fps lasts 1/30 s.

    Parameters
    ----------
    t : ndarray of shape (N,)
        Strictly increasing sample times (s).
    y : ndarray of shape (N,) or (N, D)
        Values with NaN in the gaps; each column is bridged on its own.
    max_gap_s : float
        Longest gap that is filled.
    span, iterations : optional
        Parameters of the robust local fit used for ``method="loess"`` (see :func:`rloess`).
    method : {"loess", "cubic"}
        ``"loess"`` evaluates the robust local quadratic fit of the surrounding data in the gap;
        ``"cubic"`` interpolates the raw samples with a cubic spline.

    Returns
    -------
    y_filled : ndarray of the shape of ``y``
        Raw values, with short gaps filled; long gaps and gaps touching either end of the record
        (which would need extrapolation) stay NaN.
    filled_mask : ndarray of bool, shape of ``y``
        True where a value was filled in.
    long_gaps : list of (start_s, end_s)
        Time intervals (first and last missing sample) left unfilled, merged over columns.
    """
    y = np.asarray(y, dtype=np.float64)
    if y.ndim not in (1, 2):
        raise InputError(f"y must have shape (N,) or (N, D), got {y.shape}")
    t = _as_time(t, y.shape[0])
    if not np.isfinite(max_gap_s) or max_gap_s < 0:
        raise InputError(f"max_gap_s must be a non-negative number, got {max_gap_s}")
    if method not in ("loess", "cubic"):
        raise InputError(f"method must be 'loess' or 'cubic', got {method!r}")
    cols = y.reshape(y.shape[0], -1).copy()
    filled = np.zeros(cols.shape, dtype=bool)
    dt = float(np.median(np.diff(t))) if t.shape[0] > 1 else 0.0
    long_gaps: list[tuple[float, float]] = []
    n = t.shape[0]
    for c in range(cols.shape[1]):
        missing = ~np.isfinite(cols[:, c])
        runs = _nan_runs(missing)
        if not runs:
            continue
        fill_idx = []
        for first, last in runs:
            duration_s = (last - first + 1) * dt
            interior = first > 0 and last < n - 1
            if interior and duration_s <= max_gap_s + 1e-9 * max(dt, 1.0):
                fill_idx.extend(range(first, last + 1))
            else:
                long_gaps.append((float(t[first]), float(t[last])))
        if not fill_idx:
            continue
        ok = ~missing
        if ok.sum() < 5:
            raise InputError(f"column {c} has {int(ok.sum())} finite samples; cannot bridge its gaps")
        where = np.asarray(fill_idx, dtype=np.intp)
        if method == "loess":
            _, values = _rloess_1d(t[ok], cols[ok, c], span, iterations, t_eval=t[where])
        else:
            values = CubicSpline(t[ok], cols[ok, c])(t[where])
        cols[where, c] = values
        filled[where, c] = True
    return cols.reshape(y.shape), filled.reshape(y.shape), _merge_intervals(long_gaps)

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

__all__ = [
    "span_points",
    "rloess",
    "bridge_gaps",
    "regularize_depth",
]

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


class _Windows:
    """Neighbour windows, distance weights and abscissa powers of a set of evaluation times.

    They depend on the times only, so they are computed once and reused by every robustness
    pass (cached when they fit in memory, recomputed chunk by chunk otherwise).
    """

    def __init__(self, t_fit: np.ndarray, t_eval: np.ndarray, k: int, degree: int = 2):
        self.t_fit, self.t_eval, self.k, self.degree = t_fit, t_eval, k, degree
        self.starts = _window_starts(t_fit, t_eval, k)
        self.chunk = max(1, _CHUNK_ELEMENTS // max(k, 1))
        n_chunks = -(-t_eval.shape[0] // self.chunk)
        self.cache: dict[int, tuple] | None = {} if n_chunks * self.chunk * k <= 2 * _CHUNK_ELEMENTS else None

    def chunk_data(self, lo: int) -> tuple:
        if self.cache is not None and lo in self.cache:
            return self.cache[lo]
        hi = min(lo + self.chunk, self.t_eval.shape[0])
        k = self.k
        idx = self.starts[lo:hi, None] + np.arange(k)[None, :]  # (r, k)
        dt = self.t_fit[idx] - self.t_eval[lo:hi, None]
        dist = np.abs(dt)
        dmax = dist.max(axis=1, keepdims=True)
        dmax = np.where(dmax > 0, dmax, 1.0)
        # Tricube distance weights. Scaling by k/(k-1) of the furthest distance leaves the outermost
        # neighbours a small weight: with a short span (5 points) a zero weight would leave a
        # quadratic through three points, which does not smooth at all.
        u = dist / (dmax * k / (k - 1))
        w_dist = (1.0 - np.clip(u, 0.0, 1.0) ** 3) ** 3
        x = dt / dmax  # centred and scaled abscissa keeps the normal equations well conditioned
        powers = np.empty(x.shape + (2 * self.degree + 1,))  # (r, k, 2 degree + 1)
        powers[..., 0] = 1.0
        for p in range(1, powers.shape[-1]):
            powers[..., p] = powers[..., p - 1] * x
        data = (hi, idx, np.sign(dt), w_dist, powers)
        if self.cache is not None:
            self.cache[lo] = data
        return data


def _local_quadratic(win: _Windows, y_fit: np.ndarray, robust_w: np.ndarray) -> np.ndarray:
    """Weighted local polynomial value at each evaluation time of ``win``; y_fit, robust_w : (n,)."""
    n_eval = win.t_eval.shape[0]
    n_coef = win.degree + 1
    out = np.empty(n_eval)
    ij = np.add.outer(np.arange(n_coef), np.arange(n_coef))
    for lo in range(0, n_eval, win.chunk):
        hi, idx, side, w_dist, powers = win.chunk_data(lo)
        w = w_dist * robust_w[idx]
        # Weighted moments sum w x^p and sum w y x^p build every normal matrix at once.
        moments = np.matmul(w[:, None, :], powers)[:, 0, :]  # (r, 2 degree + 1)
        b = np.matmul((w * y_fit[idx])[:, None, :], powers[..., :n_coef])[:, 0, :]
        A = moments[:, ij]  # Hankel: A[c, d] = sum w x^(c + d)
        coef = np.zeros((hi - lo, n_coef))
        todo = np.ones(hi - lo, dtype=bool)
        # Where robust weights leave support on one side only (and none at the point itself, as
        # at a record's end whose last samples were rejected), a quadratic would extrapolate
        # wildly: use a line there.
        positive = w > 0
        extrapolating = ~((positive & (side < 0)).any(axis=1) & (positive & (side > 0)).any(axis=1)) & ~(
            positive & (side == 0)).any(axis=1)
        # Robust weights may zero most of a window: drop to a local line, then to a weighted mean,
        # rather than take a minimum-norm quadratic through two points (which can be far off).
        for c in range(n_coef, 0, -1):
            if not todo.any():
                break
            todo_c = todo & ~extrapolating if c > 2 else todo
            if not todo_c.any():
                continue
            Ac = A[todo_c][:, :c, :c]
            scale = np.einsum("rcc->r", Ac) ** c
            good = np.abs(np.linalg.det(Ac)) > 1e-10 * np.maximum(scale, 1e-300)
            rows = np.flatnonzero(todo_c)[good]
            if rows.size:
                coef[rows, :c] = np.linalg.solve(Ac[good], b[rows, :c][..., None])[..., 0]
                todo[rows] = False
        if todo.any():  # robust weights zeroed the whole window: plain distance-weighted mean
            wd = w_dist[todo]
            coef[todo, 0] = np.sum(wd * y_fit[idx[todo]], axis=1) / np.sum(wd, axis=1)
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
               t_eval: np.ndarray | None = None, win: _Windows | None = None,
               ) -> tuple[np.ndarray, np.ndarray | None]:
    """Smooth one finite series; optionally also evaluate the final local fit at t_eval."""
    n = t.shape[0]
    k = span_points(n, k_span)
    if win is None or win.k != k or win.t_fit.shape != t.shape:
        win = _Windows(t, t, k)
    robust_w = np.ones(n)
    fit = _local_quadratic(win, y, robust_w)
    for _ in range(iterations):
        robust_w = _bisquare(y - fit)
        fit = _local_quadratic(win, y, robust_w)
    extra = None
    if t_eval is not None and t_eval.size:
        extra = _local_quadratic(_Windows(t, t_eval, k), y, robust_w)
    return fit, extra


def rloess(t, y, *, span: float = 0.10, iterations: int = 4, span_s: float | None = None) -> np.ndarray:
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
    span_s : float, optional
        The window as a duration instead (overrides ``span``): 10 % of a long ride can exceed a
        stride and flatten the motion, whereas the thesis smoothed only its two-period window.

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
    if span_s is not None:
        if not np.isfinite(span_s) or span_s <= 0:
            raise InputError(f"span_s must be a positive duration, got {span_s}")
        dt = float(np.median(np.diff(t))) if t.shape[0] > 1 else 1.0
        span = float(max(1, round(span_s / dt) + 1))
    cols = y.reshape(y.shape[0], -1)
    out = np.full_like(cols, np.nan)
    shared = None  # the windows of complete columns are the same: compute them once
    for c in range(cols.shape[1]):
        ok = np.isfinite(cols[:, c])
        if ok.sum() < 5:
            raise InputError(f"column {c} has {int(ok.sum())} finite samples; rloess needs at least 5")
        if ok.all():
            if shared is None:
                shared = _Windows(t, t, span_points(t.shape[0], span))
            out[:, c], _ = _rloess_1d(t, cols[:, c], span, iterations, win=shared)
        else:
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
        fill_idx: list[int] = []
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


def regularize_depth(t, xyz_mm, origin_mm, axis, *, period_s: float, max_order: int = 4,
                     trend_degree: int = 1) -> tuple[np.ndarray, list[int]]:
    """Smooth each marker's depth, keeping its direction from the cameras (its image position).

    With cameras close together the depth of a point is tens of times noisier than its position
    across the viewing ray, and that noise leaks into every rig axis (x = depth * ray). Each
    marker's depth d(t) = axis . (p(t) - origin) (linear in time for travel on a straight line) is
    fitted with a trend of ``trend_degree`` plus a Fourier series of the stride (f0 = 1 / ``period_s``)
    whose order 0..``max_order`` is chosen by the Bayesian information criterion, so the sway a
    precise rig sees is kept and the noise of a narrow rig is not; the point is then moved along
    its own ray to the fitted depth.

    Parameters
    ----------
    t : ndarray of shape (N,)
        Sample times (s).
    xyz_mm : ndarray of shape (N, M, 3)
        Marker positions (rig mm), finite.
    origin_mm : ndarray of shape (3,)
        The mean camera centre (rig mm).
    axis : ndarray of shape (3,)
        The worst-fixed direction (roughly the viewing direction).
    period_s : float
        Stride period (s).
    max_order : int, optional
        Highest Fourier order tried.
    trend_degree : int, optional
        Degree of the polynomial trend of the depth.

    Returns
    -------
    xyz_mm : ndarray of shape (N, M, 3)
        The regularised points (rig mm).
    orders : list of int
        The Fourier order chosen per marker.
    """
    t = _as_time(t)
    xyz = np.asarray(xyz_mm, dtype=np.float64)
    if xyz.ndim != 3 or xyz.shape[0] != t.shape[0] or xyz.shape[2] != 3:
        raise InputError(f"xyz_mm must have shape (N, M, 3) with N = {t.shape[0]}, got {xyz.shape}")
    if not np.all(np.isfinite(xyz)):
        raise InputError("regularize_depth needs finite points (bridge the gaps first)")
    if not (period_s > 0 and np.isfinite(period_s)):
        raise InputError(f"period_s must be positive, got {period_s}")
    n = t.shape[0]
    tau = t - t.mean()
    w = 2.0 * np.pi / period_s
    base = [tau ** d for d in range(trend_degree + 1)]
    designs = []
    for order in range(max_order + 1):
        cols = base + [f(k * w * tau) for k in range(1, order + 1) for f in (np.cos, np.sin)]
        if len(cols) >= n - 2:
            break
        designs.append(np.column_stack(cols))
    rel = xyz - np.asarray(origin_mm, dtype=np.float64).reshape(1, 1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(3)
    axis = axis / np.linalg.norm(axis)
    rng = rel @ axis
    if np.any(np.abs(rng) < 1e-6):
        raise InputError("a marker lies in the cameras' plane across the depth axis; its depth is undefined")
    out = xyz.copy()
    orders = []
    for m in range(xyz.shape[1]):
        best = None
        for order, design in enumerate(designs):
            coef, *_ = np.linalg.lstsq(design, rng[:, m], rcond=None)
            fitted = design @ coef
            rss = float(np.sum((rng[:, m] - fitted) ** 2))
            bic = n * np.log(max(rss, 1e-300) / n) + design.shape[1] * np.log(n)
            if best is None or bic < best[0]:
                best = (bic, order, fitted)
        assert best is not None  # designs is never empty
        _, order, fitted = best
        orders.append(order)
        out[:, m] = np.asarray(origin_mm, dtype=np.float64) + rel[:, m] * (fitted / rng[:, m])[:, None]
    return out, orders

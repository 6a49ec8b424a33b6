"""Stride period from the marker tracks, and the analysis window (thesis 5.3, 8.4.1).

The thesis typed the period in by hand (``period = 18`` frames). Here it is found from the
tracks. In walk and trot the saddle rises and falls twice per stride while the lateral sway and
the pitch repeat once per stride, so the strongest spectral line is often *half* the stride
period. The stride is the fundamental common period: the shortest lag at which every principal
motion of the markers repeats. The search therefore takes the dominant spectral frequency
``f_dom``, tries the sub-harmonic periods ``m / f_dom`` (m = 1, 2, ...) and keeps the shortest
one at which the amplitude-weighted autocorrelation of all principal components is (close to)
as high as at any candidate.
"""

from __future__ import annotations

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError

__all__ = [
    "estimate_period",
    "analysis_window",
]

# A principal component counts if its amplitude is at least this fraction of the largest one.
_COMPONENT_FRACTION = 0.1
# A shorter candidate is kept if its score is within this margin of the best candidate's score.
_SCORE_MARGIN = 0.1
# Below this best score the tracks do not look periodic at all.
_MIN_SCORE = 0.3


def _uniform_signals(t_s: np.ndarray, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Resample the (F, M, 3) tracks to a uniform grid with NaN gaps interpolated linearly."""
    n_frames = t_s.shape[0]
    cols = xyz.reshape(n_frames, -1)
    keep = np.isfinite(cols).mean(axis=0) >= 0.5
    if not keep.any():
        raise KinematicsError("markers are lost for most of the ride: no coordinate is present in "
                              "half of the frames, so no period can be estimated")
    cols = cols[:, keep]
    dt = float(np.median(np.diff(t_s)))
    n = int(round((t_s[-1] - t_s[0]) / dt)) + 1
    grid = t_s[0] + dt * np.arange(n)
    out = np.empty((n, cols.shape[1]))
    for c in range(cols.shape[1]):
        ok = np.isfinite(cols[:, c])
        out[:, c] = np.interp(grid, t_s[ok], cols[ok, c])
    return grid, out


def _detrend(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Remove a least-squares straight line from each column (the travel)."""
    tc = (t - t.mean()) / max(np.ptp(t), 1e-12)
    basis = np.column_stack([np.ones_like(tc), tc])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    return x - basis @ coef


def _dominant_frequency(comp: np.ndarray, dt: float, f_lo: float, f_hi: float) -> tuple[float, np.ndarray,
                                                                                           np.ndarray]:
    """Strongest spectral line of the summed power of the components, with parabolic refinement."""
    n = comp.shape[0]
    window = np.hanning(n)
    n_fft = int(2 ** np.ceil(np.log2(max(16 * n, 4096))))
    spec = np.fft.rfft(comp * window[:, None], n=n_fft, axis=0)
    power = np.sum(np.abs(spec) ** 2, axis=1)
    freqs = np.fft.rfftfreq(n_fft, dt)
    band = np.flatnonzero((freqs >= f_lo) & (freqs <= f_hi))
    if band.size < 3:
        raise KinematicsError(f"the ride ({n * dt:.2f} s at {1 / dt:.1f} fps) cannot resolve the frequency "
                              f"range {f_lo:.2f}-{f_hi:.2f} Hz")
    i = band[np.argmax(power[band])]
    f_peak = freqs[i]
    if 0 < i < power.shape[0] - 1:
        # Parabolic interpolation of the log power around the peak bin.
        # Only at a true local maximum: at the band's edge the neighbour outside may be higher, and
        # the vertex of that parabola lies anywhere (a 0.51 Hz edge bin once became 0.28 Hz).
        a, b, c = np.log(power[i - 1: i + 2] + 1e-300)
        denom = a - 2 * b + c
        if denom < 0 and b >= max(a, c):
            shift = float(np.clip(0.5 * (a - c) / denom, -0.5, 0.5))
            f_peak = freqs[i] + shift * (freqs[1] - freqs[0])
    return float(f_peak), freqs, power


def _similarity(comp: np.ndarray, lag: int) -> tuple[np.ndarray, float, float]:
    """Similarity of each component with itself ``lag`` samples later.

    Returns the per-component ``1 - var(b - a) / (var(a) + var(b))`` (a = c(t), b = c(t + lag):
    the correlation coefficient when both have equal variance, but blind to a residual linear
    trend, which only adds a constant to b - a) and the pooled numerator and denominator.
    """
    n = comp.shape[0]
    a = comp[: n - lag]
    b = comp[lag:]
    num = np.var(b - a, axis=0)
    den = np.var(a, axis=0) + np.var(b, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        sim = np.where(den > 0, 1.0 - num / den, 0.0)
    return sim, float(num.sum()), float(den.sum())


def _refine_lag(comp: np.ndarray, lag0: float, dt: float) -> float:
    """Period (s) near ``lag0`` samples minimising the pooled lagged difference, sub-sample.

    Integer lags only: white noise then adds the same floor to every lag, whereas interpolating
    the signal to fractional lags would make that floor ripple and bias the minimum. The minimum
    is refined by a parabola through its neighbours.
    """
    n = comp.shape[0]
    lo = max(1, int(np.floor(0.93 * lag0)) - 1)
    hi = min(n - 8, int(np.ceil(1.07 * lag0)) + 1)
    if hi - lo < 2:
        return lag0 * dt
    lags = np.arange(lo, hi + 1)
    d = np.array([_similarity(comp, int(L))[1] / _similarity(comp, int(L))[2] for L in lags])
    i = int(np.argmin(d))
    if 0 < i < lags.size - 1:
        denom = d[i - 1] - 2 * d[i] + d[i + 1]
        shift = 0.5 * (d[i - 1] - d[i + 1]) / denom if denom > 0 else 0.0
        return float((lags[i] + np.clip(shift, -0.5, 0.5)) * dt)
    return float(lags[i] * dt)


def estimate_period(t_s, xyz, *, f_range_hz: tuple[float, float] = (0.5, 3.0), max_harmonic: int = 4,
                    ) -> tuple[float, dict]:
    """Stride period of the marker tracks, found automatically.

    Parameters
    ----------
    t_s : ndarray of shape (F,)
        Strictly increasing sample times (s).
    xyz : ndarray of shape (F, M, 3)
        Marker positions in any fixed frame (e.g. rig mm); NaN in gaps. Each coordinate is
        detrended linearly (removing the travel) and the principal components of all coordinates
        of all markers are analysed together.
    f_range_hz : (float, float), optional
        Plausible stride frequencies (walk 0.85-0.95 Hz ... canter 1.6-1.7 Hz). The dominant line
        is searched up to ``max_harmonic`` times the upper bound; the stride must lie inside.
    max_harmonic : int, optional
        Largest sub-harmonic tried: the stride may be up to this many periods of the dominant line.

    Returns
    -------
    period_s : float
        The stride period.
    details : dict
        ``f_dominant_hz``, ``harmonic`` (stride period / dominant period), ``score`` (weighted
        autocorrelation at the stride period, 1 = perfectly periodic), ``candidates`` (list of
        dicts with ``harmonic``, ``period_s``, ``score``, ``correlations``), ``component_std``
        (amplitudes of the principal components used), ``spectrum_hz`` and ``spectrum_power``.

    Raises
    ------
    KinematicsError
        If the record is too short, markers are missing most of the time or no periodic motion
        is found.
    """
    t_s, xyz, f_lo, f_hi = _check_tracks(t_s, xyz, f_range_hz)
    duration_s = float(t_s[-1] - t_s[0])
    if duration_s < 2.0 / f_hi:
        raise KinematicsError(f"the ride lasts {duration_s:.2f} s, shorter than two periods even at the "
                              f"highest stride frequency considered ({f_hi:.2f} Hz)")
    comp, weights, dt = _principal_motions(t_s, xyz)
    nyquist = 0.5 / dt
    f_dom, freqs, power = _dominant_frequency(comp, dt, f_lo, min(max_harmonic * f_hi, 0.95 * nyquist))
    candidates = _candidate_periods(comp, weights, dt, f_dom, f_lo, f_hi, duration_s, max_harmonic)
    if not candidates:
        raise KinematicsError(
            f"the dominant motion frequency {f_dom:.2f} Hz has no sub-harmonic inside the stride range "
            f"{f_lo:.2f}-{f_hi:.2f} Hz that fits in the {duration_s:.2f} s ride; the ride may be too short")
    best = max(c["score"] for c in candidates)
    if best < _MIN_SCORE:
        raise KinematicsError(f"no periodic motion found in the marker tracks (best autocorrelation "
                              f"{best:.2f} at any candidate stride period)")
    chosen = next(c for c in candidates if c["score"] >= best - _SCORE_MARGIN)
    details = {
        "f_dominant_hz": f_dom,
        "harmonic": chosen["harmonic"],
        "score": chosen["score"],
        "candidates": candidates,
        "component_std": (weights / np.sqrt(comp.shape[0])).tolist(),
        "spectrum_hz": freqs,
        "spectrum_power": power,
    }
    return chosen["period_s"], details


def _check_tracks(t_s, xyz, f_range_hz) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Times (F,) and tracks (F, M, 3) as float arrays, and the stride band (Hz); InputError if bad."""
    xyz = np.asarray(xyz, dtype=np.float64)
    if xyz.ndim != 3 or xyz.shape[2] != 3:
        raise InputError(f"xyz must have shape (F, M, 3), got {xyz.shape}")
    t_s = np.asarray(t_s, dtype=np.float64)
    if t_s.shape != (xyz.shape[0],) or not np.all(np.isfinite(t_s)) or np.any(np.diff(t_s) <= 0):
        raise InputError(f"t_s must be {xyz.shape[0]} strictly increasing finite times, "
                         f"got shape {t_s.shape}")
    f_lo, f_hi = (float(f) for f in f_range_hz)
    if not 0 < f_lo < f_hi:
        raise InputError(f"f_range_hz must be (low, high) with 0 < low < high, got {f_range_hz}")
    return t_s, xyz, f_lo, f_hi


def _principal_motions(t_s: np.ndarray, xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The tracks' principal components on a uniform grid, with the travel removed.

    Returns the components (n, C) that count (at most six, each at least ``_COMPONENT_FRACTION`` of
    the largest), their singular values (C,) as weights, and the grid step dt (s).
    """
    t, signals = _uniform_signals(t_s, xyz)
    dt = float(t[1] - t[0])
    x = _detrend(signals, t)
    u, s, _ = np.linalg.svd(x, full_matrices=False)
    if s[0] <= 0:
        raise KinematicsError("the markers do not move relative to a straight line: no period to estimate")
    keep = s >= _COMPONENT_FRACTION * s[0]
    keep[6:] = False
    return u[:, keep] * s[keep], s[keep], dt


def _candidate_periods(comp: np.ndarray, weights: np.ndarray, dt: float, f_dom: float, f_lo: float,
                       f_hi: float, duration_s: float, max_harmonic: int) -> list[dict]:
    """The sub-harmonic periods m / f_dom inside the stride band, each refined and scored.

    Each candidate is a dict of ``harmonic`` (m), ``period_s``, ``score`` (weighted similarity of the
    components with themselves one period later) and ``correlations`` (per component).
    """
    candidates = []
    for m in range(1, max_harmonic + 1):
        period = m / f_dom
        if not f_lo <= 1.0 / period <= f_hi:
            continue
        if period > 0.7 * duration_s:
            continue  # too little overlap for a trustworthy comparison
        p_best = _refine_lag(comp, period / dt, dt)
        lag = int(round(p_best / dt))
        if lag >= comp.shape[0] - 8:
            continue
        corr = _similarity(comp, lag)[0]
        score = float(np.sum(weights * corr) / np.sum(weights))
        candidates.append({"harmonic": m, "period_s": p_best, "score": score,
                           "correlations": corr.tolist()})
    return candidates


def analysis_window(t_s, valid_mask, period_s: float, *, n_periods: int = 2,
                    max_invalid_fraction: float = 0.2) -> tuple[int, int]:
    """A whole number of periods of valid data to analyse.

    The window holds ``L = round(n_periods * period_s / dt)`` samples, so its duration ``L * dt``
    is ``n_periods`` periods to within half a frame (thesis: 36 frames = 2 x 18 at 30 fps). Sample
    ``stop`` (if it exists) is the position one whole window later, useful for eq. 5.7.

    Parameters
    ----------
    t_s : ndarray of shape (F,)
        Sample times (s), uniformly spaced.
    valid_mask : ndarray of bool, shape (F,)
        True where every marker needed is present.
    period_s : float
        The stride period.
    n_periods : int, optional
        Number of periods in the window (two, as the thesis).
    max_invalid_fraction : float, optional
        Largest fraction of invalid samples accepted in the window.

    Returns
    -------
    start_index, stop_index : int
        The window is ``slice(start_index, stop_index)``: the one with the fewest invalid
        samples, and among those the one closest to the middle of the ride.

    Raises
    ------
    KinematicsError
        If the ride is shorter than the window, or every window has too many invalid samples.
    """
    t_s = np.asarray(t_s, dtype=np.float64)
    valid = np.asarray(valid_mask, dtype=bool)
    if t_s.ndim != 1 or valid.shape != t_s.shape:
        raise InputError(f"t_s and valid_mask must be 1-D of equal length, got {t_s.shape} and {valid.shape}")
    if not np.isfinite(period_s) or period_s <= 0:
        raise InputError(f"period_s must be positive, got {period_s}")
    if n_periods < 1:
        raise InputError(f"n_periods must be at least 1, got {n_periods}")
    n = t_s.shape[0]
    if n < 2:
        raise KinematicsError("the ride has fewer than two samples")
    dt = float(np.median(np.diff(t_s)))
    length = int(round(n_periods * period_s / dt))
    if length > n:
        raise KinematicsError(
            f"the ride lasts {n * dt:.2f} s ({n} frames), shorter than {n_periods} periods of "
            f"{period_s:.3f} s ({n_periods * period_s:.2f} s); record a longer ride")
    invalid = np.concatenate([[0], np.cumsum(~valid)])
    counts = invalid[length:] - invalid[: n - length + 1]  # invalid samples in each window
    fewest = counts.min()
    if fewest > max_invalid_fraction * length:
        raise KinematicsError(
            f"markers are lost for most of the ride: every {n_periods}-period window has at least "
            f"{fewest} of {length} frames with a marker missing ({valid.mean():.0%} of the ride is valid)")
    starts = np.flatnonzero(counts == fewest)
    centre = 0.5 * (n - length)
    start = int(starts[np.argmin(np.abs(starts - centre))])
    return start, start + length

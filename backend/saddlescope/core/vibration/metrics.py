"""Metrics of weighted accelerations: r.m.s., peak, crest factor, VDV and MTVV (thesis 7.2).

Of a sampled record (:func:`sampled_metrics`, on its band-limited interpolation at the weighting's
internal rate) and, exactly, of a periodic acceleration given as a Fourier series
(:func:`harmonic_metrics`, each harmonic weighted with the complex response).
"""

from __future__ import annotations

import math

import numpy as np

from saddlescope.core.errors import VibrationError
from saddlescope.core.vibration.weighting import (
    _as_record,
    _check_rate,
    _weight_internal,
    _weighting_name,
    weighting_response,
)

__all__ = [
    "weighted_rms",
    "peak",
    "crest_factor",
    "vdv",
    "mtvv",
    "sampled_metrics",
    "harmonic_metrics",
]


def weighted_rms(aw) -> float:
    """Root mean square of a weighted acceleration record (eq. 7.3-7.4).

    Parameters
    ----------
    aw : array_like of shape (n,)
        Weighted acceleration samples (m/s^2).

    Returns
    -------
    float
        a_w,rms in m/s^2.
    """
    arr = _as_record(aw, "weighted acceleration")
    return float(np.sqrt(np.mean(arr**2)))


def peak(aw) -> float:
    """Largest absolute sample of a record (eq. 7.5-7.6).

    Parameters
    ----------
    aw : array_like of shape (n,)
        Weighted acceleration samples (m/s^2).

    Returns
    -------
    float
        The peak in m/s^2.
    """
    arr = _as_record(aw, "weighted acceleration")
    return float(np.max(np.abs(arr)))


def crest_factor(aw) -> float:
    """Weighted peak / weighted r.m.s. (eq. 7.7).

    Parameters
    ----------
    aw : array_like of shape (n,)
        Weighted acceleration samples (m/s^2).

    Returns
    -------
    float
        The crest factor; NaN for a silent record.
    """
    rms = weighted_rms(aw)
    return float(peak(aw) / rms) if rms > 0 else math.nan


def vdv(aw, fs_hz: float) -> float:
    """Vibration dose value (integral of aw^4 dt)^(1/4) over the record (eq. 7.8-7.9).

    Parameters
    ----------
    aw : array_like of shape (n,)
        Weighted acceleration samples (m/s^2).
    fs_hz : float
        Sampling rate (Hz).

    Returns
    -------
    float
        VDV in m/s^1.75.
    """
    arr = _as_record(aw, "weighted acceleration")
    if not (math.isfinite(fs_hz) and fs_hz > 0):
        raise VibrationError(f"sampling rate must be positive, got {fs_hz!r}")
    return float((np.sum(arr**4) / fs_hz) ** 0.25)


def mtvv(aw, fs_hz: float, *, window_s: float = 1.0, periodic: bool = False) -> float:
    """Maximum transient vibration value: the largest running r.m.s. (ISO 2631-1 6.3.1).

    Linear (rectangular) integration over ``window_s`` (1 s in ISO 2631-1).  With
    ``periodic=True`` the windows wrap around the record (a whole number of periods), so a
    record shorter than the window is allowed.

    Parameters
    ----------
    aw : array_like of shape (n,)
        Weighted acceleration samples (m/s^2).
    fs_hz : float
        Sampling rate (Hz).
    window_s : float, optional
        Length of the running window (s).
    periodic : bool, optional
        Whether the record is a whole number of periods (windows wrap around).

    Returns
    -------
    float
        MTVV in m/s^2.
    """
    arr = _as_record(aw, "weighted acceleration")
    if not (math.isfinite(fs_hz) and fs_hz > 0):
        raise VibrationError(f"sampling rate must be positive, got {fs_hz!r}")
    n_win = int(round(window_s * fs_hz))
    if n_win < 1:
        raise VibrationError(f"MTVV window {window_s} s is shorter than one sample")
    sq = arr**2
    if periodic:
        reps = math.ceil(n_win / sq.size) + 1
        sq = np.tile(sq, reps)[: arr.size + n_win - 1]
    elif arr.size < n_win:
        raise VibrationError(
            f"MTVV needs a record of at least {window_s} s; this one lasts {arr.size / fs_hz:.3f} s"
        )
    csum = np.concatenate([[0.0], np.cumsum(sq)])
    running = (csum[n_win:] - csum[:-n_win]) / n_win
    return float(np.sqrt(max(running.max(), 0.0)))


def sampled_metrics(a, fs_hz: float, weighting: str | None, *, transient: str = "periodic",
                    method: str = "iir") -> dict[str, float]:
    """Weighted r.m.s., peak, crest factor, VDV and MTVV of a sampled record.

    The metrics are evaluated on the weighted, band-limited interpolation of the record at
    the internal rate (>= 500 Hz), not on the raw samples: at 30 Hz sampling the samples miss
    the true peak and the fourth power in the VDV aliases, while the interpolation converges
    to the continuous-time values (see tests).

    Parameters
    ----------
    a : array_like of shape (n,)
        Acceleration (m/s^2) sampled at ``fs_hz``.
    fs_hz : float
        Sampling rate (>= 25 Hz).
    weighting : str or None
        Weighting name, or None / "none" for unweighted.
    transient, method
        As in :func:`weight_signal` ("none" is not accepted here).

    Returns
    -------
    dict
        ``rms`` (m/s^2), ``peak`` (m/s^2), ``crest_factor``, ``vdv`` (m/s^1.75),
        ``mtvv`` (m/s^2, 1 s running r.m.s.; wraps around for periodic records, NaN for
        non-periodic records shorter than 1 s), ``duration_s``.
    """
    arr = _as_record(a)
    _check_rate(fs_hz)
    canonical = _weighting_name(weighting)
    dense, factor = _weight_internal(arr, fs_hz, canonical, transient, method)
    fs_dense = fs_hz * factor
    duration_s = arr.size / fs_hz
    rms = float(np.sqrt(np.mean(dense**2)))
    pk = float(np.max(np.abs(dense)))
    periodic = transient == "periodic"
    try:
        running = mtvv(dense, fs_dense, periodic=periodic)
    except VibrationError:
        running = math.nan
    return {
        "rms": rms,
        "peak": pk,
        "crest_factor": pk / rms if rms > 0 else math.nan,
        "vdv": float((np.sum(dense**4) / fs_dense) ** 0.25),
        "mtvv": running,
        "duration_s": duration_s,
    }


# --------------------------------------------------------------------------------------------
# Periodic signals given as Fourier series


def _eval_series(t: np.ndarray, omega: np.ndarray, amp: np.ndarray, phase: np.ndarray,
                 derivative: int = 0) -> np.ndarray:
    """Sum_k amp_k d^n/dt^n cos(omega_k t + phase_k) at times t."""
    arg = np.outer(t, omega) + phase
    if derivative == 0:
        terms = np.cos(arg)
    elif derivative == 1:
        terms = -np.sin(arg) * omega
    else:
        terms = -np.cos(arg) * omega**2
    return terms @ amp


def _series_peak(omega: np.ndarray, amp: np.ndarray, phase: np.ndarray, period_s: float,
                 n_grid: int) -> float:
    """Max |a(t)| over one period: dense grid, then Newton on a'(t) = 0 at the best maxima."""
    t = np.arange(n_grid) * (period_s / n_grid)
    values = np.abs(_eval_series(t, omega, amp, phase))
    best = float(values.max())
    local = np.flatnonzero((values >= np.roll(values, 1)) & (values >= np.roll(values, -1)))
    candidates = local[np.argsort(values[local])[::-1][:4]]
    for idx in candidates:
        tk = np.array([t[idx]])
        for _ in range(8):
            d1 = _eval_series(tk, omega, amp, phase, 1)
            d2 = _eval_series(tk, omega, amp, phase, 2)
            if d2[0] == 0:
                break
            step = d1 / d2
            # Stay inside the grid cell: Newton from a grid maximum needs only a small step.
            step = np.clip(step, -period_s / n_grid, period_s / n_grid)
            tk = tk - step
            if abs(step[0]) < 1e-15 * period_s:
                break
        best = max(best, float(abs(_eval_series(tk, omega, amp, phase)[0])))
    return best


def harmonic_metrics(f0: float, amplitudes, phases, weighting: str | None,
                     duration_s: float) -> dict[str, float]:
    """Exact weighted metrics of a periodic acceleration given as a Fourier series.

    a(t) = sum_k A_k cos(2 pi k f0 t + phi_k), k = 1, 2, ...  Each harmonic is multiplied by
    the complex weighting response H(j 2 pi k f0), magnitude *and* phase (the thesis's eq.
    7.1-7.2 multiply by a scalar, which gets peak, crest factor and VDV wrong).

    Parameters
    ----------
    f0 : float
        Fundamental frequency in Hz.
    amplitudes : array_like of shape (K,)
        A_k in m/s^2 for k = 1..K.
    phases : array_like of shape (K,)
        phi_k in rad.
    weighting : str or None
        "Wb", "Wk", ... or None / "none" for the unweighted signal.
    duration_s : float
        Analysed duration tau; must be a whole number of periods 1/f0 (relative tolerance 1e-6).

    Returns
    -------
    dict
        ``rms`` (m/s^2), ``peak`` (m/s^2, max |a_w|), ``crest_factor``, ``vdv``
        (m/s^1.75, over duration_s), ``mtvv`` (m/s^2, largest 1 s running r.m.s. of the
        periodic signal), ``n_periods``.  The r.m.s. is exact (Parseval); the VDV
        integrates a_w^4 by the rectangle rule over 64 K samples per period, exact for the
        trigonometric polynomial a_w^4 of degree 4K; the peak is refined by Newton steps.
    """
    amp = np.atleast_1d(np.asarray(amplitudes, dtype=float))
    phase = np.atleast_1d(np.asarray(phases, dtype=float))
    if amp.ndim != 1 or amp.size == 0:
        raise VibrationError(f"amplitudes must be a non-empty 1-D sequence, got shape {amp.shape}")
    if phase.shape != amp.shape:
        raise VibrationError(
            f"phases must match amplitudes: {phase.size} phases for {amp.size} harmonics"
        )
    if not (np.all(np.isfinite(amp)) and np.all(np.isfinite(phase))):
        raise VibrationError("amplitudes and phases must be finite")
    if not (isinstance(f0, int | float | np.floating | np.integer) and math.isfinite(f0) and f0 > 0):
        raise VibrationError(f"fundamental frequency f0 must be a positive number of Hz, got {f0!r}")
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise VibrationError(f"duration_s must be positive, got {duration_s!r}")
    n_periods_exact = duration_s * f0
    n_periods = round(n_periods_exact)
    if n_periods < 1 or abs(n_periods_exact - n_periods) > 1e-6 * max(n_periods_exact, 1.0):
        raise VibrationError(
            f"duration {duration_s} s is not a whole number of periods of {1 / f0:.6g} s "
            f"(f0 = {f0} Hz gives {n_periods_exact:.6f} periods)"
        )
    canonical = _weighting_name(weighting)
    k = np.arange(1, amp.size + 1)
    if canonical is not None:
        h = weighting_response(canonical, k * f0)
        amp = amp * np.abs(h)
        phase = phase + np.angle(h)
    omega = 2 * np.pi * k * f0
    period_s = 1.0 / f0
    rms = float(np.sqrt(np.sum(amp**2) / 2))  # Parseval, no DC term
    n_grid = max(64 * amp.size, 256)
    t = np.arange(n_grid) * (period_s / n_grid)
    a_grid = _eval_series(t, omega, amp, phase)
    fourth_per_period = float(np.mean(a_grid**4) * period_s)
    pk = _series_peak(omega, amp, phase, period_s, n_grid)
    return {
        "rms": rms,
        "peak": pk,
        "crest_factor": pk / rms if rms > 0 else math.nan,
        "vdv": float((n_periods * fourth_per_period) ** 0.25),
        "mtvv": mtvv(a_grid, n_grid * f0, periodic=True),
        "n_periods": float(n_periods),
    }

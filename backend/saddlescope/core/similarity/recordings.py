"""Two recordings of a motion aligned in time and space before their shape is compared.

A lab's recordings of the same motion start at other moments, last other lengths, go at another pace
and are recorded in another frame. Resampling both over their own length (the former ``kabsch``
frame) compares a recording that starts later against the wrong part of the other, and the travel
along the track (metres) drowns the shape (millimetres). So, before any measure:

1. **Progression removed**: the markers' centroid's straight-line travel (a least-squares line per
   coordinate) is taken off every marker, which keeps the markers' places relative to each other.
2. **Periodic recordings** (a gait: the period found by :func:`saddlescope.core.kinematics.estimate_period`
   as for rides, at least two whole cycles in both) are cut into cycles from their first sample,
   each resampled to ``n_samples`` of cycle phase and averaged (a truncated Fourier series, as a
   ride's strides); the second mean cycle is shifted in phase and turned (Kabsch, all markers at
   once) to best match the first: ``alignment="cycle_phase"``.
3. **Other recordings** are aligned by open-begin / open-end (subsequence) DTW
   (dtaidistance): the shorter recording is searched in the longer, so a cropped or longer recording
   still finds its match; the rotation is refined on the matched stretch and the search repeated:
   ``alignment="subsequence_dtw"``.

:class:`AlignedRecordings` holds both on one time base (cycle phase or the shorter recording's
samples) and in one frame; every measure (DTW, chain codes, D') and the per-marker, per-stretch
differences (:func:`stretch_differences`) are computed on it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dtaidistance import dtw as dtai_dtw
from dtaidistance.subsequence.dtw import subsequence_alignment

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.kinematics import estimate_period
from saddlescope.core.similarity.canonical import DEFAULT_HARMONICS, kabsch_align, noise_of_track

__all__ = ["ALIGNMENTS", "AlignedRecordings", "RecordingSignature", "align_recordings", "align_signatures",
           "recording_signature", "remove_progression", "stretch_differences"]

ALIGNMENTS = ("cycle_phase", "subsequence_dtw")
# Samples of one mean cycle (cycle phase) or of the matched stretch.
RECORDING_SAMPLES = 128
# A recording is cut into cycles only when its period's autocorrelation reaches this (1 = periodic).
MIN_PERIODIC_SCORE = 0.6
# ... and it holds at least this many whole cycles.
MIN_CYCLES = 2
# The subsequence search runs at this many samples per second at most (speed).
SEARCH_RATE_HZ = 25.0
# dtaidistance's C code where its extension was built (else its Python code, slower, same answer).
_DTAI_C = getattr(dtai_dtw, "dtw_cc", None) is not None


@dataclass(frozen=True)
class AlignedRecordings:
    """Two recordings of the same markers on one time base and in one frame.

    Attributes
    ----------
    alignment : {"cycle_phase", "subsequence_dtw"}
        How they were aligned in time.
    a, b : ndarray of shape (n, M, 3)
        The compared curves (mm): the mean cycles (phase 0 at A's first sample) or the matched
        stretches, resampled to n samples; B turned and moved onto A.
    sigma_a, sigma_b : float
        Noise left in ``a`` and ``b`` (mm, per axis), for the chain codes' grid step.
    closed : bool
        True for cycles (each curve one closed loop).
    span_a_s, span_b_s : (float, float)
        The part of each recording compared, seconds from its first sample (the whole for cycles).
    period_s : (float, float) or None
        Each recording's cycle period (cycle phase only).
    cycles : (int, int) or None
        Whole cycles averaged in each (cycle phase only).
    phase_shift : float or None
        B's cycle shifted by this fraction of a cycle (cycle phase only).
    rotation_residual_mm : float
        RMS distance of the aligned curves after the rigid fit.
    """

    alignment: str
    a: np.ndarray
    b: np.ndarray
    sigma_a: float
    sigma_b: float
    closed: bool
    span_a_s: tuple[float, float]
    span_b_s: tuple[float, float]
    period_s: tuple[float, float] | None = None
    cycles: tuple[int, int] | None = None
    phase_shift: float | None = None
    rotation_residual_mm: float = 0.0


def remove_progression(xyz: np.ndarray) -> np.ndarray:
    """``xyz`` (N, M, 3) less the straight-line travel of its markers' centroid (mean kept at zero)."""
    centroid = xyz.mean(axis=1)
    n = xyz.shape[0]
    basis = np.column_stack([np.ones(n), np.arange(n) - (n - 1) / 2.0])
    coef, *_ = np.linalg.lstsq(basis, centroid, rcond=None)
    return xyz - (basis @ coef)[:, None, :]


def _period(x: np.ndarray, rate_hz: float, f_range_hz: tuple[float, float]) -> tuple[float, float] | None:
    """(period in samples, autocorrelation score), None where no period is found."""
    try:
        period_s, details = estimate_period(np.arange(x.shape[0]) / rate_hz, x, f_range_hz=f_range_hz)
    except (KinematicsError, InputError):
        return None
    return period_s * rate_hz, float(details["score"])


def _cycles(x: np.ndarray, period: float, n_samples: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Whole cycles (S, n, M, 3) from the first sample, their mean (n, M, 3) and their scatter.

    The mean is a truncated Fourier series; the scatter is the per-axis RMS of the cycles about it
    (noise plus what does not repeat).
    """
    n_cycles = int((x.shape[0] - 1) // period)
    tq = (np.arange(n_cycles)[:, None] * period + np.arange(n_samples)[None, :] * (period / n_samples)).ravel()
    cyc = _interp_rows(x, tq).reshape((n_cycles, n_samples) + x.shape[1:])
    spec = np.fft.rfft(cyc, axis=1)
    spec[:, DEFAULT_HARMONICS + 1:] = 0.0
    cyc = np.fft.irfft(spec, n=n_samples, axis=1)
    mean = cyc.mean(axis=0)
    sigma = float(np.sqrt(np.mean((cyc - mean) ** 2))) if n_cycles > 1 else 0.0
    return cyc, mean - mean.mean(axis=(0, 1)), sigma


# Shifts whose cross-covariance has the largest Frobenius norm, given the exact Kabsch score.
_PHASE_CANDIDATES = 8


def _best_phase_and_turn(a: np.ndarray, b: np.ndarray, up: int | None) -> tuple[int, np.ndarray, float]:
    """The cyclic shift s and rotation R that best map ``roll(b, -s)`` onto ``a`` (both (n, M, 3)).

    Every shift's cross-covariance at once (9 FFTs); both are centred. The Kabsch score (the sum of
    singular values, the smallest signed) is exact for the shifts of largest Frobenius norm, which
    bounds it within a factor sqrt(3): the best shift is among them in practice, and a pair costs
    a few SVDs instead of n.
    """
    n = a.shape[0]
    fa, fb = np.fft.rfft(a, axis=0), np.fft.rfft(b, axis=0)
    # h[s, i, j] = sum_t sum_m b[t + s, m, i] a[t, m, j]
    h = np.fft.irfft(np.einsum("fmi,fmj->fij", fb, np.conj(fa)), n=n, axis=0)
    if up is not None:
        i, j = [k for k in range(3) if k != up]
        s = int(np.argmax(np.hypot(h[:, i, j] - h[:, j, i], h[:, i, i] + h[:, j, j]) + h[:, up, up]))
        _, rot, residual = kabsch_align(a.reshape(-1, 3), np.roll(b, -s, axis=0).reshape(-1, 3), up=up)
        return s, rot, residual
    cand = np.argsort(-np.sum(h * h, axis=(1, 2)))[:_PHASE_CANDIDATES]
    u, sv, vt = np.linalg.svd(h[cand])
    d = np.sign(np.linalg.det(h[cand]))
    d[d == 0] = 1.0
    score = sv[:, 0] + sv[:, 1] + d * sv[:, 2]
    k = int(np.argmax(score))
    rot = vt[k].T @ np.diag([1.0, 1.0, d[k]]) @ u[k].T
    shift = int(cand[k])
    moved = np.roll(b, -shift, axis=0) @ rot.T
    return shift, rot, float(np.sqrt(np.mean(np.sum((moved - a) ** 2, axis=2))))


def _cycle_phase(cycles_a, cycles_b, periods, lengths, rates, up) -> AlignedRecordings:
    """Both mean cycles in one phase and frame: B's shifted and turned onto A's."""
    (cyc_a, mean_a, sig_a), (cyc_b, mean_b, sig_b) = cycles_a, cycles_b
    n_samples = mean_a.shape[0]
    shift, rot, residual = _best_phase_and_turn(mean_a, mean_b, up)
    mean_b = np.roll(mean_b, -shift, axis=0) @ rot.T
    return AlignedRecordings(
        alignment="cycle_phase", a=mean_a, b=mean_b - mean_b.mean(axis=(0, 1)),
        sigma_a=sig_a / np.sqrt(cyc_a.shape[0]), sigma_b=sig_b / np.sqrt(cyc_b.shape[0]), closed=True,
        span_a_s=(0.0, lengths[0] / rates[0]), span_b_s=(0.0, lengths[1] / rates[1]),
        period_s=(periods[0] / rates[0], periods[1] / rates[1]), cycles=(cyc_a.shape[0], cyc_b.shape[0]),
        phase_shift=shift / n_samples, rotation_residual_mm=residual)


def _interp_rows(x: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """``x`` (N, ...) linearly interpolated at the fractional sample indices ``tq`` (clipped to the ends)."""
    tq = np.clip(tq, 0.0, x.shape[0] - 1.0)
    i0 = np.minimum(np.floor(tq).astype(np.int64), x.shape[0] - 2)
    w = (tq - i0).reshape((-1,) + (1,) * (x.ndim - 1))
    return x[i0] * (1.0 - w) + x[i0 + 1] * w


def _resample(x: np.ndarray, n_out: int, start: float = 0.0, end: float | None = None) -> np.ndarray:
    """Samples ``start``..``end`` (fractional indices) of ``x`` (N, ...) resampled to ``n_out``."""
    end = x.shape[0] - 1.0 if end is None else end
    return _interp_rows(x, np.linspace(start, end, n_out))


def _refined_span(q: np.ndarray, s: np.ndarray, start: float, end: float, half_width: float, n_samples: int
                  ) -> tuple[float, float]:
    """The span of ``s`` near ``start``..``end`` whose resampling best fits ``q``'s, turned freely.

    Both are (N, M, 3) at full rate; start and end move by at most ``half_width`` samples (a 9 x 9
    grid). Every candidate, like ``q``, has its own travel removed and is scored by its Kabsch
    residual, all at once (batched 3 x 3 SVDs).
    """
    target = remove_progression(_resample(q, n_samples))
    offsets = np.linspace(-half_width, half_width, 9)
    st = np.clip(start + offsets[:, None] + 0.0 * offsets[None, :], 0.0, s.shape[0] - 1.0).ravel()
    en = np.clip(end + 0.0 * offsets[:, None] + offsets[None, :], 0.0, s.shape[0] - 1.0).ravel()
    ok = en - st >= 4  # the ends themselves are candidates
    st, en = st[ok], en[ok]
    frac = np.linspace(0.0, 1.0, n_samples)
    segs = _interp_rows(s, (st[:, None] + (en - st)[:, None] * frac[None, :]).ravel())
    segs = segs.reshape((st.size, n_samples) + s.shape[1:])
    # each candidate without its own straight-line travel, as the target (a walk's speed varies)
    basis = np.column_stack([np.ones(n_samples), frac - 0.5])
    trend = basis @ np.linalg.pinv(basis)  # (n, n): the least-squares line through a series
    segs = segs - np.matmul(trend, segs.mean(axis=2))[:, :, None, :]
    flat = segs.reshape(st.size, -1, 3)
    h = np.matmul(flat.transpose(0, 2, 1), target.reshape(-1, 3))  # (c, 3, 3) cross-covariances
    sv = np.linalg.svd(h, compute_uv=False)
    d = np.where(np.linalg.det(h) < 0, -1.0, 1.0)
    cost = np.sum(segs * segs, axis=(1, 2, 3)) - 2.0 * (sv[:, 0] + sv[:, 1] + d * sv[:, 2])
    k = int(np.argmin(cost))
    return float(st[k]), float(en[k])


def _subsequence(xa, xb, rates, up, n_samples) -> AlignedRecordings:
    """The shorter recording searched in the longer by subsequence DTW, rotation refined twice."""
    swap = xb.shape[0] / rates[1] < xa.shape[0] / rates[0]  # the shorter is searched in the longer
    (q, rq), (s, rs) = ((xa, rates[0]), (xb, rates[1])) if not swap else ((xb, rates[1]), (xa, rates[0]))
    step_q = max(1, int(rq / SEARCH_RATE_HZ))
    # one time base for the search: the series at the query's (decimated) rate
    q_small = q[::step_q]
    s_small = _resample(s, max(2, int(round((s.shape[0] - 1) * (rq / step_q) / rs)) + 1))
    coarse_q = _resample(q_small, 64)
    coarse_s = _resample(s_small, 64)
    _, rot_q, _ = kabsch_align(coarse_s.reshape(-1, 3), coarse_q.reshape(-1, 3), up=up)
    start, end = 0, s_small.shape[0] - 1
    for _ in range(2):
        qq = (q_small - q_small.mean(axis=(0, 1))) @ rot_q.T
        ss = s_small - s_small[start:end + 1].mean(axis=(0, 1))
        sa = subsequence_alignment(qq.reshape(qq.shape[0], -1), ss.reshape(ss.shape[0], -1), use_c=_DTAI_C)
        match = sa.best_match()
        start, end = int(match.segment[0]), int(match.segment[1])
        matched_q = _resample(q_small, 64)
        matched_s = _resample(s_small, 64, start, end)
        _, rot_q, _ = kabsch_align(matched_s.reshape(-1, 3), matched_q.reshape(-1, 3), up=up)
    scale = (s.shape[0] - 1) / max(1, s_small.shape[0] - 1)
    turned_q = (q - q.mean(axis=(0, 1))) @ rot_q.T
    st, en = _refined_span(turned_q, s, start * scale, end * scale, 1.5 * scale, n_samples)
    for width in (0.375 * scale, 0.1 * scale):  # to a fortieth of a coarse step
        st, en = _refined_span(turned_q, s, st, en, width, n_samples)
    # the travel again, over the same stretch of motion in both (a walk's speed is not constant)
    seg_q = remove_progression(_resample(q, n_samples))
    seg_s = remove_progression(_resample(s, n_samples, st, en))
    span_q = (0.0, (q.shape[0] - 1) / rq)
    span_s = (float(st / rs), float(en / rs))
    sig_q = max(noise_of_track(q[:, m]) for m in range(q.shape[1]))
    sig_s = max(noise_of_track(s[:, m]) for m in range(s.shape[1]))
    first, second, sig1, sig2, span1, span2 = ((seg_q, seg_s, sig_q, sig_s, span_q, span_s) if not swap
                                               else (seg_s, seg_q, sig_s, sig_q, span_s, span_q))
    first = first - first.mean(axis=(0, 1))
    moved, _, residual = kabsch_align(first.reshape(-1, 3), second.reshape(-1, 3), up=up)
    return AlignedRecordings(alignment="subsequence_dtw", a=first, b=moved.reshape(second.shape), sigma_a=sig1,
                             sigma_b=sig2, closed=False, span_a_s=span1, span_b_s=span2,
                             rotation_residual_mm=residual)


@dataclass(frozen=True)
class RecordingSignature:
    """What a recording brings to every comparison, computed once (ranking many reuses it).

    Attributes
    ----------
    x : ndarray of shape (N, M, 3)
        The positions (mm) without the progression.
    rate_hz : float
        Sampling rate.
    period : float or None
        Cycle period in samples where the recording is periodic with at least ``MIN_CYCLES``
        whole cycles, else None.
    cycles : tuple (ndarray (S, n, M, 3), ndarray (n, M, 3), float) or None
        Its cycles, mean cycle and scatter (:func:`_cycles`) where periodic.
    """

    x: np.ndarray
    rate_hz: float
    period: float | None
    cycles: tuple | None


def _check_recording(name: str, x: np.ndarray, rate: float) -> None:
    if x.ndim != 3 or x.shape[2] != 3:
        raise InputError(f"{name} must be (N, M, 3) marker positions, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise InputError(f"{name} has gaps (NaN positions); bridge them before comparing")
    if x.shape[0] < 8:
        raise InputError(f"{name} has {x.shape[0]} samples; at least 8 are needed")
    if not (np.isfinite(rate) and rate > 0):
        raise InputError(f"{name}: the sampling rate must be positive, got {rate}")


def recording_signature(xyz, rate_hz: float, *, n_samples: int = RECORDING_SAMPLES,
                        f_range_hz: tuple[float, float] = (0.5, 3.0), name: str = "the recording"
                        ) -> RecordingSignature:
    """A recording without its progression, with its cycles where it is periodic (module docstring)."""
    x = np.asarray(xyz, dtype=np.float64)
    _check_recording(name, x, rate_hz)
    x = remove_progression(x)
    found = _period(x, float(rate_hz), f_range_hz)
    if found is None or found[1] < MIN_PERIODIC_SCORE or x.shape[0] - 1 < MIN_CYCLES * found[0]:
        return RecordingSignature(x=x, rate_hz=float(rate_hz), period=None, cycles=None)
    return RecordingSignature(x=x, rate_hz=float(rate_hz), period=found[0], cycles=_cycles(x, found[0], n_samples))


def align_signatures(sig_a: RecordingSignature, sig_b: RecordingSignature, *, up: int | None = None,
                     n_samples: int = RECORDING_SAMPLES, alignment: str | None = None) -> AlignedRecordings:
    """:func:`align_recordings` on precomputed signatures.

    Both periodic: cycle phase. One periodic and the other at least one of its cycles long (in
    seconds; a cropped copy): the other is cut into cycles of the same duration and put in cycle
    phase too. Otherwise subsequence DTW.
    """
    if sig_a.x.shape[1] != sig_b.x.shape[1]:
        raise InputError(f"recording A has {sig_a.x.shape[1]} markers but recording B has {sig_b.x.shape[1]}")
    if alignment is not None and alignment not in ALIGNMENTS:
        raise InputError(f"unknown alignment {alignment!r}; choose one of {', '.join(ALIGNMENTS)}")
    rates = (sig_a.rate_hz, sig_b.rate_hz)
    if alignment != "subsequence_dtw":
        cyc_a, cyc_b, pa, pb = sig_a.cycles, sig_b.cycles, sig_a.period, sig_b.period
        if pa is not None and pb is not None and not 0.8 < (pa / rates[0]) / (pb / rates[1]) < 1.25:
            # one found a sub-harmonic (a trot's vertical beats twice a stride): the longer period is the
            # stride, used for the other too where it holds one
            if pa / rates[0] > pb / rates[1]:
                cyc_b, pb = None, None
            else:
                cyc_a, pa = None, None
        if cyc_a is not None and pa is not None and cyc_b is None and sig_b.x.shape[0] - 1 >= pa * rates[1] / rates[0]:
            pb = pa * rates[1] / rates[0]
            cyc_b = _cycles(sig_b.x, pb, n_samples)
        elif (cyc_b is not None and pb is not None and cyc_a is None
              and sig_a.x.shape[0] - 1 >= pb * rates[0] / rates[1]):
            pa = pb * rates[0] / rates[1]
            cyc_a = _cycles(sig_a.x, pa, n_samples)
        if cyc_a is not None and cyc_b is not None and cyc_a[1].shape[0] == cyc_b[1].shape[0] == n_samples:
            return _cycle_phase(cyc_a, cyc_b, (pa, pb), (sig_a.x.shape[0], sig_b.x.shape[0]), rates, up)
        if alignment == "cycle_phase":
            raise InputError("no cycle period was found in the recordings; they cannot be put in cycle phase")
    return _subsequence(sig_a.x, sig_b.x, rates, up, n_samples)


def align_recordings(xyz_a, rate_a_hz: float, xyz_b, rate_b_hz: float, *, up: int | None = None,
                     n_samples: int = RECORDING_SAMPLES, f_range_hz: tuple[float, float] = (0.5, 3.0),
                     alignment: str | None = None) -> AlignedRecordings:
    """Two recordings of the same markers aligned in time and space (see the module docstring).

    Parameters
    ----------
    xyz_a, xyz_b : ndarray of shape (N, M, 3), (K, M, 3)
        Gap-free marker positions (mm), the same markers in the same order.
    rate_a_hz, rate_b_hz : float
        Their sampling rates.
    up : {None, 0, 1, 2}, optional
        The vertical axis: B may then only be turned about it.
    n_samples : int, optional
        Samples of the compared curves.
    f_range_hz : (float, float), optional
        Plausible cycle frequencies.
    alignment : {None, "cycle_phase", "subsequence_dtw"}, optional
        Force one; None: cycle phase where the recordings are periodic, else subsequence DTW.

    Returns
    -------
    AlignedRecordings
    """
    if alignment is not None and alignment not in ALIGNMENTS:
        raise InputError(f"unknown alignment {alignment!r}; choose one of {', '.join(ALIGNMENTS)}")
    sig_a = recording_signature(xyz_a, rate_a_hz, n_samples=n_samples, f_range_hz=f_range_hz, name="recording A")
    sig_b = recording_signature(xyz_b, rate_b_hz, n_samples=n_samples, f_range_hz=f_range_hz, name="recording B")
    return align_signatures(sig_a, sig_b, up=up, n_samples=n_samples, alignment=alignment)


def stretch_differences(a: np.ndarray, b: np.ndarray, n_stretches: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Where two aligned motions differ: RMS distance per marker and per stretch of the time base.

    Parameters
    ----------
    a, b : ndarray of shape (n, M, 3)
        Curves on one time base and in one frame (:class:`AlignedRecordings`' ``a`` and ``b``, or two
        rides' phase-aligned mean strides).
    n_stretches : int, optional
        The time base is cut into this many equal stretches (of the cycle, or of the matched span).

    Returns
    -------
    per_stretch : ndarray of shape (M, n_stretches)
        RMS distance of each marker's curves over each stretch (units of the positions).
    per_marker : ndarray of shape (M,)
        RMS distance over the whole time base.
    """
    if a.shape != b.shape or a.ndim != 3 or a.shape[2] != 3:
        raise InputError(f"aligned curves must be two (n, M, 3) arrays of one shape, got {a.shape} and {b.shape}")
    if not 1 <= n_stretches <= a.shape[0]:
        raise InputError(f"n_stretches must be between 1 and {a.shape[0]}, got {n_stretches}")
    d2 = np.sum((a - b) ** 2, axis=2)  # (n, M)
    bins = np.array_split(np.arange(d2.shape[0]), n_stretches)
    per_stretch = np.stack([np.sqrt(d2[idx].mean(axis=0)) for idx in bins], axis=1)
    return per_stretch, np.sqrt(d2.mean(axis=0))

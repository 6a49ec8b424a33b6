"""Whole-body vibration: frequency weightings and exposure metrics (thesis chapter 7).

Weightings are the analog transfer functions of ISO 2631-1:1997 Annex A / ISO 8041 (and BS 6841
for W_b), built from their published parameters as a product of four stages (s = j 2 pi f,
omega_i = 2 pi f_i)::

    high-pass   Hh(s) = s^2 / (s^2 + sqrt(2) w1 s + w1^2)                     f1, Q = 1/sqrt(2)
    low-pass    Hl(s) = w2^2 / (s^2 + sqrt(2) w2 s + w2^2)                    f2, Q = 1/sqrt(2)
    transition  Ht(s) = (1 + s / w3) / (1 + s / (Q4 w4) + (s / w4)^2)          f3, f4, Q4
    step        Hs(s) = (s^2 + w5 / Q5 s + w5^2) / (s^2 + w6 / Q6 s + w6^2)   f5, Q5, f6, Q6
    H(s) = K Hh Hl Ht Hs

The step is written with monic polynomials, so it needs no extra factor: its gain is
(f5 / f6)^2 below f5 and 1 above f6 (W_k: 0.5 at 1 Hz, 1 at 8 Hz).  The other way of
writing it, (1 + s/(Q5 w5) + (s/w5)^2) / (1 + s/(Q6 w6) + (s/w6)^2), needs the factor
(f5 / f6)^2; multiplying the monic form by (f6 / f5)^2, or forgetting the factor on the
normalised form, doubles W_k at low frequency.  The result reproduces ISO 2631-1 Table 3 to
its printed precision when evaluated at the *nominal* one-third-octave frequencies (1.25,
1.6, 2, ... Hz); at the exact frequencies 10^(n/10) the printed W_k differs by up to 2.5 %
(tests/core/test_vibration.py).

Sampled signals are weighted by a digital filter (:func:`weighting_sos`, a least-squares
IIR design with the analog poles and zeros mapped exactly, z = exp(s T)), run at an internal
rate of at least 500 Hz on the band-limited interpolation of the record
(:func:`weight_signal`), so the weighted signal matches the analog response to better than
0.2 % (complex, magnitude and phase) from 0.5 Hz up to 0.8 times the Nyquist frequency of
the record at any rate from 25 Hz up.  Metrics: weighted r.m.s., peak, crest factor, VDV,
MTVV, A(8), and times and distances to the EU 2002/44/EC action and limit values.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy import signal

from saddlescope.core.errors import VibrationError

__all__ = [
    "A8_ACTION_M_S2",
    "A8_LIMIT_M_S2",
    "VDV_ACTION_M_S175",
    "VDV_LIMIT_M_S175",
    "HORIZONTAL_FACTOR",
    "WEIGHTINGS",
    "WeightingParameters",
    "weighting_response",
    "weighting_sos",
    "digital_band_hz",
    "weight_signal",
    "harmonic_metrics",
    "weighted_rms",
    "peak",
    "crest_factor",
    "vdv",
    "mtvv",
    "a8",
    "sampled_metrics",
    "exposure_limits",
    "per_axis_exposure",
]

# EU Physical Agents (Vibration) Directive 2002/44/EC, whole-body (thesis Table 7.2).
A8_ACTION_M_S2 = 0.5
A8_LIMIT_M_S2 = 1.15
VDV_ACTION_M_S175 = 9.1
VDV_LIMIT_M_S175 = 21.0
# Directive and ISO 2631-1 health factor k for the horizontal axes of a seated person.
HORIZONTAL_FACTOR = 1.4
_REFERENCE_DAY_H = 8.0

_INTERNAL_RATE_HZ = 500.0  # rate at which weight_signal runs its IIR filters
_NUMERATOR_ORDER = 8  # free numerator order of the least-squares design
_OUT_OF_BAND_WEIGHT = 0.01  # keeps the gain between the fitted band and Nyquist near 1


@dataclass(frozen=True)
class WeightingParameters:
    """Parameters of one ISO 8041 / ISO 2631-1 Annex A weighting (frequencies in Hz).

    ``math.inf`` marks an absent stage: f3 = inf removes the transition zero, f4 = inf the
    whole transition, f5 = f6 = inf the upward step.
    """

    f1: float
    f2: float
    f3: float
    f4: float
    q4: float
    f5: float
    q5: float
    f6: float
    q6: float
    k: float
    description: str


_INF = math.inf
WEIGHTINGS: dict[str, WeightingParameters] = {
    # ISO 8041 / BS 6841, vertical seated (thesis: W_b).
    "Wb": WeightingParameters(0.4, 100.0, 16.0, 16.0, 0.55, 2.5, 0.90, 4.0, 0.95, 1.024,
                              "BS 6841 vertical, seated"),
    # ISO 2631-1 Table A.1 (additional weightings).
    "Wc": WeightingParameters(0.4, 100.0, 8.0, 8.0, 0.63, _INF, 1.0, _INF, 1.0, 1.0,
                              "ISO 2631-1 seat-back, fore-aft"),
    "Wd": WeightingParameters(0.4, 100.0, 2.0, 2.0, 0.63, _INF, 1.0, _INF, 1.0, 1.0,
                              "ISO 2631-1 horizontal (x, y)"),
    "We": WeightingParameters(0.4, 100.0, 1.0, 1.0, 0.63, _INF, 1.0, _INF, 1.0, 1.0,
                              "ISO 2631-1 rotational (roll, pitch, yaw)"),
    "Wf": WeightingParameters(0.08, 0.63, _INF, 0.25, 0.86, 0.0625, 0.80, 0.10, 0.80, 1.0,
                              "ISO 2631-1 vertical, motion sickness"),
    "Wj": WeightingParameters(0.4, 100.0, _INF, _INF, 1.0, 3.75, 0.91, 5.32, 0.91, 1.0,
                              "ISO 2631-1 vertical, head (recumbent)"),
    "Wk": WeightingParameters(0.4, 100.0, 12.5, 12.5, 0.63, 2.37, 0.91, 3.35, 0.91, 1.0,
                              "ISO 2631-1 vertical (z)"),
}
_ALIASES = {name.lower(): name for name in WEIGHTINGS} | {
    f"w_{name[1].lower()}": name for name in WEIGHTINGS
}


def _weighting_name(name: str | None) -> str | None:
    """Canonical weighting name ("Wk") or None for unweighted; raise on anything else."""
    if name is None:
        return None
    if not isinstance(name, str):
        raise VibrationError(f"weighting must be a name such as 'Wk', got {name!r}")
    key = name.strip().lower()
    if key in {"none", "", "unweighted"}:
        return None
    if key not in _ALIASES:
        raise VibrationError(
            f"unknown frequency weighting {name!r}; expected one of {', '.join(WEIGHTINGS)} or 'none'"
        )
    return _ALIASES[key]


def _analog_stages(name: str) -> tuple[list[np.ndarray], list[np.ndarray], float]:
    """Numerator and denominator polynomials (in s, highest power first) of each stage."""
    par = WEIGHTINGS[name]
    w1, w2 = 2 * np.pi * par.f1, 2 * np.pi * par.f2
    nums = [np.array([1.0, 0.0, 0.0]), np.array([w2**2])]
    dens = [np.array([1.0, np.sqrt(2) * w1, w1**2]), np.array([1.0, np.sqrt(2) * w2, w2**2])]
    if math.isfinite(par.f4):
        w4 = 2 * np.pi * par.f4
        # (1 + s/w3) w4^2 / (s^2 + w4/Q4 s + w4^2): unit gain at DC.
        if math.isfinite(par.f3):
            w3 = 2 * np.pi * par.f3
            nums.append(np.array([w4**2 / w3, w4**2]))
        else:
            nums.append(np.array([w4**2]))
        dens.append(np.array([1.0, w4 / par.q4, w4**2]))
    if math.isfinite(par.f5):
        w5, w6 = 2 * np.pi * par.f5, 2 * np.pi * par.f6
        # Monic form: gain (f5/f6)^2 at DC, 1 at high frequency; no extra factor.
        nums.append(np.array([1.0, w5 / par.q5, w5**2]))
        dens.append(np.array([1.0, w6 / par.q6, w6**2]))
    return nums, dens, par.k


def weighting_response(name: str, f) -> np.ndarray:
    """Complex frequency response H(j 2 pi f) of a frequency weighting.

    Parameters
    ----------
    name : str
        One of "Wb", "Wc", "Wd", "We", "Wf", "Wj", "Wk" (case-insensitive, "W_k" also accepted).
    f : float or array_like of shape (...)
        Frequencies in Hz (>= 0).

    Returns
    -------
    ndarray of complex, shape of ``f``
        ``abs()`` is the weighting factor (ISO 2631-1 Tables 3 and 4), ``angle()`` its phase.
    """
    canonical = _weighting_name(name)
    if canonical is None:
        raise VibrationError("weighting_response needs a weighting name, not 'none'")
    f_hz = np.asarray(f, dtype=float)
    if not np.all(np.isfinite(f_hz)) or np.any(f_hz < 0):
        raise VibrationError("weighting_response: frequencies must be finite and >= 0 Hz")
    s = 2j * np.pi * f_hz
    nums, dens, gain = _analog_stages(canonical)
    h = np.full(f_hz.shape, gain, dtype=complex)
    for num, den in zip(nums, dens, strict=True):
        h = h * np.polyval(num, s) / np.polyval(den, s)
    return h


def _significant_band_hz(name: str) -> tuple[float, float]:
    """Frequencies where |H| is at least 1e-3 of its maximum: where relative error matters."""
    f = np.logspace(-3, 3.5, 1301)
    mag = np.abs(weighting_response(name, f))
    inside = f[mag >= 1e-3 * mag.max()]
    return float(inside[0]), float(inside[-1])


def digital_band_hz(name: str, fs_hz: float) -> tuple[float, float]:
    """Band in which the causal filter of :func:`weighting_sos` follows the analog response.

    Within it the complex response (magnitude and phase) of ``weighting_sos(name, fs_hz)`` is
    within 2 % of :func:`weighting_response` for W_b, W_c, W_d, W_e, W_j, W_k from 0.5 Hz
    (W_f from 0.02 Hz).  The upper end is a quarter of the sampling rate (half the Nyquist
    frequency): a causal low-order IIR at the sampling rate itself cannot follow the phase of
    the analog response closer to Nyquist, where any real digital filter becomes real-valued.
    At 30 Hz sampling that is 7.5 Hz, at 60 Hz 15 Hz, at 120 Hz 30 Hz.  :func:`weight_signal`
    does better (up to 0.8 fs/2) by filtering at an internal rate.

    Returns
    -------
    (low_hz, high_hz) : tuple of float
    """
    canonical = _weighting_name(name)
    if canonical is None:
        raise VibrationError("digital_band_hz needs a weighting name, not 'none'")
    _check_rate(fs_hz)
    lo, hi = _significant_band_hz(canonical)
    return max(lo, 1e-4 * fs_hz), min(hi, 0.25 * fs_hz)


def _check_rate(fs_hz: float) -> None:
    if not (isinstance(fs_hz, int | float | np.floating | np.integer) and math.isfinite(fs_hz)):
        raise VibrationError(f"sampling rate must be a finite number of Hz, got {fs_hz!r}")
    if fs_hz < 25.0:
        raise VibrationError(
            f"sampling rate {fs_hz} Hz is too low for whole-body vibration weighting (need >= 25 Hz)"
        )


@functools.lru_cache(maxsize=64)
def _design(name: str, fs_hz: float) -> np.ndarray:
    """Least-squares IIR design; see :func:`weighting_sos`."""
    nums, dens, _ = _analog_stages(name)
    poles_s = np.concatenate([np.roots(d) for d in dens])
    zeros_s = np.concatenate([np.roots(n) for n in nums if len(n) > 1])
    at_dc = np.abs(zeros_s) < 1e-9
    n_dc = int(at_dc.sum())
    zeros_s = zeros_s[~at_dc]
    # Poles and zeros well below Nyquist map exactly (z = exp(sT), the sampled modes); those
    # near or above it are left to the fitted numerator.
    cut_rad_s = 2 * np.pi * 0.25 * fs_hz
    poles_z = np.exp(poles_s[np.abs(poles_s) < cut_rad_s] / fs_hz)
    zeros_z = np.concatenate([np.ones(n_dc), np.exp(zeros_s[np.abs(zeros_s) < cut_rad_s] / fs_hz)])

    lo, hi = digital_band_hz(name, fs_hz)
    f_fit = np.logspace(np.log10(lo), np.log10(hi), 400)
    f_out = np.linspace(hi, fs_hz / 2, 60)[1:]

    def fixed_part(f):
        zinv = np.exp(-2j * np.pi * f / fs_hz)
        num = np.prod(1 - np.outer(zinv, zeros_z), axis=1)
        den = np.prod(1 - np.outer(zinv, poles_z), axis=1)
        return num / den, zinv[:, None] ** np.arange(_NUMERATOR_ORDER + 1)[None, :]

    # Relative complex error fixed * C(z) / H - 1 is linear in the coefficients of C.
    fixed_in, basis_in = fixed_part(f_fit)
    rows_in = (fixed_in / weighting_response(name, f_fit))[:, None] * basis_in
    fixed_out, basis_out = fixed_part(f_out)
    rows_out = _OUT_OF_BAND_WEIGHT * fixed_out[:, None] * basis_out
    lhs = np.vstack([rows_in.real, rows_in.imag, rows_out.real, rows_out.imag])
    rhs = np.concatenate([np.ones(len(f_fit)), np.zeros(len(f_fit) + 2 * len(f_out))])
    coef, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)

    zeros = np.concatenate([zeros_z, np.roots(coef)])
    poles = np.concatenate([poles_z, np.zeros(max(len(zeros) - len(poles_z), 0))])
    zeros = np.concatenate([zeros, np.zeros(max(len(poles) - len(zeros), 0))])
    if np.any(np.abs(poles) >= 1):  # cannot happen for stable analog poles; cheap to check
        raise VibrationError(f"digital {name} filter at {fs_hz} Hz came out unstable")
    sos = signal.zpk2sos(zeros, poles, coef[0])
    sos.setflags(write=False)
    return sos


def weighting_sos(name: str, fs_hz: float) -> np.ndarray:
    """Causal digital (IIR) realisation of a weighting at sampling rate ``fs_hz``.

    The analog poles and zeros below fs/4 are mapped exactly (z = exp(s / fs), so the
    filter's slow modes are the sampled analog modes and its DC zeros stay at z = 1), and a
    numerator of order 8 is fitted by linear least squares to the relative complex error
    over :func:`digital_band_hz`, with a small penalty keeping the gain near 1 above it.
    Accuracy (complex, tested): within 2 % in ``digital_band_hz(name, fs_hz)``; below 0.1 %
    from 0.5 Hz to 60 Hz at 500 Hz and above.

    Parameters
    ----------
    name : str
        Weighting name ("Wk", "Wb", ...).
    fs_hz : float
        Sampling rate in Hz, >= 25.

    Returns
    -------
    sos : ndarray of shape (n_sections, 6)
        Second-order sections for :func:`scipy.signal.sosfilt` (a copy of a cached design).
    """
    canonical = _weighting_name(name)
    if canonical is None:
        raise VibrationError("weighting_sos needs a weighting name, not 'none'")
    _check_rate(fs_hz)
    return _design(canonical, float(fs_hz)).copy()


def _periodic_steady_state(sos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Filter one period of a periodic input as if it had been repeated forever.

    The state after one period is affine in the initial state, z1 = Phi z0 + c; the periodic
    steady state solves z = Phi z + c exactly, however slow the filter's modes are.
    """
    n_sections = sos.shape[0]
    zero_state = np.zeros((n_sections, 2))
    _, c = signal.sosfilt(sos, x, zi=zero_state)
    n_states = 2 * n_sections
    phi = np.empty((n_states, n_states))
    silence = np.zeros_like(x)
    for j in range(n_states):
        unit = np.zeros(n_states)
        unit[j] = 1.0
        _, zf = signal.sosfilt(sos, silence, zi=unit.reshape(n_sections, 2))
        phi[:, j] = zf.ravel()
    try:
        z_ss = np.linalg.solve(np.eye(n_states) - phi, c.ravel())
    except np.linalg.LinAlgError as exc:
        raise VibrationError("periodic steady state of the weighting filter is singular") from exc
    y, _ = signal.sosfilt(sos, x, zi=z_ss.reshape(n_sections, 2))
    return y


def _upsample_factor(fs_hz: float) -> int:
    return max(2, math.ceil(_INTERNAL_RATE_HZ / fs_hz))


def _as_record(a, what: str = "acceleration") -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.ndim != 1:
        raise VibrationError(f"{what} must be a 1-D array of samples, got shape {arr.shape}")
    if arr.size < 4:
        raise VibrationError(f"{what} has {arr.size} samples; need at least 4")
    if not np.all(np.isfinite(arr)):
        raise VibrationError(f"{what} contains NaN or infinite samples")
    return arr


def _weight_internal(a: np.ndarray, fs_hz: float, name: str | None, transient: str,
                     method: str) -> tuple[np.ndarray, int]:
    """Weighted signal at the internal rate fs * L, and L."""
    if transient not in {"periodic", "pad"}:
        raise VibrationError(f"transient must be 'periodic' or 'pad' here, got {transient!r}")
    n = a.size
    # 'pad': extend by the mirror image, so the extension is periodic without a jump.
    record = a if transient == "periodic" else np.concatenate([a, a[::-1]])
    factor = _upsample_factor(fs_hz)
    if method == "fft" or name is None:
        weighted = record
        if name is not None:
            freqs = np.fft.rfftfreq(record.size, 1 / fs_hz)
            weighted = np.fft.irfft(np.fft.rfft(record) * weighting_response(name, freqs), record.size)
        dense = signal.resample(weighted, record.size * factor)
    elif method == "iir":
        # Band-limited (periodic) interpolation, then the IIR at the internal rate.
        dense = signal.resample(record, record.size * factor)
        dense = _periodic_steady_state(weighting_sos(name, fs_hz * factor), dense)
    else:
        raise VibrationError(f"method must be 'iir' or 'fft', got {method!r}")
    return dense[: n * factor], factor


def weight_signal(a, fs_hz: float, name: str, *, transient: str = "periodic",
                  method: str = "iir") -> np.ndarray:
    """Frequency-weighted version of a sampled acceleration record.

    Parameters
    ----------
    a : array_like of shape (n,)
        Acceleration samples (m/s^2) at ``fs_hz``.
    fs_hz : float
        Sampling rate, >= 25 Hz.
    name : str
        Weighting ("Wk", "Wb", "Wd", ...); "none" returns the record unchanged.
    transient : {"periodic", "pad", "none"}
        How the filter's start-up transient is handled.  "periodic": the record is a whole
        number of periods (the thesis's analysed window), so the output is the periodic
        steady state, as if the record had been repeated forever.  "pad": the record is
        preceded and followed by its mirror image (no jump in value) and filtered to steady
        state on that extension; use it for records that are not periodic.  "none": a plain
        causal filter started at rest at the record's own rate (what a simple vibration meter
        does); the first 1-3 s are then wrong, which is why it is never the default.
    method : {"iir", "fft"}
        "iir": band-limited interpolation to an internal rate >= 500 Hz, the
        :func:`weighting_sos` IIR there, decimation back.  "fft": multiply the spectrum of the
        (periodic or mirror-extended) record by the analog response, exact for band-limited
        periodic records.  Both agree within 0.2 % from 0.5 Hz to 0.8 fs/2.

    Returns
    -------
    ndarray of shape (n,)
        Weighted acceleration at ``fs_hz``.
    """
    arr = _as_record(a)
    _check_rate(fs_hz)
    canonical = _weighting_name(name)
    if canonical is None:
        return arr.copy()
    if transient == "none":
        return signal.sosfilt(weighting_sos(canonical, fs_hz), arr)
    dense, factor = _weight_internal(arr, fs_hz, canonical, transient, method)
    return dense[::factor].copy()


# --------------------------------------------------------------------------------------------
# Metrics of weighted signals


def weighted_rms(aw) -> float:
    """Root mean square of a weighted acceleration record (eq. 7.3-7.4), m/s^2."""
    arr = _as_record(aw, "weighted acceleration")
    return float(np.sqrt(np.mean(arr**2)))


def peak(aw) -> float:
    """Largest absolute sample of a record (eq. 7.5-7.6), m/s^2."""
    arr = _as_record(aw, "weighted acceleration")
    return float(np.max(np.abs(arr)))


def crest_factor(aw) -> float:
    """Weighted peak / weighted r.m.s. (eq. 7.7); NaN for a silent record."""
    rms = weighted_rms(aw)
    return float(peak(aw) / rms) if rms > 0 else math.nan


def vdv(aw, fs_hz: float) -> float:
    """Vibration dose value (integral of aw^4 dt)^(1/4) over the record (eq. 7.8-7.9), m/s^1.75."""
    arr = _as_record(aw, "weighted acceleration")
    if not (math.isfinite(fs_hz) and fs_hz > 0):
        raise VibrationError(f"sampling rate must be positive, got {fs_hz!r}")
    return float((np.sum(arr**4) / fs_hz) ** 0.25)


def mtvv(aw, fs_hz: float, *, window_s: float = 1.0, periodic: bool = False) -> float:
    """Maximum transient vibration value: the largest running r.m.s. (ISO 2631-1 6.3.1).

    Linear (rectangular) integration over ``window_s`` (1 s in ISO 2631-1).  With
    ``periodic=True`` the windows wrap around the record (a whole number of periods), so a
    record shorter than the window is allowed.

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


def a8(rms: float, exposure_h: float) -> float:
    """Daily exposure A(8) = a_w,rms sqrt(T / 8 h) for ``exposure_h`` hours a day, m/s^2."""
    _check_non_negative(rms=rms, exposure_h=exposure_h)
    return float(rms * math.sqrt(exposure_h / _REFERENCE_DAY_H))


def _check_non_negative(**values: float) -> None:
    for key, value in values.items():
        if not isinstance(value, int | float | np.floating | np.integer) or not math.isfinite(value):
            raise VibrationError(f"{key} must be a finite number, got {value!r}")
        if value < 0:
            raise VibrationError(f"{key} must be >= 0, got {value}")


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


# --------------------------------------------------------------------------------------------
# Exposure


def exposure_limits(rms: float, vdv: float, duration_s: float, speed_kmh: float) -> dict[str, float]:
    """Times and distances to the EU 2002/44/EC whole-body action and limit values.

    T_A(8) = 8 h (A8_threshold / a_w,rms)^2                      (eq. 7.10-7.13)
    T_VDV  = tau (VDV_threshold / VDV)^4                           (eq. 7.14-7.17, corrected:
             VDV grows with the fourth root of time; the thesis prints a linear ratio and uses
             the action value for the limit)
    D      = v_x,avg T                                             (eq. 7.18-7.25)

    Parameters
    ----------
    rms : float
        Weighted r.m.s. acceleration a_w,rms (m/s^2) over the analysed window.
    vdv : float
        VDV (m/s^1.75) of the analysed window.
    duration_s : float
        Duration tau of the analysed window (s) that produced ``vdv``.
    speed_kmh : float
        Average speed in the direction of travel (km/h).

    Returns
    -------
    dict
        ``t_a8_action_h``, ``t_a8_limit_h``, ``t_vdv_action_h``, ``t_vdv_limit_h`` (hours) and
        ``d_a8_action_km``, ``d_a8_limit_km``, ``d_vdv_action_km``, ``d_vdv_limit_km`` (km).
        Zero vibration gives infinite times.
    """
    _check_non_negative(rms=rms, vdv=vdv, duration_s=duration_s, speed_kmh=speed_kmh)
    if duration_s == 0:
        raise VibrationError("duration_s must be > 0 to scale a VDV to a daily exposure")

    def a8_time(threshold: float) -> float:
        return _REFERENCE_DAY_H * (threshold / rms) ** 2 if rms > 0 else math.inf

    def vdv_time(threshold: float) -> float:
        return duration_s * (threshold / vdv) ** 4 / 3600.0 if vdv > 0 else math.inf

    times = {
        "t_a8_action_h": a8_time(A8_ACTION_M_S2),
        "t_a8_limit_h": a8_time(A8_LIMIT_M_S2),
        "t_vdv_action_h": vdv_time(VDV_ACTION_M_S175),
        "t_vdv_limit_h": vdv_time(VDV_LIMIT_M_S175),
    }
    out = dict(times)
    for key, hours in times.items():
        out["d" + key[1:-2] + "_km"] = speed_kmh * hours if speed_kmh > 0 else 0.0
    return out


def per_axis_exposure(rms_by_axis: Mapping[str, float], vdv_by_axis: Mapping[str, float],
                      duration_s: float, speed_kmh: float, *, vertical_axis: str = "y",
                      horizontal_factor: float = HORIZONTAL_FACTOR) -> dict:
    """Exposure from several axes with the directive's worst-axis rule.

    2002/44/EC (Annex, B.1) and ISO 2631-1 (7.2.3): the daily exposure is the highest of
    1.4 a_wx, 1.4 a_wy, a_wz for a seated person (x, y horizontal with W_d, z vertical with
    W_k); the same for the VDV.  In the thesis's motion frame the vertical axis is y.

    Parameters
    ----------
    rms_by_axis, vdv_by_axis : mapping of axis name -> float
        Weighted r.m.s. (m/s^2) and VDV (m/s^1.75) per axis, same axes in both.
    duration_s, speed_kmh : float
        As in :func:`exposure_limits`.
    vertical_axis : str
        Axis that takes factor 1; every other axis takes ``horizontal_factor``.

    Returns
    -------
    dict
        ``rms_effective`` and ``vdv_effective`` (axis -> value after the factor),
        ``worst_axis_a8``, ``worst_axis_vdv`` (axis names), ``rms``, ``vdv`` (the worst
        effective values) and the eight keys of :func:`exposure_limits` computed from them.
    """
    if set(rms_by_axis) != set(vdv_by_axis) or not rms_by_axis:
        raise VibrationError(
            f"per-axis r.m.s. and VDV must name the same axes, got {sorted(rms_by_axis)} and "
            f"{sorted(vdv_by_axis)}"
        )
    if vertical_axis not in rms_by_axis:
        raise VibrationError(f"vertical axis {vertical_axis!r} is not among {sorted(rms_by_axis)}")
    factors = {axis: 1.0 if axis == vertical_axis else horizontal_factor for axis in rms_by_axis}
    for axis in rms_by_axis:
        _check_non_negative(**{f"rms_{axis}": rms_by_axis[axis], f"vdv_{axis}": vdv_by_axis[axis]})
    rms_eff = {axis: factors[axis] * float(rms_by_axis[axis]) for axis in rms_by_axis}
    vdv_eff = {axis: factors[axis] * float(vdv_by_axis[axis]) for axis in vdv_by_axis}
    worst_a8 = max(rms_eff, key=rms_eff.__getitem__)
    worst_vdv = max(vdv_eff, key=vdv_eff.__getitem__)
    out: dict = {
        "rms_effective": rms_eff,
        "vdv_effective": vdv_eff,
        "worst_axis_a8": worst_a8,
        "worst_axis_vdv": worst_vdv,
        "rms": rms_eff[worst_a8],
        "vdv": vdv_eff[worst_vdv],
    }
    out.update(exposure_limits(rms_eff[worst_a8], vdv_eff[worst_vdv], duration_s, speed_kmh))
    return out


"""Whole-body vibration: the frequency weightings and their digital filters (thesis chapter 7).

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
(tests/core/vibration/test_vibration.py).

Sampled signals are weighted by a digital filter (:func:`weighting_sos`, a least-squares
IIR design with the analog poles and zeros mapped exactly, z = exp(s T)), run at an internal
rate of at least 500 Hz on the band-limited interpolation of the record
(:func:`weight_signal`), so the weighted signal matches the analog response to better than
0.2 % (complex, magnitude and phase) from 0.5 Hz up to 0.8 times the Nyquist frequency of
the record at any rate from 25 Hz up.  The metrics of weighted signals are in
:mod:`saddlescope.core.vibration.metrics`, the exposure limits in
:mod:`saddlescope.core.vibration.exposure`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from saddlescope.core.errors import VibrationError

__all__ = [
    "WEIGHTINGS",
    "WeightingParameters",
    "weighting_response",
    "weighting_sos",
    "digital_band_hz",
    "weight_signal",
]

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

    Parameters
    ----------
    name : str
        Weighting name ("Wk", "Wb", ...).
    fs_hz : float
        Sampling rate in Hz, >= 25.

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

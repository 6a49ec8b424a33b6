"""Canonical frames: what is compared once frame, speed, start and noise are taken out.

Two recordings of the same motion differ in where they were recorded from, how fast the horse went
and when the recording started; their noise differs too. Before any chain code or DTW both are
brought into one canonical frame:

- **rides** (``frame="motion+stride_phase"``): the tracks are already in the motion frame of the
  result (x travel, y down, z = x cross y); the travel (a straight line per coordinate) and the mean
  are removed, and every stride is resampled to ``n_samples`` samples of stride phase, so speed and
  stride rate drop out (:func:`ride_strides`). The mean stride's start phase is aligned to the other
  ride's by circular cross-correlation with a sub-sample (Fourier) shift (:func:`align_phase`).
- **generic motion capture** (``frame="kabsch"``): each recording is resampled to ``n_samples``
  samples over its length (:func:`time_normalise`) and the second is rigidly aligned to the first
  (Kabsch, :func:`kabsch_align`), whose residual is reported.

The grid step of the chain codes follows a stated rule from the measured noise
(:func:`noise_step`): ``step = max(extent / 50, 4 sigma)``; for rides sigma is the per-axis RMS of
the strides about their mean stride (noise plus what does not repeat from stride to stride), which
does not depend on how many strides were recorded; for generic recordings it is the white noise
measured from second differences, reduced by the averaging of the time normalisation. A curve
whose extent stays under one step in every axis makes no step of the anchored walk: it is
reported as "no motion", not as a chain of noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.kinematics import estimate_period
from saddlescope.core.similarity.chain_code import DEFAULT_CELLS, _as_trajectory

__all__ = [
    "DEFAULT_STRIDE_SAMPLES",
    "DEFAULT_HARMONICS",
    "NOISE_STEPS",
    "RideStrides",
    "ride_strides",
    "align_phase",
    "fourier_shift",
    "time_normalise",
    "kabsch_align",
    "noise_of_track",
    "noise_step",
]

# Samples of one normalised stride.
DEFAULT_STRIDE_SAMPLES = 128
# Harmonics of the stride frequency kept in a normalised stride.
DEFAULT_HARMONICS = 8
# The grid step is at least this many standard deviations of the noise left in the coded curves:
# with the anchored walk's one step of hysteresis, noise then practically never makes a step.
NOISE_STEPS = 4.0


@dataclass(frozen=True)
class RideStrides:
    """A track in stride phase: its mean stride, every whole stride and their noise.

    Attributes
    ----------
    mean : ndarray of shape (n, 3)
        The mean stride (mean zero, truncated to its first harmonics), one closed loop: sample n
        would be sample 0 again.
    strides : ndarray of shape (S, n, 3)
        Every whole stride, each resampled to n samples of stride phase, travel and mean removed,
        truncated to the same harmonics as the mean stride.
    sigma_m : float
        Per-axis RMS of the strides about the mean stride: measurement noise plus the stride-to-stride
        variation, the part of the motion that does not repeat (same units as the track).
    """

    mean: np.ndarray
    strides: np.ndarray
    sigma_m: float

    @property
    def moves(self) -> bool:
        """False for "no motion" (the mean stride's extent under ``NOISE_STEPS`` noise deviations).

        Such a stride would not make one step of the anchored walk on a grid of its own noise step.
        """
        return bool(np.ptp(self.mean, axis=0).max() >= NOISE_STEPS * self.sigma_m)

    @property
    def sigma_mean_m(self) -> float:
        """Noise left in the mean stride: ``sigma_m / sqrt(S)``."""
        return self.sigma_m / float(np.sqrt(self.strides.shape[0]))


def _detrended(x: np.ndarray) -> np.ndarray:
    """The track (N, 3) without its travel: a least-squares straight line per coordinate."""
    n = x.shape[0]
    idx = np.arange(n, dtype=np.float64)
    basis = np.column_stack([np.ones(n), idx - idx.mean()])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    return x - basis @ coef


def _period(x: np.ndarray, period_samples: float | None, fps: float, ride) -> float:
    if period_samples is None:
        if not np.isfinite(fps) or fps <= 0:
            raise InputError(f"fps must be a positive sampling rate, got {fps}")
        idx = np.arange(x.shape[0], dtype=np.float64)
        try:
            period_s, _ = estimate_period(idx / fps, x[:, None, :])
        except KinematicsError as exc:
            raise InputError(f"ride {ride!r}: no stride period could be estimated ({exc}); pass "
                             "period_samples") from exc
        period_samples = period_s * fps
    period_samples = float(period_samples)
    if not np.isfinite(period_samples) or period_samples < 4:
        raise InputError(f"ride {ride!r}: the stride period must be at least 4 samples, got {period_samples}")
    if period_samples > x.shape[0] - 1:
        raise InputError(f"ride {ride!r}: the track ({x.shape[0]} samples) is shorter than one stride "
                         f"({period_samples:.1f} samples)")
    return period_samples


def ride_strides(xyz, *, period_samples: float | None = None, fps: float = 30.0,
                 n_samples: int = DEFAULT_STRIDE_SAMPLES, harmonics: int | None = DEFAULT_HARMONICS,
                 ride="track") -> RideStrides:
    """A ride's track in stride phase: every stride resampled to ``n_samples``, and their mean.

    Parameters
    ----------
    xyz : ndarray of shape (N, 3)
        Positions of one marker or of the saddle point in the motion frame, sampled at ``fps``.
    period_samples : float, optional
        Stride period in samples; default estimated with
        :func:`saddlescope.core.kinematics.estimate_period` (about two strides are needed).
    fps : float, optional
        Sampling rate, used only to estimate the period.
    n_samples : int, optional
        Samples per stride.
    harmonics : int or None, optional
        Harmonics of the stride frequency kept in the mean stride (a truncated Fourier series, as
        the thesis fits to one period); None keeps everything.
    ride : hashable, optional
        Name used in error messages.

    Returns
    -------
    RideStrides
        The strides start at the track's first sample (stride k at ``k * period``).
    """
    x = _as_trajectory(xyz, f"ride {ride!r}: the track", min_samples=8)
    if n_samples < 8:
        raise InputError(f"n_samples must be at least 8, got {n_samples}")
    if harmonics is not None and not 1 <= harmonics < n_samples // 2:
        raise InputError(f"harmonics must be between 1 and {n_samples // 2 - 1}, got {harmonics}")
    x = _detrended(x)
    period = _period(x, period_samples, fps, ride)
    n = x.shape[0]
    n_strides = int((n - 1) // period)
    tq = (np.arange(n_strides)[:, None] * period + np.arange(n_samples)[None, :] * (period / n_samples)).ravel()
    idx = np.arange(n, dtype=np.float64)
    strides = np.stack([np.interp(tq, idx, x[:, k]) for k in range(3)], axis=-1).reshape(n_strides, n_samples, 3)
    strides = strides - strides.mean(axis=1, keepdims=True)
    mean = strides.mean(axis=0)
    sigma = float(np.sqrt(np.mean((strides - mean) ** 2))) if n_strides > 1 else noise_of_track(x)
    if harmonics is not None:
        spec = np.fft.rfft(np.concatenate([mean[None], strides]), axis=1)
        spec[:, harmonics + 1:] = 0.0
        smooth = np.fft.irfft(spec, n=n_samples, axis=1)
        mean, strides = smooth[0], smooth[1:]
    return RideStrides(mean=mean - mean.mean(axis=0), strides=strides - strides.mean(axis=1, keepdims=True),
                       sigma_m=sigma)


def fourier_shift(x: np.ndarray, shift: float) -> np.ndarray:
    """A closed loop (n, 3) read ``shift`` samples later (``x(t + shift)``), exact for band-limited loops."""
    n = x.shape[0]
    k = np.fft.rfftfreq(n, d=1.0 / n)
    return np.fft.irfft(np.fft.rfft(x, axis=0) * np.exp(2j * np.pi * k * shift / n)[:, None], n=n, axis=0)


def align_phase(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """Loop ``b`` (n, 3) shifted in phase to best match loop ``a`` (n, 3), and the shift in samples.

    The shift maximises the circular cross-correlation of the positions (all axes), refined
    between samples by a parabola through the peak; ``b`` is shifted in the Fourier domain.
    """
    n = a.shape[0]
    xc = np.fft.irfft(np.sum(np.conj(np.fft.rfft(a, axis=0)) * np.fft.rfft(b, axis=0), axis=1), n=n)
    k = int(np.argmax(xc))
    y0, y1, y2 = xc[(k - 1) % n], xc[k], xc[(k + 1) % n]
    denom = y0 - 2 * y1 + y2
    frac = 0.5 * (y0 - y2) / denom if denom < 0 else 0.0
    shift = float(k + np.clip(frac, -0.5, 0.5))
    return fourier_shift(b, shift), shift


def time_normalise(xyz, n_samples: int = 256) -> tuple[np.ndarray, float]:
    """A recording (N, M, 3) resampled to ``n_samples`` over its length, and its noise there.

    Each output sample is the mean of the input over its 1 / n_samples of the recording (a box
    filter, then linear interpolation), so the speed of the motion drops out.

    Returns
    -------
    resampled : ndarray of shape (n_samples, M, 3)
    sigma : float
        :func:`noise_of_track` of the input, divided by the square root of the samples averaged.
    """
    x = np.asarray(xyz, dtype=np.float64)
    n = x.shape[0]
    if n < 4:
        raise InputError(f"the recording has {n} samples; at least 4 are needed")
    width = max(1, int(round(n / n_samples)))
    if width > 1:
        kernel = np.ones(width) / width
        pad = np.concatenate([np.repeat(x[:1], width // 2, 0), x, np.repeat(x[-1:], width - 1 - width // 2, 0)])
        x = np.apply_along_axis(lambda c: np.convolve(c, kernel, mode="valid"), 0, pad)
    tq = np.linspace(0.0, n - 1.0, n_samples)
    flat = x.reshape(n, -1)
    out = np.stack([np.interp(tq, np.arange(n), flat[:, k]) for k in range(flat.shape[1])], axis=-1)
    sigma = max(noise_of_track(np.asarray(xyz, dtype=np.float64)[:, m]) for m in range(x.shape[1]))
    return out.reshape((n_samples,) + x.shape[1:]), sigma / float(np.sqrt(width))


def kabsch_align(a: np.ndarray, b: np.ndarray, *, up: int | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """The rotation and translation that best map ``b`` onto ``a`` (Kabsch), and the residual.

    Parameters
    ----------
    a, b : ndarray of shape (P, 3)
        Corresponding points (all samples of all markers).
    up : {None, 0, 1, 2}, optional
        The vertical axis: only turns about it are allowed (gravity keeps its direction); None
        allows any rotation.

    Returns
    -------
    b_aligned : ndarray of shape (P, 3)
        ``b @ R.T + t``.
    rotation : ndarray of shape (3, 3)
        Proper rotation R (det +1).
    residual : float
        RMS distance between ``a`` and ``b_aligned``, units of the positions.
    """
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    h = (b - cb).T @ (a - ca)
    if up is None:
        u, _, vt = np.linalg.svd(h)
        d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
        rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    else:  # a turn about the vertical axis only: the 2-D Kabsch of the horizontal plane
        i, j = [k for k in range(3) if k != up]
        angle = np.arctan2(h[i, j] - h[j, i], h[i, i] + h[j, j])
        rot = np.eye(3)
        rot[[i, i, j, j], [i, j, i, j]] = np.cos(angle), -np.sin(angle), np.sin(angle), np.cos(angle)
    aligned = (b - cb) @ rot.T + ca
    return aligned, rot, float(np.sqrt(np.mean(np.sum((aligned - a) ** 2, axis=1))))


def noise_of_track(xyz) -> float:
    """White measurement noise of a track (N, 3), per axis, from its second differences.

    ``sigma = 1.4826 MAD(d2 x) / sqrt(6)`` per axis (the variance of a second difference of white
    noise is 6 sigma^2), the largest of the three axes; robust to a few jumps. Smooth motion sampled
    slowly adds to it, so it is an upper bound.
    """
    x = np.asarray(xyz, dtype=np.float64)
    if x.shape[0] < 5:
        return 0.0
    d2 = np.diff(x, n=2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return float(np.max(1.4826 * mad / np.sqrt(6.0)))


def noise_step(curves, sigmas, *, cells: int = DEFAULT_CELLS, noise_steps: float = NOISE_STEPS) -> float:
    """The common grid step of the chain codes: ``max(extent / cells, noise_steps * sigma)``.

    Parameters
    ----------
    curves : sequence of ndarray of shape (N, 3)
        The curves to be coded with this step.
    sigmas : sequence of float
        The noise (standard deviation per axis) left in each coded curve.
    cells : int, optional
        The largest axis-aligned extent of the curves spans at most this many cells.
    noise_steps : float, optional
        A step is at least this many noise standard deviations.

    Returns
    -------
    step : float
        Units of the curves; positive (a tiny floor when nothing moves and there is no noise).
    """
    extent = max(float(np.ptp(np.asarray(c, dtype=np.float64), axis=0).max()) for c in curves)
    step = max(extent / cells, noise_steps * max(float(s) for s in sigmas))
    return step if step > 0 else 1e-12

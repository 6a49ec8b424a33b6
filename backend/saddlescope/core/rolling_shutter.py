"""Rolling shutters: a phone exposes its rows one after another, top to bottom, over its readout time.

Times are defined as everywhere else in the analysis: a frame's instant is its top row's exposure
instant, and row y (pixel centre y, rows 0..H-1) is exposed ``(y + 0.5) / H * readout`` later. A
global shutter has readout 0. Three things follow:

- the sync flash sweeps down the rows: a frame's mean brightness rises as more of its rows are lit
  (:func:`sweep_fit` models it, with the lamp's own ramp and the exposure);
- the flash's onset appears ``u * readout`` earlier in a band of rows at height ``u`` (0 top, 1
  bottom): the onsets of the row bands against their heights give the readout
  (:func:`readout_from_bands`);
- every marker observation has its own instant, its frame's plus its row's delay
  (:func:`row_delay_frames`; :func:`saddlescope.core.triangulation.tracks.triangulate_tracks` places
  it there).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from saddlescope.core.errors import InputError, SyncError

__all__ = ["MAX_READOUT_MS", "CameraReadout", "ReadoutEstimate", "SweepFit", "readout_from_bands", "readouts_from_meta",
           "row_delay_frames", "sweep_fit", "sweep_response"]

MAX_READOUT_MS = 40.0  # phones read a frame out in 10-35 ms; a longer readout is a typo (or seconds)
_MIN_BANDS = 4  # bands with a flash needed for a readout estimate
_SIGNIFICANT_SIGMAS = 4.0  # a readout below this many standard errors is taken as a global shutter
_LOG_WIDTHS = (float(np.log(0.02)), float(np.log(30.0)))  # a lamp's ramp: 0.02-30 frames
_MIN_READOUT_MS = 0.5  # and one below half a millisecond too (sub-0.02 frame at 30 fps)


@dataclass(frozen=True)
class CameraReadout:
    """One camera's readout in one clip set and where it comes from.

    ``source``: "ride.json" (given), "flash sweep" (measured in the clip's own flash), "flash sweep
    elsewhere" (the clip has no flash: the camera's readout measured in its other clips) or "none" (no
    flash anywhere: a global shutter assumed). ``sigma_s`` the measurement's standard error.
    """

    readout_s: float
    source: str
    sigma_s: float | None = None


def readouts_from_meta(meta: Mapping, cameras: Sequence[str]) -> dict[str, float] | None:
    """The cameras' readout times (s) given in ride.json's ``sync.readout_ms``, or None when not given.

    ``{"sync": {"readout_ms": {"left": 25, "middle": 25, "right": 25}}}``: cameras not named get 0
    (a global shutter).

    Raises
    ------
    InputError
        A value that is not a number of 0-40 ms, or a camera the ride does not have.
    """
    sync = meta.get("sync") if isinstance(meta, Mapping) else None
    given = sync.get("readout_ms") if isinstance(sync, Mapping) else None
    if given is None:
        return None
    if not isinstance(given, Mapping):
        raise InputError("ride.json's sync.readout_ms must be an object: camera -> readout time in ms "
                         "(e.g. {\"left\": 25, \"middle\": 25, \"right\": 25})")
    unknown = [c for c in given if c not in cameras]
    if unknown:
        raise InputError(f"ride.json's sync.readout_ms names camera(s) {', '.join(map(str, unknown))} the ride "
                         f"does not have (it has {', '.join(cameras)})")
    out = {}
    for cam in cameras:
        value = given.get(cam, 0.0)
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value) \
                or not 0.0 <= value <= MAX_READOUT_MS:
            raise InputError(f"ride.json's sync.readout_ms gives the {cam} camera a readout of {value!r}: a rolling "
                             f"shutter's readout time must be a number of 0-{MAX_READOUT_MS:g} ms (a phone's is "
                             "10-35 ms, 0 for a global shutter)")
        out[cam] = float(value) / 1000.0
    return out


def row_delay_frames(y_px: np.ndarray, readout_frames: float, rows: int) -> np.ndarray:
    """How much later than its frame's instant (frames) a point at image row ``y_px`` was exposed.

    ``(y + 0.5) / rows * readout``, clipped to the image; NaN rows give NaN.
    """
    y = np.asarray(y_px, dtype=np.float64)
    return float(readout_frames) * np.clip((y + 0.5) / float(rows), 0.0, 1.0)


def sweep_response(s: np.ndarray, width: float, readout: float) -> np.ndarray:
    """The lit share of a frame (0..1) whose top row is exposed ``s`` frames after a lamp's half-level rise.

    The lamp rises linearly over ``width`` frames (its own ramp and the exposure); row u (0 top, 1
    bottom) sees it ``u * readout`` frames later, and the frame's mean brightness averages the rows:
    the mean over u of clip((s + u r) / w + 1/2, 0, 1), in closed form. With readout 0 it is the ramp.
    """
    w = max(float(width), 1e-6)
    a = np.asarray(s, dtype=np.float64) / w + 0.5
    b = float(readout) / w
    if b < 1e-9:
        return np.clip(a, 0.0, 1.0)

    def ramp_integral(x: np.ndarray) -> np.ndarray:  # the integral of clip(x, 0, 1) from -inf
        return np.where(x <= 0, 0.0, np.where(x < 1, 0.5 * x ** 2, x - 0.5))

    return (ramp_integral(a + b) - ramp_integral(a)) / b


@dataclass(frozen=True)
class SweepFit:
    """A flash fitted with the sweep model: the lamp's half-level rise and fall (frames), its ramp width.

    ``rms`` is the fit's residual r.m.s. in grey levels. The brightness curve is the lamp's time on
    (fall - rise) smoothed by its ramp and by the readout, three boxes in one convolution: their order
    does not show, so a ramp and a time on may swap (``rise`` and ``fall`` move in opposite directions)
    but their mid time ``mid`` is fixed; and a readout cannot be told from a ramp in one brightness
    curve (it is measured from the row bands, :func:`readout_from_bands`, or given).
    """

    rise: float
    fall: float
    width: float
    rms: float

    @property
    def mid(self) -> float:
        """The flash's mid time (frames, at the top rows' instants): what the sync compares."""
        return 0.5 * (self.rise + self.fall)


def sweep_fit(brightness: np.ndarray, start: int, stop: int, readout_frames: float, *,
              width: float | None = None, starts: tuple[float, ...] = (0.3, 1.0, 2.5)) -> SweepFit:
    """Fit the flash of a brightness curve with the rolling-shutter sweep model.

    Frame k's brightness is ``base + drift * k + A * (H(k - rise) - H(k - fall))`` with H
    :func:`sweep_response` (a lamp that ramps up over ``width`` and down as fast, swept down the rows
    over ``readout_frames``). The plateau need not be sampled (a readout shortens the stretch where
    every row is lit, so a frame may never be fully lit): it is fitted with the rest.

    Parameters
    ----------
    brightness : ndarray of shape (F,)
    start, stop : int
        The first and last lit frames (:func:`saddlescope.core.sync.flash_interval`'s lit run).
    readout_frames : float
        The readout in frames (0: a global shutter).
    width : float, optional
        The lamp's ramp width (frames) when known (one lamp seen by every camera); fitted otherwise.
    starts : tuple of float
        Ramp widths (frames) the fit starts from; the best fit wins.

    Returns
    -------
    SweepFit
    """
    b = np.asarray(brightness, dtype=np.float64)
    lo, hi = max(0, start - 5), min(len(b), stop + 6)
    k = np.arange(lo, hi, dtype=np.float64)
    y = b[lo:hi]
    r = float(readout_frames)

    def design(p: np.ndarray) -> np.ndarray:
        rise, fall = p[0], p[1]
        w = np.exp(np.clip(p[2], _LOG_WIDTHS[0], _LOG_WIDTHS[1])) if width is None else width
        lit = sweep_response(k - rise, w, r) - sweep_response(k - fall, w, r)
        return np.stack([np.ones_like(k), k - k.mean(), lit], axis=1)

    def residual(p: np.ndarray) -> np.ndarray:
        a = design(p)
        coef = np.linalg.lstsq(a, y, rcond=None)[0]  # base, drift and amplitude: linear once the times are set
        return a @ coef - y

    # from the lit run, then from a few ramp widths (one of them starts near); the log width is held in bounds
    best = None
    for w_start in (starts if width is None else (width,)):
        p0 = [start - 0.5 * r, stop + 0.5 - 0.5 * r] + ([np.log(w_start)] if width is None else [])
        fit = least_squares(residual, np.array(p0, dtype=np.float64), method="lm")
        if best is None or fit.cost < best.cost:
            best = fit
    assert best is not None
    rise, fall = float(best.x[0]), float(best.x[1])
    w = float(np.exp(np.clip(best.x[2], *_LOG_WIDTHS))) if width is None else float(width)
    return SweepFit(rise, fall, w, float(np.sqrt(np.mean(best.fun ** 2))))


@dataclass(frozen=True)
class ReadoutEstimate:
    """A camera's readout estimated from one clip's flash sweeping down its row bands.

    ``readout_s`` (0 when the sweep is not significant), ``measured_s`` the slope as measured and
    ``sigma_s`` its standard error, ``bands`` how many row bands showed the flash.
    """

    readout_s: float
    measured_s: float
    sigma_s: float
    bands: int


def readout_from_bands(band_brightness: np.ndarray, row_fraction: np.ndarray, fps: float, *, start: int,
                       stop: int) -> ReadoutEstimate:
    """The readout from when the flash reaches each band of rows.

    One fit of every band at once with the sweep model: band j (rows at height u_j, 0 top, 1 bottom)
    sees the flash as a global shutter whose frames are ``u_j * readout`` late, so its rise and fall
    come ``u_j * readout`` frames earlier in its frame count; the lamp's rise, fall and ramp are shared,
    each band has its own baseline, drift and brightness (solved linearly), and the readout is fitted
    with its standard error (from the fit's Jacobian and residuals). It is kept when it is at least
    ``_SIGNIFICANT_SIGMAS`` standard errors and ``_MIN_READOUT_MS`` (else 0: a global shutter), and
    clipped to 0-``MAX_READOUT_MS``.

    Parameters
    ----------
    band_brightness : ndarray of shape (F, B)
        Each frame's mean brightness per band of rows.
    row_fraction : ndarray of shape (B,)
        Each band's mean row height as a fraction of the image's height (0 top, 1 bottom).
    fps : float
    start, stop : int
        The flash's first and last lit frames in the whole frame's brightness.

    Raises
    ------
    SyncError
        Fewer than ``_MIN_BANDS`` bands, or a flash too close to the clip's start or end to fit.
    """
    y_all = np.asarray(band_brightness, dtype=np.float64)
    u = np.asarray(row_fraction, dtype=np.float64)
    lo, hi = max(0, start - 5), min(y_all.shape[0], stop + 6)
    if u.size < _MIN_BANDS or hi - lo < 8:
        raise SyncError(f"{u.size} bands of rows over {hi - lo} frames around the flash: too few for a readout")
    k = np.arange(lo, hi, dtype=np.float64)
    y = y_all[lo:hi].T  # (B, n)
    band_width = float(np.median(np.diff(u))) if u.size > 1 else 1.0

    def residual(p: np.ndarray) -> np.ndarray:
        rise, fall, r = p[0], p[1], p[3]
        w = np.exp(np.clip(p[2], *_LOG_WIDTHS))
        shift = k[None, :] + u[:, None] * r  # (B, n): band j's frames at their rows' instants
        within = abs(r) * band_width  # the band's own rows' sweep
        lit = sweep_response(shift - rise, w, within) - sweep_response(shift - fall, w, within)
        x = np.stack([np.ones_like(lit), np.broadcast_to(k - k.mean(), lit.shape), lit], axis=-1)  # (B, n, 3)
        xtx = np.einsum("bni,bnj->bij", x, x) + 1e-9 * np.eye(3)
        coef = np.linalg.solve(xtx, np.einsum("bni,bn->bi", x, y)[..., None])[..., 0]
        return (np.einsum("bni,bi->bn", x, coef) - y).ravel()

    best = None
    for r0 in (0.0, 0.5):
        fit = least_squares(residual, np.array([start, stop + 0.5, 0.0, r0], dtype=np.float64), method="lm")
        if best is None or fit.cost < best.cost:
            best = fit
    assert best is not None
    n_params = 4 + 3 * u.size
    dof = max(best.fun.size - n_params, 1)
    jtj = best.jac.T @ best.jac
    try:
        sigma_r = float(np.sqrt(np.linalg.inv(jtj)[3, 3] * float(best.fun @ best.fun) / dof))
    except np.linalg.LinAlgError:
        sigma_r = float("inf")
    measured_s, sigma_s = float(best.x[3]) / fps, sigma_r / fps
    significant = measured_s > max(_SIGNIFICANT_SIGMAS * sigma_s, _MIN_READOUT_MS / 1000.0)
    readout_s = float(np.clip(measured_s, 0.0, MAX_READOUT_MS / 1000.0)) if significant else 0.0
    return ReadoutEstimate(readout_s, measured_s, sigma_s, int(u.size))

"""Synchronisation of the cameras from a flash of light (thesis 3.5 eq. 3.11-3.14, 8.2).

The thesis found the frame offsets (53 and 73 frames) by eye. Here the flash is found in each clip's
per-frame mean brightness: a rise of several times the clip's own frame-to-frame noise, a plateau,
and a fall back to the baseline. The onset is estimated to a fraction of a frame from the partially
lit first frame: if a frame integrates light over a fraction ``integration`` of the frame period
(global shutter: exposure / period; rolling shutter: (exposure + readout) / period; 1.0 when either
spans the whole period) and the flash starts at time tau inside frame k's integration window
[k, k + integration), that frame's brightness is baseline + phi * (plateau - baseline) with
phi = (k + integration - tau) / integration, so tau = k + integration * (1 - phi). The end of the flash
gives a second estimate the same way.

Time is in frame units of each clip: frame k starts at time k. An offset o_c of camera c means that
the instant seen in frame k of the reference (left) camera appears in frame k + o_c of camera c
(thesis eq. 3.11: F_L(k) <-> F_M(k + dF_LM)).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from saddlescope.core.errors import SyncError
from saddlescope.core.rolling_shutter import SweepFit, sweep_fit

__all__ = [
    "MIN_FRAMES",
    "flash_interval",
    "flash_onset",
    "clip_offsets",
    "flash_run",
    "sweep_interval",
    "offsets_from_intervals",
    "offsets_from_spec",
    "clip_frames_at",
    "nominal_frames_of",
]

MIN_FRAMES = 8  # the shortest clip a flash is looked for in


def _robust_sigma(x: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def flash_interval(mean_brightness: np.ndarray, *, clip: str, camera: str, min_sigma: float = 8.0,
                   noise_floor: float = 0.02, integration: float = 1.0,
                   max_flash_fraction: float = 0.5, edges: str = "step",
                   ramp_width: float | None = None) -> tuple[float, float]:
    """Sub-frame start and end of the flash in one clip.

    Parameters
    ----------
    mean_brightness : ndarray of shape (F,)
        Mean grey level of each frame (0-255 scale, any consistent scale works).
    clip, camera : str
        Named in error messages.
    min_sigma : float
        The flash must rise and fall by more than this many standard deviations of the clip's own
        frame-to-frame brightness noise (robust estimate; at least ``noise_floor`` grey levels).
    integration : float in (0, 1]
        Fraction of the frame period over which a frame's mean brightness integrates light.
    max_flash_fraction : float
        A bright interval longer than this fraction of the clip is a lighting change, not a flash.
    edges : {"step", "ramp", "auto"}
        "step" (default): an instantaneous flash integrated over ``integration`` of the frame period
        (returns the onset and end themselves). "ramp": each edge's half-level time, from a linear ramp
        of width ``ramp_width`` through its samples (lamps that rise over a frame or more); "auto":
        "ramp" when the flash lights four frames or more. :func:`clip_offsets` chooses for all cameras.

    Returns
    -------
    (onset, end) : floats in frames

    Raises
    ------
    SyncError
        Clip too short, no flash, or a brightness step that never comes back down.
    """
    where = f"{clip} clip of the {camera} camera"
    b = _checked_brightness(mean_brightness, where, integration)
    start, stop, base_before, base_after, plateau = _lit_run(b, where, min_sigma, noise_floor, max_flash_fraction)
    if edges == "auto":
        # a lamp lit for several frames shows its plateau and ramps; a brief flash is a step
        edges = "ramp" if stop - start + 1 >= 4 else "step"
    if edges in ("ramp", "samples"):
        rise, fall = _edge_samples(b, base_before, base_after, start, stop)
        if edges == "samples":
            return rise, fall
        w = _ramp_width([rise], [fall]) if ramp_width is None else ramp_width
        return _edge_mid(rise, w, +1, start), _edge_mid(fall, w, -1, stop)
    # the step model (module docstring): the partly lit first and last frames place onset and end
    phi = np.clip((b[start] - base_before) / (plateau - base_before), 0.0, 1.0)
    psi = np.clip((b[stop] - base_after) / (plateau - base_after), 0.0, 1.0)
    onset = start + integration * (1.0 - phi)
    end = stop + integration * psi
    return float(onset), float(end)


def _checked_brightness(mean_brightness: np.ndarray, where: str, integration: float) -> np.ndarray:
    """The brightness curve as float64 (F,), refused if too short or not finite (or a bad ``integration``)."""
    b = np.asarray(mean_brightness, np.float64).ravel()
    if len(b) < MIN_FRAMES:
        raise SyncError(f"{where} has only {len(b)} frame(s); need at least {MIN_FRAMES} to find the "
                        f"sync flash")
    if not np.all(np.isfinite(b)):
        raise SyncError(f"{where}: brightness has non-finite values")
    if not 0 < integration <= 1:
        raise SyncError(f"integration fraction {integration} must be in (0, 1]")
    return b


def _lit_run(b: np.ndarray, where: str, min_sigma: float, noise_floor: float,
             max_flash_fraction: float) -> tuple[int, int, float, float, float]:
    """The flash in the brightness curve ``b`` (F,), or SyncError if none stands out of the noise.

    Returns its first and last lit frames, the baselines before and after it, and its plateau.
    """
    d = np.diff(b)
    sigma = max(_robust_sigma(d) / np.sqrt(2), noise_floor)
    level = min_sigma * sigma
    rise_at = int(np.argmax(d))
    if d[rise_at] <= level:
        raise SyncError(f"no sync flash found in the {where}: the largest brightness rise is "
                        f"{d[rise_at]:.2f} grey levels, under {min_sigma:g} x the frame-to-frame noise "
                        f"({sigma:.3f})")
    base_before = float(np.median(b[max(0, rise_at - 5): rise_at])) if rise_at > 0 else float(b[0])
    start, stop = _lit_frames(b, rise_at, base_before, level)
    if stop == len(b) - 1:
        raise SyncError(f"no sync flash found in the {where}: the brightness rises at frame {start} but "
                        f"never comes back down (a lighting change, or the clip ends during the flash)")
    if stop - start + 1 > max_flash_fraction * len(b):
        raise SyncError(f"no sync flash found in the {where}: the bright interval (frames {start}-{stop}) "
                        f"lasts more than {max_flash_fraction:.0%} of the clip")
    base_after = float(np.median(b[stop + 1: stop + 6]))
    run = b[start: stop + 1]
    # the brightest frame lies on the lamp's plateau (a sync flash stays on for a frame or more)
    plateau = float(run.max())
    if plateau - max(base_before, base_after) <= level:
        raise SyncError(f"no sync flash found in the {where}: the bright frames {start}-{stop} do not "
                        f"stand out of the noise")
    return start, stop, base_before, base_after, plateau


def flash_run(mean_brightness: np.ndarray, *, clip: str, camera: str, min_sigma: float = 8.0,
              noise_floor: float = 0.02, max_flash_fraction: float = 0.5) -> tuple[int, int]:
    """The first and last frames the flash lights (the lit run of :func:`flash_interval`).

    Raises
    ------
    SyncError
        As :func:`flash_interval`.
    """
    where = f"{clip} clip of the {camera} camera"
    b = _checked_brightness(mean_brightness, where, 1.0)
    start, stop, *_ = _lit_run(b, where, min_sigma, noise_floor, max_flash_fraction)
    return start, stop


def sweep_interval(mean_brightness: np.ndarray, readout_frames: float, *, clip: str, camera: str,
                   width: float | None = None, **kwargs) -> SweepFit:
    """The flash's half-level rise and fall (frames, at the frames' top-row instants) under a rolling shutter.

    The lit run is found as by :func:`flash_interval` (``kwargs``: its ``min_sigma``, ``noise_floor``,
    ``max_flash_fraction``), then fitted with the sweep model
    (:func:`saddlescope.core.rolling_shutter.sweep_fit`): the frame's brightness rises as the lamp's
    light reaches more of its rows.
    """
    kwargs = {k: v for k, v in kwargs.items() if k in ("min_sigma", "noise_floor", "max_flash_fraction")}
    start, stop = flash_run(mean_brightness, clip=clip, camera=camera, **kwargs)
    return sweep_fit(np.asarray(mean_brightness, np.float64), start, stop, readout_frames, width=width)


def _swept_intervals(brightness_by_camera: Mapping[str, np.ndarray], readout_frames: Mapping[str, float],
                     cameras: list[str], clip: str, **kwargs) -> dict[str, tuple[float, float]]:
    """Each camera's flash as (mid, mid) from the sweep model: its mid time is what the model fixes.

    (A ramp and the lamp's time on may swap in the fit, moving its rise and fall apart, never its mid.)
    """
    out = {}
    for c in cameras:
        mid = sweep_interval(brightness_by_camera[c], float(readout_frames.get(c, 0.0)), clip=clip, camera=c,
                             **kwargs).mid
        out[c] = (mid, mid)
    return out


def _lit_frames(b: np.ndarray, rise_at: int, base_before: float, level: float) -> tuple[int, int]:
    """First and last frame of the flash that lights the frame after the largest rise ``rise_at``."""
    # the lit run: contiguous frames above the baseline that include the frame after the largest rise
    # lit: well above the baseline relative to the flash itself, so slow lighting drift after a flash
    # (clouds, auto-exposure) is not taken for a flash lasting half the clip
    peak = float(b[rise_at + 1: rise_at + 1 + max(8, len(b) // 10)].max())
    lit = b > base_before + max(level, 0.25 * (peak - base_before))
    start = rise_at + 1
    while start > 0 and lit[start - 1]:
        start -= 1
    stop = rise_at + 1
    while stop + 1 < len(b) and lit[stop + 1]:
        stop += 1
    # then the dim edge frames of the flash (above the noise, falling away from it), a few at most
    faint = b > base_before + level
    for _ in range(3):
        if start > 0 and faint[start - 1] and b[start - 1] < b[start]:
            start -= 1
        if stop + 1 < len(b) and faint[stop + 1] and b[stop + 1] < b[stop]:
            stop += 1
    return start, stop


def _edges_of(b, *, clip: str, camera: str, **kwargs):
    kwargs = {k: v for k, v in kwargs.items() if k not in ("edges", "ramp_width")}
    return flash_interval(b, clip=clip, camera=camera, edges="samples", **kwargs)


def _edge_samples(b, base_before, base_after, start, stop):
    """(k, y) of the samples strictly inside the rising and the falling edge, y normalised 0..1."""
    plateau = float(b[start: stop + 1].max())
    out = []
    for base, lo, hi in ((base_before, start - 1, stop + 1), (base_after, start, stop + 2)):
        k = np.arange(max(lo, 0), min(hi, len(b)))
        y = (b[k] - base) / (plateau - base)
        inside = (y > 0.03) & (y < 0.97)
        out.append((k[inside].astype(np.float64), y[inside]))
    # the rise is the first run of inside samples, the fall the last
    rise_k, rise_y = out[0]
    fall_k, fall_y = out[1]
    peak = start + int(np.argmax(b[start: stop + 1]))  # the rise comes before the brightest frame
    rise = (rise_k[rise_k < peak], rise_y[rise_k < peak])
    fall = (fall_k[fall_k > peak], fall_y[fall_k > peak])
    return rise, fall


def _ramp_width(rises, falls) -> float:
    """Width (frames) of the lamp's ramp as the exposures see it.

    From every edge with two or more samples on it (the same lamp and exposure in every camera); one
    frame (an instant flash integrated over a whole frame period) when no edge shows it.
    """
    widths = []
    for k, y in list(rises) + list(falls):
        if len(k) >= 2:
            slope = np.polyfit(k, y, 1)[0]
            if abs(slope) > 1e-6:
                widths.append(1.0 / abs(slope))
    return float(np.clip(np.median(widths), 0.05, 20.0)) if widths else 1.0


def _edge_mid(samples, w: float, direction: int, edge: int) -> float:
    """Half-level time of one edge: each sample on a linear ramp of width w gives it (eq. of a line)."""
    k, y = samples
    if len(k) == 0:  # the edge fell between two frames
        return float(edge - 0.5) if direction > 0 else float(edge + 0.5)
    if direction > 0:
        return float(np.mean(k - y * w) + w / 2)
    return float(np.mean(k + y * w) - w / 2)


def flash_onset(mean_brightness: np.ndarray, *, clip: str, camera: str, **kwargs) -> float:
    """Sub-frame time (in frames) at which the sync flash starts.

    Parameters
    ----------
    mean_brightness : ndarray of shape (F,)
        Mean grey level of each frame.
    clip, camera : str
        Named in error messages.
    **kwargs
        Passed to :func:`flash_interval`.

    Returns
    -------
    float
        The onset of :func:`flash_interval`, in frames.
    """
    return flash_interval(mean_brightness, clip=clip, camera=camera, **kwargs)[0]


def _check_fps(fps_by_camera: Mapping[str, float], cameras: list[str], clip: str, rel_tol: float) -> None:
    missing = [c for c in cameras if c not in fps_by_camera]
    if missing:
        raise SyncError(f"{clip} clip: frame rate unknown for camera(s) {', '.join(missing)}")
    ref = cameras[0]
    f0 = float(fps_by_camera[ref])
    for cam in cameras:
        f = float(fps_by_camera[cam])
        if not np.isfinite(f) or f <= 0:
            raise SyncError(f"{clip} clip of the {cam} camera: frame rate {f} is not positive")
        if abs(f - f0) > rel_tol * f0:
            raise SyncError(f"{clip} clip: the {cam} camera runs at {f:g} fps but the {ref} camera at "
                            f"{f0:g} fps; frame offsets need equal frame rates")


def clip_offsets(brightness_by_camera: Mapping[str, np.ndarray], fps_by_camera: Mapping[str, float], *,
                 clip: str, reference: str | None = None, fps_rel_tol: float = 1e-3,
                 readout_frames: Mapping[str, float] | None = None, **flash_kwargs) -> dict[str, float]:
    """Frame offsets of every camera relative to the reference (first, i.e. left) camera.

    Parameters
    ----------
    brightness_by_camera : dict camera -> ndarray of shape (F_c,)
        Mean frame brightness of each camera's clip.
    fps_by_camera : dict camera -> float
    clip : str
        Clip kind (e.g. "motion"), named in errors.
    reference : str, optional
        Camera whose offset is 0; default the first key.
    readout_frames : dict camera -> float, optional
        Rolling shutters' readout times in frames (:mod:`saddlescope.core.rolling_shutter`): where any is
        above 0, every camera's flash is fitted with the sweep model (:func:`sweep_interval`, one lamp
        ramp for all), whose times are the frames' top-row instants.
    flash_kwargs
        Passed to :func:`flash_interval`.

    Returns
    -------
    dict camera -> offset in frames (float, sub-frame): the reference's frame k shows the same
    instant as frame k + offset of that camera. Onset and end of the flash each give an estimate;
    their mean is used when they agree within half a frame, the onset alone otherwise.

    Raises
    ------
    SyncError
        Different frame rates, clips too short, or no flash in a clip.
    """
    cameras = list(brightness_by_camera)
    if not cameras:
        raise SyncError(f"{clip} clip: no cameras to synchronise")
    reference = reference or cameras[0]
    if reference not in brightness_by_camera:
        raise SyncError(f"{clip} clip: reference camera {reference} has no brightness curve")
    cameras = [reference] + [c for c in cameras if c != reference]
    _check_fps(fps_by_camera, cameras, clip, fps_rel_tol)
    if readout_frames and any(float(v) > 0 for v in readout_frames.values()):
        swept = _swept_intervals(brightness_by_camera, readout_frames, cameras, clip, **flash_kwargs)
        return offsets_from_intervals(swept, reference=reference)
    if "edges" not in flash_kwargs:
        # A lamp that ramps over two frames or more (seen on some edge) is timed by its half-level
        # crossings, with one ramp width for all cameras (one lamp, one exposure setting); a brief
        # flash by the step model.
        samples = {c: _edges_of(brightness_by_camera[c], clip=clip, camera=c, **flash_kwargs) for c in cameras}
        rises, falls = [e[0] for e in samples.values()], [e[1] for e in samples.values()]
        lit_frames = [np.ptp(np.concatenate([r[0], f[0]])) + 1 if len(r[0]) and len(f[0]) else 0
                      for r, f in zip(rises, falls, strict=True)]
        if min(lit_frames) >= 4 and any(len(k) >= 2 for k, _ in rises + falls):
            flash_kwargs = {**flash_kwargs, "edges": "ramp", "ramp_width": _ramp_width(rises, falls)}
    times = {c: flash_interval(brightness_by_camera[c], clip=clip, camera=c, **flash_kwargs) for c in cameras}
    return offsets_from_intervals(times, reference=reference)


def offsets_from_intervals(intervals: Mapping[str, tuple[float, float]], *,
                           reference: str | None = None) -> dict[str, float]:
    """Offsets in frames from each camera's flash (onset, end), relative to the reference camera.

    The mean of the onset and end differences when they agree within half a frame (it halves the
    noise), the onset difference otherwise. The reference defaults to the first camera.
    """
    reference = reference or next(iter(intervals))
    on0, end0 = intervals[reference]
    offsets = {}
    for cam, (on, end) in intervals.items():
        d_on, d_end = on - on0, end - end0
        offsets[cam] = 0.5 * (d_on + d_end) if abs(d_on - d_end) < 0.5 else d_on
    offsets[reference] = 0.0
    return offsets


def offsets_from_spec(sync: Mapping, *, clip: str, cameras: list[str]) -> dict[str, float] | None:
    """Known offsets from ride.json ``{"method": "offsets", "offsets": {clip: {camera: frames}}}``.

    Returns None when the method is "flash" (offsets must be measured). Offsets are made relative to
    the first camera of ``cameras``.

    Raises
    ------
    SyncError
        Unknown method, or an offset missing or not a finite number for a camera of this clip.
    """
    method = sync.get("method", "flash") if isinstance(sync, Mapping) else None
    if method == "flash":
        return None
    if method != "offsets":
        raise SyncError(f"sync method {method!r} is not 'flash' or 'offsets'")
    table = sync.get("offsets", {})
    per_clip = table.get(clip) if isinstance(table, Mapping) else None
    if not isinstance(per_clip, Mapping):
        raise SyncError(f"sync offsets for the {clip} clip are missing from ride.json")
    out = {}
    for cam in cameras:
        value = per_clip.get(cam)
        if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
            raise SyncError(f"sync offset of the {cam} camera in the {clip} clip is missing or not a number "
                            f"({value!r})")
        out[cam] = float(value)
    ref = out[cameras[0]]
    return {cam: v - ref for cam, v in out.items()}


# --------------------------------------------------------------------------------------------------
# Variable frame rate: a clip's timestamps against the nominal even clock the offsets count in
# --------------------------------------------------------------------------------------------------

def _stamps(frame_times_s: np.ndarray, anchor_frame: float) -> tuple[np.ndarray, np.ndarray, float]:
    """A clip's stamps (F,), its frame numbers (F,) and the instant of its (fractional) anchor frame."""
    times = np.asarray(frame_times_s, dtype=np.float64)
    idx = np.arange(times.size, dtype=np.float64)
    return times, idx, float(np.interp(anchor_frame, idx, times))


def clip_frames_at(nominal_frames: np.ndarray, frame_times_s: np.ndarray, anchor_frame: float,
                   fps: float) -> np.ndarray:
    """Fractional frame positions in a variable-rate clip of the instants of its nominal frames.

    The nominal clock runs evenly at ``fps`` and agrees with the clip's timestamps at ``anchor_frame``
    (the sync flash's onset, where the frame offsets tie the cameras together): nominal frame n is the
    instant τ(anchor) + (n - anchor) / fps, placed between the clip's stamped frames (NaN outside).
    For an even clip this is n itself.

    Parameters
    ----------
    nominal_frames : ndarray of shape (N,)
        Frames on the nominal even clock.
    frame_times_s : ndarray of shape (F,)
        The clip's frame timestamps in seconds.
    anchor_frame : float
        The (fractional) clip frame where both clocks agree.
    fps : float
        The nominal frame rate.

    Returns
    -------
    ndarray of shape (N,)
        Fractional clip frames, NaN outside the clip.
    """
    times, idx, t_anchor = _stamps(frame_times_s, anchor_frame)
    want = t_anchor + (np.asarray(nominal_frames, dtype=np.float64) - anchor_frame) / fps
    return np.interp(want, times, idx, left=np.nan, right=np.nan)


def nominal_frames_of(clip_frames: np.ndarray, frame_times_s: np.ndarray, anchor_frame: float,
                      fps: float) -> np.ndarray:
    """The inverse of :func:`clip_frames_at`: the nominal (even-clock) frame of each clip frame.

    Parameters
    ----------
    clip_frames : ndarray of shape (N,)
        (Fractional) frames of the clip.
    frame_times_s : ndarray of shape (F,)
        The clip's frame timestamps in seconds.
    anchor_frame : float
        The (fractional) clip frame where both clocks agree.
    fps : float
        The nominal frame rate.

    Returns
    -------
    ndarray of shape (N,)
        Frames on the nominal even clock.
    """
    times, idx, t_anchor = _stamps(frame_times_s, anchor_frame)
    return anchor_frame + (np.interp(np.asarray(clip_frames, dtype=np.float64), idx, times) - t_anchor) * fps

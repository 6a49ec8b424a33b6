"""The hidden saddle point: its kinematics from three horse markers and the rider's indicators.

Thesis stages 5-10: the tracked markers are checked and bridged (5.2), put in the motion reference
frame (5.3), registered to the static shot (5.4) and fitted (5.5); the rigid body's angular
velocity and acceleration (6.1-6.2) carry the static shot's saddle marker to the saddle point S
(6.3-6.4), whose vertical harmonics feed the vibration indicators (7, 8.5).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.kinematics import (
    AngularKinematics,
    MarkerKinematics,
    MotionFrame,
    PointKinematics,
    Registration,
    analysis_window,
    angular_kinematics,
    bridge_gaps,
    broken_distance_samples,
    estimate_period,
    fit_marker_kinematics,
    marker_model,
    register_rigid,
    regularize_depth,
    rloess,
    saddle_body_coordinates,
    saddle_point_kinematics,
)
from saddlescope.core.kinematics import frames as motion
from saddlescope.core.kinematics.hidden_phase import hidden_marker_refusal, unmeasured_phase
from saddlescope.core.params import PipelineParams
from saddlescope.core.types import MarkerTracks
from saddlescope.core.vibration import ride_indicators

__all__ = ["STRIDE_RANGE_HZ", "SaddleAnalysis", "hidden_marker_refusal", "identify_saddle_marker",
           "kinematics_indicators", "layout_mismatch_mm", "match_horse_markers", "pairwise_distances",
           "saddle_kinematics", "static_positions", "vertical_harmonics"]

# Stride frequencies searched per declared gait (literature: walk 0.85-0.95 Hz, trot 1.3-1.5 Hz,
# canter 1.6-1.7 Hz), with wide margins. They keep the stride apart from the 2x vertical line of walk
# and trot, whose lateral 1x content is the first to drown in depth noise on a narrow rig.
STRIDE_RANGE_HZ: dict[str, tuple[float, float]] = {
    "walk": (0.6, 1.25), "sitting_trot": (1.0, 1.9), "rising_trot": (1.0, 1.9), "canter": (1.25, 2.3)}


def _count(n, noun: str) -> str:
    """"1 frame", "3 frames": counts in flags read as sentences."""
    return f"{int(n)} {noun}{'' if int(n) == 1 else 's'}"


def static_positions(tracks: MarkerTracks, what: str) -> np.ndarray:
    """The median position (M, 3) mm of each marker of a still clip over its frames with every marker."""
    xyz = tracks.xyz_mm
    ok = np.all(np.isfinite(xyz), axis=(1, 2))
    if ok.sum() < 1:
        raise KinematicsError(f"the {what} clip has no frame where every marker is seen by two cameras")
    return np.median(xyz[ok], axis=0)


def _despiked(xyz: np.ndarray, dt_s: float, *, min_spike_mm: float = 30.0, window_s: float = 0.15) -> np.ndarray:
    """Tracks (F, M, 3) with short spikes replaced by the running median.

    A copy of finite tracks (F, M, 3) with short spikes (a look-alike taken for a marker for a few
    frames) replaced by the running median over ``window_s``: one such spike (0.85 m for 4 frames) took
    a wide-rig trot's autocorrelation from 0.9 to 0.25. Spikes: beyond 5 robust standard deviations
    and ``min_spike_mm``.
    """
    from scipy.ndimage import median_filter

    size = max(5, 2 * int(round(window_s / dt_s / 2)) + 1)
    med = median_filter(xyz, size=(size, 1, 1), mode="nearest")
    resid = xyz - med
    sigma = 1.4826 * np.median(np.abs(resid), axis=0, keepdims=True)
    spike = np.abs(resid) > np.maximum(5.0 * sigma, min_spike_mm)
    return np.where(spike, med, xyz)


def _longest_run(mask: np.ndarray) -> tuple[int, int]:
    """[start, stop) of the longest run of True."""
    best, start = (0, 0), None
    for i, ok in enumerate(list(mask) + [False]):
        if ok and start is None:
            start = i
        elif not ok and start is not None:
            if i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    return best


def _on_window(fits, in_win: slice):
    """Marker fits with their sampled velocities and accelerations cut to the analysed window."""
    return replace(fits, t_s=fits.t_s[in_win], velocity_m_s=fits.velocity_m_s[in_win],
                   acceleration_m_s2=fits.acceleration_m_s2[in_win])


def pairwise_distances(xyz: np.ndarray) -> np.ndarray:
    """Distances between every pair of markers (per frame when given frames).

    Parameters
    ----------
    xyz : ndarray of shape (..., M, 3)

    Returns
    -------
    ndarray of shape (..., M, M)
    """
    return np.linalg.norm(xyz[..., :, None, :] - xyz[..., None, :, :], axis=-1)


def layout_mismatch_mm(static_horse_mm: np.ndarray, motion_mm: np.ndarray) -> float:
    """How far (RMS, mm) the tracked markers' distances are from the static shot's.

    RMS difference (mm) between the static shot's horse-marker distances and the tracked ones'
    (medians over the clip; label order does not matter). inf when no frame has all markers.
    """
    full = np.all(np.isfinite(motion_mm), axis=(1, 2))
    if not full.any():
        return float("inf")
    pairs = np.triu_indices(len(static_horse_mm), 1)
    d_static = np.sort(pairwise_distances(static_horse_mm)[pairs])
    d_motion = np.sort(np.median(pairwise_distances(motion_mm[full]), axis=0)[pairs])
    return float(np.sqrt(np.mean((d_static - d_motion) ** 2)))


def identify_saddle_marker(static_mm: np.ndarray, motion_mm: np.ndarray) -> tuple[list[int], int, float]:
    """Which static-shot markers are horse markers 1-3 (in the motion clip's order) and which is S.

    The static shot shows the three horse markers and the saddle marker; the motion clip the three
    horse markers. The triple whose distances best match the motion clip's (rigid body) is the horse
    markers, the remaining one S.

    Parameters
    ----------
    static_mm : ndarray of shape (M, 3)
        The static shot's markers (mm).
    motion_mm : ndarray of shape (F, 3, 3)
        The ride's tracked horse markers (mm), NaN where lost.

    Returns
    -------
    tuple
        (static indices of motion markers 1-3, static index of S, RMS distance mismatch in mm).
    """
    scored = _orders_by_mismatch(static_mm, itertools.permutations(range(static_mm.shape[0]), motion_mm.shape[1]),
                                 motion_mm)
    err, idx = min(scored, key=lambda s: s[0] if np.isfinite(s[0]) else np.inf, default=(np.nan, []))
    rest = [i for i in range(static_mm.shape[0]) if i not in idx]
    if not rest or not np.isfinite(err):
        raise KinematicsError("the static shot must show the three horse markers and the saddle marker")
    return idx, rest[0], err


def _orders_by_mismatch(static_mm: np.ndarray, orders, motion_mm: np.ndarray) -> list[tuple[float, list[int]]]:
    """Score every order of static markers against the motion clip's distances.

    (RMS mismatch mm, order) for each order of static markers standing for motion markers 1..M:
    the static shot's distances between them against the motion clip's median per-frame distances.
    """
    d_motion = np.nanmedian(pairwise_distances(motion_mm), axis=0)
    d_static = pairwise_distances(static_mm)
    return [(float(np.sqrt(np.nanmean((d_static[np.ix_(idx, idx)] - d_motion) ** 2))), idx)
            for idx in map(list, orders)]


def match_horse_markers(static_mm: np.ndarray, horse_idx: list[int], motion_mm: np.ndarray) -> list[int]:
    """The static shot's horse markers in the motion clip's label order.

    Each camera labels the markers it tracks in its own order, so motion marker 1 need not be the
    static shot's first horse marker; registering the static layout to swapped labels bends the
    saddle point's path (a wide-rig rising trot: 10.4 % vertical acceleration error with tracks good
    to a millimetre). The order whose per-frame distances match the static shot's is taken; where
    the layout is near-symmetric and two orders match, the one that keeps the horse nearest to its
    static pose (smallest rotation from the static shot: the same side faces the cameras).

    Parameters
    ----------
    static_mm : ndarray of shape (M, 3)
        The static shot's markers (mm).
    horse_idx : list of int
        The static indices of the horse markers, in any order.
    motion_mm : ndarray of shape (F, 3, 3)
        The ride's tracked horse markers (mm).

    Returns
    -------
    list of int
        ``horse_idx`` reordered so that entry k is motion marker k + 1.
    """
    scored = _orders_by_mismatch(static_mm, itertools.permutations(horse_idx), motion_mm)
    best = min(score for score, _ in scored)
    close = [idx for score, idx in scored if score <= max(3.0, 2.0 * best)]
    if len(close) == 1:
        return close[0]

    def rotation_deg(idx: list[int]) -> float:
        reg = register_rigid(motion_mm, static_mm[idx])
        rot = reg.R[reg.valid]
        if not len(rot):
            return np.inf
        cos = np.clip((np.trace(rot, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
        return float(np.degrees(np.median(np.arccos(cos))))

    return min(close, key=rotation_deg)



@dataclass(frozen=True)
class SaddleAnalysis:
    """What :func:`saddle_kinematics` found (thesis 5.2-6.4), on the analysed window.

    ``t_s`` (F,) and ``markers_m`` (F, 3, 3) cover the window of ``window`` = (first, stop) frames of the
    motion clip; the fits saw the frames ``fitted`` = (first, stop) around it. ``saddle`` holds the
    saddle point S's position, velocity and acceleration in the motion frame; ``flags`` say, in
    sentences, what the stage had to assume or leave out.
    """

    t_s: np.ndarray
    period_s: float
    period_estimate_s: float
    period_info: dict
    window: tuple[int, int]
    fitted: tuple[int, int]
    frame: MotionFrame
    registration: Registration
    fits: MarkerKinematics
    angular: AngularKinematics
    saddle: PointKinematics
    markers_m: np.ndarray
    static_mismatch_mm: float
    r_bs_m: np.ndarray
    flags: tuple[Finding, ...]
    long_gaps: list
    # the share of the stride's phase no fitted frame measured (all markers, and per marker front to rear):
    # see :func:`unmeasured_phase`
    unmeasured_phase: dict = field(default_factory=dict)


@dataclass(frozen=True)
class _Span:
    """The frames analysed: the longest tracked run, its window of whole strides and the fitted span."""

    run: tuple[int, int]
    window: tuple[int, int]
    fitted: tuple[int, int]
    period_s: float
    period_info: dict

    @property
    def fit_slice(self) -> slice:
        """The fitted span within the clip."""
        return slice(*self.fitted)

    @property
    def in_window(self) -> slice:
        """The window within the fitted span."""
        return slice(self.window[0] - self.fitted[0], self.window[1] - self.fitted[0])


def _checked_tracks(t: np.ndarray, xyz: np.ndarray, params: PipelineParams, flags: list[Finding]
                    ) -> tuple[np.ndarray, np.ndarray, list, np.ndarray]:
    """The motion tracks (F, 3, 3) mm with broken samples dropped and short gaps bridged (5.2.1).

    Returns (tracks, bridged frames (F,) bool, long gaps [(start_s, end_s)], each marker's measured
    samples (F, M) bool); appends its flags.
    """
    n_frames, n_markers, _ = xyz.shape
    if n_markers != 3:
        raise KinematicsError(f"the motion clip must track 3 horse markers, got {n_markers}")
    together = np.all(np.isfinite(xyz), axis=(1, 2))
    if not together.any():
        raise KinematicsError("the three markers are never seen together in the motion clip; the ride cannot be "
                              "analysed")
    # Lost for most of the ride: judged between the first and the last frame where all markers are
    # seen, not over the clip: cameras run before and after the horse crosses their view (a 10 s
    # thesis-rig clip holds a trot for 2 s).
    first_seen, last_seen = np.flatnonzero(together)[[0, -1]]
    in_view = together[first_seen:last_seen + 1].mean()
    if in_view < 0.3:
        raise KinematicsError(f"the markers are seen together in only {100 * in_view:.0f} % of the frames from "
                              f"{t[first_seen]:.2f} s to {t[last_seen]:.2f} s, while the horse is in view; the "
                              "ride cannot be analysed")
    # A look-alike taken for a marker breaks the markers' distances (often as the horse enters the
    # view, before the markers do): such samples go before anything reads them.
    broken = broken_distance_samples(xyz)
    if broken.any():
        xyz = np.where(broken[..., None], np.nan, xyz)
        flags.append(Finding("tracking.dropped_samples",
                             f"{_count(broken.sum(), 'marker sample')} in {_count(broken.any(axis=1).sum(), 'frame')} "
                             "broke the markers' distances (a look-alike taken for a marker) and were dropped",
                             {"samples": int(broken.sum()), "frames": int(broken.any(axis=1).sum())}))
    # Short gaps bridged (and flagged), long ones reported (5.2.1).
    measured = np.all(np.isfinite(xyz), axis=2)  # (F, M): each marker's own measurements
    filled, filled_mask, long_gaps = bridge_gaps(t, xyz.reshape(n_frames, -1), max_gap_s=params.max_gap_s)
    xyz = filled.reshape(n_frames, n_markers, 3)
    bridged_frames = np.any(filled_mask.reshape(n_frames, -1), axis=1)
    if bridged_frames.any():
        flags.append(Finding("tracking.gaps_bridged",
                             f"{_count(bridged_frames.sum(), 'frame')} with a short marker gap bridged (for the "
                             "registration; the fits use measured frames only and give the positions there)",
                             {"frames": int(bridged_frames.sum())}))
    flags.extend(_gap_flags(t, long_gaps))
    return xyz, bridged_frames, long_gaps, measured


def _gap_flags(t: np.ndarray, long_gaps: list) -> list[Finding]:
    """A finding for each long gap in the markers' tracks.

    A finding for each long gap; at the record's ends the markers are not lost but not yet (or no
    longer) in every view.
    """
    dt_s = float(np.median(np.diff(t)))
    flags = []
    for start_s, end_s in long_gaps:
        gap = {"gap_start_s": start_s, "gap_end_s": end_s}
        if start_s <= t[0] < t[-1] <= end_s:
            flags.append(Finding("tracking.lost_all_along",
                                 f"markers lost from {start_s:.2f} s to {end_s:.2f} s (one or another, all along)",
                                 gap))
        elif start_s <= t[0]:
            flags.append(Finding("tracking.not_in_view_at_start",
                                 f"markers not all in view before {end_s + dt_s:.2f} s (the record starts at "
                                 f"{t[0]:.2f} s)", {"in_view_from_s": end_s + dt_s}))
        elif end_s >= t[-1]:
            flags.append(Finding("tracking.not_in_view_at_end",
                                 f"markers not all in view after {start_s - dt_s:.2f} s (the record ends at "
                                 f"{t[-1]:.2f} s)", {"in_view_until_s": start_s - dt_s}))
        else:
            flags.append(Finding("tracking.lost", f"markers lost from {start_s:.2f} s to {end_s:.2f} s", gap))
    return flags


def _planar_period(t: np.ndarray, xyz: np.ndarray, valid: np.ndarray, span: tuple[int, int], dt_s: float,
                   f_range: tuple[float, float]) -> tuple[float, dict]:
    """:func:`estimate_period` on the frames ``span`` [start, stop) of the tracks with depth set to 0."""
    a, b = span
    planar = _despiked(np.where(valid[a:b, None, None], xyz[a:b], np.nan), dt_s)
    planar[..., 2] = 0.0
    return estimate_period(t[a:b], planar, f_range_hz=f_range)


def _run_off_guessed_lens(t: np.ndarray, valid: np.ndarray, run: tuple[int, int], period_s: float,
                          beyond_px: np.ndarray | None, flags: list[Finding]) -> tuple[int, int]:
    """The run to analyse: the longest stretch whose depth does not rest on a guessed lens.

    ``beyond_px`` (F,) how far beyond its calibration board's reach a camera of a two-camera sample saw
    a marker (:class:`~saddlescope.core.triangulation.ReachCheckedTracks`; 0: three cameras or the
    board's region fix every marker). Such samples were 0.1-0.8 m off in depth on band-calibrated
    partial-view canters, smoothly but differently per marker, and the saddle point's W_b r.m.s. came
    out two to four times the truth. The stretch without them is analysed; when it holds less than a
    stride, it grows by the least extrapolated frames next to it until it holds one (the lens error
    grows with the distance beyond the reach); when the run holds less than a stride, the run stays
    and the user is told the result may be broken.
    """
    if beyond_px is None or not np.any(beyond_px[run[0]:run[1]] > 0):
        return run
    dt_s = float(np.median(np.diff(t[run[0]:run[1]])))
    guessed = np.flatnonzero(beyond_px[run[0]:run[1]] > 0) + run[0]
    what = (f"markers seen by two cameras only, one of them outside the region its calibration board covered, "
            f"in {_count(guessed.size, 'frame')} from {t[guessed[0]]:.2f} s to {t[guessed[-1]]:.2f} s: their "
            "depth rests on the lens model extrapolated there")
    i0, i1 = (i + run[0] for i in _longest_run((valid & (beyond_px <= 0))[run[0]:run[1]]))
    if i1 == i0:  # no sound frame: start from the least extrapolated
        i0 = i1 = run[0] + int(np.argmin(beyond_px[run[0]:run[1]]))
    need = int(np.ceil(period_s / dt_s - 1e-9))
    while i1 - i0 < need:
        before = beyond_px[i0 - 1] if i0 > run[0] else np.inf
        after = beyond_px[i1] if i1 < run[1] else np.inf
        if not np.isfinite(min(before, after)):
            flags.append(Finding("calibration.guessed_depth_broken",
                                 f"{what}, and the run holds less than a stride without them: the saddle point's "
                                 "motion may be broken (move the board to the edges of every camera's view)",
                                 {"frames": guessed.size}))
            return run
        i0, i1 = (i0 - 1, i1) if before <= after else (i0, i1 + 1)
    worst = float(np.max(beyond_px[i0:i1]))
    flags.append(Finding("calibration.guessed_depth",
                         f"{what}; the analysis used the {(i1 - i0) * dt_s:.2f} s from {t[i0]:.2f} s to "
                         f"{t[i1 - 1]:.2f} s"
                         + (f", at most {worst:.0f} px beyond the board's reach (a stride needs them)" if worst > 0
                            else " where three cameras or the board's region fix them"),
                         {"frames": guessed.size, "used_s": (i1 - i0) * dt_s, "beyond_reach_px_max": worst}))
    return i0, i1


def _stride_span(t: np.ndarray, xyz: np.ndarray, params: PipelineParams, gait: str | None,
                 flags: list[Finding] | None = None, beyond_px: np.ndarray | None = None) -> _Span:
    """The stride period, the analysed window and the span the fits see.

    The stride period and the analysed window within the longest stretch where every marker is
    tracked (the horse crosses the view; a stretch seen by two cameras counts as much as one seen by
    three), and the span the fits see around it. A stretch too short for ``params.n_periods`` strides
    but holding at least one is analysed on the whole strides it holds (flagged): the indicators are
    those of the fitted periodic motion over ``n_periods`` strides either way.
    """
    valid = np.all(np.isfinite(xyz), axis=(1, 2))
    run0, run1 = _longest_run(valid)
    if run1 - run0 < 8:
        raise KinematicsError(f"the markers are tracked together for at most {run1 - run0} consecutive frames; "
                              "the ride cannot be analysed")
    dt_s = float(np.median(np.diff(t[run0:run1])))
    # Period from the image-plane coordinates of the left camera: depth is the noisiest direction
    # when the cameras stand close together (thesis rig).
    f_range = STRIDE_RANGE_HZ.get(gait or "", (0.5, 3.0))
    try:
        period_s, period_info = _planar_period(t, xyz, valid, (run0, run1), dt_s, f_range)
    except KinematicsError:
        # Too short a run for a period: every tracked frame from the first to the last (gaps
        # interpolated) holds more strides than the run alone (a 0.97 s run was refused for its period).
        first, last = np.flatnonzero(valid)[[0, -1]]
        if (first, last + 1) == (run0, run1):
            raise
        period_s, period_info = _planar_period(t, xyz, valid, (first, last + 1), dt_s, f_range)
    flags_ = flags if flags is not None else []
    # the period from every tracked frame (the image-plane motion is periodic even where depth is
    # guessed); the window and the fits only where depth is not
    run0, run1 = _run_off_guessed_lens(t, valid, (run0, run1), period_s, beyond_px, flags_)
    n_periods = int(params.n_periods)
    whole = int(np.floor((run1 - run0) * dt_s / period_s + 1e-9))
    if whole < 1 and (hidden := hidden_marker_refusal(t, xyz, (run1 - run0) * dt_s, period_s)) is not None:
        raise hidden
    if 1 <= whole < n_periods:
        flags_.append(Finding("fit.short_crossing",
                              f"the markers were tracked together for {(run1 - run0) * dt_s:.2f} s, "
                              f"{_count(whole, 'stride')} of {period_s:.2f} s: the fits saw {_count(whole, 'stride')}, "
                              f"not {n_periods}, and the indicators are those of the fitted motion over {n_periods} "
                              "strides", {"tracked_s": (run1 - run0) * dt_s, "period_s": period_s,
                                          "strides_fitted": whole, "strides_asked": n_periods}))
        n_periods = whole
    i0, i1 = analysis_window(t[run0:run1], valid[run0:run1], period_s, n_periods=n_periods)
    i0, i1 = i0 + run0, i1 + run0
    # The fits see every tracked frame around the window ("run"), the thesis only the window: more
    # strides average out camera noise and skin wobble that is not locked to the stride.
    if params.fit_span not in ("run", "window"):
        raise InputError(f"fit_span must be 'run' or 'window', got {params.fit_span!r}")
    f0_, f1_ = i0, i1
    if params.fit_span == "run":
        margin = int(round(params.fit_margin_periods * period_s / dt_s))
        f0_, f1_ = max(run0, i0 - margin), min(run1, i1 + margin)
    return _Span((run0, run1), (i0, i1), (f0_, f1_), period_s, period_info)


def _smoothed(t_w: np.ndarray, xyz_w: np.ndarray, params: PipelineParams, period_s: float,
              depth: Mapping | None, flags: list[Finding]) -> tuple[np.ndarray, np.ndarray]:
    """The fitted span's tracks, smoothed as the rig and the user ask.

    The fitted span's tracks (F, 3, 3) mm with a narrow rig's depth fitted smoothly and, when asked,
    robust LOESS (5.2.2). Returns (smoothed tracks, frames (F,) with every marker).
    """
    n_markers = xyz_w.shape[1]
    if depth is not None and depth["anisotropy"] >= params.depth_anisotropy and np.all(np.isfinite(xyz_w)):
        # Narrow rig: the depth noise (systematic too: sub-frame sync, interpolation) leaks into
        # every axis through x = depth * ray, and the lateral sway is far below it: keep each
        # marker's rays and fit its depth with the straight path across the view.
        xyz_w, depth_orders = regularize_depth(t_w, xyz_w, depth["ray_origin_mm"], depth["worst_axis"],
                                               period_s=period_s, max_order=params.depth_max_order)
        flags.append(Finding("rig.weak_depth",
                             f"the rig fixes depth {depth['anisotropy']:.0f} times worse than image position: each "
                             "marker's depth was fitted with a straight path across the view (stride orders "
                             f"{depth_orders}); lateral sway and roll are not measured by this rig (both move the "
                             "markers in depth), so the saddle point misses its roll times its sideways offset from "
                             "the markers (a few % of the vertical acceleration; cameras 2-3 m apart see it)",
                             {"depth_anisotropy": depth["anisotropy"]}))
    # Robust LOESS on every coordinate in the window (5.2.2), as the thesis did, when asked. Not by
    # default: its local quadratic spans >= 5 samples (a sixth of a second at 30 fps) and flattens
    # the stride's higher harmonics (noiseless rides lose 2-13 % of the vertical acceleration's
    # r.m.s.); the Fourier fits smooth and reject outliers themselves.
    ok_w = np.all(np.isfinite(xyz_w), axis=(1, 2))
    if params.smoothing not in ("rloess", "none"):
        raise InputError(f"smoothing must be 'rloess' or 'none', got {params.smoothing!r}")
    smooth = xyz_w.copy() if params.smoothing == "none" else np.full_like(xyz_w, np.nan)
    if params.smoothing == "rloess":
        smooth[ok_w] = rloess(t_w[ok_w], xyz_w[ok_w].reshape(ok_w.sum(), -1), span=params.smoothing_span,
                              iterations=params.smoothing_iterations).reshape(-1, n_markers, 3)
    return smooth, ok_w


def _plumb_ends(plumb_tracks: MarkerTracks | None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The plumb line's upper and lower marker tracks (F, 3) mm, or (None, None)."""
    if plumb_tracks is None:
        return None, None
    p = static_positions(plumb_tracks, "plumb") if plumb_tracks.xyz_mm.ndim == 3 else None
    if p is None or p.shape[0] < 2:
        return None, None
    # the upper plumb marker is the one further against gravity; the left camera's image y
    # points roughly down, so it has the smaller rig y.
    top, bottom = (0, 1) if p[0, 1] < p[1, 1] else (1, 0)
    return plumb_tracks.xyz_mm[:, top], plumb_tracks.xyz_mm[:, bottom]


def _fit_markers(t_s: np.ndarray, xyz_m: np.ndarray, period_s: float, params: PipelineParams) -> MarkerKinematics:
    """Fourier (and linear) fits of every marker coordinate (5.5) with the user's model choices."""
    return fit_marker_kinematics(t_s, xyz_m, period_s=period_s, x_model=params.x_model,
                                 extra_orders=params.extra_orders, max_order=params.max_order,
                                 criterion=params.criterion, trend_degree=params.trend_degree,
                                 omega_from=params.omega_from, up_to_frame_rate=params.harmonics_up_to_frame_rate)


def _register_static_model(xyz: np.ndarray, xyz_m: np.ndarray, static_all: np.ndarray, static_tracks: MarkerTracks,
                           horse_idx: list[int], frame: MotionFrame) -> tuple[float, Registration]:
    """Register the static shot's horse markers to every frame (5.4).

    The static shot's horse markers registered to every frame (5.4), and how far (RMS of the
    pairwise distances, mm) the tracked layout is from the static shot's.
    """
    # per-frame distances, then their median (the median of each coordinate of a moving, bobbing
    # marker set is no one instant's layout: 118 mm off on a correctly tracked canter)
    d_motion = np.nanmedian(pairwise_distances(xyz), axis=0)
    d_static = pairwise_distances(static_all[horse_idx])
    mismatch_mm = float(np.sqrt(np.mean((d_static - d_motion) ** 2)))
    model_mm = marker_model(static_tracks.xyz_mm[:, horse_idx])
    reg = register_rigid(xyz_m, motion.to_motion_frame(model_mm, frame))
    if not np.all(reg.valid):
        raise KinematicsError("some frames of the analysed stretch could not be registered")
    return mismatch_mm, reg


def _fitted_saddle_point(t_fit: np.ndarray, reg: Registration, xyz_m: np.ndarray, bridged_fit: np.ndarray,
                         span: _Span, static_all: np.ndarray, horse_idx: list[int], saddle_idx: int,
                         frame: MotionFrame, params: PipelineParams, flags: list[Finding]):
    """Fits (5.5), angular kinematics (6.1-6.2) and the saddle point (6.3-6.4) on the window.

    Returns (marker fits, registration, registered markers (F, 3, 3) m, angular kinematics, the saddle
    point's kinematics, S in body coordinates (3,) m) on the window; appends its flags.
    """
    period_s, in_win = span.period_s, span.in_window
    # Curve fitting (5.5): velocities and accelerations are analytic derivatives of the fits; what
    # follows is reported on the analysed window.
    # Bridged samples keep the registration whole but are not measurements: the fits leave them out
    # (a 4-frame bridge flattened a canter's acceleration peak, 24 % error on a thesis-rig ride).
    measured = ~bridged_fit[:, None, None]
    fits = _fit_markers(t_fit, np.where(measured, reg.registered, np.nan), period_s, params)
    flags.extend(fits.flags)
    fits = _on_window(fits, in_win)
    reg = Registration(*(getattr(reg, f.name)[in_win] for f in fields(reg)))
    rigidity_mm = float(np.nanmedian(reg.rms_residual) * 1e3)
    if rigidity_mm > params.max_rigidity_residual_mm:
        flags.append(Finding("markers.rigidity",
                             f"the markers kept the static shot's layout only to {rigidity_mm:.0f} mm (median "
                             "rigidity residual; skin motion leaves a few mm): a look-alike was tracked, a marker "
                             "moved after the static shot, or the static shot is of another set-up; the saddle point "
                             "is unreliable", {"rigidity_residual_mm": rigidity_mm,
                                               "limit_mm": params.max_rigidity_residual_mm}))
    r = reg.registered
    t_win = t_fit[in_win]
    bridged_w = bridged_fit[in_win]
    if bridged_w.any():
        # a bridge is an interpolation across up to a quarter second of a canter's stride; the fits,
        # which saw the same phase in the other strides, are the better positions there
        r = r.copy()
        r[bridged_w] = fits.position_m(t_win[bridged_w])

    # Angular velocity and acceleration (6.1-6.2), the invisible saddle point (6.3-6.4).
    raw = None
    if params.angular_method == "lsq_wiener":
        raw_fits = _on_window(_fit_markers(t_fit, np.where(measured, xyz_m, np.nan), period_s, params), in_win)
        # bridged positions are no measurements of the skin motion the gain weighs
        raw = (np.where(bridged_w[:, None, None], np.nan, xyz_m[in_win]), raw_fits.velocity_m_s,
               raw_fits.acceleration_m_s2)
    ang = angular_kinematics(r, fits.velocity_m_s, fits.acceleration_m_s2,
                             singularity_threshold=params.singularity_threshold, method=params.angular_method, raw=raw)
    flags.extend(ang.flags)
    static_motion = motion.to_motion_frame(static_all, frame)
    r_bs = saddle_body_coordinates(static_motion[horse_idx], static_motion[saddle_idx])
    s = saddle_point_kinematics(r, fits.velocity_m_s, fits.acceleration_m_s2, ang, r_bs)

    return fits, reg, r, ang, s, r_bs


def saddle_kinematics(motion_tracks: MarkerTracks, static_tracks: MarkerTracks,
                      plumb_tracks: MarkerTracks | None, params: PipelineParams, *,
                      horse_idx: list[int] | None = None, saddle_idx: int | None = None,
                      gait: str | None = None, depth: Mapping | None = None,
                      down_hint: np.ndarray | None = None) -> SaddleAnalysis:
    """Saddle point kinematics from 3-D tracks (thesis 5.2-6.4).

    Parameters
    ----------
    motion_tracks : MarkerTracks
        The three horse markers through the ride, ``xyz_mm`` of shape (F, 3, 3). A
        :class:`~saddlescope.core.triangulation.ReachCheckedTracks` also says where their depth rests
        on a guessed lens: those frames give the period but not the window or the fits, while a stride
        remains (:func:`_run_off_guessed_lens`).
    static_tracks : MarkerTracks
        The standing horse's markers and the saddle marker, ``xyz_mm`` of shape (G, 4, 3).
    plumb_tracks : MarkerTracks or None
        The plumb line's two markers, ``xyz_mm`` of shape (H, 2, 3): gravity.
    params : PipelineParams
    horse_idx, saddle_idx : optional
        The static shot's horse markers (in the motion clip's order) and saddle marker; found from
        the markers' distances when not given.
    gait : str, optional
        Narrows the stride frequencies searched (:data:`STRIDE_RANGE_HZ`).
    depth : mapping, optional
        The rig's :func:`~saddlescope.core.triangulation.position_uncertainty` at the markers; where
        depth is much worse fixed than the image position (``params.depth_anisotropy``) each marker's
        depth is fitted smoothly before anything else.
    down_hint : ndarray of shape (3,), optional
        Stands in for gravity (rig coordinates) when there is no plumb line: the pipeline passes the
        cameras' mean image-down direction (one tilted camera then costs a third of its tilt).

    Returns
    -------
    SaddleAnalysis
    """
    t = np.asarray(motion_tracks.t_s, dtype=np.float64)
    flags: list[Finding] = []
    xyz, bridged_frames, long_gaps, measured = _checked_tracks(
        t, np.asarray(motion_tracks.xyz_mm, dtype=np.float64), params, flags)
    beyond_px = getattr(motion_tracks, "lens_extrapolation_px", None)  # ReachCheckedTracks
    span = _stride_span(t, xyz, params, gait, flags,
                        beyond_px=None if beyond_px is None else np.max(beyond_px, axis=1))
    period_s, win, in_win = span.period_s, span.fit_slice, span.in_window
    t_w = t[win]
    smooth, ok_w = _smoothed(t_w, xyz[win], params, period_s, depth, flags)

    # Motion reference frame (5.3): travel of marker 1, gravity from the plumb.
    plumb_top, plumb_bottom = _plumb_ends(plumb_tracks)
    # travel (eq. 5.6-5.7, as a fitted velocity) from marker 1's measured positions over the fitted
    # frames: a bridged peak tilted x by 1.5 mrad, a 7 mm ramp on a canter's vertical (a look-alike
    # followed for a few frames is left out by the travel fit itself)
    travel = np.where(bridged_frames[win, None], np.nan, xyz[win, 0])
    frame = motion.motion_frame(travel, plumb_top_mm=plumb_top, plumb_bottom_mm=plumb_bottom, rig_down_hint=down_hint,
                                hint_name="the cameras' mean image-down direction (level cameras assumed)",
                                origin_mm=smooth[in_win][0, 0] if ok_w[in_win][0] else None,
                                t_s=t_w, period_s=period_s)
    flags.extend(frame.warnings)
    xyz_m = motion.to_motion_frame(smooth, frame)

    # Rigid registration of the static-shot model (5.4).
    static_all = static_positions(static_tracks, "static")
    if horse_idx is None or saddle_idx is None:
        horse_idx, saddle_idx, _ = identify_saddle_marker(static_all, xyz)
    mismatch_mm, reg = _register_static_model(xyz, xyz_m, static_all, static_tracks, horse_idx, frame)

    fit_reg = reg
    fits, reg, r, ang, s, r_bs = _fitted_saddle_point(t[win], reg, xyz_m, bridged_frames[win], span, static_all,
                                                     horse_idx, saddle_idx, frame, params, flags)
    refit = _deletion_refit(t_w, fit_reg, xyz_m, bridged_frames[win], span, static_all, horse_idx, saddle_idx, frame,
                            params, fits)
    omega = fits.omega_rad_s if np.isfinite(fits.omega_rad_s) else 2 * np.pi / period_s
    unmeasured = unmeasured_phase(t_w, measured[win], xyz_m, float(2 * np.pi / omega), flags, refit=refit,
                                  base=_vertical_of(fits, s, t_w[in_win], period_s))
    return SaddleAnalysis(t_s=t_w[in_win], period_s=float(2 * np.pi / omega), period_estimate_s=float(period_s),
                          period_info=span.period_info, window=span.window, fitted=span.fitted, frame=frame,
                          registration=reg, fits=fits, angular=ang, saddle=s, markers_m=r,
                          static_mismatch_mm=mismatch_mm, r_bs_m=r_bs, flags=tuple(flags), long_gaps=long_gaps,
                          unmeasured_phase=unmeasured)


def _deletion_refit(t_w: np.ndarray, reg: Registration, xyz_m: np.ndarray, bridged_w: np.ndarray, span: _Span,
                    static_all: np.ndarray, horse_idx: list[int], saddle_idx: int, frame: MotionFrame,
                    params: PipelineParams, base: MarkerKinematics):
    """The refit the phase-deletion test asks for (:func:`~saddlescope.core.kinematics.hidden_phase.unmeasured_phase`).

    ``refit(deleted)``: the saddle point's vertical harmonics (:func:`_vertical_of`) fitted exactly as the
    analysis fits them (:func:`_fitted_saddle_point`) with the fitted frames ``deleted`` (F,) left out instead
    of the hidden ones. The hidden frames take the analysis's own fitted positions (``base``): each refit then
    has one gap, as wide as the hidden part, as the analysis had; leaving the hidden part out as well made two
    gaps, which a thesis rig's noisy fits bridge with lower orders, so the test measured the second gap, not
    the first (docs/accuracy.md, "What a hidden phase costs").
    """
    if bridged_w.any():
        guessed = base.position_m(t_w[bridged_w])
        registered = reg.registered.copy()
        registered[bridged_w] = guessed
        reg = replace(reg, registered=registered)
        xyz_m = xyz_m.copy()
        xyz_m[bridged_w] = guessed
        left_out = np.zeros_like(bridged_w)
    else:
        left_out = bridged_w

    def refit(deleted: np.ndarray) -> dict:
        fits, _, _, _, s, _ = _fitted_saddle_point(t_w, reg, xyz_m, left_out | deleted, span, static_all, horse_idx,
                                                   saddle_idx, frame, params, [])
        return _vertical_of(fits, s, t_w[span.in_window], span.period_s)
    return refit


def _vertical_of(fits: MarkerKinematics, s, t_win: np.ndarray, period_s: float) -> dict:
    """The saddle point's vertical harmonics (:func:`vertical_harmonics`) as the indicators take them."""
    omega = fits.omega_rad_s if np.isfinite(fits.omega_rad_s) else 2 * np.pi / period_s
    return vertical_harmonics(t_win, s.acceleration_m_s2[:, 1], s.position_m[:, 1], float(2 * np.pi / omega),
                              max(f.order for f in fits.fits_y))


def _harmonic_form(t_s: np.ndarray, y: np.ndarray, f0_hz: float, order: int, *, trend: bool = False
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares cosine series at a known fundamental.

    Least-squares cosine series y ~ c0 + sum A_k cos(2 pi k f0 t + phi_k) at a known f0 (plus a
    straight line c1 t with ``trend``: a slope is no part of an oscillation).

    Returns (A (order,), phi (order,), fitted y).
    """
    cols = [np.ones_like(t_s)] + ([t_s - t_s.mean()] if trend else [])
    for k in range(1, order + 1):
        w = 2 * np.pi * k * f0_hz * t_s
        cols += [np.cos(w), np.sin(w)]
    design = np.stack(cols, axis=1)
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    harm = coef[2:] if trend else coef[1:]
    a_k, b_k = harm[0::2], harm[1::2]
    # a cos + b sin = A cos(wt + phi) with A = hypot(a, b), phi = atan2(-b, a)
    return np.hypot(a_k, b_k), np.arctan2(-b_k, a_k), design @ coef


def vertical_harmonics(t_s: np.ndarray, acc_y: np.ndarray, pos_y: np.ndarray, period_s: float,
                       fit_order: int) -> dict:
    """Fourier form of the saddle point's vertical motion at the stride frequency.

    Fourier form of the saddle point's vertical motion at the stride frequency (for the exact
    harmonic weighting of the vibration stage) and its peak-to-peak displacement.

    Parameters
    ----------
    t_s, acc_y, pos_y : ndarray of shape (F,)
        Times (s), vertical acceleration (m/s²) and position (m) of S over the window.
    period_s : float
        The stride period.
    fit_order : int
        The vertical fits' order: the series goes two orders beyond it (at least 4).

    Returns
    -------
    dict
        ``f0_hz``, ``amplitudes_m_s2`` and ``phases_rad`` (order,), ``order``, ``fit_rms_residual_m_s2``,
        ``amplitude_y_m`` (peak to peak).
    """
    f0 = 1.0 / period_s
    max_order = max(1, (len(t_s) - 1) // 2 - 1)
    order = int(min(max_order, max(fit_order + 2, 4)))
    amps, phases, fitted = _harmonic_form(t_s, acc_y, f0, order)
    resid = acc_y - fitted
    # the registered position may keep a slope over the window (a tilt of gravity, a wandering
    # depth): fitted as a line, not folded into the peak-to-peak
    pos_amp, pos_phase, _ = _harmonic_form(t_s, pos_y, f0, order, trend=True)
    dense = np.linspace(0.0, period_s, 2048, endpoint=False)
    k = np.arange(1, order + 1)
    y_dense = np.sum(pos_amp[None, :] * np.cos(2 * np.pi * f0 * dense[:, None] * k[None, :] + pos_phase[None, :]),
                     axis=1)
    return {"f0_hz": f0, "amplitudes_m_s2": amps, "phases_rad": phases, "order": order,
            "fit_rms_residual_m_s2": float(np.sqrt(np.mean(resid ** 2))),
            "amplitude_y_m": float(y_dense.max() - y_dense.min())}


def kinematics_indicators(kin: SaddleAnalysis, params: PipelineParams) -> tuple[dict, dict]:
    """The saddle point's vertical harmonics and the rider's indicators (thesis 7, 8.5).

    The vertical harmonics of the saddle point and the rider's indicators (thesis 7, 8.5) from the
    output of :func:`saddle_kinematics`.
    """
    s = kin.saddle
    fit_order = max(f.order for f in kin.fits.fits_y)
    harm = vertical_harmonics(kin.t_s, s.acceleration_m_s2[:, 1], s.position_m[:, 1], kin.period_s,
                              fit_order)
    indicators = ride_indicators(f0_hz=harm["f0_hz"], acc_y_amplitudes_m_s2=harm["amplitudes_m_s2"],
                                 acc_y_phases_rad=harm["phases_rad"], duration_s=kin.period_s * params.n_periods,
                                 speed_kmh=abs(kin.fits.average_speed_m_s) * 3.6,
                                 amplitude_y_m=harm["amplitude_y_m"], stride_frequency_hz=1.0 / kin.period_s)
    return harm, indicators

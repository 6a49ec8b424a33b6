"""Synchronisation without a flash: the cameras' offsets from the markers' own motion.

Phones are not genlocked and a club may have no flash. Two steps find the offsets (same convention
as :mod:`saddlescope.core.sync`: the instant of the reference camera's frame k is camera c's frame
k + o_c; for a variable-rate clip o_c counts nominal frames from clip frame 0):

1. **Whole frames, from image speed.** Each camera's image speed s_c(k) = mean over its markers of
   |x(k+1) - x(k)| (px/frame; a board's corners play the markers' part) differs between views by
   little more than a scale, so the normalised cross-correlation of s_c against the reference's over
   every candidate lag finds the offset to a frame, up to whole strides: a periodic gait repeats its
   speed every stride, so every correlation peak within ``keep_peak`` of the best is a candidate
   (a camera seeing only part of the crossing may peak higher a stride away than at its offset).
   With a rig, ``MAX_CANDIDATES`` peaks per camera, and their combinations ranked by how well every
   pair of cameras' speeds agree at the lags they imply (a walk's true lag can be a tenth peak).
2. **Sub-frame, from triangulation consistency** (when a calibrated rig is given). Every camera's
   track is smoothed by the same Gaussian (``SMOOTH_FRAMES``); for offsets o it is sampled at the
   reference's frames shifted by o_c (cubic, as :func:`~saddlescope.core.triangulation.resample_tracks`),
   each marker is triangulated (linear DLT in ideal normalised coordinates) and reprojected. A wrong
   offset moves a marker along its path in one camera only, which no 3-D point explains; the
   best ``MAX_COMBINATIONS`` combinations are ranked by that cost (with three cameras or more, on the
   points every camera saw: two views of the wide rig's horizontal motion agree at nearly any
   offset), the best and the best ones a stride or more away are refined (Powell, within 1.5
   frames), the most consistent is kept and finished by Newton steps on the cost's local quadratic.
   A rival that the cost does not join to the best without a rise, at a cost within
   ``AMBIGUOUS_COST_RATIO`` of the best's, is refused as ambiguous.

Why smooth: white tracking noise resampled between frames is averaged with its neighbours' and so
smaller at half a frame than at a whole one, which pulls the offsets towards half frames wherever the
cost changes little with them. On the wide rig it changes little in one direction: the cameras'
centres and the track lie nearly in one plane, so the horse's horizontal motion stays in the
cameras' epipolar planes and, while its velocity keeps its direction, shifting the three clocks in
one combination (the middle camera's at about the mean of the outer two's) leaves every ray meeting;
only the markers' vertical motion fixes it. On a wide-rig walk's exact tracks with 0.09 px of white
noise that pull was 0.3 frame unsmoothed, 0.05 with 1 frame of smoothing; the same smoothing in every
camera delays every clock alike, but bends fast motion a little (0.01 frame on a 30 fps rising trot's
exact tracks). Variable-rate clips are not smoothed: over their uneven instants it bent the motion more.

Uncertainty: with g_k the cost's gradient from the reference's frame k and H its Hessian (central
differences on the residuals present at every step), the tracking noise's covariance of the offsets
is H^-1 V H^-1, V the long-run covariance of g_k (Bartlett weights over a quarter of a second: the
smoothed errors are correlated over a few frames), and never less than Gauss-Newton's with the
residuals independent once per smoothing width; to it is added the smoothing's own pull (it grows
as the smoothing's width squared: 4/3 of the offsets' move with half the smoothing). An offset not
fixed to half a frame is refused. Without a rig (the calibration clip, whose board is held still
while it is photographed, so whole frames suffice) the offsets come from the correlation alone, of
the board's signed velocity across and down the image (:func:`board_velocity`) rather than its
speed, its peak placed between frames by a parabola; their uncertainty is the peak's curvature and
at least a whole frame's rounding, 1/sqrt(12) frame.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from saddlescope.core.camera_model import undistort_normalized
from saddlescope.core.errors import SyncError
from saddlescope.core.sync import clip_frames_at
from saddlescope.core.triangulation import resample_tracks
from saddlescope.core.triangulation.matching import match_markers_across_cameras
from saddlescope.core.triangulation.tracks import at_top_row_instants
from saddlescope.core.types import ImageTracks, Rig

__all__ = ["MotionSync", "board_velocity", "image_speed", "motion_offsets", "speed_correlation",
           "speed_offset_candidates"]

MIN_SPEED_PX = 1.0  # px/frame: markers moving less than this (90th percentile) give no motion to sync on
MIN_OVERLAP_FRAMES = 12  # frames where both cameras' speeds are known, at the least
MAX_GAP_FRAMES = 3  # gaps of a track bridged for its image speed
HUBER_PX = 2.0  # residuals beyond this count linearly (a marker mistracked for a frame)
AMBIGUOUS_COST_RATIO = 4.0  # a rival offset's cost within this factor of the best's: the offset is ambiguous
SMOOTH_FRAMES = 1.0  # Gaussian smoothing of every track before resampling, frames (see _smoothed)
MAX_CANDIDATES = 12  # correlation peaks kept per camera (with a rig: the combinations are ranked first)
MAX_COMBINATIONS = 36  # whole-frame combinations triangulated, the best by pairwise speed correlation
MAX_RIVALS = 4  # combinations a stride or more from the best whole-frame one also refined


@dataclass(frozen=True)
class MotionSync:
    """Offsets of every camera from the markers' motion, with their uncertainty.

    ``offsets`` and ``sigma_frames`` map camera -> frames (the reference 0); ``method`` is
    "motion"; ``rms_px`` the r.m.s. reprojection residual at the chosen offsets (None without a
    rig); ``candidates`` the whole-frame offsets tried per camera; ``n_frames`` the reference frames
    that took part.
    """

    offsets: dict[str, float]
    sigma_frames: dict[str, float]
    rms_px: float | None = None
    n_frames: int = 0
    candidates: dict[str, list[int]] = field(default_factory=dict)
    method: str = "motion"


def _nominal_xy(track: ImageTracks, n_frames: int, fps: float,
                clock: tuple[np.ndarray, float] | None) -> np.ndarray:
    """A camera's tracks on its nominal even clock, frames 0..n_frames-1, shape (n_frames, M, 2)."""
    frames = np.arange(n_frames, dtype=np.float64)
    times = None
    if clock is not None:
        times, anchor = clock
        frames = clip_frames_at(frames, times, anchor, fps)
    return _bridge_gaps(resample_tracks(track, frames, kind="linear", frame_times_s=times))


def _bridge_gaps(xy: np.ndarray, max_gap: int = MAX_GAP_FRAMES) -> np.ndarray:
    """Gaps of up to ``max_gap`` frames inside each marker's track filled linearly, shape as ``xy`` (F, M, 2).

    A blurred board is not found while it moves (the frames the board's motion is in), a marker
    is hidden for a frame or two: the step across the gap is spread over it.
    """
    out = xy.copy()
    k = np.arange(xy.shape[0])
    for m in range(xy.shape[1]):
        ok = np.all(np.isfinite(xy[:, m]), axis=1)
        if ok.sum() < 2:
            continue
        seen = k[ok]
        # the length of the gap each missing frame sits in (from the previous to the next seen frame)
        nxt = np.searchsorted(seen, k)
        inside = (~ok) & (nxt > 0) & (nxt < seen.size)
        gap = np.where(inside, seen[np.clip(nxt, 0, seen.size - 1)] - seen[np.clip(nxt - 1, 0, seen.size - 1)] - 1, 0)
        fill = inside & (gap <= max_gap)
        for d in range(2):
            out[fill, m, d] = np.interp(k[fill], seen, xy[ok, m, d])
    return out


def image_speed(xy_px: np.ndarray) -> np.ndarray:
    """Image speed of a camera's markers, px/frame, shape (F - 1,): sample k is frames k to k+1.

    The mean over the markers seen in both frames of |x(k+1) - x(k)|; NaN where none was.

    Parameters
    ----------
    xy_px : ndarray of shape (F, M, 2)
        Marker positions on an even clock, NaN in gaps.
    """
    xy = np.asarray(xy_px, dtype=np.float64)
    if xy.ndim != 3 or xy.shape[-1] != 2:
        raise SyncError(f"marker tracks must have shape (F, M, 2), got {xy.shape}")
    step = np.linalg.norm(np.diff(xy, axis=0), axis=-1)  # (F-1, M), NaN where a marker is missing
    seen = np.isfinite(step)
    with np.errstate(invalid="ignore"):
        return np.where(seen.any(axis=1), np.nansum(np.where(seen, step, 0.0), axis=1) / seen.sum(axis=1), np.nan)


def board_velocity(xy_px: np.ndarray) -> np.ndarray:
    """Signed image velocity of a board, px/frame, shape (F - 1, 2): the mean step of its corners seen in both frames.

    The calibration clip's board is held still three frame periods and moved in one, so its image
    speed repeats every four frames and the moves' sizes alone match the cameras' clocks poorly (a wide-
    rig clip, seed 8, was placed 28 and 36 frames off). The moves' directions tell them apart: cameras
    side by side and upright see a move to the right or down as one, whatever their distance and angle.
    NaN where no corner was seen in both frames.
    """
    xy = np.asarray(xy_px, dtype=np.float64)
    step = np.diff(xy, axis=0)  # (F-1, N, 2)
    seen = np.all(np.isfinite(step), axis=2)
    count = seen.sum(axis=1)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, np.where(seen[..., None], step, 0.0).sum(axis=1) / count, np.nan)


def _speed_changes(speed: np.ndarray, *, window: int) -> np.ndarray:
    """Relative changes of the image speed: log(1 + speed / 1 px) minus its running mean over ``window`` samples.

    The log takes out each view's scale (distance, focal length) of a moving horse, while a board
    held still (speed 0) stays finite; the running mean takes out the slow change of scale as the
    horse crosses each view (perspective), which differs from camera to camera and would otherwise
    outweigh the stride's speed changes that all cameras share.
    """
    v = np.log1p(np.asarray(speed, dtype=np.float64))
    ok = np.isfinite(v)
    kernel = np.ones(window)
    total = np.convolve(np.where(ok, v, 0.0), kernel, mode="same")
    count = np.convolve(ok.astype(np.float64), kernel, mode="same")
    with np.errstate(invalid="ignore", divide="ignore"):
        trend = total / count
    return np.where(ok & (count >= window / 2), v - trend, np.nan)


def speed_correlation(ref_speed: np.ndarray, cam_speed: np.ndarray, lags: np.ndarray, *,
                      min_overlap: int = MIN_OVERLAP_FRAMES) -> np.ndarray:
    """Normalised cross-correlation of two image-speed curves at integer lags, shape (L,).

    Lag L pairs reference sample k with camera sample k + L (NaN where fewer than ``min_overlap``
    samples are known in both, or either is constant there).
    """
    a = np.asarray(ref_speed, dtype=np.float64)
    b = np.asarray(cam_speed, dtype=np.float64)
    out = np.full(len(lags), np.nan)
    for i, lag in enumerate(np.asarray(lags, dtype=np.int64)):
        lo, hi = max(0, -lag), min(len(a), len(b) - lag)
        if hi - lo < min_overlap:
            continue
        x, y = a[lo:hi], b[lo + lag: hi + lag]
        ok = np.isfinite(x) & np.isfinite(y)
        if ok.sum() < min_overlap:
            continue
        x, y = x[ok] - x[ok].mean(), y[ok] - y[ok].mean()
        den = np.sqrt(np.sum(x * x) * np.sum(y * y))
        if den > 0:
            out[i] = float(np.sum(x * y) / den)
    return out


def _peaks(lags: np.ndarray, ncc: np.ndarray, keep_peak: float, max_candidates: int) -> list[int]:
    """The lags of the correlation's local maxima within ``keep_peak`` of the best, best first."""
    c = np.where(np.isfinite(ncc), ncc, -np.inf)
    best = float(c.max())
    left = np.concatenate([[-np.inf], c[:-1]])
    right = np.concatenate([c[1:], [-np.inf]])
    is_peak = (c >= left) & (c >= right) & (c >= best - keep_peak) & np.isfinite(ncc) & (c > 0)
    order = np.argsort(-c[is_peak])
    return [int(v) for v in lags[is_peak][order][:max_candidates]]


def _parabola_peak(lags: np.ndarray, ncc: np.ndarray, lag: int) -> tuple[float, float]:
    """The correlation peak at ``lag`` placed between frames by a parabola, and its curvature (> 0)."""
    i = int(np.flatnonzero(lags == lag)[0])
    if i == 0 or i == len(lags) - 1 or not np.all(np.isfinite(ncc[i - 1: i + 2])):
        return float(lag), 0.0
    ym, y0, yp = ncc[i - 1: i + 2]
    curv = float(ym - 2 * y0 + yp)
    if curv >= 0:
        return float(lag), 0.0
    return float(lag + np.clip(0.5 * (ym - yp) / curv, -0.5, 0.5)), -curv


def speed_offset_candidates(speeds: Mapping[str, np.ndarray], *, reference: str, max_lag: int,
                            keep_peak: float = 0.5, max_candidates: int = 6, min_ncc: float = 0.3,
                            clip: str = "motion") -> dict[str, tuple[list[int], np.ndarray, np.ndarray]]:
    """Whole-frame offset candidates of every camera from its image speed against the reference's.

    Returns
    -------
    dict camera -> (candidate lags best first, lags (L,), correlation (L,)); the reference's is ([0], ...).

    Raises
    ------
    SyncError
        A camera whose speed correlates with the reference's at no lag.
    """
    out: dict[str, tuple[list[int], np.ndarray, np.ndarray]] = {}
    lags = np.arange(-max_lag, max_lag + 1)
    for cam, s in speeds.items():
        if cam == reference:
            out[cam] = ([0], lags, np.full(len(lags), np.nan))
            continue
        # a short overlap correlates well by chance: at least half the shorter curve's known samples
        ref_curves, curves = np.asarray(speeds[reference]), np.asarray(s)
        if curves.ndim == 1:
            ref_curves, curves = ref_curves[:, None], curves[:, None]
        known = min(np.isfinite(ref_curves[:, 0]).sum(), np.isfinite(curves[:, 0]).sum())
        overlap = max(MIN_OVERLAP_FRAMES, int(0.5 * known))
        # several curves per camera (a board's velocity across and down the image): their mean correlation
        ncc = np.mean([speed_correlation(ref_curves[:, i], curves[:, i], lags, min_overlap=overlap)
                       for i in range(curves.shape[1])], axis=0)
        if not np.any(np.isfinite(ncc)) or np.nanmax(ncc) < min_ncc:
            best = np.nanmax(ncc) if np.any(np.isfinite(ncc)) else float("nan")
            raise SyncError(f"no sync flash, and the markers' motion in the {cam} camera's {clip} clip matches "
                            f"the {reference} camera's at no offset within {max_lag} frames (best "
                            f"correlation {best:.2f}, under {min_ncc:g}): the cameras may not see the same "
                            "motion at the same time; film a flash, or give the offsets in ride.json")
        out[cam] = (_peaks(lags, ncc, keep_peak, max_candidates), lags, ncc)
    return out


class _Consistency:
    """Triangulation consistency of the cameras' tracks at trial offsets (module docstring, step 2)."""

    def __init__(self, rig: Rig, tracks: Mapping[str, ImageTracks], reference: str, fps: float,
                 clocks: Mapping[str, tuple[np.ndarray, float]], smooth_frames: float = SMOOTH_FRAMES):
        self.cams = list(tracks)
        self.reference, self.fps, self.clocks = reference, fps, clocks
        self.ref_frames = np.asarray(tracks[reference].frame_index, dtype=np.float64)
        self.tracks_px = {c: _smoothed(tr, smooth_frames) for c, tr in tracks.items()}
        self.focal = {c: float(np.mean(np.diag(rig.cameras[c].K)[:2])) for c in self.cams}
        self.P = {c: np.hstack([rig.cameras[c].R, np.reshape(rig.cameras[c].t_mm, (3, 1))]) for c in self.cams}
        self.rig = rig
        self.set_labels({c: np.arange(np.asarray(tracks[c].xy_px).shape[1]) for c in self.cams})

    def set_labels(self, perms: Mapping[str, np.ndarray]) -> None:
        """Reorder each camera's markers to the reference's labels; tracks in ideal normalised coordinates."""
        self.norm, self.perms = {}, dict(perms)
        for c in self.cams:
            tr = self.tracks_px[c]
            xy = np.asarray(tr.xy_px, dtype=np.float64)[:, perms[c]]
            self.norm[c] = ImageTracks(c, undistort_normalized(self.rig.cameras[c], xy), tr.frame_index)

    def sampled(self, offsets: Mapping[str, float], *, pixels: bool = False) -> dict[str, np.ndarray]:
        """Every camera's markers at the reference's frames, (F, M, 2), with the trial offsets."""
        out = {}
        for c in self.cams:
            wanted = self.ref_frames + float(offsets.get(c, 0.0))
            times = None
            if c in self.clocks:
                times, anchor = self.clocks[c]
                wanted = clip_frames_at(wanted, times, anchor, self.fps)
            src = self.tracks_px[c] if pixels else self.norm[c]
            out[c] = resample_tracks(src, wanted, frame_times_s=times)
        return out

    def residual_table(self, offsets: Mapping[str, float]) -> np.ndarray:
        """Reprojection residual (px) of every camera's view of every reference (frame, marker), (C, F * M).

        NaN where the camera did not see it or fewer than two cameras did (nothing to triangulate).
        """
        xy = self.sampled(offsets)
        obs = np.stack([xy[c].reshape(-1, 2) for c in self.cams])  # (C, N, 2)
        seen = np.all(np.isfinite(obs), axis=2)  # (C, N)
        use = seen.sum(axis=0) >= 2
        out = np.full(seen.shape, np.nan)
        if not use.any():
            return out
        obs, seen = obs[:, use], seen[:, use]
        P = np.stack([self.P[c] for c in self.cams])  # (C, 3, 4)
        # linear DLT: x P3 - P1 = 0, y P3 - P2 = 0 for every camera that saw the point
        o = np.nan_to_num(obs)
        rows_x = o[..., 0:1] * P[:, None, 2, :] - P[:, None, 0, :]  # (C, N, 4)
        rows_y = o[..., 1:2] * P[:, None, 2, :] - P[:, None, 1, :]
        A = np.concatenate([rows_x, rows_y], axis=0) * np.concatenate([seen, seen])[..., None]  # (2C, N, 4)
        _, _, vt = np.linalg.svd(np.transpose(A, (1, 0, 2)))
        X = vt[:, -1, :]  # (N, 4)
        X = X[:, :3] / X[:, 3:4]
        for i, c in enumerate(self.cams):
            xc = X @ self.P[c][:, :3].T + self.P[c][:, 3]
            proj = xc[:, :2] / xc[:, 2:3]
            r = np.linalg.norm(proj - obs[i], axis=1) * self.focal[c]
            out[i, np.flatnonzero(use)] = np.where(seen[i], r, np.nan)
        return out

    def residuals(self, offsets: Mapping[str, float]) -> tuple[np.ndarray, int]:
        """Reprojection residuals (px) of every marker seen by two cameras or more, and how many points."""
        table = self.residual_table(offsets)
        return table[np.isfinite(table)], int(np.any(np.isfinite(table), axis=0).sum())

    def cost(self, offsets: Mapping[str, float], *, all_cameras: bool = False) -> tuple[float, int, int]:
        """Sum of Huber losses (px^2), residuals and points (``all_cameras``: of the points every camera saw)."""
        table = self.residual_table(offsets)
        if all_cameras:
            table = table[:, np.all(np.isfinite(table), axis=0)]
        r = table[np.isfinite(table)]
        if r.size == 0:
            return np.inf, 0, 0
        return float(_huber(r).sum()), int(r.size), int(np.any(np.isfinite(table), axis=0).sum())


def _huber(r_px: np.ndarray) -> np.ndarray:
    """Huber loss of residual norms (px^2): 1/2 r^2 within HUBER_PX, linear beyond."""
    return np.where(r_px <= HUBER_PX, 0.5 * r_px * r_px, HUBER_PX * (r_px - 0.5 * HUBER_PX))


def _smoothed(track: ImageTracks, sigma_frames: float = SMOOTH_FRAMES) -> ImageTracks:
    """A camera's tracks smoothed over its frames by a Gaussian (the same in every camera), NaN near gaps.

    Resampling white tracking noise between frames averages neighbours: a camera shifted by half a
    frame shows less noise than one shifted by a whole frame, so the triangulation cost favours
    half frames. Where the cost hardly changes with the offsets (the wide rig's walk) that pulled the
    offsets 0.3 frame off on exact tracks with 0.09 px of noise. Smoothed first, the noise varies
    little between frames; the same filter in every camera delays every clock alike.
    """
    fi = np.asarray(track.frame_index, dtype=np.int64)
    xy = np.asarray(track.xy_px, dtype=np.float64)
    if fi.size == 0 or sigma_frames <= 0:
        return track
    dense = np.full((int(fi.max() - fi.min()) + 1, *xy.shape[1:]), np.nan)
    dense[fi - fi.min()] = xy
    half = int(np.ceil(3 * sigma_frames))
    kernel = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma_frames) ** 2)
    kernel /= kernel.sum()
    ok = np.isfinite(dense)
    total = np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="same"), 0, np.where(ok, dense, 0.0))
    weight = np.apply_along_axis(lambda v: np.convolve(v, kernel, mode="same"), 0, ok.astype(np.float64))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(weight > 1 - 1e-9, total / weight, np.nan)  # only where every tap saw the marker
    return ImageTracks(track.camera, out, np.arange(fi.min(), fi.max() + 1))


def _match_labels(cons: _Consistency, offsets: Mapping[str, float], n_instants: int = 12) -> None:
    """The cameras' marker labels matched at trial offsets (as triangulate_tracks does)."""
    cons.set_labels({c: np.arange(np.asarray(cons.tracks_px[c].xy_px).shape[1]) for c in cons.cams})
    xy = cons.sampled(offsets, pixels=True)
    full = np.all(np.stack([np.all(np.isfinite(v), axis=(1, 2)) for v in xy.values()]), axis=0)
    hits = np.flatnonzero(full)
    if hits.size == 0 or np.asarray(cons.tracks_px[cons.reference].xy_px).shape[1] < 2:
        return
    pick = hits[np.unique(np.linspace(0, hits.size - 1, min(hits.size, n_instants)).round().astype(int))]
    cons.set_labels(match_markers_across_cameras(cons.rig, {c: xy[c][pick] for c in cons.cams},
                                                 reference=cons.reference))


def motion_offsets(tracks: Mapping[str, ImageTracks], fps: float, *, rig: Rig | None = None,
                   reference: str | None = None, clocks: Mapping[str, tuple[np.ndarray, float]] | None = None,
                   max_offset_s: float = 2.0, clip: str = "motion",
                   row_readout: Mapping[str, tuple[float, int]] | None = None) -> MotionSync:
    """Offsets of every camera against the reference from the markers' motion (module docstring).

    Parameters
    ----------
    tracks : dict camera -> ImageTracks
        Each camera's 2-D tracks of the same markers (labels need not agree), in its own clip frames.
    fps : float
        Nominal frame rate (equal in every camera, as for the flash).
    rig : Rig, optional
        The calibrated rig: offsets refined to a fraction of a frame by triangulation consistency.
        Without it, whole-frame offsets from image speed with a parabolic sub-frame estimate.
    reference : str, optional
        Camera whose offset is 0 (default the first).
    clocks : dict camera -> (frame times (F,) s, anchor frame), optional
        Variable-rate clips' timestamps (:func:`saddlescope.core.pipeline.setup.frame_clocks`).
    max_offset_s : float
        Largest offset looked for, seconds either way.
    clip : str
        Clip kind named in errors.

    Raises
    ------
    SyncError
        Fewer than two cameras, no motion, no matching motion, or an offset the cost cannot fix.
    """
    cams = list(tracks)
    if len(cams) < 2:
        raise SyncError(f"{clip} clip: motion synchronisation needs two cameras or more, got {len(cams)}")
    reference = reference or cams[0]
    if reference not in tracks:
        raise SyncError(f"{clip} clip: reference camera {reference} has no marker tracks")
    cams = [reference] + [c for c in cams if c != reference]
    if not (np.isfinite(fps) and fps > 0):
        raise SyncError(f"{clip} clip: frame rate {fps} is not positive")
    clocks = dict(clocks or {})
    tracks = {c: at_top_row_instants(tracks[c], *(row_readout or {}).get(c, (0.0, 1)),
                                     frame_times_s=clocks[c][0] if c in clocks else None) for c in cams}
    speeds = {}
    for c in cams:
        fi = np.asarray(tracks[c].frame_index)
        if fi.size < MIN_OVERLAP_FRAMES:
            raise SyncError(f"no sync flash and too little motion to synchronise the {clip} clip: the {c} camera "
                            f"tracked the markers on {fi.size} frame(s), at least {MIN_OVERLAP_FRAMES} are needed")
        raw = image_speed(_nominal_xy(tracks[c], int(fi.max()) + 1, fps, clocks.get(c)))
        # the 90th percentile: a board held still between moves moves in a quarter of the frames
        moving = float(np.nanpercentile(raw, 90)) if np.isfinite(raw).sum() >= MIN_OVERLAP_FRAMES else 0.0
        if moving < MIN_SPEED_PX:
            raise SyncError(f"no sync flash and not enough motion to synchronise the {clip} clip: the {c} "
                            f"camera's markers moved {moving:.2f} px/frame (90th percentile; at least {MIN_SPEED_PX:g} "
                            f"over {MIN_OVERLAP_FRAMES} frames is needed); film a flash, or give the offsets "
                            "in ride.json")
        if rig is None:  # a board: its signed velocity (board_velocity)
            speeds[c] = board_velocity(_nominal_xy(tracks[c], int(fi.max()) + 1, fps, clocks.get(c)))
        else:
            speeds[c] = _speed_changes(raw, window=max(3, int(round(fps))))
    max_lag = max(1, int(round(max_offset_s * fps)))
    found = speed_offset_candidates(speeds, reference=reference, max_lag=max_lag, clip=clip,
                                    max_candidates=MAX_CANDIDATES if rig is not None else 6)
    others = cams[1:]
    candidates = {c: found[c][0] for c in others}
    if rig is None:
        offsets, sigma = {reference: 0.0}, {reference: 0.0}
        for c in others:
            lags, ncc = found[c][1], found[c][2]
            offsets[c], curv = _parabola_peak(lags, ncc, candidates[c][0])
            # the peak's own spread (the correlation's drop per frame^2 against its 1 / sqrt(n) noise) and
            # the parabola's: between frames it is only a rough guess, so never better than a whole
            # frame's rounding (1 / sqrt(12))
            n = max(np.isfinite(np.reshape(speeds[c], (len(speeds[c]), -1))[:, 0]).sum(), 1)
            sigma[c] = float(np.sqrt((1.0 / n) / curv + 1.0 / 12.0)) if curv > 0 else 0.5
        return MotionSync(offsets, sigma, None, int(len(speeds[reference])), candidates)
    missing = [c for c in cams if c not in rig.cameras]
    if missing:
        raise SyncError(f"{clip} clip: camera(s) {', '.join(missing)} are not in the calibration")
    combos = _pairwise_ranked(candidates, speeds, max_lag)
    return _refine(rig, {c: tracks[c] for c in cams}, reference, fps, clocks, candidates, combos, clip)


def _pairwise_ranked(candidates: Mapping[str, list[int]], speeds: Mapping[str, np.ndarray],
                     max_lag: int) -> list[tuple[int, ...]]:
    """The candidates' whole-frame combinations, the ``MAX_COMBINATIONS`` whose speeds agree best pair by pair.

    A walk's speed changes correlate weakly and a stride apart nearly as well: the true lag against the
    reference was as far down as a camera's tenth peak. So each camera keeps more peaks, and a combination
    is ranked by the sum of the correlations of every pair of cameras at the lags it implies (between two
    cameras other than the reference, the difference of their offsets): fewer to triangulate.
    """
    others = list(candidates)
    lags = np.arange(-2 * max_lag, 2 * max_lag + 1)
    ref = next(c for c in speeds if c not in candidates)
    pair = {}
    for a, b in itertools.combinations([ref, *others], 2):
        known = min(np.isfinite(speeds[a]).sum(), np.isfinite(speeds[b]).sum())
        ncc = speed_correlation(speeds[a], speeds[b], lags, min_overlap=max(MIN_OVERLAP_FRAMES, int(0.5 * known)))
        pair[a, b] = dict(zip(lags.tolist(), np.nan_to_num(ncc, nan=-1.0).tolist(), strict=True))
    scored = []
    for combo in itertools.product(*(candidates[c] for c in others)):
        at = {ref: 0, **dict(zip(others, combo, strict=True))}
        scored.append((-sum(pair[a, b].get(at[b] - at[a], -1.0) for a, b in pair), combo))
    scored.sort()
    return [combo for _, combo in scored[:MAX_COMBINATIONS]]


def _refine(rig: Rig, tracks: Mapping[str, ImageTracks], reference: str, fps: float, clocks: Mapping,
            candidates: Mapping[str, list[int]], combos: list[tuple[int, ...]], clip: str) -> MotionSync:
    """Step 2 of the module docstring: the best whole-frame combination, refined, with its covariance."""
    # variable-rate clips are not smoothed: over uneven instants the smoothing bent the motion (0.05 frame
    # on a synthetic canter with 0.2 frame of jitter, against 0.001 unsmoothed)
    smooth = 0.0 if clocks else SMOOTH_FRAMES
    cons = _Consistency(rig, tracks, reference, fps, clocks, smooth_frames=smooth)
    others = list(candidates)
    # With three cameras or more, combinations are judged on the points every camera saw: a point seen by
    # two meets only the epipolar constraint, which the wide rig's horizontal motion meets at nearly any
    # offset, so a combination whose cameras hardly see the markers together would otherwise look best.
    for all_cameras in ([True, False] if len(cons.cams) >= 3 else [False]):
        scored = []
        for combo in combos:
            trial = dict(zip(others, map(float, combo), strict=True))
            _match_labels(cons, trial, n_instants=4)  # enough to rank the combinations
            s, n, n_points = cons.cost(trial, all_cameras=all_cameras)
            if n and n_points >= MIN_OVERLAP_FRAMES:
                scored.append((s / n, trial))
        if scored:
            break
    if not scored:
        raise SyncError(f"no sync flash, and the {clip} clip's markers are never seen by two cameras at once "
                        "at any offset the motion suggests")
    scored.sort(key=lambda item: item[0])
    start = scored[0][1]

    def objective(v: np.ndarray) -> float:
        s, n, _ = cons.cost(dict(zip(others, v, strict=True)), all_cameras=all_cameras)
        return s / max(n, 1)

    def polish(trial: Mapping[str, float]) -> tuple[np.ndarray, float]:
        _match_labels(cons, trial)
        x0 = np.array([trial[c] for c in others])
        fit = minimize(objective, x0, method="Powell", bounds=[(v - 1.5, v + 1.5) for v in x0],
                       options={"xtol": 1e-3, "ftol": 1e-9})
        return np.asarray(fit.x, dtype=np.float64), float(fit.fun)

    # the best combinations a stride or more apart refined too, the most consistent kept: a camera that sees
    # the markers with only one other at some offset meets just the epipolar constraint there, which the
    # wide rig's horizontal motion nearly always does, so an offset a stride off can rank first in whole
    # frames; if a refined rival stays away and is nearly as consistent, the cameras cannot tell the
    # strides apart; one in the best's valley is the same answer, not a rival
    starts = [start] + [t for _, t in scored[1:] if max(abs(t[c] - start[c]) for c in others) > 1.5][:MAX_RIVALS]
    refined = sorted((polish(t) for t in starts), key=lambda item: item[1])
    x, best_cost = refined[0]
    _match_labels(cons, dict(zip(others, x, strict=True)))
    # a rival the cost joins to the best without rising between them lies in the same valley
    rival_x, rival_cost = next(((tx, tc) for tx, tc in refined[1:]
                                if objective(0.5 * (x + tx)) > max(best_cost, tc)), (None, np.inf))
    if rival_x is not None and rival_cost < AMBIGUOUS_COST_RATIO * best_cost:
        far = ", ".join(f"{c} {x[i]:+.1f} or {rival_x[i]:+.1f}" for i, c in enumerate(others))
        raise SyncError(f"no sync flash, and the markers' motion fits the {clip} clip's cameras about as well at "
                        f"other offsets ({far} frames): the {len(cons.cams)} cameras cannot tell them apart (a "
                        "stride apart with two cameras, or markers that do not move alike in every camera); "
                        "film a flash, or give the offsets in ride.json")
    if all_cameras:  # then refined on every point seen twice or more, from the chosen combination
        all_cameras = False
        x, _ = polish(dict(zip(others, x, strict=True)))
    x = _newton(cons, others, x)
    offsets = {reference: 0.0, **dict(zip(others, map(float, x), strict=True))}
    less = _Consistency(rig, tracks, reference, fps, clocks, smooth_frames=0.5 * smooth)
    less.set_labels(cons.perms)
    sigma = _offset_sigma(cons, others, x, _newton(less, others, x), lag_frames=max(1, int(round(0.25 * fps))),
                          smooth_frames=smooth)
    r, _ = cons.residuals(offsets)
    bad = [c for c in others if not np.isfinite(sigma[c]) or sigma[c] > 0.5]
    if bad:
        raise SyncError(f"no sync flash, and the markers' motion does not fix the {clip} clip's offset of the "
                        f"{' and '.join(bad)} camera(s) to half a frame (uncertainty "
                        f"{', '.join(f'{sigma[c]:.2f}' for c in bad)} frames): the markers move too little, too "
                        "evenly, or (cameras at the markers' height) too little up and down; film a flash, or "
                        "give the offsets in ride.json")
    return MotionSync(offsets, {reference: 0.0, **sigma}, float(np.sqrt(np.mean(r * r))),
                      int(len(cons.ref_frames)), {c: list(v) for c, v in candidates.items()})


def _local_quadratic(cons: _Consistency, others: list[str], x: np.ndarray,
                     h: float = 0.2) -> tuple[np.ndarray, np.ndarray, float]:
    """The cost's gradient per reference frame (F, p), Hessian (p, p) and residual variance (px^2) at offsets ``x``.

    Steps of ``h`` frames; only the residuals present at every step count: a marker entering the view
    between two steps is no change of the cost (the cost per residual of the whole-frame search jumps there).
    """
    p = len(others)
    e = np.eye(p) * h
    steps = [np.zeros(p)] + [s * e[i] for i in range(p) for s in (1, -1)]
    steps += [si * e[i] + sj * e[j] for i in range(p) for j in range(i + 1, p) for si in (1, -1) for sj in (1, -1)]
    tables = [cons.residual_table(dict(zip(others, x + d, strict=True))) for d in steps]
    common = np.all(np.isfinite(np.stack(tables)), axis=0)  # (C, F * M)
    n_frames = len(cons.ref_frames)
    frame = np.arange(common.shape[1]) // max(common.shape[1] // max(n_frames, 1), 1)
    loss = {tuple(np.round(d / h).astype(int)): np.bincount(
        frame, weights=np.where(common, _huber(np.nan_to_num(t)), 0.0).sum(axis=0), minlength=n_frames)
        for d, t in zip(steps, tables, strict=True)}

    def at(*moves: tuple[int, int]) -> np.ndarray:
        key = np.zeros(p, dtype=int)
        for i, sign in moves:
            key[i] += sign
        return loss[tuple(key)]

    grad, H = np.zeros((n_frames, p)), np.zeros((p, p))
    for i in range(p):
        grad[:, i] = (at((i, 1)) - at((i, -1))) / (2 * h)
        H[i, i] = float(np.sum(at((i, 1)) - 2 * at() + at((i, -1)))) / h**2
        for j in range(i + 1, p):
            H[i, j] = H[j, i] = float(np.sum(at((i, 1), (j, 1)) - at((i, 1), (j, -1)) - at((i, -1), (j, 1))
                                             + at((i, -1), (j, -1)))) / (4 * h * h)
    # the residual variance per image coordinate: 2 per residual norm, 3 unknowns per triangulated point
    r = tables[0][common]
    dof = 2 * r.size - 3 * int(np.any(common, axis=0).sum()) - p
    return grad, H, float(np.sum(r * r)) / max(dof, 1)


def _newton(cons: _Consistency, others: list[str], x: np.ndarray, max_steps: int = 8) -> np.ndarray:
    """Newton steps on the cost's local quadratic from ``x``, each within a frame, until under 0.001 frame.

    Powell's line searches along the axes stop early in a long narrow valley of the cost (module
    docstring: on the wide rig, one combination of the offsets changes the cost little): on a walk's
    exact tracks they stopped a quarter of a frame from the minimum.
    """
    for _ in range(max_steps):
        grad, H, _ = _local_quadratic(cons, others, x)
        if np.any(np.linalg.eigvalsh(H) <= 0):
            break
        step = -np.linalg.solve(H, grad.sum(axis=0))
        step *= min(1.0, 1.0 / max(float(np.max(np.abs(step))), 1e-12))
        x = x + step
        if np.max(np.abs(step)) < 1e-3:
            break
    return x


def _offset_sigma(cons: _Consistency, others: list[str], x: np.ndarray, x_less_smoothed: np.ndarray,
                  lag_frames: int, smooth_frames: float) -> dict[str, float]:
    """One standard deviation of each offset (module docstring); inf where the cost's Hessian is not positive.

    The tracking noise's share H^-1 V H^-1, V the long-run covariance of the cost's gradient over the
    reference's frames (Bartlett weights to ``lag_frames``: smoothed tracks' errors are correlated over
    a few frames); and the method's: the smoothing's own pull on the offsets, which grows as its width
    squared, so 4/3 of how far they move with half the smoothing (``x_less_smoothed``).
    """
    grad, H, var_px2 = _local_quadratic(cons, others, x)
    if grad.shape[0] < 2 or np.any(np.linalg.eigvalsh(H) <= 0):
        return {c: float("inf") for c in others}
    g = grad - grad.mean(axis=0)  # the gradient's sum is ~0 at the minimum
    V = g.T @ g
    for k in range(1, min(lag_frames, g.shape[0] - 1) + 1):
        lagged = g[k:].T @ g[:-k]
        V += (1.0 - k / (lag_frames + 1.0)) * (lagged + lagged.T)
    H_inv = np.linalg.inv(H)
    # the long-run covariance can cancel between lags on a short clip: never less than Gauss-Newton's with
    # the residuals counted as independent only once per smoothing width (2 sqrt(pi) sigma frames)
    independent = var_px2 * max(1.0, 2.0 * np.sqrt(np.pi) * smooth_frames) * np.diag(H_inv)
    noise = np.maximum(np.diag(H_inv @ V @ H_inv), independent)
    method = (4.0 / 3.0 * (np.asarray(x) - np.asarray(x_less_smoothed))) ** 2
    return {c: float(np.sqrt(v)) for c, v in zip(others, np.maximum(noise, 0.0) + method, strict=True)}

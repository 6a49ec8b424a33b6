"""Camera tracks to 3-D marker tracks: resampling onto the reference clock, then triangulation.

Each camera's 2-D tracks are resampled onto the left camera's frame times with the sub-frame
synchronisation offsets (thesis eq. 3.11: frame k of the left clip is frame k + offset of another
camera's clip), the cameras' labels are matched, and the markers triangulated into ``MarkerTracks``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from saddlescope.core.errors import InputError, TriangulationError
from saddlescope.core.rolling_shutter import row_delay_frames
from saddlescope.core.sync import clip_frames_at
from saddlescope.core.triangulation.lens_reach import reach_radius
from saddlescope.core.triangulation.matching import match_markers_across_cameras
from saddlescope.core.triangulation.nview import triangulate_nview
from saddlescope.core.triangulation.pairs import triangulate_thesis_pairs
from saddlescope.core.types import ImageTracks, MarkerTracks, Rig

__all__ = ["ReachCheckedTracks", "at_top_row_instants", "resample_at_instants", "resample_tracks", "triangulate_tracks"]


@dataclass(frozen=True)
class ReachCheckedTracks(MarkerTracks):
    """:class:`MarkerTracks` that also say where a sample's depth rests on an extrapolated lens.

    ``lens_extrapolation_px`` (F, M): for a sample triangulated from two cameras, how far (px of image
    radius) the farthest of them saw the marker beyond its calibration board's reach (with the margin
    of :func:`~saddlescope.core.triangulation.lens_reach.undistort_within_reach`); 0 for a sample that
    three cameras fix, or two within their reach. Two views leave one redundant equation, blind along
    the epipolar line, so nothing in the sample tells a guessed lens from a right one: on
    band-calibrated ``wide_partial`` canters such samples were 0.1-0.8 m off in depth with sub-pixel
    reprojection errors, the more the farther beyond the reach.
    """

    lens_extrapolation_px: np.ndarray | None = None

    @property
    def lens_extrapolated(self) -> np.ndarray | None:
        """(F, M) bool: the sample's depth rests on a lens model extrapolated beyond the board's reach."""
        return None if self.lens_extrapolation_px is None else self.lens_extrapolation_px > 0


def resample_tracks(tracks: ImageTracks, frames: np.ndarray, *, kind: str = "cubic",
                    frame_times_s: np.ndarray | None = None) -> np.ndarray:
    """Sample a camera's 2-D tracks at fractional frame positions of its own clip.

    ``kind="cubic"``: the cubic through the four nearest frames (two each side), where all four are
    tracked, else linear between the two neighbours; ``"linear"``: always linear. Linear interpolation
    misses the curvature of the motion by a Δt²/8 (0.4 px half way between frames for a saddle
    bobbing at 3 px/frame², which over a 0.23 m baseline at 7.5 m is a decimetre in depth); the cubic
    is exact up to third-order motion. A gap (NaN) in either neighbour, or a position outside the
    tracked frames, gives NaN; integer positions take the frame as it is.

    Parameters
    ----------
    tracks : ImageTracks
        ``xy_px`` of shape (F, M, 2) at ``frame_index`` (F,) (need not be contiguous).
    frames : ndarray of shape (N,)
        Wanted positions in this clip's frame numbers.
    kind : {"cubic", "linear"}, keyword-only
    frame_times_s : ndarray of shape (F_clip,), keyword-only
        Each clip frame's timestamp, for a variable-rate clip: the cubic then goes through the four
        frames at their own instants (a dropped frame leaves a double interval), and a fractional
        position means that fraction of the time between its two frames.

    Returns
    -------
    ndarray of shape (N, M, 2)
    """
    if kind not in ("cubic", "linear"):
        raise InputError(f"unknown interpolation {kind!r} (use 'cubic' or 'linear')")
    xy = np.asarray(tracks.xy_px, dtype=np.float64)
    fi = np.asarray(tracks.frame_index, dtype=np.int64)
    if xy.ndim != 3 or xy.shape[-1] != 2 or xy.shape[0] != fi.shape[0]:
        raise InputError(f"camera {tracks.camera!r}: tracks must be (F, M, 2) with F frame indices, got "
                         f"{xy.shape} and {fi.shape}")
    frames = np.asarray(frames, dtype=np.float64)
    out = np.full((frames.size, xy.shape[1], 2), np.nan)
    if fi.size == 0:
        return out
    first = int(fi.min())
    # Dense frames with a NaN frame before and two after, so every neighbour index exists.
    dense = np.full((int(fi.max()) - first + 4, xy.shape[1], 2), np.nan)
    dense[fi - first + 1] = xy
    pos = frames - first + 1
    base = np.floor(pos)
    frac = pos - base
    snap = frac < 1e-9
    inside = (base >= 1) & (base <= dense.shape[0] - 3) & np.isfinite(pos)
    b = np.where(inside, base, 1).astype(np.int64)
    p0, p1 = dense[b], dense[b + 1]
    t = frac[:, None, None]
    val = np.where(snap[:, None, None], p0, (1 - t) * p0 + t * p1)  # NaN in p1 poisons only real blends
    if kind == "cubic":
        pm, p2 = dense[b - 1], dense[b + 2]
        if frame_times_s is None:
            # Lagrange weights of the cubic through frames -1, 0, 1, 2 at t in [0, 1).
            cubic = (-t * (t - 1) * (t - 2) / 6 * pm + (t + 1) * (t - 1) * (t - 2) / 2 * p0
                     - (t + 1) * t * (t - 2) / 2 * p1 + (t + 1) * t * (t - 1) / 6 * p2)
        else:
            # the same cubic through the four frames at their stamped instants (uneven nodes)
            tn = _dense_frame_times(frame_times_s, first, dense.shape[0])
            nodes = np.stack([tn[b - 1], tn[b], tn[b + 1], tn[b + 2]], axis=1)  # (N, 4)
            tq = nodes[:, 1] + frac * (nodes[:, 2] - nodes[:, 1])
            cubic = 0.0
            for j, pj in enumerate((pm, p0, p1, p2)):
                w = np.ones_like(tq)
                for m in range(4):
                    if m != j:
                        w *= (tq - nodes[:, m]) / (nodes[:, j] - nodes[:, m])
                cubic = cubic + w[:, None, None] * pj
        use = ~snap[:, None, None] & np.isfinite(cubic)
        val = np.where(use, cubic, val)
    out[inside] = val[inside]
    return out


def _dense_frame_times(frame_times_s: np.ndarray, first: int, n_dense: int) -> np.ndarray:
    """Timestamps of the dense rows of :func:`resample_tracks` (frame ``first - 1 + j``), shape (n_dense,).

    Extended evenly at the median interval beyond the clip's stamped frames.
    """
    times = np.asarray(frame_times_s, dtype=np.float64)
    dt = float(np.median(np.diff(times))) if times.size > 1 else 1.0
    fnum = first - 1 + np.arange(n_dense, dtype=np.float64)
    last = times.size - 1
    tn = np.interp(fnum, np.arange(times.size, dtype=np.float64), times)
    tn = np.where(fnum < 0, times[0] + fnum * dt, tn)
    return np.where(fnum > last, times[-1] + (fnum - last) * dt, tn)


def triangulate_tracks(rig: Rig, tracks: Mapping[str, ImageTracks], offsets_frames: Mapping[str, float],
                       fps: float, *, reference: str | None = None, method: str = "nview",
                       match_labels: bool = True, names: Sequence[str] | None = None,
                       interpolation: str = "cubic",
                       clocks: Mapping[str, tuple[np.ndarray, float]] | None = None,
                       camera_set_bias: bool = False, row_readout: Mapping[str, tuple[float, int]] | None = None,
                       **kwargs) -> MarkerTracks:
    """2-D tracks of several cameras -> 3-D marker tracks on the reference camera's clock.

    Camera c's clip frame ``k + offsets_frames[c]`` shows the same instant as the reference clip's frame
    ``k`` (CONTRACTS: frame k of the left clip is frame k + offset of another camera's clip); offsets
    may be fractional (sub-frame sync). Each camera's tracks are resampled there (cubic where four
    frames around are tracked, else linear; a gap stays a gap), then triangulated.

    Parameters
    ----------
    rig : Rig
    tracks : dict of camera name -> ImageTracks
        ``xy_px`` (F_c, M, 2) with the same M in every camera.
    offsets_frames : dict of camera name -> float
        Missing cameras (and the reference) default to 0.
    fps : float
        Frame rate of the reference clip; ``t_s = frame_index / fps``.
    reference : str, keyword-only
        Default "left" if present, else the first camera.
    method : {"nview", "thesis_pairs"}, keyword-only
    match_labels : bool, keyword-only
        Relabel the other cameras' markers to the reference's with
        :func:`match_markers_across_cameras` on up to 12 instants where every camera sees every marker.
    names : sequence of str, keyword-only
        Marker names (default "1", "2", ...).
    interpolation : {"cubic", "linear"}, keyword-only
        How tracks are resampled between frames (see :func:`resample_tracks`).
    clocks : dict of camera name -> (frame times (F_clip,) s, anchor frame), keyword-only
        For variable-rate clips: each frame's timestamp and the frame (sub-frame) where the offsets
        were measured. Offsets then count nominal frames at ``fps`` from that anchor, and the camera's
        tracks are sampled at the stamped instants (:func:`clip_frames_at`); the reference's too, so
        ``t_s`` stays even.
    row_readout : dict of camera name -> (readout in frames, image rows), keyword-only
        Rolling shutters: a marker seen at row y of a frame was exposed ``(y + 0.5) / rows * readout``
        frames after the frame's (top row's) instant. Each observation is then placed at its own instant
        and every camera's tracks (the reference's too) interpolated to the reference frames' instants
        (:func:`resample_at_instants`). Cameras not given (or with readout 0) have a global shutter.
    camera_set_bias : bool, keyword-only
        With "nview": where a marker is triangulated from fewer cameras (a camera entered or left), remove
        that set's offset from the full set's on the nearest frames both saw (no step at the switch).
    **kwargs
        Passed to the triangulation function.

    Returns
    -------
    MarkerTracks
        ``xyz_mm`` (F, M, 3), ``reprojection_error_px`` (F, M), ``views`` (F, M), ``t_s`` (F,) with F
        the reference camera's tracked frames.
        With "nview" and ``lens_reach_px``: :class:`ReachCheckedTracks`, which also say how far beyond
        a camera's lens reach each two-camera sample was seen (its depth rests on a guessed lens there).
    """
    _, reference, M = _check_tracks(tracks, method, fps, reference)
    ref_frames = np.asarray(tracks[reference].frame_index, dtype=np.float64)
    xy = _on_reference_clock(tracks, offsets_frames, reference, ref_frames, fps, interpolation, clocks or {},
                             row_readout or {})
    if match_labels and M > 1:
        xy = _labels_of_reference(rig, xy, reference)
    used = None
    if method == "nview" and camera_set_bias:
        X, err, views, used = _nview_without_set_steps(rig, xy, **kwargs)
    elif method == "nview":
        X, err, views, used = triangulate_nview(rig, xy, return_used=True, **kwargs)
    else:
        X, err, views = triangulate_thesis_pairs(rig, xy, **kwargs)
    names = tuple(names) if names is not None else tuple(str(i + 1) for i in range(M))
    if len(names) != M:
        raise InputError(f"{len(names)} marker names given for {M} markers")
    reach = kwargs.get("lens_reach_px")
    if used is None or not reach:
        return MarkerTracks(names=tuple(names), t_s=ref_frames / fps, xyz_mm=X, reprojection_error_px=err,
                            views=views)
    beyond_px = _two_view_extrapolation_px(rig, xy, used, views, reach)
    return ReachCheckedTracks(names=tuple(names), t_s=ref_frames / fps, xyz_mm=X, reprojection_error_px=err,
                              views=views, lens_extrapolation_px=beyond_px)


def _two_view_extrapolation_px(rig: Rig, xy: Mapping[str, np.ndarray], used: np.ndarray, views: np.ndarray,
                               reach_px: Mapping[str, float]) -> np.ndarray:
    """(F, M) how far (px) beyond its lens reach the farthest camera of a two-camera sample saw the marker.

    ``used`` (C, F, M) the cameras used, in ``xy``'s order. A third camera checks the other two (its
    ray crosses the epipolar line), so three-view samples get 0, as do samples within every reach.
    """
    beyond_px = np.zeros(views.shape)
    for i, cam in enumerate(xy):
        if reach_px.get(cam) is None:
            continue
        camera = rig.cameras[cam]
        K = np.asarray(camera.K, dtype=np.float64)
        f_px = float(np.sqrt(K[0, 0] * K[1, 1]))
        rho_t = reach_radius(camera, reach_px[cam])[1]  # where undistort_within_reach's continuation starts
        kinv = np.linalg.inv(K)
        obs = np.asarray(xy[cam], dtype=np.float64) @ kinv[:2, :2].T + kinv[:2, 2]  # distorted normalised
        with np.errstate(invalid="ignore"):
            out_px = np.where(used[i], np.fmax(np.linalg.norm(obs, axis=-1) - rho_t, 0.0) * f_px, 0.0)
        beyond_px = np.fmax(beyond_px, np.nan_to_num(out_px))
    return np.where(views == 2, beyond_px, 0.0)


_SET_BIAS_FRAMES = 5  # the offset of a camera set is the median over this many nearest shared frames
_SET_BIAS_MIN_BASELINE = 0.15  # sets narrower than this share of the distance to the markers are left alone


def _nview_without_set_steps(rig: Rig, xy: Mapping[str, np.ndarray], **kwargs):
    """:func:`triangulate_nview` with each reduced camera set's offset from the full set removed.

    Each camera set sees the marker through its own calibration errors (beyond the board's reach,
    its own lens extrapolation): where the set changes along the crossing the track steps, and a
    step is broadband acceleration. On frames where every camera is used, each set that leaves one
    camera out is triangulated too; a frame triangulated from that set alone is then moved by the
    set's offset from the full solution, the median over the ``_SET_BIAS_FRAMES`` nearest frames
    that had both (the offset at the switch, so the step goes; its drift beyond stays).

    Returns (xyz_mm (F, M, 3), reprojection_error_px (F, M), views (F, M), cameras used (C, F, M)).
    """
    X, err, views, used = triangulate_nview(rig, xy, return_used=True, **kwargs)
    cams = list(xy)
    n_cams = len(cams)
    if n_cams < 3:
        return X, err, views, used
    full = views == n_cams  # (F, M)
    centres = np.stack([rig.cameras[c].center_mm for c in cams])
    depth_mm = float(np.nanmedian(np.linalg.norm(X[full] - centres.mean(axis=0), axis=-1))) if full.any() else np.nan
    for m in range(X.shape[1]):
        t_full = np.flatnonzero(full[:, m])
        if t_full.size == 0:
            continue
        for drop in range(n_cams):
            rest = np.delete(centres, drop, axis=0)
            baseline_mm = max(np.linalg.norm(a - b) for a in rest for b in rest)
            if not baseline_mm > _SET_BIAS_MIN_BASELINE * depth_mm:
                continue  # a narrow set's depth noise is no offset (thesis rig: 0.23 m at 7.5 m)
            subset = used[:, :, m].T  # (F, C)
            this_set = (views[:, m] == n_cams - 1) & ~subset[:, drop] & np.all(np.delete(subset, drop, axis=1),
                                                                                  axis=1)
            if not this_set.any():
                continue
            sub = {c: xy[c][t_full, m] for i, c in enumerate(cams) if i != drop}
            X_sub, _, v_sub = triangulate_nview(rig, sub, **{k: v for k, v in kwargs.items()
                                                             if k in ("lens_reach_px", "refine_iterations")},
                                                reject_outliers=False)
            diff = X_sub - X[t_full, m]
            ok = (v_sub == n_cams - 1) & np.all(np.isfinite(diff), axis=1)
            if not ok.any():
                continue
            t_ok, d_ok = t_full[ok], diff[ok]
            for f in np.flatnonzero(this_set):
                X[f, m] -= np.median(d_ok[np.argsort(np.abs(t_ok - f))[:_SET_BIAS_FRAMES]], axis=0)
    return X, err, views, used


def _check_tracks(tracks: Mapping[str, ImageTracks], method: str, fps: float,
                  reference: str | None) -> tuple[list[str], str, int]:
    """The arguments of :func:`triangulate_tracks` checked: cameras, reference camera, markers M."""
    if not tracks:
        raise InputError("no camera tracks to triangulate")
    if method not in ("nview", "thesis_pairs"):
        raise InputError(f"unknown triangulation method {method!r} (use 'nview' or 'thesis_pairs')")
    if not (fps > 0 and math.isfinite(fps)):
        raise InputError(f"frame rate must be positive, got {fps}")
    cams = list(tracks)
    if reference is None:
        reference = "left" if "left" in cams else cams[0]
    if reference not in tracks:
        raise InputError(f"reference camera {reference!r} has no tracks")
    M = np.asarray(tracks[reference].xy_px).shape[1]
    for c in cams:
        shape = np.asarray(tracks[c].xy_px).shape
        if len(shape) != 3 or shape[1] != M:
            raise InputError(f"camera {c!r}: tracks have shape {shape}, expected (F, {M}, 2) like "
                             f"camera {reference!r}")
    if len(cams) < 2:
        raise TriangulationError(f"triangulation needs at least two cameras, got only {reference!r}")
    return cams, reference, M


def _on_reference_clock(tracks: Mapping[str, ImageTracks], offsets_frames: Mapping[str, float], reference: str,
                        ref_frames: np.ndarray, fps: float, interpolation: str,
                        clocks: Mapping[str, tuple[np.ndarray, float]],
                        row_readout: Mapping[str, tuple[float, int]]) -> dict[str, np.ndarray]:
    """Every camera's tracks (F, M, 2) at the instants of the reference's frames ``ref_frames`` (F,)."""
    base = float(offsets_frames.get(reference, 0.0))
    xy = {}
    for c in tracks:
        offset = float(offsets_frames.get(c, 0.0)) - base
        wanted = ref_frames + offset
        times = None
        to_clip = None
        if c in clocks:
            times, anchor = clocks[c]
            to_clip = _nominal_to_clip(times, anchor, fps)
        readout, rows = row_readout.get(c, (0.0, 1))
        if readout > 0:
            xy[c] = resample_at_instants(tracks[c], wanted, readout, rows, kind=interpolation, frame_times_s=times,
                                         to_clip_frames=to_clip)
            continue
        if to_clip is not None:
            wanted = to_clip(wanted)
        xy[c] = resample_tracks(tracks[c], wanted, kind=interpolation, frame_times_s=times)
    return xy


def _nominal_to_clip(times: np.ndarray, anchor: float, fps: float):
    """Nominal (even-clock) frames -> a variable-rate clip's fractional frames (:func:`clip_frames_at`)."""
    return lambda frames: clip_frames_at(frames, times, anchor, fps)


def resample_at_instants(tracks: ImageTracks, instants: np.ndarray, readout_frames: float, rows: int, *,
                         kind: str = "cubic", frame_times_s: np.ndarray | None = None, to_clip_frames=None,
                         iterations: int = 3) -> np.ndarray:
    """A rolling-shutter camera's 2-D tracks at given instants, each observation at its own instant.

    The marker seen at row y of frame k was exposed at ``k + (y + 0.5) / rows * readout`` (frames of
    this clip, top-row instants). Its track as a function of the frame number is smooth, so the
    position at instant t is the track at the fractional frame k* with ``k* + delay(y(k*)) = t``,
    found by fixed-point iteration for each marker (the delay changes by ``readout / rows`` per pixel
    of vertical motion: a contraction, a few iterations reach 1e-4 frame).

    Parameters
    ----------
    tracks : ImageTracks
        (F, M, 2) at ``frame_index``.
    instants : ndarray of shape (N,)
        Wanted instants in this clip's (nominal) frames, at the frames' top-row convention.
    readout_frames : float
        The readout time in frames.
    rows : int
        The image's height in pixels.
    kind, frame_times_s
        As :func:`resample_tracks`.
    to_clip_frames : callable, optional
        Nominal frames -> clip frames for a variable-rate clip (identity otherwise).
    iterations : int

    Returns
    -------
    ndarray of shape (N, M, 2), NaN where the track does not reach.
    """
    xy = np.asarray(tracks.xy_px, dtype=np.float64)
    t = np.asarray(instants, dtype=np.float64)
    out = np.full((t.size, xy.shape[1], 2), np.nan)
    convert = to_clip_frames or (lambda frames: frames)
    for m in range(xy.shape[1]):
        one = ImageTracks(tracks.camera, xy[:, m:m + 1], tracks.frame_index)
        delay = np.full(t.size, 0.5 * readout_frames)  # mid-frame to start, then each marker's own row
        for _ in range(iterations):
            at = resample_tracks(one, convert(t - delay), kind=kind, frame_times_s=frame_times_s)[:, 0]
            delay = np.where(np.isfinite(at[:, 1]), row_delay_frames(at[:, 1], readout_frames, rows), delay)
        out[:, m] = resample_tracks(one, convert(t - delay), kind=kind, frame_times_s=frame_times_s)[:, 0]
    return out


def _labels_of_reference(rig: Rig, xy: dict[str, np.ndarray], reference: str) -> dict[str, np.ndarray]:
    """The other cameras' markers relabelled to the reference's.

    :func:`match_markers_across_cameras` on up to 12 instants where every camera sees every marker;
    unchanged if there is none.
    """
    cams = list(xy)
    full = np.all(np.stack([np.all(np.isfinite(v), axis=(1, 2)) for v in xy.values()]), axis=0)
    hits = np.flatnonzero(full)
    if hits.size:
        # A dozen instants spread over the clip, so that one odd frame cannot decide the labels.
        pick = hits[np.unique(np.linspace(0, hits.size - 1, min(hits.size, 12)).round().astype(int))]
        perms = match_markers_across_cameras(rig, {c: xy[c][pick] for c in cams}, reference=reference)
        xy = {c: xy[c][:, perms[c]] for c in cams}
    return xy


def at_top_row_instants(tracks: ImageTracks, readout_frames: float, rows: int, *,
                        frame_times_s: np.ndarray | None = None) -> ImageTracks:
    """A rolling-shutter camera's tracks moved to their frames' top-row instants, as a global shutter's.

    Each frame's markers where they were at the frame's own instant (:func:`resample_at_instants` at the
    tracked frames); a frame the track does not reach around gets NaN. Unchanged with readout 0.
    """
    if readout_frames <= 0:
        return tracks
    frames = np.asarray(tracks.frame_index, dtype=np.float64)
    xy = resample_at_instants(tracks, frames, readout_frames, rows, frame_times_s=frame_times_s)
    return ImageTracks(tracks.camera, xy, tracks.frame_index)

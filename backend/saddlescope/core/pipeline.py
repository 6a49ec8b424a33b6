"""The whole analysis of a ride: clips in, the result of CONTRACTS section 2 out.

Stages (thesis stages 1-12): sync -> calibration -> detection -> triangulation -> kinematics ->
indicators. The core opens no files: frames come from a :class:`ClipReader` (``saddlescope.io``
provides one over a ride bundle), and progress goes to an ``on_progress(fraction, stage)`` callback
so the core never knows about jobs or queues.
"""

from __future__ import annotations

import itertools
import math
import os
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Protocol

import cv2
import numpy as np

from saddlescope.core import calibration as calib
from saddlescope.core import frames as motion
from saddlescope.core.errors import DetectionError, InputError, KinematicsError, SyncError, TriangulationError
from saddlescope.core.fitting import fit_marker_kinematics
from saddlescope.core.indicators import ride_indicators
from saddlescope.core.marker_search import (
    SequentialFrames,
    camera_down,
    find_markers_multiview,
    find_plumb_multiview,
    find_static_multiview,
    in_image,
    tilt_from_down_deg,
)
from saddlescope.core.markers import track_markers
from saddlescope.core.period import analysis_window, estimate_period
from saddlescope.core.registration import Registration, broken_distance_samples, marker_model, register_rigid
from saddlescope.core.rigid_body import angular_kinematics, saddle_body_coordinates, saddle_point_kinematics
from saddlescope.core.smoothing import bridge_gaps, regularize_depth, rloess
from saddlescope.core.sync import clip_frames_at, clip_offsets, flash_interval, nominal_frames_of, offsets_from_spec
from saddlescope.core.triangulation import position_uncertainty, triangulate_tracks
from saddlescope.core.types import Board, ImageTracks, MarkerTracks, Rig

RESULT_FORMAT = "saddlescope.result/1"

# Stride frequencies searched per declared gait (literature: walk 0.85-0.95 Hz, trot 1.3-1.5 Hz,
# canter 1.6-1.7 Hz), with wide margins. They keep the stride apart from the 2x vertical line of walk
# and trot, whose lateral 1x content is the first to drown in depth noise on a narrow rig.
STRIDE_RANGE_HZ: dict[str, tuple[float, float]] = {
    "walk": (0.6, 1.25), "sitting_trot": (1.0, 1.9), "rising_trot": (1.0, 1.9), "canter": (1.25, 2.3)}

# Share of the total progress each stage reports (rough wall-time shares on the thesis rig).
STAGE_WEIGHTS: dict[str, float] = {"sync": 0.15, "calibration": 0.35, "detection": 0.3,
                                   "triangulation": 0.05, "kinematics": 0.1, "indicators": 0.05}


class ClipReader(Protocol):
    """What the pipeline needs of a ride's clips (``saddlescope.io.clip_source.BundleClips``)."""

    def has(self, kind: str) -> bool: ...
    def cameras(self, kind: str) -> list[str]: ...
    def fps(self, kind: str, camera: str) -> float: ...
    def frame_count(self, kind: str, camera: str) -> int: ...
    def image_size(self, kind: str, camera: str) -> tuple[int, int]: ...
    def brightness(self, kind: str, camera: str) -> np.ndarray: ...
    def frame_times(self, kind: str, camera: str) -> np.ndarray | None: ...
    def gray_frames(self, kind: str, camera: str, start: int = 0, stop: int | None = None,
                    step: int = 1) -> Iterator[tuple[int, np.ndarray]]: ...


@dataclass(frozen=True)
class PipelineParams:
    """Choices a user may override; the defaults follow the thesis where it was right."""

    n_periods: int = 2
    smoothing: str = "none"  # or "rloess" (thesis 5.2.2); the Fourier fits smooth and reject outliers
    smoothing_span: float = 0.10
    smoothing_iterations: int = 4
    # gaps bridged for the registration (the fits skip bridged frames, and report the fits' positions
    # there): the arena's pole hid a marker for 0.2 s in a fast thesis-rig canter, and at 0.15 s the
    # longest stretch left was under two strides
    max_gap_s: float = 0.25
    triangulation: str = "nview"  # or "thesis_pairs"
    max_calibration_instants: int = 150
    calibration_step: int | None = None  # frames between board looks; None: every frame (tracking is cheap)
    still_board_only: bool = True  # calibrate from frames where the board was held still
    max_square_error_pct: float = 1.0
    singularity_threshold: float = 0.2
    # the motion markers' distances against the static shot's (RMS, mm): beyond it a look-alike was
    # tracked (wide-rig trot: 280 mm; true markers: depth noise and skin, a few to 20 mm)
    max_layout_mismatch_mm: float = 50.0
    # a plumb line leaning more than this from the cameras' image-down direction is not one (cameras
    # stand roughly level; the plumb search takes pairs within 25 degrees)
    max_plumb_lean_deg: float = 30.0
    # median rigidity residual (registration) above which the saddle point is flagged unreliable:
    # 1-3 mm on synthetic rides of both rigs (skin motion), 180 mm with two markers' labels swapped
    max_rigidity_residual_mm: float = 15.0
    depth_anisotropy: float = 5.0  # fit marker depth smoothly when the rig fixes it this many times worse
    depth_max_order: int = 0  # stride harmonics allowed in that depth fit (0: straight path only)
    # "lsq_wiener": least squares with the weakest axis shrunk by the skin motion the raw markers
    # show; "lsq_observable" drops it when the markers lie near a line; "lsq"; "versions" (thesis)
    angular_method: str = "lsq_wiener"
    x_model: str = "fourier"  # the thesis's "linear" drops the surge within the stride
    extra_orders: int = 3  # orders tried above the extrema rule's E/2 + 1 (chosen by AICc)
    omega_from: str = "vertical"  # series whose fitted fundamental is pooled (fitting.fit_marker_kinematics)
    # a straight line fitted with the y and z series: the registered markers keep slow drifts over the
    # fitted span (gravity's tilt across the depth travelled, each marker's straight depth path) that
    # a periodic series smears over its harmonics (a thesis-rig canter lost its fourth harmonic: 16 %)
    trend_degree: int = 1
    # "run": fit the tracked frames around the window, at most fit_margin_periods strides on either
    # side, and report the window; "window": the thesis's 5.5. The margin is bounded because a real
    # horse's stride drifts over a long side of the arena and one periodic fit would smear it.
    fit_span: str = "run"
    fit_margin_periods: float = 1.0
    max_order: int | None = None  # cap on the Fourier order the extrema rule and AICc choose
    # order criterion (fitting.CRITERIA): "aicc" takes the noise's correlation over frames into
    # account, "aicc_white" is the textbook AICc
    criterion: str = "aicc"
    detection: dict = field(default_factory=dict)  # per clip kind: keyword overrides of track_markers


@dataclass
class _Progress:
    callback: Callable[[float, str], None] | None
    done: float = 0.0
    timings_s: dict = field(default_factory=dict)

    def stage(self, name: str, fraction_of_stage: float) -> None:
        if self.callback is not None:
            self.callback(min(1.0, self.done + STAGE_WEIGHTS[name] * fraction_of_stage), name)

    def finish(self, name: str, started: float, *, seconds: float | None = None) -> None:
        self.timings_s[name] = round(time.perf_counter() - started if seconds is None else seconds, 4)
        self.done += STAGE_WEIGHTS[name]
        self.stage(name, 0.0)


def board_from_meta(meta: Mapping) -> Board:
    """The calibration board of ride.json's ``board`` section."""
    spec = meta.get("board")
    if not isinstance(spec, Mapping):
        raise InputError("ride.json has no 'board' section describing the calibration board")
    try:
        cols, rows = (int(v) for v in spec["inner_corners"])
        return calib.make_board(str(spec.get("kind", "checkerboard")), (cols, rows), float(spec["square_mm"]),
                                dictionary=spec.get("dictionary"), marker_mm=spec.get("marker_mm"),
                                legacy=bool(spec.get("legacy", False)))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"ride.json board section is incomplete or wrong: {exc}") from None


# --------------------------------------------------------------------------------------------------
# Stage 2: synchronisation
# --------------------------------------------------------------------------------------------------


def synchronise(clips: ClipReader, meta: Mapping, kinds: list[str]) -> tuple[dict, dict]:
    """Frame offsets per clip kind and camera (relative to the first camera) and the first frame
    after the flash in each camera's clip, where detection may start."""
    from concurrent.futures import ThreadPoolExecutor

    offsets: dict[str, dict[str, float]] = {}
    first_frame: dict[str, dict[str, int]] = {}
    sync_spec = meta.get("sync") or {"method": "flash"}
    # Every clip is decoded for its brightness: in threads (the decoder releases the GIL), in order.
    jobs = [(kind, c) for kind in kinds for c in clips.cameras(kind)]
    with ThreadPoolExecutor(max_workers=max(1, min(len(jobs), os.cpu_count() or 1))) as pool:
        decoded = dict(zip(jobs, pool.map(lambda job: clips.brightness(*job), jobs), strict=True))
    for kind in kinds:
        cams = clips.cameras(kind)
        fps = {c: clips.fps(kind, c) for c in cams}
        known = offsets_from_spec(sync_spec, clip=kind, cameras=cams)
        brightness = {c: decoded[kind, c] for c in cams}
        # a variable-rate clip's nominal rate comes from its stamps (a short clip's to a few tenths of
        # a percent); its frames are then placed by their stamps, not by the rate
        rel_tol = 0.01 if any(clips.frame_times(kind, c) is not None for c in cams) else 1e-3
        offsets[kind] = known if known is not None else clip_offsets(brightness, fps, clip=kind, fps_rel_tol=rel_tol)
        first_frame[kind] = {}
        for c in cams:
            try:
                _, end = flash_interval(brightness[c], clip=kind, camera=c)
                first_frame[kind][c] = int(math.ceil(end)) + 1
            except SyncError:
                if known is None:
                    raise
                first_frame[kind][c] = 0  # known offsets: the clip need not hold a flash
    return offsets, first_frame


def frame_clocks(clips: ClipReader, kinds: list[str]) -> tuple[dict, list[str]]:
    """The timestamps of variable-rate clips (phones) and the frame where each was synchronised.

    Returns ``clocks[kind][camera] = (frame times (F,) s, anchor frame)`` for every camera of a clip
    set where one camera's frames are not evenly spaced (the even ones get their own even stamps),
    and a flag for each uneven clip. The anchor is the sync flash's onset: frame offsets are measured
    there, so the nominal even clock is tied to the clip's timestamps at that frame."""
    clocks: dict[str, dict[str, tuple[np.ndarray, float]]] = {}
    flags: list[str] = []
    for kind in kinds:
        stamped = {cam: clips.frame_times(kind, cam) for cam in clips.cameras(kind)}
        if all(times is None for times in stamped.values()):
            continue
        for cam, times in stamped.items():
            if times is None:
                # an even camera beside a variable one: its own even stamps, so every camera of the
                # clip is placed by time (the nominal rate of the others may differ from its rate)
                times = np.arange(clips.frame_count(kind, cam)) / clips.fps(kind, cam)
            else:
                dt_ms = np.diff(times) * 1000.0
                flags.append(f"the {kind} clip of the {cam} camera has a variable frame rate (frames "
                             f"{dt_ms.min():.1f}-{dt_ms.max():.1f} ms apart, nominal "
                             f"{1000.0 / clips.fps(kind, cam):.1f} ms): its frames are placed at their timestamps")
            try:
                anchor, _ = flash_interval(clips.brightness(kind, cam), clip=kind, camera=cam)
            except SyncError:
                anchor = 0.0  # offsets given in ride.json: counted from the clip's first frame
            clocks.setdefault(kind, {})[cam] = (np.asarray(times, dtype=np.float64), float(anchor))
    return clocks, flags


# --------------------------------------------------------------------------------------------------
# Stage 1: calibration
# --------------------------------------------------------------------------------------------------


def calibrate_from_clips(clips: ClipReader, board: Board, offsets: Mapping[str, float],
                         first_frame: Mapping[str, int], params: PipelineParams,
                         progress: _Progress | None = None,
                         clocks: Mapping[str, tuple[np.ndarray, float]] | None = None) -> tuple[Rig, dict]:
    """Board views from every camera's calibration clip, put on the first camera's clock, then
    intrinsics, stereo pairs, bundle adjustment and metric checks (thesis 3.4-3.6, 8.2)."""
    from concurrent.futures import ThreadPoolExecutor, as_completed

    cams = clips.cameras("calibration")
    fps = clips.fps("calibration", cams[0])
    # The board is tracked from frame to frame, which costs little: look at every frame by default (sampling
    # every other frame at 60 fps missed most short holds of the board in one camera or another).
    step = params.calibration_step or 1
    search_every = max(1, int(round(0.5 * fps / step)))  # a lost board is searched for in whole frames twice a second
    # Start every camera on the same instant so that the sampled frames coincide after the offsets.
    base = max(first_frame.get(c, 0) - int(round(offsets.get(c, 0.0))) for c in cams)

    def board_views(cam: str) -> tuple[list, tuple[int, int]]:
        start = max(0, base + int(round(offsets.get(cam, 0.0))))
        views, size = calib.detect_board_views(
            clips.gray_frames("calibration", cam, start=start, step=step), board, search_every=search_every)
        # frame k of this camera shows the instant of frame k - offset of the first camera (for a
        # variable-rate clip, k counted on its nominal clock: a dropped frame shifts the rest)
        views = _still_views(views, step) if params.still_board_only else views
        frames = np.array([v.frame for v in views], dtype=np.float64)
        if cam in (clocks or {}) and views:
            frames = nominal_frames_of(frames, clocks[cam][0], clocks[cam][1], fps)
        return ([replace(v, frame=int(round(k - offsets.get(cam, 0.0)))) for v, k in zip(views, frames, strict=True)],
                size or clips.image_size("calibration", cam))

    # One thread per camera: decoding (PyAV) and the board search (OpenCV) release the GIL. Each camera's
    # views depend on its clip alone, so the result does not depend on the threads' timing; progress is
    # reported from this thread.
    with ThreadPoolExecutor(max_workers=len(cams)) as pool:
        jobs = {pool.submit(board_views, cam): cam for cam in cams}
        for done, job in enumerate(as_completed(jobs), 1):
            job.result()
            if progress is not None:
                progress.stage("calibration", 0.6 * done / len(cams))
    found = {cam: job.result() for job, cam in jobs.items()}
    views_by_camera = {cam: found[cam][0] for cam in cams}
    sizes = {cam: found[cam][1] for cam in cams}
    if len(cams) > 1:
        views_by_camera = _average_holds(views_by_camera)
        keep = set(calib.select_instants(views_by_camera, board, sizes,
                                         max_instants=params.max_calibration_instants))
        views_by_camera = {c: [v for v in vs if v.frame in keep] for c, vs in views_by_camera.items()}
    rig, report = calib.calibrate_rig(views_by_camera, board, sizes,
                                      max_square_error_pct=params.max_square_error_pct)
    report["n_views"] = {c: len(v) for c, v in views_by_camera.items()}
    report["board_coverage"] = {c: board_coverage(v, sizes[c]) for c, v in views_by_camera.items() if v}
    return rig, report


def board_coverage(views: list, image_size: tuple[int, int]) -> dict:
    """The image region the board covered (convex hull of every corner) and its share of the image.

    The lens distortion is only known where the board has been: beyond it k1, k2 (and k3) are
    extrapolated, by a pixel or more at the edges of a wide lens (synthetic wide rig).
    """
    pts = np.concatenate([v.corners_px for v in views]).astype(np.float32)
    hull = cv2.convexHull(pts).reshape(-1, 2)
    return {"hull_px": hull.astype(float).round(1).tolist(),
            "area_fraction": float(cv2.contourArea(hull) / (image_size[0] * image_size[1]))}


def outside_coverage(tracks: Mapping[str, ImageTracks], coverage: Mapping[str, dict], *,
                     margin_px: float = 10.0) -> dict[str, float]:
    """Per camera, the share of marker detections farther than ``margin_px`` outside the board's hull."""
    out = {}
    for cam, tr in tracks.items():
        if cam not in coverage:
            continue
        hull = np.asarray(coverage[cam]["hull_px"], dtype=np.float32).reshape(-1, 1, 2)
        xy = np.asarray(tr.xy_px, dtype=np.float64).reshape(-1, 2)
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if xy.size == 0:
            continue
        d = np.array([cv2.pointPolygonTest(hull, (float(x), float(y)), True) for x, y in xy])
        out[cam] = float(np.mean(d < -margin_px))
    return out


def _average_holds(views_by_camera: Mapping[str, list], *, same_pose_px: float = 0.5) -> dict[str, list]:
    """One view per pose and camera, its corners averaged over the pose's still instants.

    Consecutive still instants are split where the board has moved more than ``same_pose_px`` (a slow
    sweep is many poses, a hold one). Averaging a hold's frames halves the corners' frame-to-frame
    noise without giving the bundle adjustment many copies of one pose to weigh (wide rig: markers
    4.6 mm RMS from 60 instants of any pose, 2.5 mm from every still instant, 2.3 mm from every pose
    averaged)."""
    by_frame: dict[int, dict] = {}
    for cam, views in views_by_camera.items():
        for v in views:
            by_frame.setdefault(v.frame, {})[cam] = v

    def same_pose(a: dict, b: dict) -> bool:
        for cam in set(a) & set(b):
            if np.array_equal(a[cam].ids, b[cam].ids):
                return float(np.max(np.linalg.norm(a[cam].corners_px - b[cam].corners_px, axis=1))) <= same_pose_px
        return False

    out: dict[str, list] = {cam: [] for cam in views_by_camera}

    def close(group: list[int]) -> None:
        most = max(len(by_frame[f]) for f in group)
        best = [f for f in group if len(by_frame[f]) == most]
        key = best[len(best) // 2]
        for cam, ref in by_frame[key].items():
            same = [by_frame[f][cam] for f in group
                    if cam in by_frame[f] and np.array_equal(by_frame[f][cam].ids, ref.ids)]
            out[cam].append(replace(ref, corners_px=np.mean([v.corners_px for v in same], axis=0)))

    group: list[int] = []
    for frame in sorted(by_frame):
        if group and (frame != group[-1] + 1 or not same_pose(by_frame[group[0]], by_frame[frame])):
            close(group)
            group = []
        group.append(frame)
    if group:
        close(group)
    return out


def rig_from_result(calibration: Mapping) -> Rig:
    """The rig of a result's ``calibration`` section (the inverse of :func:`rig_to_result`)."""
    from saddlescope.core.types import Camera

    cams = {}
    for name, c in calibration["cameras"].items():
        ext = calibration.get("extrinsics", {}).get(name)
        cams[name] = Camera(name, np.asarray(c["K"], dtype=np.float64), np.asarray(c["dist"], dtype=np.float64),
                            (int(c["image_size"][0]), int(c["image_size"][1])),
                            R=np.asarray(ext["R"], dtype=np.float64) if ext else np.eye(3),
                            t_mm=np.asarray(ext["t_mm"], dtype=np.float64) if ext else np.zeros(3),
                            rms_px=c.get("rms_px"))
    return Rig(cams, checks=dict(calibration.get("checks", {})), flags=tuple(calibration.get("flags", ())))


def _still_views(views: list, step: int, max_motion_px: float = 0.5) -> list:
    """Views of a board held still: its corners moved less than ``max_motion_px`` since the view
    ``step`` frames before. A moving board is blurred, and the cameras' frames (whole frames apart
    after rounding the sync offsets) would show it at different places."""
    by_frame = {v.frame: v for v in views}
    still = []
    for v in views:
        prev = by_frame.get(v.frame - step)
        if prev is None or len(prev.ids) != len(v.ids) or np.any(prev.ids != v.ids):
            continue
        if float(np.max(np.linalg.norm(prev.corners_px - v.corners_px, axis=1))) < max_motion_px:
            still.append(v)
    return still if len(still) >= 6 else views


def rig_to_result(rig: Rig) -> dict:
    """The ``calibration`` section of the result (CONTRACTS section 2)."""
    names = rig.names
    cameras = {}
    for name, cam in rig.cameras.items():
        entry = {"K": np.asarray(cam.K).tolist(), "dist": np.asarray(cam.dist).ravel().tolist(),
                 "image_size": [int(cam.image_size[0]), int(cam.image_size[1])], "rms_px": cam.rms_px}
        if cam.K_std is not None:
            entry["K_std"] = np.asarray(cam.K_std).tolist()
        if cam.dist_std is not None:
            entry["dist_std"] = np.asarray(cam.dist_std).ravel().tolist()
        cameras[name] = entry
    extrinsics = {name: {"R": np.asarray(rig.cameras[name].R).tolist(),
                         "t_mm": np.asarray(rig.cameras[name].t_mm).ravel().tolist()} for name in names[1:]}
    pairs = {key: {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v) for k, v in p.items()}
             for key, p in rig.pairs.items()}
    return {"cameras": cameras, "extrinsics": extrinsics, "checks": dict(rig.checks), "flags": list(rig.flags),
            "pairs": pairs}


# --------------------------------------------------------------------------------------------------
# Stages 3-4: detection and triangulation
# --------------------------------------------------------------------------------------------------


def detect_clip(clips: ClipReader, kind: str, n_markers: int, first_frame: Mapping[str, int],
                params: PipelineParams, *, spare_cameras: bool = False,
                start_xy: Mapping[str, np.ndarray] | None = None) -> tuple[dict[str, ImageTracks], list[str]]:
    """2-D marker tracks of every camera of one clip set (thesis 4.5), and flags.

    With ``spare_cameras`` (still scenes: the plumb line, the standing horse) a camera that does not
    see the markers is left out while two others do (a plumb line hung at the end of the arena may be
    outside one camera's view): its failure is a flag, not the end of the analysis.
    ``start_xy`` {camera: (n, 2)} gives the markers' positions on each camera's first frame (found
    with all cameras at once); a camera it leaves out is not used (with ``spare_cameras``)."""
    overrides = dict(params.detection.get(kind, {}))
    tracks = {}
    missed: dict[str, DetectionError] = {}
    for cam in clips.cameras(kind):
        cam_overrides = overrides.pop(cam, {}) if isinstance(overrides.get(cam), Mapping) else {}
        common = {k: v for k, v in overrides.items() if not isinstance(v, Mapping)}
        if start_xy is not None and "first_frame_xy" not in {**common, **cam_overrides}:
            if cam not in start_xy:
                if spare_cameras:
                    what = "the plumb line's markers" if kind == "plumb" else f"the {kind} clip's markers"
                    missed[cam] = DetectionError(f"the {cam} camera's view does not hold the spots that the "
                                                 f"other cameras see as {what}")
                    continue
            else:
                cam_overrides = {**cam_overrides, "first_frame_xy": start_xy[cam]}
        try:
            tracks[cam] = track_markers(clips.gray_frames(kind, cam, start=first_frame.get(cam, 0)),
                                        n_markers=n_markers, camera=cam, clip=kind, **common, **cam_overrides)
        except DetectionError as exc:
            if not spare_cameras:
                raise
            missed[cam] = exc
    if len(tracks) < 2 and missed:
        raise next(iter(missed.values()))
    flags = [f"the {kind} clip was triangulated from the {' and '.join(tracks)} cameras only: {exc}"
             for exc in missed.values()]
    return tracks, flags


def still_start_positions(clips: ClipReader, rig: Rig, kind: str, first_frame: Mapping[str, int], n_markers: int
                          ) -> dict[str, np.ndarray] | None:
    """Each camera's markers on its first frame of a still clip (``kind`` "plumb" or "static"), found
    with all cameras at once (:func:`find_plumb_multiview`, :func:`find_static_multiview`), or None
    (then each camera searches alone)."""
    if kind == "plumb" and n_markers != 2:
        return None
    frames = {}
    for cam in clips.cameras(kind):
        if cam in rig.cameras:
            for _, gray in clips.gray_frames(kind, cam, start=first_frame.get(cam, 0)):
                frames[cam] = gray.copy()
                break
    if len(frames) < 2:
        return None
    found = (find_plumb_multiview(rig, frames) if kind == "plumb"
             else find_static_multiview(rig, frames, n_markers))
    if found is None:
        return None
    xy, _, points_mm = found
    for cam in frames:
        if cam not in xy and in_image(rig, cam, points_mm):
            xy[cam] = rig.cameras[cam].project(points_mm)  # found by the other two: look where they put it
    return xy


def triangulate_clip(rig: Rig, tracks: Mapping[str, ImageTracks], offsets: Mapping[str, float], fps: float,
                     names: tuple[str, ...], params: PipelineParams, *, match_labels: bool = True,
                     clocks: Mapping[str, tuple[np.ndarray, float]] | None = None) -> MarkerTracks:
    return triangulate_tracks(rig, tracks, offsets, fps, method=params.triangulation, names=names,
                              match_labels=match_labels, clocks=clocks)


def _names(n: int) -> tuple[str, ...]:
    return tuple(f"M{i + 1}" for i in range(n))


def _plumb_lean_deg(plumb: MarkerTracks, rig: Rig) -> float:
    """Angle (degrees) between the plumb line's two markers and the cameras' image-down direction."""
    try:
        p = _static_positions(plumb, "plumb")
    except KinematicsError:
        return 0.0  # no still positions: the kinematics stage says so
    if p.shape[0] < 2 or not np.all(np.isfinite(p[:2])):
        return 0.0
    return float(tilt_from_down_deg(rig, p[1] - p[0]))


def _down_direction(plumb: MarkerTracks | None, cameras_down: np.ndarray) -> np.ndarray:
    """Gravity in rig coordinates: from the plumb line where seen, else ``cameras_down`` (the cameras'
    mean image down, :func:`camera_down`)."""
    if plumb is not None:
        try:
            p = _static_positions(plumb, "plumb")
        except KinematicsError:
            p = None
        if p is not None and p.shape[0] >= 2:
            g = p[1] - p[0]
            g = g / np.linalg.norm(g)
            return g if g[1] > 0 else -g
    return cameras_down


def detect_motion(clips: ClipReader, rig: Rig, static_mm: np.ndarray, n_horse: int, offsets: Mapping[str, float],
                  first_frame: Mapping[str, int], params: PipelineParams, *, down: np.ndarray,
                  multiview: bool = False, clocks: Mapping[str, tuple[np.ndarray, float]] | None = None,
                  ) -> tuple[dict[str, ImageTracks], list[int], int | None, bool]:
    """Track the horse markers through the motion clip of every camera.

    The horse may enter the view late and look-alikes abound, so the start is found with all cameras
    at once (:func:`saddlescope.core.marker_search.find_markers_multiview`): the first instant where
    the cameras agree on a triangle of the static shot's layout. That also tells which static marker
    is the saddle marker S (the one left out). Tracking then follows each camera from there.

    ``multiview`` skips the per-camera search (when what it found does not match the static shot).
    ``clocks`` (:func:`frame_clocks`) pairs the cameras' frames by their timestamps (phones).

    Returns (tracks per camera, static indices of horse markers 1-3, static index of S, whether the
    all-cameras search found the start).
    """
    cams = clips.cameras("motion")
    # The saddle marker sits on the saddle above the horse markers: the static marker farthest
    # against gravity is S, the others are the horse markers in the static shot's order.
    height = -(static_mm @ down)
    order = [int(i) for i in np.argsort(height)]
    horse_idx = sorted(order[:n_horse])
    rest = [i for i in range(static_mm.shape[0]) if i not in horse_idx]
    overrides = {k: v for k, v in params.detection.get("motion", {}).items() if not isinstance(v, Mapping)}
    if not multiview:
        try:
            # First choice: each camera finds the markers by itself among what moves (glints stand still).
            tracks = {c: track_markers(clips.gray_frames("motion", c, start=first_frame.get(c, 0)),
                                       n_markers=n_horse, camera=c, clip="motion", **{"moving": True, **overrides})
                      for c in cams}
            return tracks, horse_idx, (rest[0] if rest else None), False
        except DetectionError:
            pass
    # Then all cameras together: the first instant where they agree on the static shot's triangle.
    frames = SequentialFrames(lambda cam, start: clips.gray_frames("motion", cam, start=start))
    first = max(int(first_frame.get(c, 0) - math.floor(offsets.get(c, 0.0))) for c in cams)
    last = min(int(clips.frame_count("motion", c) - math.ceil(offsets.get(c, 0.0))) - 1 for c in cams)
    fps = clips.fps("motion", cams[0])

    def stamped_position(cam: str, k: int) -> float:  # the camera's frame at reference frame k's instant
        times, anchor = clocks[cam]
        return float(clip_frames_at(np.array([k + offsets.get(cam, 0.0)]), times, anchor, fps)[0])
    position = stamped_position if clocks else None
    _, found = find_markers_multiview(rig, frames, offsets, [static_mm[horse_idx]], first=max(first, 0), last=last,
                                      frame_position=position)
    tracks = {c: track_markers(clips.gray_frames("motion", c, start=found["frames"][c]), n_markers=n_horse,
                               camera=c, clip="motion", first_frame_xy=found["xy"][c], **overrides)
              for c in cams}
    return tracks, horse_idx, (rest[0] if rest else None), True


def _pairwise(xyz: np.ndarray) -> np.ndarray:
    """(..., M, 3) -> (..., M, M) distances between every pair of markers (per frame when 3-D)."""
    return np.linalg.norm(xyz[..., :, None, :] - xyz[..., None, :, :], axis=-1)


def _layout_mismatch_mm(static_horse_mm: np.ndarray, motion_mm: np.ndarray) -> float:
    """RMS difference (mm) between the static shot's horse-marker distances and the tracked ones'
    (medians over the clip; label order does not matter). inf when no frame has all markers."""
    full = np.all(np.isfinite(motion_mm), axis=(1, 2))
    if not full.any():
        return float("inf")
    pairs = np.triu_indices(len(static_horse_mm), 1)
    d_static = np.sort(_pairwise(static_horse_mm)[pairs])
    d_motion = np.sort(np.median(_pairwise(motion_mm[full]), axis=0)[pairs])
    return float(np.sqrt(np.mean((d_static - d_motion) ** 2)))


def identify_saddle_marker(static_mm: np.ndarray, motion_mm: np.ndarray) -> tuple[list[int], int, float]:
    """Which static-shot markers are horse markers 1-3 (in the motion clip's order) and which is S.

    The static shot shows the three horse markers and the saddle marker; the motion clip the three
    horse markers. The triple whose distances best match the motion clip's (rigid body) is the horse
    markers, the remaining one S.

    Returns (static indices of motion markers 1-3, static index of S, RMS distance mismatch in mm).
    """
    scored = _orders_by_mismatch(static_mm, itertools.permutations(range(static_mm.shape[0]), motion_mm.shape[1]),
                                 motion_mm)
    err, idx = min(scored, key=lambda s: s[0] if np.isfinite(s[0]) else np.inf, default=(np.nan, []))
    rest = [i for i in range(static_mm.shape[0]) if i not in idx]
    if not rest or not np.isfinite(err):
        raise KinematicsError("the static shot must show the three horse markers and the saddle marker")
    return idx, rest[0], err


def _orders_by_mismatch(static_mm: np.ndarray, orders, motion_mm: np.ndarray) -> list[tuple[float, list[int]]]:
    """(RMS mismatch mm, order) for each order of static markers standing for motion markers 1..M:
    the static shot's distances between them against the motion clip's median per-frame distances."""
    d_motion = np.nanmedian(_pairwise(motion_mm), axis=0)
    d_static = _pairwise(static_mm)
    return [(float(np.sqrt(np.nanmean((d_static[np.ix_(idx, idx)] - d_motion) ** 2))), idx)
            for idx in map(list, orders)]


def match_horse_markers(static_mm: np.ndarray, horse_idx: list[int], motion_mm: np.ndarray) -> list[int]:
    """The static shot's horse markers in the motion clip's label order.

    Each camera labels the markers it tracks in its own order, so motion marker 1 need not be the
    static shot's first horse marker; registering the static layout to swapped labels bends the
    saddle point's path (a wide-rig rising trot: 10.4 % vertical acceleration error with tracks good
    to a millimetre). The order whose per-frame distances match the static shot's is taken; where
    the layout is near-symmetric and two orders match, the one that keeps the horse nearest to its
    static pose (smallest rotation from the static shot: the same side faces the cameras)."""
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


# --------------------------------------------------------------------------------------------------
# Stages 5-10: kinematics
# --------------------------------------------------------------------------------------------------


def _count(n, noun: str) -> str:
    """"1 frame", "3 frames": counts in flags read as sentences."""
    return f"{int(n)} {noun}{'' if int(n) == 1 else 's'}"


def _static_positions(tracks: MarkerTracks, what: str) -> np.ndarray:
    xyz = tracks.xyz_mm
    ok = np.all(np.isfinite(xyz), axis=(1, 2))
    if ok.sum() < 1:
        raise KinematicsError(f"the {what} clip has no frame where every marker is seen by two cameras")
    return np.median(xyz[ok], axis=0)


def _despiked(xyz: np.ndarray, dt_s: float, *, min_spike_mm: float = 30.0, window_s: float = 0.15) -> np.ndarray:
    """A copy of finite tracks (F, M, 3) with short spikes (a look-alike taken for a marker for a few
    frames) replaced by the running median over ``window_s``: one such spike (0.85 m for 4 frames) took
    a wide-rig trot's autocorrelation from 0.9 to 0.25. Spikes: beyond 5 robust standard deviations
    and ``min_spike_mm``."""
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


def saddle_kinematics(motion_tracks: MarkerTracks, static_tracks: MarkerTracks,
                      plumb_tracks: MarkerTracks | None, params: PipelineParams, *,
                      horse_idx: list[int] | None = None, saddle_idx: int | None = None,
                      gait: str | None = None, depth: Mapping | None = None,
                      down_hint: np.ndarray | None = None) -> dict:
    """Saddle point kinematics from 3-D tracks (thesis 5.2-6.4). Returns plain arrays and fits.

    ``down_hint`` (rig coordinates) stands in for gravity when there is no plumb line: the pipeline
    passes the cameras' mean image-down direction (one tilted camera then costs a third of its tilt).

    ``depth`` is the rig's :func:`~saddlescope.core.triangulation.position_uncertainty` at the
    markers; where depth is much worse fixed than the image position (``params.depth_anisotropy``)
    each marker's depth is fitted smoothly before anything else.
    """
    t = np.asarray(motion_tracks.t_s, dtype=np.float64)
    xyz = np.asarray(motion_tracks.xyz_mm, dtype=np.float64)
    n_frames, n_markers, _ = xyz.shape
    flags: list[str] = []
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
        flags.append(f"{_count(broken.sum(), 'marker sample')} in {_count(broken.any(axis=1).sum(), 'frame')} "
                     "broke the markers' distances (a look-alike taken for a marker) and were dropped")
    # Short gaps bridged (and flagged), long ones reported (5.2.1).
    filled, filled_mask, long_gaps = bridge_gaps(t, xyz.reshape(n_frames, -1), max_gap_s=params.max_gap_s)
    xyz = filled.reshape(n_frames, n_markers, 3)
    bridged_frames = np.any(filled_mask.reshape(n_frames, -1), axis=1)
    if bridged_frames.any():
        flags.append(f"{_count(bridged_frames.sum(), 'frame')} with a short marker gap bridged (for the "
                     "registration; the fits use measured frames only and give the positions there)")
    dt_s = float(np.median(np.diff(t)))
    for start_s, end_s in long_gaps:
        # at the record's ends the markers are not lost but not yet (or no longer) in every view
        if start_s <= t[0] < t[-1] <= end_s:
            flags.append(f"markers lost from {start_s:.2f} s to {end_s:.2f} s (one or another, all along)")
        elif start_s <= t[0]:
            flags.append(f"markers not all in view before {end_s + dt_s:.2f} s (the record starts at {t[0]:.2f} s)")
        elif end_s >= t[-1]:
            flags.append(f"markers not all in view after {start_s - dt_s:.2f} s (the record ends at {t[-1]:.2f} s)")
        else:
            flags.append(f"markers lost from {start_s:.2f} s to {end_s:.2f} s")
    valid = np.all(np.isfinite(xyz), axis=(1, 2))

    # The horse crosses the view: analyse the longest stretch where every marker is tracked.
    run0, run1 = _longest_run(valid)
    if run1 - run0 < 8:
        raise KinematicsError(f"the markers are tracked together for at most {run1 - run0} consecutive frames; "
                              "the ride cannot be analysed")
    # Period from the image-plane coordinates of the left camera: depth is the noisiest direction
    # when the cameras stand close together (thesis rig).
    planar = _despiked(xyz[run0:run1], float(np.median(np.diff(t[run0:run1]))))
    planar[..., 2] = 0.0
    period_s, period_info = estimate_period(t[run0:run1], planar, f_range_hz=STRIDE_RANGE_HZ.get(gait, (0.5, 3.0)))
    i0, i1 = analysis_window(t[run0:run1], valid[run0:run1], period_s, n_periods=params.n_periods)
    i0, i1 = i0 + run0, i1 + run0
    # The fits see every tracked frame around the window ("run"), the thesis only the window: more
    # strides average out camera noise and skin wobble that is not locked to the stride.
    if params.fit_span not in ("run", "window"):
        raise InputError(f"fit_span must be 'run' or 'window', got {params.fit_span!r}")
    f0_, f1_ = i0, i1
    if params.fit_span == "run":
        margin = int(round(params.fit_margin_periods * period_s / float(np.median(np.diff(t[run0:run1])))))
        f0_, f1_ = max(run0, i0 - margin), min(run1, i1 + margin)
    win = slice(f0_, f1_)
    in_win = slice(i0 - f0_, i1 - f0_)
    t_w = t[win]
    xyz_w = xyz[win]
    if depth is not None and depth["anisotropy"] >= params.depth_anisotropy and np.all(np.isfinite(xyz_w)):
        # Narrow rig: the depth noise (systematic too: sub-frame sync, interpolation) leaks into
        # every axis through x = depth * ray, and the lateral sway is far below it: keep each
        # marker's rays and fit its depth with the straight path across the view.
        xyz_w, depth_orders = regularize_depth(t_w, xyz_w, depth["ray_origin_mm"], depth["worst_axis"],
                                               period_s=period_s, max_order=params.depth_max_order)
        flags.append(f"the rig fixes depth {depth['anisotropy']:.0f} times worse than image position: each "
                     "marker's depth was fitted with a straight path across the view (stride orders "
                     f"{depth_orders}); lateral sway and roll are not measured by this rig (both move the markers "
                     "in depth), so the saddle point misses its roll times its sideways offset from the markers "
                     "(a few % of the vertical acceleration; cameras 2-3 m apart see it)")
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

    # Motion reference frame (5.3): travel of marker 1, gravity from the plumb.
    plumb_top = plumb_bottom = None
    if plumb_tracks is not None:
        p = _static_positions(plumb_tracks, "plumb") if plumb_tracks.xyz_mm.ndim == 3 else None
        if p is not None and p.shape[0] >= 2:
            # the upper plumb marker is the one further against gravity; the left camera's image y
            # points roughly down, so it has the smaller rig y.
            top, bottom = (0, 1) if p[0, 1] < p[1, 1] else (1, 0)
            plumb_top = plumb_tracks.xyz_mm[:, top]
            plumb_bottom = plumb_tracks.xyz_mm[:, bottom]
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
    static_all = _static_positions(static_tracks, "static")
    if horse_idx is None or saddle_idx is None:
        horse_idx, saddle_idx, _ = identify_saddle_marker(static_all, xyz)
    # per-frame distances, then their median (the median of each coordinate of a moving, bobbing
    # marker set is no one instant's layout: 118 mm off on a correctly tracked canter)
    d_motion = np.nanmedian(_pairwise(xyz), axis=0)
    d_static = _pairwise(static_all[horse_idx])
    mismatch_mm = float(np.sqrt(np.mean((d_static - d_motion) ** 2)))
    model_mm = marker_model(static_tracks.xyz_mm[:, horse_idx])
    model_m_motion = motion.to_motion_frame(model_mm, frame)
    reg = register_rigid(xyz_m, model_m_motion)
    if not np.all(reg.valid):
        raise KinematicsError("some frames of the analysed stretch could not be registered")

    # Curve fitting (5.5): velocities and accelerations are analytic derivatives of the fits; what
    # follows is reported on the analysed window.
    # Bridged samples keep the registration whole but are not measurements: the fits leave them out
    # (a 4-frame bridge flattened a canter's acceleration peak, 24 % error on a thesis-rig ride).
    measured = ~bridged_frames[win][:, None, None]
    fits = fit_marker_kinematics(t_w, np.where(measured, reg.registered, np.nan), period_s=period_s,
                                 x_model=params.x_model, extra_orders=params.extra_orders, max_order=params.max_order,
                                 criterion=params.criterion, trend_degree=params.trend_degree,
                                 omega_from=params.omega_from)
    flags.extend(fits.flags)
    fits = _on_window(fits, in_win)
    reg = Registration(*(getattr(reg, f.name)[in_win] for f in fields(reg)))
    rigidity_mm = float(np.nanmedian(reg.rms_residual) * 1e3)
    if rigidity_mm > params.max_rigidity_residual_mm:
        flags.append(f"the markers kept the static shot's layout only to {rigidity_mm:.0f} mm (median rigidity "
                     "residual; skin motion leaves a few mm): a look-alike was tracked, a marker moved after the "
                     "static shot, or the static shot is of another set-up; the saddle point is unreliable")
    r, v, a = reg.registered, fits.velocity_m_s, fits.acceleration_m_s2
    t_w = t_w[in_win]
    bridged_w = bridged_frames[win][in_win]
    if bridged_w.any():
        # a bridge is an interpolation across up to a quarter second of a canter's stride; the fits,
        # which saw the same phase in the other strides, are the better positions there
        r = r.copy()
        r[bridged_w] = fits.position_m(t_w[bridged_w])

    # Angular velocity and acceleration (6.1-6.2), the invisible saddle point (6.3-6.4).
    raw = None
    if params.angular_method == "lsq_wiener":
        raw_fits = _on_window(fit_marker_kinematics(t[win], np.where(measured, xyz_m, np.nan), period_s=period_s,
                                                    x_model=params.x_model, extra_orders=params.extra_orders,
                                                    max_order=params.max_order, criterion=params.criterion,
                                                    trend_degree=params.trend_degree, omega_from=params.omega_from),
                              in_win)
        # bridged positions are no measurements of the skin motion the gain weighs
        raw = (np.where(bridged_w[:, None, None], np.nan, xyz_m[in_win]), raw_fits.velocity_m_s,
               raw_fits.acceleration_m_s2)
    ang = angular_kinematics(r, v, a, singularity_threshold=params.singularity_threshold,
                             method=params.angular_method, raw=raw)
    flags.extend(ang.flags)
    static_motion = motion.to_motion_frame(static_all, frame)
    r_bs = saddle_body_coordinates(static_motion[horse_idx], static_motion[saddle_idx])
    s = saddle_point_kinematics(r, v, a, ang, r_bs)

    omega = fits.omega_rad_s if np.isfinite(fits.omega_rad_s) else 2 * np.pi / period_s
    period_fit_s = 2 * np.pi / omega
    return {"t_s": t_w, "period_s": float(period_fit_s), "period_estimate_s": float(period_s),
            "period_info": period_info, "window": (i0, i1), "fitted": (f0_, f1_), "frame": frame, "registration": reg,
            "fits": fits, "angular": ang, "saddle": s, "markers_m": r, "static_mismatch_mm": mismatch_mm,
            "r_bs_m": r_bs, "flags": flags, "long_gaps": long_gaps}


def _harmonic_form(t_s: np.ndarray, y: np.ndarray, f0_hz: float, order: int, *, trend: bool = False
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares cosine series y ~ c0 + sum A_k cos(2 pi k f0 t + phi_k) at a known f0 (plus a
    straight line c1 t with ``trend``: a slope is no part of an oscillation).

    Returns (A (order,), phi (order,), fitted y)."""
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
    """Fourier form of the saddle point's vertical motion at the stride frequency (for the exact
    harmonic weighting of the vibration stage) and its peak-to-peak displacement."""
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


# --------------------------------------------------------------------------------------------------
# The whole ride
# --------------------------------------------------------------------------------------------------


def _finite_list(x) -> list:
    arr = np.asarray(x, dtype=np.float64)
    return np.where(np.isfinite(arr), np.round(arr, 9), np.nan).tolist()


def _nan_to_none(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _nan_to_none(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_nan_to_none(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _nan_to_none(obj.tolist())
    if isinstance(obj, np.floating):
        return _nan_to_none(float(obj))
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def analyze_ride(clips: ClipReader, meta: Mapping, *, params: PipelineParams | None = None,
                 rig: Rig | None = None, on_progress: Callable[[float, str], None] | None = None) -> dict:
    """Run every stage on one ride and return the result document (CONTRACTS section 2).

    Parameters
    ----------
    clips : ClipReader
        The ride's clips: calibration (unless ``rig`` is given), static, motion, optional plumb.
    meta : mapping
        ride.json (board, sync, markers, gait, direction, ...).
    rig : Rig, optional
        A calibration to reuse (e.g. the rig's, computed once for every ride of that day).
    on_progress : callable(fraction, stage), optional
    """
    params = params or PipelineParams()
    progress = _Progress(on_progress)
    t_start = time.perf_counter()
    for kind in ("static", "motion"):
        if not clips.has(kind):
            raise InputError(f"the ride has no {kind} clip; it is required")
    if rig is None and not clips.has("calibration"):
        raise InputError("the ride has no calibration clip and no calibration was given")
    markers = dict(meta.get("markers") or {})
    n_horse = int(markers.get("horse", 3))
    n_saddle = int(markers.get("saddle", 1))
    n_plumb = int(markers.get("plumb", 2))
    kinds = [k for k in ("calibration", "plumb", "static", "motion") if clips.has(k)]
    if rig is not None:
        kinds = [k for k in kinds if k != "calibration"]

    t0 = time.perf_counter()
    progress.stage("sync", 0.0)
    offsets, first_frame = synchronise(clips, meta, kinds)
    clocks, clock_flags = frame_clocks(clips, kinds)
    progress.finish("sync", t0)

    t0 = time.perf_counter()
    calib_report: dict = {}
    if rig is None:
        rig, calib_report = calibrate_from_clips(clips, board_from_meta(meta), offsets["calibration"],
                                                 first_frame["calibration"], params, progress,
                                                 clocks=clocks.get("calibration"))
    progress.finish("calibration", t0)

    t0 = time.perf_counter()
    tracks3d: dict[str, MarkerTracks] = {}
    # Detection and triangulation interleave (the static shot's 3-D layout guides the motion search):
    # time the triangulations apart so each stage's timing is its own.
    triangulation_s = 0.0

    def triangulate(kind, tracks2d, n, **kw) -> MarkerTracks:
        nonlocal triangulation_s
        started = time.perf_counter()
        out = triangulate_clip(rig, tracks2d, offsets[kind], fps[kind], _names(n), params,
                               clocks=clocks.get(kind), **kw)
        triangulation_s += time.perf_counter() - started
        return out

    fps = {kind: clips.fps(kind, clips.cameras(kind)[0]) for kind in ("static", "motion", "plumb")
           if clips.has(kind)}
    if clips.has("plumb"):
        try:
            plumb2d, plumb_flags = detect_clip(clips, "plumb", n_plumb, first_frame["plumb"], params,
                                               spare_cameras=True,
                                               start_xy=still_start_positions(clips, rig, "plumb",
                                                                              first_frame["plumb"], n_plumb))
            tracks3d["plumb"] = triangulate("plumb", plumb2d, n_plumb)
            plumb_problem = "; ".join(plumb_flags) or None
            lean_deg = _plumb_lean_deg(tracks3d["plumb"], rig)
            if lean_deg > params.max_plumb_lean_deg:
                # A plumb line hangs along gravity and cameras stand roughly level: this is not one (a
                # marker taken at the string's end put gravity 62 degrees off on a thesis-rig ride).
                del tracks3d["plumb"]
                plumb_problem = (f"plumb clip not used: the plumb line found leans {lean_deg:.0f} degrees from the "
                                 f"cameras' vertical (more than {params.max_plumb_lean_deg:.0f}): its markers were "
                                 "not found (check that every camera sees both plumb markers)")
        except (DetectionError, TriangulationError, KinematicsError) as exc:
            plumb_problem = f"plumb clip not used: {exc}"
    else:
        plumb_problem = "no plumb clip"
    progress.stage("detection", 0.2)
    static2d, static_flags = detect_clip(clips, "static", n_horse + n_saddle, first_frame["static"], params,
                                         spare_cameras=True,
                                         start_xy=still_start_positions(clips, rig, "static", first_frame["static"],
                                                                        n_horse + n_saddle))
    tracks3d["static"] = triangulate("static", static2d, n_horse + n_saddle)
    progress.stage("detection", 0.4)
    static_mm = _static_positions(tracks3d["static"], "static")
    cameras_down = camera_down(rig)
    down = _down_direction(tracks3d.get("plumb"), cameras_down)
    motion2d, horse_idx, saddle_idx, searched_together = detect_motion(
        clips, rig, static_mm, n_horse, offsets["motion"], first_frame["motion"], params, down=down,
        clocks=clocks.get("motion"))
    tracks3d["motion"] = triangulate("motion", motion2d, n_horse)
    layout_flags = []
    found_mm = _layout_mismatch_mm(static_mm[horse_idx], tracks3d["motion"].xyz_mm)
    if found_mm > params.max_layout_mismatch_mm:
        # Each camera took the same moving look-alike (a stirrup's glint, the saddle pad) for a marker:
        # the triangle does not match the static shot. Search again with all cameras and that triangle
        # (unless that search is what found these).
        again_mm = np.inf
        if not searched_together:
            try:
                again2d, again_h, again_s, _ = detect_motion(
                    clips, rig, static_mm, n_horse, offsets["motion"], first_frame["motion"], params, down=down,
                    multiview=True, clocks=clocks.get("motion"))
                again = triangulate("motion", again2d, n_horse)
                again_mm = _layout_mismatch_mm(static_mm[again_h], again.xyz_mm)
            except (DetectionError, TriangulationError):
                pass
        if again_mm < found_mm:
            layout_flags.append(f"the moving spots each camera found were {found_mm:.0f} mm RMS off the static shot's "
                                f"marker distances (a look-alike moving with the horse); the markers were found "
                                f"again with all cameras and the static layout ({again_mm:.0f} mm)")
            motion2d, horse_idx, saddle_idx, tracks3d["motion"] = again2d, again_h, again_s, again
        else:
            layout_flags.append(f"the tracked markers are {found_mm:.0f} mm RMS off the static shot's marker distances "
                                "and no closer triangle was found: a look-alike may have been tracked, or a marker "
                                "moved between the static shot and the ride (check both clips)")
    horse_idx = match_horse_markers(static_mm, horse_idx, tracks3d["motion"].xyz_mm)
    coverage_flags = []
    if calib_report.get("board_coverage"):
        for cam, share in outside_coverage(motion2d, calib_report["board_coverage"]).items():
            if share > 0.05:
                coverage_flags.append(f"the {cam} camera saw the markers outside the region the calibration board "
                                      f"covered in {100 * share:.0f} % of its detections: its lens distortion is "
                                      "extrapolated there (move the board to the edges of every camera's view)")
    progress.finish("detection", t0, seconds=time.perf_counter() - t0 - triangulation_s)
    progress.finish("triangulation", t0, seconds=triangulation_s)

    t0 = time.perf_counter()
    depth = depth_uncertainty(rig, tracks3d["motion"])
    kin = saddle_kinematics(tracks3d["motion"], tracks3d["static"], tracks3d.get("plumb"), params,
                            horse_idx=horse_idx, saddle_idx=saddle_idx, gait=meta.get("gait"), depth=depth,
                            down_hint=cameras_down)
    if plumb_problem:
        kin["flags"].insert(0, plumb_problem)
    kin["flags"][:0] = (clock_flags + static_flags + layout_flags + coverage_flags
                        + [f for kind, tr in tracks3d.items() if (f := _disagreement_flag(kind, tr))])
    progress.finish("kinematics", t0)

    t0 = time.perf_counter()

    harm, indicators = kinematics_indicators(kin, params)
    progress.finish("indicators", t0)
    progress.timings_s["total"] = round(time.perf_counter() - t_start, 4)
    return _result_document(meta, rig, calib_report, offsets, tracks3d, kin, harm, indicators, clips,
                            progress.timings_s, params)


def depth_uncertainty(rig: Rig, tracks: MarkerTracks) -> dict | None:
    """The rig's position uncertainty at the markers' median place (None if it cannot be had)."""
    xyz = np.asarray(tracks.xyz_mm, dtype=np.float64).reshape(-1, 3)
    xyz = xyz[np.all(np.isfinite(xyz), axis=1)]
    if xyz.shape[0] == 0:
        return None
    try:
        return position_uncertainty(rig, np.median(xyz, axis=0))
    except TriangulationError:
        return None


def kinematics_indicators(kin: Mapping, params: PipelineParams) -> tuple[dict, dict]:
    """The vertical harmonics of the saddle point and the rider's indicators (thesis 7, 8.5) from the
    output of :func:`saddle_kinematics`."""
    s = kin["saddle"]
    fit_order = max(f.order for f in kin["fits"].fits_y)
    harm = vertical_harmonics(kin["t_s"], s.acceleration_m_s2[:, 1], s.position_m[:, 1], kin["period_s"],
                              fit_order)
    indicators = ride_indicators(f0_hz=harm["f0_hz"], acc_y_amplitudes_m_s2=harm["amplitudes_m_s2"],
                                 acc_y_phases_rad=harm["phases_rad"], duration_s=kin["period_s"] * params.n_periods,
                                 speed_kmh=abs(kin["fits"].average_speed_m_s) * 3.6,
                                 amplitude_y_m=harm["amplitude_y_m"], stride_frequency_hz=1.0 / kin["period_s"])
    return harm, indicators


def _disagreement_flag(kind: str, tracks: MarkerTracks, *, share: float = 0.05) -> str | None:
    """A flag when over ``share`` of a clip's triangulated samples reproject worse than 2 px and 8 times
    the clip's median: the cameras saw different things there (one followed a look-alike, or the
    synchronisation or calibration is off) and nothing could tell which camera was wrong."""
    if tracks.reprojection_error_px is None:
        return None
    err = np.asarray(tracks.reprojection_error_px, dtype=np.float64)
    err = err[np.isfinite(err)]
    if err.size < 20:
        return None
    median = float(np.median(err))
    limit = max(2.0, 8.0 * median)
    bad = float(np.mean(err > limit))
    if bad <= share:
        return None
    return (f"the cameras disagree on the {kind} clip's markers by more than {limit:.1f} px in {100 * bad:.0f} % "
            f"of the triangulated samples (median {median:.2f} px): a camera may have followed a look-alike there, "
            "or the synchronisation or calibration is off (check the cameras' tracks)")


def _track_quality(tracks: MarkerTracks) -> dict:
    xyz = tracks.xyz_mm
    seen = np.all(np.isfinite(xyz), axis=2)
    out = {"frames": int(xyz.shape[0]), "markers_seen_fraction": _finite_list(seen.mean(axis=0))}
    if tracks.reprojection_error_px is not None:
        err = np.asarray(tracks.reprojection_error_px, dtype=np.float64)
        fin = err[np.isfinite(err)]
        out["reprojection_error_px_median"] = float(np.median(fin)) if fin.size else None
        out["reprojection_error_px_p95"] = float(np.percentile(fin, 95)) if fin.size else None
    return out


def _result_document(meta, rig: Rig, calib_report, offsets, tracks3d, kin, harm, indicators, clips,
                     timings_s, params: PipelineParams) -> dict:
    s = kin["saddle"]
    ang = kin["angular"]
    fits = kin["fits"]
    reg = kin["registration"]
    frame = kin["frame"]
    motion_cam = clips.cameras("motion")[0]
    fps = float(clips.fps("motion", motion_cam))
    t_s = kin["t_s"]
    quality = {
        "flags": list(dict.fromkeys(list(rig.flags) + kin["flags"])),
        "calibration_ok": not rig.flags,
        "gravity_source": frame.gravity_source,
        "angle_travel_gravity_deg": frame.angle_travel_gravity_deg,
        "rigidity_residual_mm": {"median": float(np.nanmedian(reg.rms_residual) * 1e3),
                                 "max": float(np.nanmax(reg.rms_residual) * 1e3)},
        "static_marker_mismatch_mm": kin["static_mismatch_mm"],
        "singularity_index_median": ang.median_singularity_index,
        "omega_versions_excluded_fraction": float(np.mean(ang.excluded)),
        "saddle_acceleration_spread_m_s2_median": float(np.nanmedian(s.acceleration_spread)),
        "vertical_harmonic_fit_rms_m_s2": harm["fit_rms_residual_m_s2"],
        "tracks": {kind: _track_quality(tr) for kind, tr in tracks3d.items()},
        "long_gaps_s": [list(g) for g in kin["long_gaps"]],
        "period_estimate_s": kin["period_estimate_s"],
        # the frames the fits saw (the window's harmonics are estimated from every tracked stride)
        "fitted_frames": {"start_frame": int(kin["fitted"][0]), "frames": int(kin["fitted"][1] - kin["fitted"][0])},
    }
    fits_doc = fits_document(fits)
    result = {
        "format": RESULT_FORMAT,
        "fps": fps,
        "gait": meta.get("gait"),
        "direction": meta.get("direction"),
        "calibration": rig_to_result(rig),
        "sync": {kind: {c: float(v) for c, v in off.items()} for kind, off in offsets.items()},
        "period_s": kin["period_s"],
        "window": {"start_s": float(t_s[0]), "duration_s": float(len(t_s) / fps),
                   "start_frame": int(kin["window"][0]), "frames": int(len(t_s))},
        "saddle": {"t_s": _finite_list(t_s), "position_m": _finite_list(s.position_m),
                   "velocity_m_s": _finite_list(s.velocity_m_s),
                   "acceleration_m_s2": _finite_list(s.acceleration_m_s2),
                   "acceleration_spread_m_s2": _finite_list(s.acceleration_spread),
                   "body_coordinates_m": _finite_list(s.body_coordinates_m)},
        "angular": {"omega_rad_s": _finite_list(ang.omega_rad_s), "alpha_rad_s2": _finite_list(ang.alpha_rad_s2),
                    "singularity_index": ang.median_singularity_index,
                    "singularity_index_per_frame": _finite_list(ang.singularity_index),
                    "omega_versions_rad_s": _finite_list(ang.omega_versions),
                    "omega_versions_excluded": np.asarray(ang.excluded).tolist(),
                    "omega_spread_rad_s": _finite_list(ang.omega_spread),
                    "method": ang.method,
                    "weak_axis_gain": (None if ang.weak_axis_gain is None else
                                       {"omega": ang.weak_axis_gain[0], "alpha": ang.weak_axis_gain[1]})},
        "markers": {"names": ["M1", "M2", "M3"], "position_m": _finite_list(kin["markers_m"]),
                    "velocity_m_s": _finite_list(fits.velocity_m_s),
                    "acceleration_m_s2": _finite_list(fits.acceleration_m_s2),
                    "rigidity_residual_mm": _finite_list(reg.rms_residual * 1e3), "fits": fits_doc},
        "motion_frame": {"R_rig_to_motion": _finite_list(frame.R), "origin_mm": _finite_list(frame.origin_mm),
                         "gravity_source": frame.gravity_source},
        "vertical_harmonics": {"f0_hz": harm["f0_hz"], "amplitudes_m_s2": _finite_list(harm["amplitudes_m_s2"]),
                               "phases_rad": _finite_list(harm["phases_rad"])},
        "indicators": {k: float(v) for k, v in indicators.items()},
        "quality": quality,
        "params": {"n_periods": params.n_periods, "triangulation": params.triangulation,
                   "smoothing_span": params.smoothing_span, "angular_method": params.angular_method,
                   "x_model": params.x_model, "omega_from": params.omega_from, "fit_span": params.fit_span,
                   "smoothing": params.smoothing, "criterion": params.criterion},
        "timings_s": dict(timings_s),
    }
    if calib_report:
        result["calibration"]["n_views"] = calib_report.get("n_views")
        result["calibration"]["board_coverage_fraction"] = {
            c: v["area_fraction"] for c, v in calib_report.get("board_coverage", {}).items()}
    return _nan_to_none(result)


def fits_document(fits) -> dict:
    """The result's ``markers.fits``: per axis (x, y, z) and marker, the fit's kind, goodness of fit
    (SSE, R², adjusted R², RMSE, the residuals' and the noise's lag-1 autocorrelation), order,
    fundamental, coefficients and their 95 % confidence intervals (thesis 5.5)."""
    return {axis: [_fit_summary(f) for f in group]
            for axis, group in (("x", fits.fits_x), ("y", fits.fits_y), ("z", fits.fits_z))}


def _fit_summary(fit) -> dict:
    out = {"kind": type(fit).__name__}
    gof = getattr(fit, "gof", None)
    if gof is not None:
        out.update({k: (float(v) if isinstance(v, int | float | np.floating) else v)
                    for k, v in gof.as_dict().items()})
    for attr in ("order", "f0_hz", "slope", "intercept", "omega_rad_s"):
        if hasattr(fit, attr):
            val = getattr(fit, attr)
            if isinstance(val, int | float | np.floating | np.integer):
                out[attr] = float(val)
    # the coefficients with their 95 % confidence intervals (correlated noise accounted for, see
    # fitting's module note): the slope's is the average speed's
    ci = getattr(fit, "ci", None)
    if isinstance(ci, np.ndarray):
        out["ci95"] = {"intercept": _finite_list(ci[0]), "slope": _finite_list(ci[1])}
    elif isinstance(ci, dict):
        # trend[0] of a Fourier x series is the average speed (m/s)
        out["a"], out["b"], out["trend"] = _finite_list(fit.a), _finite_list(fit.b), _finite_list(fit.trend)
        out["ci95"] = {k: _finite_list(ci[k]) for k in ("a0", "a", "b", "omega_rad_s", "trend") if k in ci}
    return out

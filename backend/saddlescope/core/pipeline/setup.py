"""Setting up a ride: the board, the clips' synchronisation and the rig's calibration (thesis 3-4).

Stage 2 (synchronisation) runs first because calibration puts every camera's board views on the
first camera's clock; stage 1 (calibration) is skipped when a stored calibration is reused.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import replace

import cv2
import numpy as np

from saddlescope.core import calibration as calib
from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.detection.detectors import DetectionSettings, marker_detector
from saddlescope.core.errors import CalibrationError, DetectionError, SyncError
from saddlescope.core.findings import Finding
from saddlescope.core.params import PipelineParams
from saddlescope.core.pipeline.inputs import ClipReader, Progress, cameras_at_once
from saddlescope.core.rolling_shutter import CameraReadout, readout_from_bands, readouts_from_meta
from saddlescope.core.sync import clip_offsets, flash_interval, flash_run, nominal_frames_of, offsets_from_spec
from saddlescope.core.sync_motion import MotionSync, motion_offsets
from saddlescope.core.types import Board, ImageTracks, Rig

__all__ = ["SYNC_METHODS", "board_corner_sample", "board_coverage", "calibrate_from_clips", "clip_readouts",
           "frame_clocks", "lens_coverage_of",
           "motion_sync", "outside_coverage", "still_views", "sync_flag", "sync_quality", "synchronise",
           "synchronise_clips"]


SYNC_METHODS = ("flash", "offsets", "motion")


def synchronise(clips: ClipReader, meta: Mapping, kinds: list[str], *,
                threads: int | None = None) -> tuple[dict, dict]:
    """Frame offsets per clip kind and camera, and where detection may start.

    Frame offsets per clip kind and camera (relative to the first camera) and the first frame
    after the flash in each camera's clip, where detection may start. ``threads``: the analysis's
    thread budget (``PipelineParams.threads``; None: one thread per camera of a clip set).

    Raises
    ------
    SyncError
        A clip set without a flash (and not still): :func:`synchronise_clips` and the motion then
        synchronise it, which this function's callers do not do.
    """
    offsets, first_frame, methods = synchronise_clips(clips, meta, kinds, threads=threads)
    pending = [k for k in kinds if methods.get(k) == "motion"]
    if pending:
        raise SyncError(methods["reasons"][pending[0]])
    return offsets, first_frame


def synchronise_clips(clips: ClipReader, meta: Mapping, kinds: list[str], *,
                      threads: int | None = None) -> tuple[dict, dict, dict]:
    """:func:`synchronise`, and how each clip set is (to be) synchronised.

    ``sync.method`` "flash" (default) finds the flash in every clip; a clip set where it is not found
    falls back to its markers' motion. "motion" does not look for a flash. Returns ``methods[kind]``:
    "flash" or "offsets" (done), "motion" (the motion clip: from its markers once the rig is known,
    :func:`motion_sync`; the calibration clip: from the board, :func:`calibrate_from_clips`), or
    "still" (the plumb and static clips without a flash: their markers stand still, so frames pair up
    whatever the offset, taken as 0); ``methods["reasons"][kind]`` why a flash was not used;
    ``methods["readouts"][kind][camera]`` the camera's rolling-shutter readout (:func:`clip_readouts`),
    which the flash's sweep model uses.
    """
    from concurrent.futures import ThreadPoolExecutor

    offsets: dict[str, dict[str, float]] = {}
    first_frame: dict[str, dict[str, int]] = {}
    methods: dict = {"reasons": {}}
    sync_spec = meta.get("sync") or {"method": "flash"}
    by_motion = isinstance(sync_spec, Mapping) and sync_spec.get("method") == "motion"
    # Every clip's brightness (up to its flash) is decoded in threads (the decoder releases the GIL), in
    # order; never more threads than the budget (the clip reader splits it among its open decoders).
    jobs = [] if by_motion else [(kind, c) for kind in kinds for c in clips.cameras(kind)]
    budget = threads or max(len(clips.cameras(kind)) for kind in kinds)
    with ThreadPoolExecutor(max_workers=max(1, min(len(jobs), budget))) as pool:
        decoded = dict(zip(jobs, pool.map(lambda job: clips.brightness(*job), jobs), strict=True))
    methods["readouts"] = readouts = clip_readouts(clips, meta, kinds, flash_clips=not by_motion)
    for kind in kinds:
        cams = clips.cameras(kind)
        fps = {c: clips.fps(kind, c) for c in cams}
        # a variable-rate clip's nominal rate comes from its stamps (a short clip's to a few tenths of
        # a percent); its frames are then placed by their stamps, not by the rate
        rel_tol = 0.01 if any(clips.frame_times(kind, c) is not None for c in cams) else 1e-3
        if by_motion:
            _same_rates(kind, fps, rel_tol)  # offsets in frames, as with the flash
            _without_flash(kind, cams, offsets, first_frame, methods, "the ride asks for sync from motion")
            continue
        known = offsets_from_spec(sync_spec, clip=kind, cameras=cams)
        brightness = {c: decoded[kind, c] for c in cams}
        if known is None:
            try:
                offsets[kind] = clip_offsets(brightness, fps, clip=kind, fps_rel_tol=rel_tol,
                                             readout_frames={c: readouts[kind][c].readout_s * fps[c] for c in cams})
            except SyncError as exc:
                if "no sync flash" not in str(exc):
                    raise  # frame rates, clip lengths: no other sync would help
                _without_flash(kind, cams, offsets, first_frame, methods, str(exc))
                continue
        else:
            offsets[kind] = known
        methods[kind] = "flash" if known is None else "offsets"
        first_frame[kind] = {}
        for c in cams:
            try:
                _, end = flash_interval(brightness[c], clip=kind, camera=c)
                first_frame[kind][c] = int(math.ceil(end)) + 1
            except SyncError:
                if known is None:
                    raise
                first_frame[kind][c] = 0  # known offsets: the clip need not hold a flash
    return offsets, first_frame, methods


def clip_readouts(clips: ClipReader, meta: Mapping, kinds: list[str], *,
                  flash_clips: bool = True) -> dict[str, dict[str, CameraReadout]]:
    """Every camera's rolling-shutter readout in every clip set: given in ride.json, or measured.

    Measured from the flash sweeping down the clip's bands of rows
    (:func:`~saddlescope.core.rolling_shutter.readout_from_bands`, from the reader's ``band_brightness``);
    a clip without a flash takes the median of the camera's readouts measured in its other clips, and a
    camera whose clips show no flash (or a reader without row bands) a global shutter (0).

    Raises
    ------
    InputError
        ride.json's ``sync.readout_ms`` is not a number of 0-40 ms for a camera of the ride.
    """
    cameras = list(dict.fromkeys(c for kind in kinds for c in clips.cameras(kind)))
    given = readouts_from_meta(meta, cameras)
    if given is not None:
        return {kind: {c: CameraReadout(given[c], "ride.json") for c in clips.cameras(kind)} for kind in kinds}
    bands_of = getattr(clips, "band_brightness", None)
    measured: dict[str, dict[str, CameraReadout]] = {kind: {} for kind in kinds}
    for kind in kinds:
        if not flash_clips or bands_of is None:
            break
        for cam in clips.cameras(kind):
            try:
                start, stop = flash_run(clips.brightness(kind, cam), clip=kind, camera=cam)
                curves, rows = bands_of(kind, cam)
                est = readout_from_bands(curves, rows, clips.fps(kind, cam), start=start, stop=stop)
            except SyncError:
                continue
            measured[kind][cam] = CameraReadout(est.readout_s, "flash sweep", est.sigma_s)
    out: dict[str, dict[str, CameraReadout]] = {}
    for kind in kinds:
        out[kind] = {}
        for cam in clips.cameras(kind):
            elsewhere = [m[cam].readout_s for m in measured.values() if cam in m]
            out[kind][cam] = measured[kind].get(cam) or (
                CameraReadout(float(np.median(elsewhere)), "flash sweep elsewhere") if elsewhere
                else CameraReadout(0.0, "none"))
    return out


def _same_rates(kind: str, fps: Mapping[str, float], rel_tol: float) -> None:
    """Refuse cameras at different nominal frame rates (offsets count frames), as the flash does."""
    ref, f0 = next(iter(fps.items()))
    for cam, f in fps.items():
        if not (np.isfinite(f) and f > 0):
            raise SyncError(f"{kind} clip of the {cam} camera: frame rate {f} is not positive")
        if abs(f - f0) > rel_tol * f0:
            raise SyncError(f"{kind} clip: the {cam} camera runs at {f:g} fps but the {ref} camera at {f0:g} fps; "
                            "frame offsets need equal frame rates")


def _without_flash(kind: str, cams: list[str], offsets: dict, first_frame: dict, methods: dict, reason: str) -> None:
    """A clip set synchronised without a flash: offsets 0 until its motion gives them."""
    offsets[kind] = {c: 0.0 for c in cams}
    first_frame[kind] = {c: 0 for c in cams}
    methods[kind] = "still" if kind in ("plumb", "static") else "motion"
    methods["reasons"][kind] = reason


def motion_sync(clips: ClipReader, rig: Rig, kind: str, n_markers: int, params: PipelineParams,
                clocks: Mapping[str, tuple[np.ndarray, float]] | None = None,
                readouts: Mapping[str, CameraReadout] | None = None) -> MotionSync:
    """Offsets of a clip set without a flash from its markers' motion, with the calibrated rig.

    Each camera tracks the moving markers by itself (as :func:`~saddlescope.core.pipeline.detection.detect_motion`
    first does), then :func:`~saddlescope.core.sync_motion.motion_offsets` cross-correlates their image
    speeds and refines the offsets by triangulation consistency.

    Raises
    ------
    SyncError
        A camera that does not find the markers, or motion that does not fix the offsets.
    """
    cams = clips.cameras(kind)
    settings = params.detection.get(kind, DetectionSettings())
    detector = marker_detector(params.marker_detector)
    tracks = {}
    for c in cams:
        try:
            tracks[c] = detector.track(clips.gray_frames(kind, c), n_markers=n_markers, camera=c, clip=kind,
                                       options=settings.for_camera(c), moving=True)
        except DetectionError as exc:
            raise SyncError(f"no sync flash in the {kind} clip, and its markers' motion cannot synchronise the "
                            f"cameras: {exc}") from exc
    fps = clips.fps(kind, cams[0])
    row_readout = {c: (r.readout_s * fps, clips.image_size(kind, c)[1]) for c, r in (readouts or {}).items()
                   if r.readout_s > 0}
    return motion_offsets(tracks, fps, rig=rig, clocks=clocks, clip=kind, row_readout=row_readout)


def sync_quality(kinds: list[str], methods: Mapping, synced: Mapping[str, MotionSync]) -> dict:
    """The result's ``quality.sync``: per clip set its method and, from motion, the offsets' uncertainty.

    ``{kind: {"method": "flash" | "offsets" | "motion" | "still", "sigma_frames": {camera: frames},
    "rms_px": ..., "reason": why no flash, "readout_ms": {camera: ms}, "readout_source": {camera: source},
    "readout_sigma_ms": {camera: ms}}}`` (the sigmas, rms and reason only where they apply; the readouts
    where a camera has a rolling shutter or it was measured).
    """
    out = {}
    for kind in kinds:
        entry: dict = {"method": methods.get(kind, "flash")}
        entry.update(_readout_quality(methods.get("readouts", {}).get(kind, {})))
        if kind in synced:
            entry["sigma_frames"] = {c: round(float(v), 4) for c, v in synced[kind].sigma_frames.items()}
            rms_px = synced[kind].rms_px
            if rms_px is not None:
                entry["rms_px"] = round(float(rms_px), 4)
        if kind in methods.get("reasons", {}):
            entry["reason"] = methods["reasons"][kind]
        out[kind] = entry
    return out


def _readout_quality(readouts: Mapping[str, CameraReadout]) -> dict:
    """A clip set's readouts for ``quality.sync``: ms, source and (measured) standard error per camera."""
    if not readouts or all(r.source == "none" for r in readouts.values()):
        return {}
    out: dict = {"readout_ms": {c: round(1000.0 * r.readout_s, 2) for c, r in readouts.items()},
                 "readout_source": {c: r.source for c, r in readouts.items()}}
    sigmas = {c: round(1000.0 * r.sigma_s, 3) for c, r in readouts.items() if r.sigma_s is not None}
    if sigmas:
        out["readout_sigma_ms"] = sigmas
    return out


def sync_flag(kind: str, found: MotionSync) -> Finding:
    """The finding of a clip set synchronised from motion (``sync.motion``, or ``sync.motion_uncertain``)."""
    what = "the board's" if kind == "calibration" else "the markers'"
    others = [c for c in found.offsets if found.sigma_frames.get(c, 0.0) > 0 or found.offsets[c] != 0.0]
    parts = ", ".join(f"{c} {found.offsets[c]:+.2f} ± {found.sigma_frames[c]:.2f}" for c in others)
    worst = max((found.sigma_frames[c] for c in others), default=0.0)
    if kind == "calibration":  # only still views of the board are used: whole frames suffice
        verdict = "to the nearest frame" if worst < 0.5 else "uncertain"
    else:
        verdict = "uncertain" if worst > 0.1 else "within a tenth of a frame"
    return Finding("sync.motion_uncertain" if verdict == "uncertain" else "sync.motion",
                   f"the {kind} clip was synchronised from {what} motion (no sync flash), {verdict}: offsets "
                   f"{parts} frames", {"worst_sigma_frames": worst})


def frame_clocks(clips: ClipReader, kinds: list[str]) -> tuple[dict, list[Finding]]:
    """The timestamps of variable-rate clips (phones) and the frame where each was synchronised.

    Returns ``clocks[kind][camera] = (frame times (F,) s, anchor frame)`` for every camera of a clip
    set where one camera's frames are not evenly spaced (the even ones get their own even stamps),
    and a finding for each uneven clip. The anchor is the sync flash's onset: frame offsets are measured
    there, so the nominal even clock is tied to the clip's timestamps at that frame.
    """
    clocks: dict[str, dict[str, tuple[np.ndarray, float]]] = {}
    flags: list[Finding] = []
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
                nominal_ms = 1000.0 / clips.fps(kind, cam)
                flags.append(Finding("video.variable_frame_rate",
                                     f"the {kind} clip of the {cam} camera has a variable frame rate (frames "
                                     f"{dt_ms.min():.1f}-{dt_ms.max():.1f} ms apart, nominal {nominal_ms:.1f} ms): "
                                     "its frames are placed at their timestamps",
                                     {"interval_min_ms": float(dt_ms.min()), "interval_max_ms": float(dt_ms.max()),
                                      "nominal_interval_ms": nominal_ms}))
            try:
                anchor, _ = flash_interval(clips.brightness(kind, cam), clip=kind, camera=cam)
            except SyncError:
                anchor = 0.0  # offsets given in ride.json: counted from the clip's first frame
            clocks.setdefault(kind, {})[cam] = (np.asarray(times, dtype=np.float64), float(anchor))
    return clocks, flags


def calibrate_from_clips(clips: ClipReader, board: Board, offsets: Mapping[str, float],
                         first_frame: Mapping[str, int], params: PipelineParams,
                         progress: Progress | None = None, clocks: Mapping[str, tuple[np.ndarray, float]] | None = None,
                         sync_from_board: bool = False, on_views_found: Callable[[], None] | None = None
                         ) -> tuple[Rig, dict]:
    """Calibrate the rig from every camera's calibration clip.

    Board views from every camera's calibration clip, put on the first camera's clock, then
    intrinsics, stereo pairs, bundle adjustment and metric checks (thesis 3.4-3.6, 8.2).

    Parameters
    ----------
    offsets, first_frame : mapping of camera
        The calibration clip's frame offsets against the first camera and first frame after the flash.
    clocks : mapping of camera -> (ndarray of shape (F,), float), optional
        Frame timestamps (s) and anchor frame of variable-rate clips (:func:`frame_clocks`).
    sync_from_board : bool
        The clip holds no flash: ``offsets`` are found from the board's motion (its corners' image
        speed, :func:`~saddlescope.core.sync_motion.motion_offsets` without a rig) once every camera's
        views are found; whole frames matter here, as only still views are used.
    on_views_found : callable, optional
        Called once the board views are found, before the solve: work that needs no rig starts then.

    Returns
    -------
    rig : Rig
    report : dict
        ``n_views`` and ``board_coverage`` (image hull, share of the image) per camera, ``board_views`` (the
        views solved, per camera: a wand refinement checks on them); with ``sync_from_board`` also ``sync``
        (:class:`~saddlescope.core.sync_motion.MotionSync`).
    """
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
        return views, size or clips.image_size("calibration", cam)

    def on_reference_clock(cam: str, views: list) -> list:
        # frame k of this camera shows the instant of frame k - offset of the first camera (for a
        # variable-rate clip, k counted on its nominal clock: a dropped frame shifts the rest)
        views = still_views(views, step) if params.still_board_only else views
        frames = np.array([v.frame for v in views], dtype=np.float64)
        if (cam_clock := (clocks or {}).get(cam)) is not None and views:
            frames = nominal_frames_of(frames, cam_clock[0], cam_clock[1], fps)
        return [replace(v, frame=int(round(k - offsets.get(cam, 0.0)))) for v, k in zip(views, frames, strict=True)]

    # Cameras in parallel within the thread budget: decoding (PyAV) and the board search (OpenCV) release the
    # GIL. Each camera's views depend on its clip alone, so the result does not depend on the threads' timing;
    # progress is reported from this thread.
    found = _per_camera_in_threads(cams, board_views, progress, params.threads)
    for cam in cams:
        if not found[cam][0]:
            _no_board(clips, cam, board, max(0, base + int(round(offsets.get(cam, 0.0)))), step)
    if on_views_found is not None:
        on_views_found()
    board_sync = None
    if sync_from_board:
        board_sync = motion_offsets({c: board_track(found[c][0], board) for c in cams}, fps, clocks=clocks,
                                    clip="calibration")
        offsets = board_sync.offsets
    views_by_camera = {cam: on_reference_clock(cam, found[cam][0]) for cam in cams}
    sizes = {cam: found[cam][1] for cam in cams}
    views_by_camera = _instants_to_solve(views_by_camera, board, sizes, params)
    rig, report = calib.calibrate_rig(views_by_camera, board, sizes, max_square_error_pct=params.max_square_error_pct,
                                      threads=cameras_at_once(len(cams), params.threads))
    report.update(_views_report(views_by_camera, sizes))
    report["board_views"] = views_by_camera
    if board_sync is not None:
        report["sync"] = board_sync
    return rig, report


def _instants_to_solve(views_by_camera: dict, board: Board, sizes: dict, params: PipelineParams) -> dict:
    """With several cameras: each hold of the board averaged, then the instants the solve uses chosen."""
    if len(views_by_camera) < 2:
        return views_by_camera
    views_by_camera = _average_holds(views_by_camera)
    keep = set(calib.select_instants(views_by_camera, board, sizes, max_instants=params.max_calibration_instants))
    return {c: [v for v in vs if v.frame in keep] for c, vs in views_by_camera.items()}


def _views_report(views_by_camera: dict, sizes: dict) -> dict:
    """Per camera the views used, the board's coverage of the image and a sample of its corners (px)."""
    return {"n_views": {c: len(v) for c, v in views_by_camera.items()},
            "board_coverage": {c: board_coverage(v, sizes[c]) for c, v in views_by_camera.items() if v},
            "board_corners_px": {c: board_corner_sample(v) for c, v in views_by_camera.items() if v}}


def _no_board(clips: ClipReader, cam: str, board: Board, start: int, step: int) -> None:
    """Raise the error of a calibration clip without the board; where the pattern counts squares, say so."""
    grays = (gray for _, gray in clips.gray_frames("calibration", cam, start=start, step=5 * step))
    hint = calib.squares_hint(grays, board)
    raise CalibrationError(f"no calibration board found in the calibration clip of the {cam} camera"
                           + (f"; {hint}" if hint else ""))


def _per_camera_in_threads(cams: list[str], work: Callable[[str], tuple], progress: Progress | None,
                           threads: int | None = None) -> dict:
    """``work(cam)`` for every camera, :func:`~saddlescope.core.pipeline.inputs.cameras_at_once` at once.

    Progress is reported from this thread. With a budget of one thread the cameras run here, one after another.
    """
    from concurrent.futures import ThreadPoolExecutor, as_completed

    workers = cameras_at_once(len(cams), threads)
    if workers == 1:
        out = {}
        for done, cam in enumerate(cams, 1):
            out[cam] = work(cam)
            if progress is not None:
                progress.stage("calibration", 0.6 * done / len(cams))
        return out
    with ThreadPoolExecutor(max_workers=workers) as pool:
        jobs = {pool.submit(work, cam): cam for cam in cams}
        for done, job in enumerate(as_completed(jobs), 1):
            job.result()
            if progress is not None:
                progress.stage("calibration", 0.6 * done / len(cams))
    return {cam: job.result() for job, cam in jobs.items()}


def board_track(views: list, board: Board) -> ImageTracks:
    """A camera's board views as tracks of every board corner, (F, N corners, 2), NaN where not found.

    Its image speed (:func:`~saddlescope.core.sync_motion.image_speed`: the mean over the corners found
    in both frames) is the board's motion, unaffected by corners coming and going.
    """
    n = len(object_points_mm(board))
    frames = np.array(sorted({int(v.frame) for v in views}), dtype=np.int64)
    xy = np.full((frames.size, n, 2), np.nan)
    row = {int(f): i for i, f in enumerate(frames)}
    for v in views:
        xy[row[int(v.frame)], np.asarray(v.ids, dtype=np.int64)] = np.asarray(v.corners_px, dtype=np.float64)
    return ImageTracks("board", xy, frames)


def board_corner_sample(views: list, *, max_points: int = 1500) -> list[list[float]]:
    """The board corners of the views used, evenly thinned to at most ``max_points`` (for a coverage picture).

    Returns
    -------
    list of [x_px, y_px], rounded to 0.1 px.
    """
    pts = np.concatenate([np.asarray(v.corners_px, dtype=np.float64).reshape(-1, 2) for v in views])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) > max_points:
        pts = pts[np.linspace(0, len(pts) - 1, max_points).astype(int)]
    rounded: list[list[float]] = pts.round(1).tolist()
    return rounded


def board_coverage(views: list, image_size: tuple[int, int]) -> dict:
    """The image region the board covered (convex hull of every corner) and its share of the image.

    The lens distortion is only known where the board has been: beyond it k1, k2 (and k3) are
    extrapolated, by a pixel or more at the edges of a wide lens (synthetic wide rig).
    """
    pts = np.concatenate([v.corners_px for v in views]).astype(np.float32)
    hull = cv2.convexHull(pts).reshape(-1, 2)
    return {"hull_px": hull.astype(float).round(1).tolist(),
            "area_fraction": float(cv2.contourArea(hull) / (image_size[0] * image_size[1]))}


def lens_coverage_of(calib_report: Mapping | None) -> dict | None:
    """Per camera the image region the rig's lens is known in: where the board went, or the board and a wand.

    A board calibration refined by a wand (issue 35) knows its lens where the wand's ends went too
    (``lens_coverage``); else the board's coverage (the board walk's, or a wand calibration's close-ups). None
    where the calibration says neither (a calibration file).
    """
    if not calib_report:
        return None
    return calib_report.get("lens_coverage") or calib_report.get("board_coverage") or None


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
    averaged).
    """
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


def still_views(views: list, step: int, max_motion_px: float = 0.5) -> list:
    """Views of a board held still.

    Views of a board held still: its corners moved less than ``max_motion_px`` since the view
    ``step`` frames before. A moving board is blurred, and the cameras' frames (whole frames apart
    after rounding the sync offsets) would show it at different places.
    """
    by_frame = {v.frame: v for v in views}
    still = []
    for v in views:
        prev = by_frame.get(v.frame - step)
        if prev is None or len(prev.ids) != len(v.ids) or np.any(prev.ids != v.ids):
            continue
        if float(np.max(np.linalg.norm(prev.corners_px - v.corners_px, axis=1))) < max_motion_px:
            still.append(v)
    return still if len(still) >= 6 else views

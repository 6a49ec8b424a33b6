"""Stages 3-4 of a ride: the markers found in every camera's clips and triangulated (thesis 4.5-4.6).

The plumb line and the standing horse are found with all cameras at once; the static shot's 3-D
layout then guides the search for the horse markers in the ride, and tells which static marker is
the saddle marker S. Detection and triangulation interleave, so each is timed apart.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any, cast

import numpy as np

from saddlescope.core.detection import (
    SequentialFrames,
    camera_down,
    find_markers_multiview,
    find_plumb_multiview,
    find_static_multiview,
    in_image,
    tilt_from_down_deg,
)
from saddlescope.core.detection.cover import drop_partly_covered
from saddlescope.core.detection.detectors import DetectionSettings, marker_detector
from saddlescope.core.errors import DetectionError, KinematicsError, TriangulationError
from saddlescope.core.findings import Finding
from saddlescope.core.params import PipelineParams
from saddlescope.core.pipeline.inputs import ClipReader, Progress, cameras_at_once
from saddlescope.core.pipeline.setup import lens_coverage_of, outside_coverage
from saddlescope.core.saddle import layout_mismatch_mm, match_horse_markers, static_positions
from saddlescope.core.sync import clip_frames_at
from saddlescope.core.triangulation import position_uncertainty, reach_by_camera, triangulate_tracks
from saddlescope.core.types import ImageTracks, MarkerTracks, Rig

__all__ = ["EarlyMotionTracks", "RideTracks", "depth_uncertainty", "detect_clip", "detect_motion", "detect_ride",
           "disagreement_flag", "per_camera", "still_start_positions"]


def detect_clip(clips: ClipReader, kind: str, n_markers: int, first_frame: Mapping[str, int],
                params: PipelineParams, *, spare_cameras: bool = False,
                start_xy: Mapping[str, np.ndarray] | None = None) -> tuple[dict[str, ImageTracks], list[Finding]]:
    """2-D marker tracks of every camera of one clip set (thesis 4.5), and flags.

    With ``spare_cameras`` (still scenes: the plumb line, the standing horse) a camera that does not
    see the markers is left out while two others do (a plumb line hung at the end of the arena may be
    outside one camera's view): its failure is a flag, not the end of the analysis.
    ``start_xy`` {camera: (n, 2)} gives the markers' positions on each camera's first frame (found
    with all cameras at once); a camera it leaves out is not used (with ``spare_cameras``).

    Returns
    -------
    tracks : dict of camera -> ImageTracks
        ``xy_px`` of shape (F, n_markers, 2) per camera, NaN where a marker was not found.
    flags : list of Finding
        One per camera left out.
    """
    settings = params.detection.get(kind, DetectionSettings())
    detector = marker_detector(params.marker_detector)
    missed: dict[str, DetectionError] = {}
    starts: dict[str, np.ndarray | None] = {}  # camera -> the markers on its first frame, where known
    for cam in clips.cameras(kind):
        if start_xy is not None and cam not in start_xy and spare_cameras:
            what = "the plumb line's markers" if kind == "plumb" else f"the {kind} clip's markers"
            missed[cam] = DetectionError(f"the {cam} camera's view does not hold the spots that the "
                                         f"other cameras see as {what}")
            continue
        starts[cam] = start_xy.get(cam) if start_xy is not None else None

    def track(cam: str) -> ImageTracks:
        return detector.track(clips.gray_frames(kind, cam, start=first_frame.get(cam, 0)), n_markers=n_markers,
                              camera=cam, clip=kind, options=settings.for_camera(cam), first_frame_xy=starts[cam])

    tracks = {}
    for cam, got in per_camera(list(starts), track, params.threads).items():
        if isinstance(got, DetectionError):
            if not spare_cameras:
                raise got
            missed[cam] = got
        else:
            tracks[cam] = got
    missed = {cam: missed[cam] for cam in clips.cameras(kind) if cam in missed}  # in the cameras' order
    if len(tracks) < 2 and missed:
        raise next(iter(missed.values()))
    flags = [Finding("tracking.two_cameras_only",
                     f"the {kind} clip was triangulated from the {' and '.join(tracks)} cameras only: {exc}")
             for exc in missed.values()]
    return tracks, flags


def per_camera(cams: list[str], work: Callable[[str], ImageTracks], threads: int | None
               ) -> dict[str, ImageTracks | DetectionError]:
    """``work(cam)`` for every camera, cameras in parallel within the thread budget.

    Decoding (PyAV) and the marker search (OpenCV, numpy) release the GIL for most of a frame. Each
    camera's tracks depend on its own clip alone, so the result does not depend on the threads'
    timing. Cameras at once: :func:`~saddlescope.core.pipeline.inputs.cameras_at_once` (all three
    cameras on a budget of two), each with one decoder and one frame in hand, so memory stays bounded
    by the budget. A camera whose markers
    are not found maps to its DetectionError; any other error is raised.
    """
    def guarded(cam: str) -> ImageTracks | DetectionError:
        try:
            return work(cam)
        except DetectionError as exc:
            return exc

    workers = cameras_at_once(len(cams), threads)
    if workers == 1:
        return {cam: guarded(cam) for cam in cams}
    with ThreadPoolExecutor(max_workers=workers) as pool:
        return dict(zip(cams, pool.map(guarded, cams), strict=True))


def still_start_positions(clips: ClipReader, rig: Rig, kind: str, first_frame: Mapping[str, int], n_markers: int
                          ) -> dict[str, np.ndarray] | None:
    """Each camera's markers on its first frame of a still clip, found with all cameras at once.

    Each camera's markers on its first frame of a still clip (``kind`` "plumb" or "static"), found
    with all cameras at once (:func:`find_plumb_multiview`, :func:`find_static_multiview`), or None
    (then each camera searches alone).

    Returns
    -------
    dict of camera -> ndarray of shape (n_markers, 2), or None
        Pixel positions on each camera's first frame after the flash.
    """
    if kind == "plumb" and n_markers != 2:
        return None
    frames = {}
    for cam in clips.cameras(kind):
        if cam in rig.cameras:
            start = first_frame.get(cam, 0)
            for _, gray in clips.gray_frames(kind, cam, start=start, stop=start + 1):
                frames[cam] = gray.copy()
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


def _plumb_lean_deg(plumb: MarkerTracks, rig: Rig) -> float:
    """Angle (degrees) between the plumb line's two markers and the cameras' image-down direction."""
    try:
        p = static_positions(plumb, "plumb")
    except KinematicsError:
        return 0.0  # no still positions: the kinematics stage says so
    if p.shape[0] < 2 or not np.all(np.isfinite(p[:2])):
        return 0.0
    return float(tilt_from_down_deg(rig, p[1] - p[0]))


def _down_direction(plumb: MarkerTracks | None, cameras_down: np.ndarray) -> np.ndarray:
    """Gravity in rig coordinates, shape (3,).

    Gravity in rig coordinates: from the plumb line where seen, else ``cameras_down`` (the cameras'
    mean image down, :func:`camera_down`).
    """
    if plumb is not None:
        try:
            p = static_positions(plumb, "plumb")
        except KinematicsError:
            p = None
        if p is not None and p.shape[0] >= 2:
            g = p[1] - p[0]
            g = g / np.linalg.norm(g)
            down: np.ndarray = g if g[1] > 0 else -g
            return down
    return cameras_down


def _track_motion(params: PipelineParams, frames: Iterable[tuple[int, np.ndarray]], camera: str, n_horse: int, *,
                  first_frame_xy: np.ndarray | None = None, moving: bool = False) -> ImageTracks:
    """One camera's horse markers through the motion clip, with the ride's detector and options."""
    return marker_detector(params.marker_detector).track(
        frames, n_markers=n_horse, camera=camera, clip="motion",
        options=params.detection.get("motion", DetectionSettings()).for_camera(camera),
        first_frame_xy=first_frame_xy, moving=moving)


class _Cancelled(Exception):
    """The analysis stopped (an earlier stage failed) while the motion clip was tracked ahead."""


def motion_tracks_alone(clips: ClipReader, first_frame: Mapping[str, int], params: PipelineParams, n_horse: int,
                        stop: threading.Event | None = None) -> dict[str, ImageTracks | DetectionError]:
    """Each camera's horse markers found by itself among what moves (no rig needed), per :func:`per_camera`.

    ``stop``, once set, ends the tracking at the next frame (raising a private exception).
    """
    def frames(cam: str) -> Iterator[tuple[int, np.ndarray]]:
        for item in clips.gray_frames("motion", cam, start=first_frame.get(cam, 0)):
            if stop is not None and stop.is_set():
                raise _Cancelled
            yield item

    return per_camera(clips.cameras("motion"), lambda c: _track_motion(params, frames(c), c, n_horse, moving=True),
                      params.threads)


class EarlyMotionTracks:
    """:func:`motion_tracks_alone` in a background thread, started while the calibration's solve runs.

    The solve (intrinsics, stereo pairs, bundle adjustment, metric checks) keeps about one core busy for
    seconds; the motion clip's per-camera tracking needs no rig, so it fills the other core meanwhile
    (default 1080p60 ride: it was a fifth of the analysis's wall time, issue 28). Its result is what
    :func:`detect_motion` would have computed, camera by camera from its own clip.
    """

    def __init__(self, clips: ClipReader, first_frame: Mapping[str, int], params: PipelineParams, n_horse: int):
        self._args = (clips, first_frame, params, n_horse)
        self._stop = threading.Event()
        self._pool: ThreadPoolExecutor | None = None
        self._future: Future[dict[str, ImageTracks | DetectionError]] | None = None

    def start(self) -> None:
        """Start tracking (once)."""
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="early-motion")
            self._future = self._pool.submit(motion_tracks_alone, *self._args, stop=self._stop)

    def result(self) -> dict[str, ImageTracks | DetectionError] | None:
        """The tracks (waiting for them); None if never started. Errors other than a missed marker are raised."""
        if self._pool is None or self._future is None:
            return None
        try:
            return self._future.result()
        finally:
            self._pool.shutdown(wait=True)

    def cancel(self) -> None:
        """Stop the tracking at its next frame and wait for its thread (the analysis failed before using it)."""
        if self._pool is not None:
            self._stop.set()
            self._pool.shutdown(wait=True)

    def __enter__(self) -> EarlyMotionTracks:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is not None:  # an error before detection took the tracks: stop tracking for nothing
            self.cancel()


def detect_motion(clips: ClipReader, rig: Rig, static_mm: np.ndarray, n_horse: int, offsets: Mapping[str, float],
                  first_frame: Mapping[str, int], params: PipelineParams, *, down: np.ndarray,
                  multiview: bool = False, clocks: Mapping[str, tuple[np.ndarray, float]] | None = None,
                  alone: Mapping[str, ImageTracks | DetectionError] | None = None,
                  ) -> tuple[dict[str, ImageTracks], list[int], int | None, bool]:
    """Track the horse markers through the motion clip of every camera.

    The horse may enter the view late and look-alikes abound, so the start is found with all cameras
    at once (:func:`saddlescope.core.detection.find_markers_multiview`): the first instant where
    the cameras agree on a triangle of the static shot's layout. That also tells which static marker
    is the saddle marker S (the one left out). Tracking then follows each camera from there.

    ``multiview`` skips the per-camera search (when what it found does not match the static shot).
    ``clocks`` (:func:`frame_clocks`) pairs the cameras' frames by their timestamps (phones).
    ``alone``: the per-camera search's result when it was run already (:class:`EarlyMotionTracks`).

    Parameters
    ----------
    static_mm : ndarray of shape (M, 3)
        The static shot's markers in rig coordinates (mm), the horse markers and S.
    down : ndarray of shape (3,)
        Gravity in rig coordinates (unit vector).

    Returns
    -------
    tuple
        (tracks per camera with ``xy_px`` of shape (F, n_horse, 2), static indices of horse markers
        1-3, static index of S, whether the all-cameras search found the start).
    """
    cams = clips.cameras("motion")
    # The saddle marker sits on the saddle above the horse markers: the static marker farthest
    # against gravity is S, the others are the horse markers in the static shot's order.
    height = -(static_mm @ down)
    order = [int(i) for i in np.argsort(height)]
    horse_idx = sorted(order[:n_horse])
    rest = [i for i in range(static_mm.shape[0]) if i not in horse_idx]
    if not multiview:
        try:
            # First choice: each camera finds the markers by itself among what moves (glints stand still).
            tracks = dict(alone) if alone is not None else motion_tracks_alone(clips, first_frame, params, n_horse)
            failed = [got for got in tracks.values() if isinstance(got, DetectionError)]
            if not failed:
                return cast(dict[str, ImageTracks], tracks), horse_idx, (rest[0] if rest else None), False
        except DetectionError:
            pass
    # Then all cameras together: the first instant where they agree on the static shot's triangle.
    frames = SequentialFrames(lambda cam, start: clips.gray_frames("motion", cam, start=start))
    first = max(int(first_frame.get(c, 0) - math.floor(offsets.get(c, 0.0))) for c in cams)
    last = min(int(clips.frame_count("motion", c) - math.ceil(offsets.get(c, 0.0))) - 1 for c in cams)
    fps = clips.fps("motion", cams[0])

    def stamped_position(cam: str, k: int) -> float:  # the camera's frame at reference frame k's instant
        assert clocks is not None  # used only with clocks (below)
        times, anchor = clocks[cam]
        return float(clip_frames_at(np.array([k + offsets.get(cam, 0.0)]), times, anchor, fps)[0])
    position = stamped_position if clocks else None
    _, found = find_markers_multiview(rig, frames, offsets, [static_mm[horse_idx]], first=max(first, 0), last=last,
                                      frame_position=position)
    tracks = per_camera(cams, lambda c: _track_motion(
        params, clips.gray_frames("motion", c, start=found["frames"][c]), c, n_horse, first_frame_xy=found["xy"][c]),
        params.threads)
    for got in tracks.values():
        if isinstance(got, DetectionError):
            raise got
    return cast(dict[str, ImageTracks], tracks), horse_idx, (rest[0] if rest else None), True


@dataclass
class RideTracks:
    """Every clip's triangulated markers and what their detection had to say.

    ``tracks3d`` maps clip kind ("plumb", "static", "motion") to its :class:`MarkerTracks`;
    ``motion2d`` holds each camera's image tracks of the ride; ``horse_idx`` the static shot's horse
    markers in the ride's label order and ``saddle_idx`` its saddle marker S; ``cameras_down`` (3,)
    the cameras' mean image-down direction in rig coordinates.
    """

    tracks3d: dict[str, MarkerTracks] = field(default_factory=dict)
    motion2d: dict[str, ImageTracks] = field(default_factory=dict)
    horse_idx: list[int] = field(default_factory=list)
    saddle_idx: int | None = None
    cameras_down: np.ndarray | None = None
    plumb_findings: list[Finding] = field(default_factory=list)  # why the plumb clip is not (fully) used
    flags: list[Finding] = field(default_factory=list)
    triangulation_s: float = 0.0


class _Triangulator:
    """Triangulates a clip's image tracks with the ride's rig, offsets and clocks, timing itself."""

    def __init__(self, clips: ClipReader, rig: Rig, offsets: Mapping, clocks: Mapping, params: PipelineParams,
                 lens_reach_px: Mapping[str, float] | None = None, readouts: Mapping | None = None):
        self.rig, self.offsets, self.clocks, self.params = rig, offsets, clocks, params
        # rolling shutters: per clip set, camera -> (readout in frames, image rows); only where one is not 0
        self.row_readout = {kind: {c: (r.readout_s * clips.fps(kind, c), clips.image_size(kind, c)[1])
                                   for c, r in per_cam.items() if r.readout_s > 0}
                            for kind, per_cam in (readouts or {}).items()}
        # issue 27 (wt-arena-rigs): beyond the board's reach the lens model is not extrapolated, and the
        # ride's track has no step where a camera enters or leaves
        nview = params.triangulation == "nview"
        self.extra: dict[str, Any] = {"lens_reach_px": dict(lens_reach_px)} if lens_reach_px and nview else {}
        self.motion_extra: dict[str, Any] = {"camera_set_bias": True} if nview else {}
        self.fps = {kind: clips.fps(kind, clips.cameras(kind)[0]) for kind in ("static", "motion", "plumb")
                    if clips.has(kind)}
        self.seconds = 0.0

    def __call__(self, kind: str, tracks2d: Mapping[str, ImageTracks], n: int) -> MarkerTracks:
        """The 3-D tracks of ``n`` markers of clip ``kind`` (names M1..Mn)."""
        started = time.perf_counter()
        out = triangulate_tracks(self.rig, tracks2d, self.offsets[kind], self.fps[kind],
                                 method=self.params.triangulation, names=tuple(f"M{i + 1}" for i in range(n)),
                                 match_labels=True, clocks=self.clocks.get(kind),
                                 row_readout=self.row_readout.get(kind) or None, **self.extra,
                                 **(self.motion_extra if kind == "motion" else {}))
        self.seconds += time.perf_counter() - started
        return out


def _detect_plumb(clips: ClipReader, rig: Rig, first_frame: Mapping, params: PipelineParams, n_plumb: int,
                  triangulate: _Triangulator, found: RideTracks) -> None:
    """The plumb line's markers (gravity), or why the plumb clip is not used."""
    if not clips.has("plumb"):
        found.plumb_findings = [Finding("plumb.missing", "no plumb clip")]
        return
    try:
        plumb2d, plumb_flags = detect_clip(clips, "plumb", n_plumb, first_frame["plumb"], params,
                                           spare_cameras=True,
                                           start_xy=still_start_positions(clips, rig, "plumb",
                                                                          first_frame["plumb"], n_plumb))
        found.tracks3d["plumb"] = triangulate("plumb", plumb2d, n_plumb)
        found.plumb_findings = list(plumb_flags)
        lean_deg = _plumb_lean_deg(found.tracks3d["plumb"], rig)
        if lean_deg > params.max_plumb_lean_deg:
            # A plumb line hangs along gravity and cameras stand roughly level: this is not one (a
            # marker taken at the string's end put gravity 62 degrees off on a thesis-rig ride).
            del found.tracks3d["plumb"]
            found.plumb_findings = [Finding(
                "plumb.leaning",
                f"plumb clip not used: the plumb line found leans {lean_deg:.0f} degrees from the cameras' vertical "
                f"(more than {params.max_plumb_lean_deg:.0f}): its markers were not found (check that every camera "
                "sees both plumb markers)", {"lean_deg": lean_deg, "limit_deg": params.max_plumb_lean_deg})]
    except (DetectionError, TriangulationError, KinematicsError) as exc:
        found.plumb_findings = [Finding("plumb.not_used", f"plumb clip not used: {exc}")]


def _detect_horse(clips: ClipReader, rig: Rig, offsets: Mapping, first_frame: Mapping, clocks: Mapping,
                  params: PipelineParams, n_horse: int, static_mm: np.ndarray, down: np.ndarray,
                  triangulate: _Triangulator, found: RideTracks,
                  alone: Mapping[str, ImageTracks | DetectionError] | None = None) -> None:
    """The horse markers through the ride, in every camera and in 3-D.

    The horse markers through the ride, searched again with all cameras when what each camera
    found does not keep the static shot's layout.
    """
    motion2d, horse_idx, saddle_idx, searched_together = detect_motion(
        clips, rig, static_mm, n_horse, offsets["motion"], first_frame["motion"], params, down=down,
        clocks=clocks.get("motion"), alone=alone)
    motion2d = _whole_discs(motion2d, found)
    found.tracks3d["motion"] = triangulate("motion", motion2d, n_horse)
    found_mm = layout_mismatch_mm(static_mm[horse_idx], found.tracks3d["motion"].xyz_mm)
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
                again2d = _whole_discs(again2d, RideTracks())
                again = triangulate("motion", again2d, n_horse)
                again_mm = layout_mismatch_mm(static_mm[again_h], again.xyz_mm)
            except (DetectionError, TriangulationError):
                pass
        if again_mm < found_mm:
            found.flags.append(Finding(
                "tracking.lookalike_recovered",
                f"the moving spots each camera found were {found_mm:.0f} mm RMS off the static shot's marker "
                f"distances (a look-alike moving with the horse); the markers were found again with all cameras "
                f"and the static layout ({again_mm:.0f} mm)", {"mismatch_mm": found_mm, "mismatch_again_mm": again_mm}))
            motion2d, horse_idx, saddle_idx, found.tracks3d["motion"] = again2d, again_h, again_s, again
        else:
            found.flags.append(Finding(
                "tracking.lookalike",
                f"the tracked markers are {found_mm:.0f} mm RMS off the static shot's marker distances and no "
                "closer triangle was found: a look-alike may have been tracked, or a marker moved between the "
                "static shot and the ride (check both clips)", {"mismatch_mm": found_mm}))
    found.motion2d = motion2d
    found.horse_idx = match_horse_markers(static_mm, horse_idx, found.tracks3d["motion"].xyz_mm)
    found.saddle_idx = saddle_idx


def _whole_discs(motion2d: Mapping[str, ImageTracks], found: RideTracks) -> dict[str, ImageTracks]:
    """The motion tracks without the samples of partly covered discs (issue 38); a finding says how many.

    A disc half behind a boot, a tail or a lunge line has its centroid pulled off the marker: the sample
    is dropped (a gap the fits do not see), not kept nor bridged through.
    """
    out, dropped = {}, {}
    for cam, tracks in motion2d.items():
        out[cam], n = drop_partly_covered(tracks)
        if n:
            dropped[cam] = n
    if dropped:
        total = sum(dropped.values())
        per_cam = ", ".join(f"{n} in the {cam} camera" for cam, n in dropped.items())
        found.flags.append(Finding(
            "tracking.partly_covered",
            f"{total} marker sample{'s' if total != 1 else ''} of a partly covered disc (its area fell, or it was "
            f"about to vanish or had just reappeared) left out: {per_cam}",
            {"samples": total, **{f"samples_{cam}": n for cam, n in dropped.items()}}))
    return out


def _coverage_flags(motion2d: Mapping[str, ImageTracks], calib_report: Mapping) -> list[Finding]:
    """A finding per camera that saw the markers outside the region the calibration board (and wand) covered."""
    flags = []
    coverage = lens_coverage_of(calib_report)
    what, fix = (("calibration board and the wand", "walk the wand along the whole track, up to the edges of every "
                  "camera's view") if calib_report.get("lens_coverage") else
                 ("calibration board", "move the board to the edges of every camera's view"))
    if coverage:
        for cam, share in outside_coverage(motion2d, coverage).items():
            if share > 0.05:
                flags.append(Finding("calibration.coverage",
                                     f"the {cam} camera saw the markers outside the region the {what} "
                                     f"covered in {100 * share:.0f} % of its detections: its lens distortion is "
                                     f"extrapolated there ({fix})",
                                     {"outside_share_pct": 100 * share}))
    return flags


def detect_ride(clips: ClipReader, rig: Rig, offsets: Mapping, first_frame: Mapping, clocks: Mapping,
                params: PipelineParams, calib_report: Mapping, progress: Progress, *,
                n_horse: int, n_saddle: int, n_plumb: int,
                early_motion: EarlyMotionTracks | None = None, readouts: Mapping | None = None) -> RideTracks:
    """Stages 3-4: the plumb line, the standing horse and the ride's markers, in 3-D.

    ``offsets``, ``first_frame`` and ``clocks`` are :func:`~saddlescope.core.pipeline.setup.synchronise`'s
    and :func:`~saddlescope.core.pipeline.setup.frame_clocks`' per clip kind; ``calib_report`` the
    calibration's report (its board coverage flags markers seen where the lens is extrapolated);
    ``early_motion`` the motion clip's per-camera tracks started during the calibration, if they were;
    ``readouts`` per clip kind and camera the rolling shutters' readouts
    (:func:`~saddlescope.core.pipeline.setup.clip_readouts`): each observation is placed at its row's instant.
    """
    found = RideTracks()
    triangulate = _Triangulator(clips, rig, offsets, clocks, params,
                                lens_reach_px=reach_by_camera(rig, lens_coverage_of(calib_report)),
                                readouts=readouts)
    _detect_plumb(clips, rig, first_frame, params, n_plumb, triangulate, found)
    progress.stage("detection", 0.2)
    static2d, static_flags = detect_clip(clips, "static", n_horse + n_saddle, first_frame["static"], params,
                                         spare_cameras=True,
                                         start_xy=still_start_positions(clips, rig, "static", first_frame["static"],
                                                                        n_horse + n_saddle))
    found.flags.extend(static_flags)
    found.tracks3d["static"] = triangulate("static", static2d, n_horse + n_saddle)
    progress.stage("detection", 0.4)
    static_mm = static_positions(found.tracks3d["static"], "static")
    found.cameras_down = camera_down(rig)
    down = _down_direction(found.tracks3d.get("plumb"), found.cameras_down)
    alone = early_motion.result() if early_motion is not None else None
    _detect_horse(clips, rig, offsets, first_frame, clocks, params, n_horse, static_mm, down, triangulate, found,
                  alone=alone)
    found.flags.extend(_coverage_flags(found.motion2d, calib_report))
    found.triangulation_s = triangulate.seconds
    return found


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


def disagreement_flag(kind: str, tracks: MarkerTracks, *, share: float = 0.05) -> Finding | None:
    """A finding when the cameras disagree on a clip's markers, else None.

    A flag when over ``share`` of a clip's triangulated samples reproject worse than 2 px and 8 times
    the clip's median: the cameras saw different things there (one followed a look-alike, or the
    synchronisation or calibration is off) and nothing could tell which camera was wrong.
    """
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
    return Finding("tracking.cameras_disagree",
                   f"the cameras disagree on the {kind} clip's markers by more than {limit:.1f} px in "
                   f"{100 * bad:.0f} % of the triangulated samples (median {median:.2f} px): a camera may have "
                   "followed a look-alike there, or the synchronisation or calibration is off (check the cameras' "
                   "tracks)", {"limit_px": limit, "share_pct": 100 * bad, "median_px": median})

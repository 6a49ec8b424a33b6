"""The whole analysis of a ride: clips in, a :class:`~saddlescope.core.types.RideResult` out.

Stages (thesis stages 1-12): sync -> calibration -> detection -> triangulation -> kinematics ->
indicators; each is a module of this package or of ``saddlescope.core``, and this one only runs them.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import nullcontext

import cv2

from saddlescope.core.calibration.boards import board_from_meta
from saddlescope.core.errors import CamerasMovedError, InputError, KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.params import PipelineParams
from saddlescope.core.pipeline.consistency import cameras_moved_finding
from saddlescope.core.pipeline.detection import (
    EarlyMotionTracks,
    RideTracks,
    depth_uncertainty,
    detect_ride,
    disagreement_flag,
)
from saddlescope.core.pipeline.inputs import ClipReader, Progress, calibration_spec
from saddlescope.core.pipeline.passes import PassAnalysis, analyse_passes, find_passes, pool_passes
from saddlescope.core.pipeline.result import assemble_result, with_intervals
from saddlescope.core.pipeline.setup import (
    calibrate_from_clips,
    frame_clocks,
    motion_sync,
    sync_flag,
    sync_quality,
    synchronise_clips,
)
from saddlescope.core.pipeline.wand_setup import calibrate_from_wand_clips, refine_from_wand_clips
from saddlescope.core.saddle import kinematics_indicators, saddle_kinematics
from saddlescope.core.types import RideResult, Rig

__all__ = ["analyze_ride"]


def _clip_kinds(clips: ClipReader, rig: Rig | None, meta: Mapping) -> list[str]:
    """The clip sets to synchronise, after checking the ride has what the analysis needs.

    The calibration's clip sets (ride.json ``calibration.method``: the board walk's ``calibration``, a wand
    calibration's ``wand``, or both for the board walk refined by a wand) are synchronised unless a rig is
    given; a wand calibration's ``close_up`` clips are each camera's alone.
    """
    for kind in ("static", "motion"):
        if not clips.has(kind):
            raise InputError(f"the ride has no {kind} clip; it is required")
    spec = calibration_spec(meta)
    if rig is None:
        missing = [k for k in spec.clip_kinds if not clips.has(k)]
        if missing == ["calibration"] and spec.method == "board":
            raise InputError("the ride has no calibration clip and no calibration was given")
        if missing:
            raise InputError(f"the ride's {spec.method} calibration has no {' and no '.join(missing)} clips, and "
                             "no calibration was given")
        if spec.method == "wand" and not clips.has("close_up"):
            raise InputError("the ride's wand calibration has no close-up clips: each camera's lens comes from the "
                             "board filmed close to it")
    cal_kinds = spec.clip_kinds if rig is None else ()
    return [k for k in (*cal_kinds, "plumb", "static", "motion") if clips.has(k)]


def _motion_clip_sync(clips: ClipReader, rig: Rig, n_horse: int, params: PipelineParams, clocks: Mapping,
                      progress: Progress, readouts: Mapping | None = None):
    """The motion clip's offsets from the markers' own motion (no flash), timed as ``sync_motion``."""
    t0 = time.perf_counter()
    found = motion_sync(clips, rig, "motion", n_horse, params, clocks=clocks.get("motion"),
                        readouts=(readouts or {}).get("motion"))
    progress.timings_s["sync_motion"] = round(time.perf_counter() - t0, 4)
    return found


def _early_motion(clips: ClipReader, rig: Rig | None, methods: Mapping, first_frame: Mapping, params: PipelineParams,
                  n_horse: int) -> EarlyMotionTracks | None:
    """The motion clip's markers, tracked ahead while the calibration's solve keeps one core busy; None where not.

    Camera by camera needs no rig; the clip starts where the flash (or given offsets) placed it.
    """
    if rig is not None or methods.get("motion") not in ("flash", "offsets") or (params.threads or 2) <= 1:
        return None
    return EarlyMotionTracks(clips, first_frame["motion"], params, n_horse)


def _wand_synchronised(methods: Mapping) -> None:
    """Refuse wand clips without the flash (or given offsets): their ends are paired at the same instants."""
    if methods.get("wand") not in ("flash", "offsets"):
        reason = methods.get("reasons", {}).get("wand", "")
        raise InputError("the wand clips need the sync flash (or sync offsets in ride.json): the wand's ends "
                         "must be paired at the same instants in every camera" + (f" ({reason})" if reason else ""))


def _calibrate(clips: ClipReader, meta: Mapping, offsets: Mapping, first_frame: Mapping, methods: Mapping,
               clocks: Mapping, params: PipelineParams, progress: Progress,
               early: EarlyMotionTracks | None) -> tuple[Rig, dict, dict]:
    """The rig from the calibration clips, its report, and the clip's sync where the board gave it.

    The sync comes as ``{"calibration": MotionSync}`` (else empty); ``early`` starts once the views are found.
    ride.json's ``calibration.method`` chooses the way: ``wand`` calibrates from its wand and close-up clips,
    ``board+wand`` refines the board walk's rig by the wand clips where that helps (issue 35).
    """
    spec = calibration_spec(meta)
    board = board_from_meta(meta.get("board"))
    if spec.method == "wand" and spec.wand_length_mm is not None:
        _wand_synchronised(methods)
        rig, report = calibrate_from_wand_clips(clips, board, spec.wand_length_mm, offsets["wand"],
                                                first_frame["wand"], params, progress)
        if early is not None:
            early.start()
        return rig, report, {}
    if spec.method == "board+wand":
        _wand_synchronised(methods)  # before the board's solve: a missing flash is said at once
    rig, report = calibrate_from_clips(clips, board, offsets["calibration"],
                                       first_frame["calibration"], params, progress, clocks=clocks.get("calibration"),
                                       sync_from_board=methods.get("calibration") == "motion",
                                       on_views_found=early.start if early is not None else None)
    synced = {"calibration": report.pop("sync")} if "sync" in report else {}
    if spec.method == "board+wand" and spec.wand_length_mm is not None:
        rig, report = refine_from_wand_clips(clips, rig, report, board, spec.wand_length_mm, offsets["wand"],
                                             first_frame["wand"], params)
    report.pop("board_views", None)  # the solve's views: not part of the result
    return rig, report, synced


def _within_thread_budget(params: PipelineParams) -> PipelineParams:
    """Keep OpenCV's own pool (process-wide) within the worker's thread budget, where one is given."""
    if params.threads is not None:
        cv2.setNumThreads(params.threads)
    return params


def _kinematics(found: RideTracks, rig: Rig, params: PipelineParams, meta: Mapping):
    """The saddle's kinematics, and the cameras-moved finding (a list of 0 or 1).

    A rig calibrated before the ride may no longer fit it: a kinematics failure is then said as that cause.
    """
    moved = cameras_moved_finding(rig, found.tracks3d["motion"])
    try:
        kin = saddle_kinematics(found.tracks3d["motion"], found.tracks3d["static"], found.tracks3d.get("plumb"), params,
                                horse_idx=found.horse_idx, saddle_idx=found.saddle_idx, gait=meta.get("gait"),
                                depth=depth_uncertainty(rig, found.tracks3d["motion"]), down_hint=found.cameras_down)
    except KinematicsError as exc:
        if moved is None:
            raise
        raise CamerasMovedError(f"{moved.detail}; the ride's motion cannot be measured ({exc})") from exc
    return kin, [moved] if moved is not None else []


def _pass_analyses(found: RideTracks, rig: Rig, params: PipelineParams, meta: Mapping) -> list[PassAnalysis] | None:
    """Each pass of a ride whose motion clip holds several (issue 38); None for one pass.

    None too when no pass can be analysed: the clip is then analysed as a whole, as a one-pass ride always
    is (its numbers unchanged). One pass analysed of several is the ride's result alone (the others left out
    with their reasons): the whole clip would span the gaps between the passes, where the horse is out of view.
    """
    motion = found.tracks3d["motion"]
    spans = find_passes(motion.t_s, motion.xyz_mm)
    if len(spans) < 2:
        return None
    depth = depth_uncertainty(rig, motion)

    def analyse(tracks):
        return saddle_kinematics(tracks, found.tracks3d["static"], found.tracks3d.get("plumb"), params,
                                 horse_idx=found.horse_idx, saddle_idx=found.saddle_idx, gait=meta.get("gait"),
                                 depth=depth, down_hint=found.cameras_down)

    analyses = analyse_passes(motion, spans, analyse, params)
    return analyses if any(a.kin is not None for a in analyses) else None


def _pooled_result(analyses: list[PassAnalysis], found: RideTracks, rig: Rig, flags: list[Finding],
                   assemble: Callable[..., RideResult], params: PipelineParams) -> RideResult:
    """The result of a ride of several passes: each used pass assembled with its own findings, then pooled."""
    results = [assemble(a.kin, a.harm, a.indicators, flags + list(a.kin.flags)) for a in analyses if a.kin is not None]
    return pool_passes(analyses, results, found.tracks3d["motion"].t_s, params, with_intervals)


def _saddle_result(found: RideTracks, rig: Rig, params: PipelineParams, meta: Mapping,
                   flags: tuple[list[Finding], list[Finding]], assemble: Callable[..., RideResult], progress: Progress,
                   started: tuple[float, float]) -> RideResult:
    """The kinematics and indicators stages, and the result: of the one pass, or of several pooled.

    ``flags`` are the stages' findings before and after the cameras-moved one; ``started`` the kinematics
    stage's and the analysis's start (perf_counter s).
    """
    (before, after), (t0, t_start) = flags, started
    passes = _pass_analyses(found, rig, params, meta)
    if passes is not None:  # several passes: each analysed, their strides pooled
        moved_flag = cameras_moved_finding(rig, found.tracks3d["motion"])
        progress.finish("kinematics", t0)
        progress.timings_s["total"] = round(time.perf_counter() - t_start, 4)
        return _pooled_result(passes, found, rig, before + ([moved_flag] if moved_flag else []) + after, assemble,
                              params)
    kin, moved = _kinematics(found, rig, params, meta)
    progress.finish("kinematics", t0)
    t0 = time.perf_counter()
    harm, indicators = kinematics_indicators(kin, params)
    progress.finish("indicators", t0)
    progress.timings_s["total"] = round(time.perf_counter() - t_start, 4)
    return assemble(kin, harm, indicators, before + moved + after + list(kin.flags))


def analyze_ride(clips: ClipReader, meta: Mapping, *, params: PipelineParams | None = None,
                 rig: Rig | None = None, on_progress: Callable[[float, str], None] | None = None,
                 input_flags: Sequence[Finding] = (), rig_report: Mapping | None = None) -> RideResult:
    """Run every stage on one ride.

    Parameters
    ----------
    clips : ClipReader
        The ride's clips: calibration (unless ``rig`` is given), static, motion, optional plumb.
    meta : mapping
        ride.json (board, sync, markers, gait, direction, ...).
    params : PipelineParams, optional
        The user's choices (defaults: the thesis's, where it was right).
    rig : Rig, optional
        A calibration to reuse (e.g. the rig's, computed once for every ride of that day); ``rig_report``
        its ``n_views`` and ``board_coverage`` (and ``lens_coverage`` where a wand refined it), so that the lens
        limit and board-region checks still apply.
    on_progress : callable(fraction, stage), optional
        Called as each stage advances, ``fraction`` of the whole analysis in [0, 1].
    input_flags : sequence of Finding, optional
        What reading the input found (e.g. the bundle's), put first among the result's findings.

    Returns
    -------
    RideResult
        ``saddlescope.io.result_document.result_to_document`` writes it as CONTRACTS section 2.
    """
    params = _within_thread_budget(params or PipelineParams())
    progress = Progress(on_progress)
    t_start = time.perf_counter()
    kinds = _clip_kinds(clips, rig, meta)
    markers = dict(meta.get("markers") or {})

    t0 = time.perf_counter()
    progress.stage("sync", 0.0)
    offsets, first_frame, methods = synchronise_clips(clips, meta, kinds, threads=params.threads)
    clocks, clock_flags = frame_clocks(clips, kinds)
    progress.finish("sync", t0)

    t0 = time.perf_counter()
    calib_report: dict = dict(rig_report or {}) if rig is not None else {}
    synced: dict = {}  # clip kind -> MotionSync, for the clip sets synchronised from motion
    n_horse = int(markers.get("horse", 3))
    early = _early_motion(clips, rig, methods, first_frame, params, n_horse)
    with early if early is not None else nullcontext():  # cancelled if a stage fails before detection
        if rig is None:
            rig, calib_report, synced = _calibrate(clips, meta, offsets, first_frame, methods, clocks, params,
                                                   progress, early)
        progress.finish("calibration", t0)
        if methods.get("motion") == "motion":  # no flash: the markers' motion, with the rig just calibrated
            synced["motion"] = _motion_clip_sync(clips, rig, n_horse, params, clocks, progress,
                                                 methods.get("readouts"))
        for kind, found_sync in synced.items():
            offsets[kind] = dict(found_sync.offsets)
            clock_flags.append(sync_flag(kind, found_sync))
        t0 = time.perf_counter()
        found = detect_ride(clips, rig, offsets, first_frame, clocks, params, calib_report, progress, n_horse=n_horse,
                            n_saddle=int(markers.get("saddle", 1)), n_plumb=int(markers.get("plumb", 2)),
                            early_motion=early, readouts=methods.get("readouts"))
    progress.finish("detection", t0, seconds=time.perf_counter() - t0 - found.triangulation_s)
    progress.finish("triangulation", t0, seconds=found.triangulation_s)

    t0 = time.perf_counter()
    disagreements = [f for kind, tr in found.tracks3d.items() if (f := disagreement_flag(kind, tr))]
    fps = float(clips.fps("motion", clips.cameras("motion")[0]))

    def assemble(kin, harm, indicators, flags):
        return assemble_result(meta, rig, calib_report, offsets, found, kin, harm, indicators, fps, progress.timings_s,
                               params, flags, input_flags)

    result = _saddle_result(found, rig, params, meta, (clock_flags + found.flags, disagreements + found.plumb_findings),
                            assemble, progress, (t0, t_start))
    result.quality["sync"] = sync_quality(kinds, methods, synced)
    return result

"""`saddlescope bench`: performance measured as ratios taken side by side in one run.

This machine is shared and noisy, so every speed claim is a ratio of two things timed alternately
in the same run (best of a few repeats), or an absolute time with the load average next to it.
"""

from __future__ import annotations

import os
import resource
import shutil
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TypedDict

import numpy as np


class RideLength(TypedDict, total=False):
    """How long a benchmark's synthetic ride is (`write_ride_bundle`'s own lengths where absent)."""

    duration_s: float
    calibration_poses: int


class _SpeedRide(RideLength, total=False):
    rig: str


def quick_ride(quick: bool) -> RideLength:
    """A short ride (3 s, 40 board poses) for a quick run, else the writer's default length."""
    return {"duration_s": 3.0, "calibration_poses": 40} if quick else {}


def _best_of(fn: Callable[[], object], repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return float(best)


def _alternate(fns: dict[str, Callable[[], object]], repeats: int) -> dict[str, float]:
    """Best wall time of each function, run in alternation so load changes hit all alike."""
    best = {k: np.inf for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            best[k] = min(best[k], time.perf_counter() - t0)
    return {k: float(v) for k, v in best.items()}


def _motion_clip(tmp: Path, rig: str, duration_s: float) -> tuple[Path, int, int]:
    """Encode one camera's motion clip of a synthetic ride.

    Returns (path, first frame after the flash, number of frames).
    """
    from saddlescope.arena import build_scene, render_clip_frames
    from saddlescope.io.video_writer import write_h264

    scene = build_scene(gait="canter", seed=3, rig=rig, duration_s=duration_s, calibration_poses=8,
                        extras=False)
    path = tmp / f"motion_{rig}.mp4"
    n = write_h264(path, render_clip_frames(scene, "left", "motion"), fps=scene.fps)
    from saddlescope.core.sync import flash_interval
    from saddlescope.io.video import frame_brightness

    _, end = flash_interval(frame_brightness(path), clip="motion", camera="left")
    return path, int(np.ceil(end)) + 1, n


def detection_vs_decode(rig: str, *, duration_s: float, repeats: int, tmp: Path) -> dict:
    """Marker-detection throughput / decode-only throughput on the same clip (both decode it)."""
    from saddlescope.core.detection import track_markers
    from saddlescope.io.video import iter_gray_frames

    path, start, n = _motion_clip(tmp, rig, duration_s)

    def decode_only():
        for _ in iter_gray_frames(path, start=start):
            pass

    def detect():
        track_markers(iter_gray_frames(path, start=start), n_markers=3, camera="left", clip="motion")

    # CPU seconds of the process (the decoder's threads included) beside the wall time: on a loaded
    # machine the wall-time ratio swings with the neighbours, the CPU ratio much less.
    cpu_s = {"decode": np.inf, "detect": np.inf}

    def cpu_timed(key: str, fn: Callable[[], object]) -> Callable[[], None]:
        def run() -> None:
            c0 = time.process_time()
            fn()
            cpu_s[key] = min(cpu_s[key], time.process_time() - c0)
        return run

    t = _alternate({"decode": cpu_timed("decode", decode_only), "detect": cpu_timed("detect", detect)}, repeats)
    frames = n - start
    return {"ratio": t["decode"] / t["detect"], "decode_fps": frames / t["decode"],
            "detect_fps": frames / t["detect"], "frames": frames,
            "ratio_cpu": cpu_s["decode"] / cpu_s["detect"]}


def calibration_3cams(repeats: int) -> dict:
    """Three cameras from 90 board poses each (thesis-like rig and board), intrinsics + pairs + BA."""
    from saddlescope.core.calibration import calibrate_rig, thesis_like_views

    _, board, views, sizes = thesis_like_views(90, rng=np.random.default_rng(0))
    t = _best_of(lambda: calibrate_rig(views, board, sizes), repeats)
    return {"seconds": t, "board": list(board.inner_corners), "poses": 90}


def analysis_vs_footage(tmp: Path, *, quick: bool) -> dict:
    """Wall time of the whole analysis of a default thesis-rig ride / duration of its footage."""
    from saddlescope.io.synth_writer import write_ride_bundle
    from saddlescope.io.video import probe_video
    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    ride = tmp / "speed_640x480"  # the ride speed_rides analysed, when it ran first (same arguments)
    t0 = time.perf_counter()
    kwargs = quick_ride(quick)
    if not (ride / "ride.json").exists():
        write_ride_bundle(ride, gait="canter", seed=1, rig="thesis", extras=False, **kwargs)
    synth_s = time.perf_counter() - t0
    per_set: dict[str, float] = {}
    all_clips = 0.0
    for kind in ("calibration", "plumb", "static", "motion"):
        durations = [probe_video(ride / kind / f"{cam}.mp4").duration_s for cam in ("left", "middle", "right")]
        per_set[kind] = max(durations)
        all_clips += sum(durations)
    t0 = time.perf_counter()
    result = analyze_bundle(ride)
    wall = time.perf_counter() - t0
    footage = sum(per_set.values())
    return {"ratio": wall / footage, "ratio_vs_all_camera_clips": wall / all_clips, "analysis_s": wall,
            "footage_s": footage, "all_camera_clips_s": all_clips, "synth_s": synth_s,
            "stage_timings_s": result.get("timings_s", {})}


RIDE_KINDS = ("calibration", "plumb", "static", "motion")


def decode_once(ride: Path, kinds=RIDE_KINDS, *, threads: int = 1) -> dict:
    """Decode every frame of every clip of a ride once with PyAV: one thread, no conversion (the limit).

    Returns ``seconds`` (wall), ``frames`` and ``clip_s`` (the clips' summed duration). ``threads`` > 1:
    FFmpeg's frame and slice threads, to see what threaded decoding buys.
    """
    import av

    frames = 0
    clip_s = 0.0
    t0 = time.perf_counter()
    for clip in sorted(p for kind in kinds for p in (ride / kind).glob("*.mp4")):
        with av.open(str(clip)) as container:
            stream = container.streams.video[0]
            stream.thread_type = "AUTO"
            stream.thread_count = threads
            n = sum(1 for _ in container.decode(stream))
            frames += n
            if stream.average_rate is None:
                raise ValueError(f"{clip}: the video stream states no frame rate")
            clip_s += n / float(stream.average_rate)
    return {"seconds": time.perf_counter() - t0, "frames": frames, "clip_s": clip_s}


def _cpu_s() -> float:
    """CPU seconds of this process and its threads so far (user + system)."""
    use = resource.getrusage(resource.RUSAGE_SELF)
    return use.ru_utime + use.ru_stime


def analysis_vs_decode(ride: Path, *, shared_by: int = 10) -> dict:
    """The whole analysis of ``ride`` against decoding its clips once, side by side, and its CPU cost.

    ``ratio``: analysis wall time / decode_once_s; ``ratio_cpu``: the analysis's CPU seconds (all its
    threads) / the single-threaded decode's; ``stage_vs_decode``: each stage's time
    (``timings_s``) as a multiple of decode_once_s; ``vs_clip_duration``: analysis wall time / the
    summed duration of every clip analysed. ``rides_per_core_hour``: 3600 / (cpu(calibration) /
    ``shared_by`` + cpu(the ride with that calibration given)), CPU seconds from getrusage.
    """
    from saddlescope.io.rig_document import rig_from_dict
    from saddlescope.services.analysis.ride_bundle import analyze_bundle
    from saddlescope.settings import get_settings

    c0 = _cpu_s()
    decode = decode_once(ride)
    decode_cpu = [_cpu_s() - c0]
    c0, t0 = _cpu_s(), time.perf_counter()
    result = analyze_bundle(ride)
    wall, cpu_whole = time.perf_counter() - t0, _cpu_s() - c0
    c0 = _cpu_s()
    decode_again = decode_once(ride)  # the limit on both sides of the analysis: load drifts hit both
    decode_cpu.append(_cpu_s() - c0)
    decode_s = min(decode["seconds"], decode_again["seconds"])
    budget = get_settings().resolved_worker_threads
    threaded_s = decode_once(ride, threads=budget)["seconds"] if budget > 1 else decode_s
    c0 = _cpu_s()
    analyze_bundle(ride, rig=rig_from_dict(result["calibration"]))
    cpu_ride = _cpu_s() - c0
    cpu_calibration = max(0.0, cpu_whole - cpu_ride)
    timings = dict(result.get("timings_s", {}))
    # CPU seconds beside the wall times: on a loaded machine the wall times swing with the neighbours (a
    # process waiting for a core counts), CPU seconds much less; the analysis's threads are all counted
    return {"ratio": wall / decode_s, "ratio_cpu": cpu_whole / min(decode_cpu), "analysis_s": wall,
            "decode_once_s": decode_s, "decode_once_cpu_s": min(decode_cpu),
            "decode_once_s_runs": [decode["seconds"], decode_again["seconds"]], "frames": decode["frames"],
            "decode_threads": budget, "decode_threaded_s": threaded_s, "decode_thread_speedup": decode_s / threaded_s,
            "clip_duration_s": decode["clip_s"], "vs_clip_duration": wall / decode["clip_s"],
            "timings_s": timings, "stage_vs_decode": {k: v / decode_s for k, v in timings.items()},
            "cpu_s": cpu_whole, "cpu_ride_without_calibration_s": cpu_ride, "cpu_calibration_s": cpu_calibration,
            "rides_per_core_hour": 3600.0 / (cpu_calibration / shared_by + cpu_ride),
            "calibration_shared_by": shared_by}


_RSS_CHILD = """
import resource, sys
from saddlescope.services.analysis.ride_bundle import analyze_bundle
analyze_bundle(sys.argv[1])
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def peak_rss_analysis(ride: Path) -> dict:
    """Peak resident memory (MB) of the whole analysis of ``ride`` in a child process (getrusage)."""
    import subprocess
    import sys

    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", _RSS_CHILD, str(ride)], capture_output=True, text=True,
                         check=False, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        tail = (out.stderr.strip().splitlines() or ["no output"])[-1]
        return {"error": f"the analysis failed (exit {out.returncode}): {tail}"}
    # the child's own peak (KB on Linux); RUSAGE_CHILDREN is the largest child's so far
    peak_kb = max(int(out.stdout.strip().splitlines()[-1]), 0)
    return {"peak_rss_mb": peak_kb / 1024.0, "children_peak_rss_mb": max(before, resource.getrusage(
        resource.RUSAGE_CHILDREN).ru_maxrss) / 1024.0, "analysis_s": wall}


BUSY_LOOPS_PER_CPU = 3  # two cores and six busy loops: a load of 6-7, where issue 39 saw 2.1-2.8 GB


@contextmanager
def busy_loops(count: int) -> Iterator[list[int]]:
    """``count`` processes spinning on a CPU each (at the default priority) while the block runs; their ids."""
    import subprocess
    import sys

    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(count)]
    try:
        yield [p.pid for p in procs]
    finally:
        for p in procs:
            p.kill()
        for p in procs:
            p.wait()


def _with_load_avg(measure: Callable[[], dict]) -> dict:
    start = list(os.getloadavg())
    out = measure()
    return {**out, "load_avg_start": start, "load_avg_end": list(os.getloadavg())}


def peak_rss_loaded_vs_quiet(ride: Path, *, busy: int | None = None) -> dict:
    """Peak memory of the analysis of ``ride`` as the host is, and beside it with ``busy`` busy-loop processes.

    Issue 39: the peak must not grow with the host's load (frames held while their consumers wait for a
    CPU). ``busy`` defaults to :data:`BUSY_LOOPS_PER_CPU` per CPU of the worker's budget. Each measurement
    carries the load average at its start and end (the machine may be loaded by other work as well).
    """
    from saddlescope.io.threads import default_worker_threads

    busy = BUSY_LOOPS_PER_CPU * default_worker_threads() if busy is None else busy
    quiet = _with_load_avg(lambda: peak_rss_analysis(ride))
    with busy_loops(busy):
        time.sleep(1.0)  # the loops running before the analysis starts
        loaded = _with_load_avg(lambda: peak_rss_analysis(ride))
    ratio = None
    if "peak_rss_mb" in quiet and "peak_rss_mb" in loaded:
        ratio = loaded["peak_rss_mb"] / quiet["peak_rss_mb"]
    return {**quiet, "loaded": {**loaded, "busy_loops": busy}, "loaded_vs_quiet": ratio}


def speed_rides(tmp: Path, *, quick: bool) -> dict:
    """Issue 28's speed keys.

    Analysis against decoding once at 640x480 and 1920x1080@60, whole analysis against the clips' duration,
    rides per core-hour and the peak memory of a 2160p@30 ride.
    """
    from saddlescope.io.synth_writer import write_ride_bundle

    out: dict = {}
    wide: RideLength = {"duration_s": 2.5, "calibration_poses": 30} if quick else {}
    rides: dict[str, _SpeedRide] = {"640x480": {"rig": "thesis", **quick_ride(quick)},  # as analysis_vs_footage's
                                    "1920x1080": {"rig": "wide", **wide}}
    for name, kwargs in rides.items():
        ride = tmp / f"speed_{name}"
        try:
            write_ride_bundle(ride, gait="canter", seed=1, extras=False, **kwargs)
            out[name] = analysis_vs_decode(ride)
        except Exception as exc:  # noqa: BLE001 - a benchmark reports every failure and goes on
            out[name] = {"error": f"{type(exc).__name__}: {exc}"}
        out[name]["ride"] = {k: v for k, v in kwargs.items()}
    if not quick:
        ride = tmp / "speed_3840x2160"
        try:
            # short (2 s of ride, 24 board poses): rendering 4K is what takes long here, and the peak
            # is set by the frames decoded at once, not by the clips' length
            write_ride_bundle(ride, gait="canter", seed=1, extras=False, rig="wide", size=(3840, 2160), fps=30.0,
                              duration_s=2.0, calibration_poses=24)
            out["3840x2160"] = peak_rss_loaded_vs_quiet(ride)
        except Exception as exc:  # noqa: BLE001
            out["3840x2160"] = {"error": f"{type(exc).__name__}: {exc}"}
        shutil.rmtree(ride, ignore_errors=True)
    return out


def speed_keys(speed: dict) -> dict:
    """The top-level keys of ``bench --json`` from :func:`speed_rides` (None where a ride failed or was skipped)."""
    def get(ride: str, key: str):
        return speed.get(ride, {}).get(key)

    out = {"decode_once_s": get("1920x1080", "decode_once_s"), "analysis_s": get("1920x1080", "analysis_s")}
    for name in ("640x480", "1920x1080"):
        out[f"decode_once_s_{name}"] = get(name, "decode_once_s")
        out[f"analysis_s_{name}"] = get(name, "analysis_s")
        out[f"analysis_vs_decode_{name}"] = get(name, "ratio")
        out[f"analysis_vs_decode_cpu_{name}"] = get(name, "ratio_cpu")
        out[f"stages_vs_decode_{name}"] = get(name, "stage_vs_decode")
    out["whole_analysis_vs_clip_duration_1920x1080"] = get("1920x1080", "vs_clip_duration")
    out["rides_per_core_hour_1920x1080"] = get("1920x1080", "rides_per_core_hour")
    out["rides_per_core_hour_640x480"] = get("640x480", "rides_per_core_hour")
    out["peak_rss_mb_2160p30"] = get("3840x2160", "peak_rss_mb")
    # issue 39: the same ride beside busy-loop processes (a load of 6-7 on two cores); the ratio should be ~1
    out["peak_rss_mb_2160p30_loaded"] = (get("3840x2160", "loaded") or {}).get("peak_rss_mb")
    out["peak_rss_loaded_vs_quiet_2160p30"] = get("3840x2160", "loaded_vs_quiet")
    return out


def accuracy(tmp: Path, *, rig: str, gaits: tuple[str, ...], seeds: tuple[int, ...],
             duration_s: float | None = None, skin_motion: str = "stride_locked",
             marker_layout: str = "thesis") -> list[dict]:
    """Pipeline results against truth.json.

    Saddle position, vertical acceleration, speed, period and indicator errors per synthetic ride (issues 5 and 6).
    ``skin_motion`` is the arena's skin model: with "none" the markers are fixed to the saddle body, so the errors
    are the cameras' and the stages' alone. ``marker_layout`` is the markers' layout on the flank
    (arena.gait.MARKER_LAYOUTS).
    """
    from saddlescope.arena import RenderOptions, saddle_truth_at
    from saddlescope.io.synth_writer import write_ride_bundle
    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    rows = []
    for gait in gaits:
        for seed in seeds:
            ride = tmp / f"{rig}_{gait}_{seed}"
            write_ride_bundle(ride, gait=gait, seed=seed, rig=rig, duration_s=duration_s, extras=False,
                              options=RenderOptions(skin_motion=skin_motion, marker_layout=marker_layout))
            truth = __import__("json").loads((ride / "truth.json").read_text())
            row: dict = {"rig": rig, "gait": gait, "seed": seed}
            try:
                result = analyze_bundle(ride)
            except Exception as exc:  # noqa: BLE001 - a benchmark reports every failure and goes on
                row["error"] = f"{type(exc).__name__}: {exc}"
                rows.append(row)
                continue
            t = np.array(result["saddle"]["t_s"])
            exact = saddle_truth_at(truth, t)
            pos = np.array(result["saddle"]["position_m"], dtype=float)
            acc = np.array(result["saddle"]["acceleration_m_s2"], dtype=float)
            pos_true = exact["position_m"] - exact["position_m"][0]
            pos_err = np.sqrt(np.mean(np.sum((pos - pos[0] - pos_true) ** 2, axis=1)))
            acc_y = exact["acceleration_m_s2"][:, 1]
            row.update({
                "saddle_position_rms_error_m": float(pos_err),
                "acc_y_rms_error_pct_of_rms": float(100 * np.sqrt(np.mean((acc[:, 1] - acc_y) ** 2))
                                                  / np.sqrt(np.mean(acc_y ** 2))),
                "speed_error_pct": 100 * (result["indicators"]["vel_x_avg_kmh"] / truth["truth"]["speed_kmh"] - 1),
                "period_error_pct": 100 * (result["period_s"] / truth["period_s"] - 1),
            })
            floor = exact_marker_floor(truth)
            if floor is not None:
                row["exact_markers"] = floor
            # (not duration_s: that is the clips' length asked for every ride of the loop). The indicators are
            # those of the fitted periodic motion over n_periods strides, also where the window held fewer (a
            # one-stride window read +19 % on VDV, 2^0.25, as coverage.truth_indicators already knew)
            n_periods = ((result.get("params") or {}).get("n_periods")
                         or round(result["window"]["duration_s"] / result["period_s"]))
            analysed_s = result["period_s"] * n_periods
            row.update(indicator_errors_pct(result["indicators"], analysed_s, truth))
            rows.append(row)
    return rows


def indicator_errors_pct(indicators: dict, duration_s: float, truth: dict,
                         keys=("acc_y_wb_rms", "vdv_y_wb", "vel_x_avg_kmh", "amplitude_y_m")) -> dict:
    """Errors (%) of a result's indicators against truth.json, as ``<key>_error_pct``.

    VDV grows with the fourth root of the analysed duration; a synthetic ride whose view holds too
    few frames for two strides with margins has a one-stride truth window while the pipeline may
    still fit two, so the truth's VDV is taken at the result's duration (whole periods of a periodic
    signal: VDV^4 is proportional to the duration).
    """
    ref = truth.get("indicators", {})
    vdv_scale = (duration_s / float(truth["window"]["duration_s"])) ** 0.25
    return {f"{k}_error_pct": 100 * (indicators[k] / (ref[k] * (vdv_scale if k.startswith("vdv_") else 1.0)) - 1)
            for k in keys if k in ref and k in indicators}


def exact_marker_floor(truth: dict, params=None) -> dict | None:
    """The kinematics and indicator stages fed with the exact marker positions of truth.json.

    What the markers' skin motion alone costs, the floor under any measurement (no cameras involved).

    Returns the vertical acceleration error (% of its r.m.s.) and the errors (%) of ``acc_y_wb_rms``
    and ``vdv_y_wb``, or None for a truth without exact markers. ``acc_y_rms_error_pct_rig`` is the
    error when the same exact markers are treated as the ride's cameras would see them: a rig that
    fixes depth poorly (the thesis's) has each marker's depth fitted with a straight path, so roll
    about the travel direction, which moves the markers mostly in depth, is lost to it (equal to the
    first where the rig fixes depth well). ``acc_y_skin_common_mode_pct`` is the vertical
    acceleration of the sliding the three markers share (their mean), which no rigid body fitted to
    the markers can tell from the body's motion: the part of the floor no method removes.
    """
    from saddlescope.arena import GaitModel, saddle_truth_at
    from saddlescope.core.pipeline import PipelineParams, depth_uncertainty
    from saddlescope.core.saddle import kinematics_indicators, saddle_kinematics
    from saddlescope.core.types import MarkerTracks
    from saddlescope.io.rig_document import rig_from_dict

    tt = truth.get("truth", {})
    try:
        fps = float(truth["fps"])
        marks = {k: np.asarray(tt["markers_3d_mm"][k], dtype=float) for k in ("motion", "static", "plumb")}
        first, last = tt["clips"]["motion"]["markers_in_view_left_frames"]
    except (KeyError, TypeError, ValueError):
        return None

    def tracks(xyz, frames):
        return MarkerTracks(tuple(f"M{i + 1}" for i in range(xyz.shape[1])), np.asarray(frames) / fps, xyz)

    frames = np.arange(first, last + 1)
    params = params or PipelineParams()
    motion = tracks(marks["motion"][frames, :3], frames)
    static, plumb = (tracks(marks[k], np.arange(len(marks[k]))) for k in ("static", "plumb"))

    def kinematics(depth=None):
        return saddle_kinematics(motion, static, plumb, params, horse_idx=[0, 1, 2], saddle_idx=3,
                                 gait=tt.get("model", {}).get("gait"), depth=depth)

    def acc_error_pct(kin):
        exact = saddle_truth_at(truth, kin.t_s)["acceleration_m_s2"][:, 1]
        return float(100 * np.sqrt(np.mean((kin.saddle.acceleration_m_s2[:, 1] - exact) ** 2))
                     / np.sqrt(np.mean(exact ** 2)))

    kin = kinematics()
    _, ind = kinematics_indicators(kin, params)
    exact_y = saddle_truth_at(truth, kin.t_s)["acceleration_m_s2"][:, 1]
    common_y = GaitModel.from_dict(tt["model"]).skin_common_mode(kin.t_s, derivative=2)[:, 1]
    out = {"acc_y_rms_error_pct": acc_error_pct(kin),
           # the sliding all three markers share: no rigid body fitted to them can remove it
           "acc_y_skin_common_mode_pct": float(100 * np.sqrt(np.mean(common_y ** 2) / np.mean(exact_y ** 2))),
           **indicator_errors_pct(ind, kin.period_s * params.n_periods, truth, keys=("acc_y_wb_rms", "vdv_y_wb"))}
    depth = depth_uncertainty(rig_from_dict(truth["calibration"]), motion) if "calibration" in truth else None
    out["acc_y_rms_error_pct_rig"] = (acc_error_pct(kinematics(depth))
                                      if depth is not None and depth["anisotropy"] >= params.depth_anisotropy
                                      else out["acc_y_rms_error_pct"])
    return out


def kinematics_floor(*, rig: str, gaits: tuple[str, ...] = ("walk", "sitting_trot", "rising_trot", "canter"),
                     seeds: tuple[int, ...] = (1, 2, 3, 4, 5, 6), skin_motion: str = "stride_locked",
                     params=None, marker_layout: str = "thesis") -> dict:
    """:func:`exact_marker_floor` over synthetic rides (nothing rendered, a second each).

    Per gait the mean and worst vertical acceleration error and the worst W_b r.m.s. and VDV errors. ``skin_motion``
    is the arena's skin model (arena.gait.SKIN_MODELS); with "none" the markers are fixed to the saddle body and the
    stages should be exact. ``marker_layout``: see arena.gait.MARKER_LAYOUTS.
    """
    import json

    from saddlescope.arena import RenderOptions, build_scene, build_truth

    out = {}
    for gait in gaits:
        rows = []
        for seed in seeds:
            # no textured backgrounds: truth.json does not depend on them (byte for byte), and painting
            # them was 90 % of the time at 1920x1080
            scene = build_scene(gait=gait, seed=seed, rig=rig, extras=False, calibration_poses=4,
                                options=RenderOptions(skin_motion=skin_motion, marker_layout=marker_layout,
                                                      textured_background=False))
            floor = exact_marker_floor(json.loads(json.dumps(build_truth(scene))), params)
            if floor is None:
                raise ValueError(f"the {gait} scene of seed {seed} has no exact markers in its truth")
            rows.append(floor)
        acc = [r["acc_y_rms_error_pct"] for r in rows]
        acc_rig = [r["acc_y_rms_error_pct_rig"] for r in rows]
        common = [r["acc_y_skin_common_mode_pct"] for r in rows]
        out[gait] = {"acc_y_rms_error_pct_mean": float(np.mean(acc)), "acc_y_rms_error_pct_max": float(np.max(acc)),
                     "acc_y_rms_error_pct_rig_mean": float(np.mean(acc_rig)),
                     "acc_y_rms_error_pct_rig_max": float(np.max(acc_rig)),
                     "acc_y_skin_common_mode_pct_mean": float(np.mean(common)),
                     "acc_y_skin_common_mode_pct_max": float(np.max(common)),
                     "acc_y_wb_rms_error_pct_max_abs": float(max(abs(r["acc_y_wb_rms_error_pct"]) for r in rows)),
                     "vdv_y_wb_error_pct_max_abs": float(max(abs(r["vdv_y_wb_error_pct"]) for r in rows)),
                     "seeds": list(seeds)}
    return out


def _repeats(quick: bool) -> int:
    return 2 if quick else 3


def detection_section(tmp: Path, quick: bool) -> dict:
    """Marker detection against decoding the same clips, at 640x480 and 1920x1080."""
    d640 = detection_vs_decode("thesis", duration_s=3.0 if quick else 6.0, repeats=_repeats(quick), tmp=tmp)
    d1080 = detection_vs_decode("wide", duration_s=2.0 if quick else 4.0, repeats=_repeats(quick), tmp=tmp)
    return {"detection_vs_decode_640x480": d640["ratio"], "detection_vs_decode_1920x1080": d1080["ratio"],
            "detail_detection": {"640x480": d640, "1920x1080": d1080}}


def calibration_section(tmp: Path, quick: bool) -> dict:
    """The three cameras' calibration from their board clips."""
    cal = calibration_3cams(1 if quick else 2)
    return {"calibration_3cams_s": cal["seconds"], "detail_calibration": cal}


def speed_section(tmp: Path, quick: bool) -> dict:
    """Whole rides against decoding their clips once, each stage's share, rides per core-hour, peak memory."""
    speed = speed_rides(tmp, quick=quick)
    return {**speed_keys(speed), "detail_speed": speed}


def footage_section(tmp: Path, quick: bool) -> dict:
    """Whole rides against the length of their footage."""
    ana = analysis_vs_footage(tmp, quick=quick)
    return {"analysis_vs_footage": ana["ratio"], "detail_analysis": ana}


def floor_section(tmp: Path, quick: bool) -> dict:
    """The exact-marker floor of the kinematics on the thesis rig (nothing rendered)."""
    return {"kinematics_floor_thesis": kinematics_floor(rig="thesis", seeds=(1, 2) if quick else (1, 2, 3, 4, 5, 6))}


def accuracy_section(tmp: Path, quick: bool) -> dict:
    """Rendered rides against the arena's exact answers, with skin motion and with markers fixed to the saddle body.

    The fixed markers show what the cameras and the stages cost without any skin motion (the floor is then zero).
    ``passes_interval_ratio``: a three-pass canter's W_b interval over the same horse's one pass (issue 38,
    :mod:`saddlescope.bench.passes`). Skipped (no keys) in quick mode.
    """
    from saddlescope.bench.passes import passes_interval_ratio

    if quick:
        return {}
    gaits = ("walk", "sitting_trot", "rising_trot", "canter")
    return {"accuracy_thesis": accuracy(tmp, rig="thesis", gaits=gaits, seeds=(1,)),
            "accuracy_thesis_rigid_markers": accuracy(tmp, rig="thesis", gaits=gaits, seeds=(1,),
                                                      skin_motion="none"),
            "passes_interval_ratio": passes_interval_ratio(tmp)}

"""The calibration stage's time against decoding its clips once, side by side in one run (issue 28).

The stage (board views in every camera's calibration clip, intrinsics, pairs, bundle adjustment) and
decoding every frame of those clips once with PyAV (single thread, no conversion: the limit) are timed in
alternation, best of ``repeats``, so that the machine's load hits both alike. Only the pipeline's public
functions are used, so that the same function times an older checkout's stage too (``python -m
saddlescope.bench.calibration RIDE ...`` with that checkout on the path) for a before/after ratio.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

from saddlescope.bench.analysis import quick_ride

__all__ = ["calibration_check_clips_s", "calibration_stage_s", "calibration_vs_decode", "wand_canter_indicators",
           "wand_refines_band", "wand_refines_band_rendered", "wand_vs_board"]


def _decode_once(paths: list[Path]) -> int:
    """Decode every frame of every clip once (PyAV, one thread, no conversion); the number of frames."""
    import av

    frames = 0
    for path in paths:
        with av.open(str(path)) as container:
            stream = container.streams.video[0]
            stream.thread_type = "NONE"
            for _ in container.decode(stream):
                frames += 1
    return frames


def calibration_stage_s(ride: Path, *, repeats: int = 1) -> dict:
    """Best wall time (s) of the calibration stage of a ride bundle and of decoding its calibration clips.

    The clips are synchronised once beforehand (that is the sync stage's time, not this one's).

    Returns
    -------
    dict with ``calibration_s``, ``decode_s`` (every frame of every camera's calibration clip once),
    ``calibration_vs_decode`` (their ratio), ``frames``, ``image_size`` [w, h], ``n_views`` per camera and
    the calibration's ``focal_px`` and its standard error ``focal_std_px`` per camera (to see that a faster
    stage found the same rig).
    """
    from saddlescope.core.calibration.boards import board_from_meta
    from saddlescope.core.params import PipelineParams
    from saddlescope.core.pipeline.setup import calibrate_from_clips, synchronise
    from saddlescope.io.bundle import open_bundle
    from saddlescope.io.clip_source import BundleClips

    with open_bundle(Path(ride)) as bundle:
        clips = BundleClips(bundle.clip_paths)
        meta = bundle.meta
        offsets, first_frame = synchronise(clips, meta, ["calibration"])
        board = board_from_meta(meta.get("board"))
        cams = clips.cameras("calibration")
        paths = [Path(clips.path("calibration", c)) for c in cams]
        params = PipelineParams()
        best = {"calibration": float("inf"), "decode": float("inf")}
        out: dict = {}
        for _ in range(max(1, int(repeats))):
            t0 = time.perf_counter()
            rig, report = calibrate_from_clips(clips, board, offsets["calibration"], first_frame["calibration"],
                                               params)
            best["calibration"] = min(best["calibration"], time.perf_counter() - t0)
            t0 = time.perf_counter()
            out["frames"] = _decode_once(paths)
            best["decode"] = min(best["decode"], time.perf_counter() - t0)
        out.update({
            "calibration_s": round(best["calibration"], 3),
            "decode_s": round(best["decode"], 3),
            "calibration_vs_decode": round(best["calibration"] / best["decode"], 3),
            "image_size": list(clips.image_size("calibration", cams[0])),
            "n_views": report["n_views"],
            "focal_px": {c: round(float(cam.K[0, 0]), 2) for c, cam in rig.cameras.items()},
            "focal_std_px": {c: None if cam.K_std is None else round(float(cam.K_std[0, 0]), 3)
                             for c, cam in rig.cameras.items()},
        })
    return out


def calibration_vs_decode(tmp: Path, *, rig: str, quick: bool = False, repeats: int = 2) -> dict:
    """The calibration stage of a synthetic ride of ``rig`` ("thesis": 640x480, "wide": 1920x1080 at 60 fps).

    Returns :func:`calibration_stage_s`'s dict, its keys suffixed with the frame size (e.g.
    ``calibration_vs_decode_1920x1080``) where they are times or ratios, for ``saddlescope bench --json``.
    """
    from saddlescope.io.synth_writer import write_ride_bundle

    ride = Path(tmp) / f"calibration_{rig}"
    write_ride_bundle(ride, gait="canter", seed=1, rig=rig, extras=False,
                      **quick_ride(quick))
    found = calibration_stage_s(ride, repeats=repeats)
    w, h = found["image_size"]
    return {(f"{k}_{w}x{h}" if k in ("calibration_s", "decode_s", "calibration_vs_decode") else k): v
            for k, v in found.items()}


def calibration_check_clips_s(tmp: Path, *, quick: bool = False, clip_s: float = 30.0) -> dict:
    """The rig page's calibration check (issue 35) on three ``clip_s`` calibration clips of 1920x1080 at 50 fps.

    The arena's wide rig renders the clips (not timed); the check (a few frames a second sampled, the board
    searched in each, the coverage judged) is timed against decoding every frame of the three clips once.
    The target is under 2 minutes for three 30 s clips. ``quick``: 8 s clips.

    Returns
    -------
    dict with ``calibration_check_3x{N}s_1080p_s`` (wall) and ``..._cpu_s`` (this process's CPU),
    ``calibration_check_vs_decode``, ``calibration_check_clip_s``,
    ``calibration_check_frames_sampled`` and ``calibration_check_views`` per camera and the verdict.
    """
    from saddlescope.arena.scene import HOLD_FRAMES, MOVE_FRAMES
    from saddlescope.io.bundle import open_bundle
    from saddlescope.io.synth_writer import write_ride_bundle
    from saddlescope.io.video import probe_video
    from saddlescope.services.rigs.calibration_check import check_calibration_clips

    clip_s = 8.0 if quick else float(clip_s)
    fps = 50.0  # the arena holds at most 400 board poses of 4 frames: 30 s at 50 fps
    ride = Path(tmp) / f"calibration_check_{clip_s:g}s"
    write_ride_bundle(ride, gait="canter", seed=3, rig="wide", extras=False, duration_s=2.0, fps=fps,
                      calibration_poses=max(4, round(clip_s * fps / (HOLD_FRAMES + MOVE_FRAMES))))
    with open_bundle(ride) as bundle:
        paths = {c: Path(p) for c, p in bundle.clip_paths["calibration"].items()}
        board = bundle.meta["board"]
        t0, cpu0 = time.perf_counter(), time.process_time()
        check = check_calibration_clips(paths, board)
        check_s, check_cpu_s = time.perf_counter() - t0, time.process_time() - cpu0
        t0, cpu0 = time.perf_counter(), time.process_time()
        _decode_once(list(paths.values()))
        decode_s, decode_cpu_s = time.perf_counter() - t0, time.process_time() - cpu0
        info = probe_video(next(iter(paths.values())), decode_tail=False)
    n = round(clip_s)
    return {
        f"calibration_check_3x{n}s_1080p_s": round(check_s, 2),
        "calibration_check_vs_decode": round(check_s / decode_s, 3),
        # CPU seconds of this process: on a loaded machine the wall time above is mostly waiting for a core
        f"calibration_check_3x{n}s_1080p_cpu_s": round(check_cpu_s, 2),
        "calibration_check_decode_cpu_s": round(decode_cpu_s, 2),
        "calibration_check_load_avg": list(os.getloadavg()),
        "calibration_check_clip_s": round(info.frame_count / info.fps, 1),
        "calibration_check_image_size": [info.width, info.height],
        "calibration_check_frames_sampled": {c: v.frames_sampled for c, v in check.cameras.items()},
        "calibration_check_views": {c: v.views for c, v in check.cameras.items()},
        "calibration_check_verdict": check.verdict(),
    }


def _pose_errors(rig, truth) -> dict:
    """Per camera: focal length error (%), rotation error (deg) and camera-centre error (mm) against ``truth``.

    Both rigs share their reference camera (identity pose), so the centres are compared directly.
    """
    import cv2
    import numpy as np

    out = {}
    for name, true in truth.cameras.items():
        cam = rig.cameras[name]
        centre, true_centre = -cam.R.T @ cam.t_mm, -true.R.T @ true.t_mm
        turn_deg = float(np.degrees(np.linalg.norm(cv2.Rodrigues(cam.R @ true.R.T)[0])))
        out[name] = {"focal_error_pct": round(float(100 * (cam.K[0, 0] / true.K[0, 0] - 1)), 4),
                     "rotation_error_deg": round(turn_deg, 4),
                     "centre_error_mm": round(float(np.linalg.norm(centre - true_centre)), 2)}
    return out


def _baseline_errors_mm(rig, truth) -> dict:
    """Each pair's baseline (distance between camera centres) minus the true one, mm."""
    import itertools

    import numpy as np

    def centre(c):
        return -c.R.T @ c.t_mm

    return {f"{a}-{b}": round(float(np.linalg.norm(centre(rig.cameras[a]) - centre(rig.cameras[b]))
                                    - np.linalg.norm(centre(truth.cameras[a]) - centre(truth.cameras[b]))), 2)
            for a, b in itertools.combinations(truth.names, 2)}


def _volume_board_views(srig, rng, n_poses: int = 60) -> dict:
    """The arena board held through the riding volume, seen by every camera (exact corners, 0.1 px noise).

    The same views check the board squares of both calibrations (metric_checks), so neither is judged on
    views it was fitted to.
    """
    import numpy as np

    from saddlescope.arena.content import BOARD
    from saddlescope.core.calibration.simulation import simulate_board_views
    from saddlescope.core.types import Rig

    half = np.asarray(srig.volume_half_m)
    rvecs, ts = [], []
    cols, rows = BOARD.inner_corners
    centre_b = np.array([(cols - 1) * BOARD.square_mm / 2, (rows - 1) * BOARD.square_mm / 2, 0.0])
    import cv2

    for _ in range(n_poses):
        # board facing the cameras (normal along -z world), turned by up to 30 degrees
        r_bw = cv2.Rodrigues(np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.2, 0.2)]))[0]
        c_w = rng.uniform(-half, half) * np.array([1.0, 1.0, 1.0])
        r_br = srig.R_world_to_rig @ r_bw
        t = srig.world_to_rig_mm(c_w) - r_br @ centre_b
        rvecs.append(cv2.Rodrigues(r_br)[0].ravel())
        ts.append(t)
    return simulate_board_views(Rig(srig.cameras), BOARD, np.array(rvecs), np.array(ts), noise_px=0.1, rng=rng)


def _wand_rig(srig, seed: int, n_frames: int, length_m: float):
    """The arena rig calibrated from close-up board views and rendered wand clips (rig, report, views, path, CPU s)."""
    import numpy as np

    from saddlescope.arena.wand import CLOSE_UP_BOARD, close_up_board_views, render_wand_frames, wand_path
    from saddlescope.core.calibration.intrinsics import calibrate_intrinsics
    from saddlescope.core.calibration.wand import calibrate_wand, track_wand_ends

    rng = np.random.default_rng(seed + 1000)
    t0 = time.process_time()
    close = close_up_board_views(srig, rng)
    intrinsics = {r: calibrate_intrinsics(v, CLOSE_UP_BOARD, srig.cameras[r].image_size, camera=r)[0]
                  for r, v in close.items()}
    path = wand_path(srig, rng, n_frames=n_frames, length_m=length_m)
    t_render = time.process_time()
    frames = {r: list(render_wand_frames(srig, path, r, rng=rng)) for r in srig.cameras}
    render_s = time.process_time() - t_render
    views = {r: track_wand_ends(frames[r]) for r in srig.cameras}
    del frames
    rig, report = calibrate_wand(views, intrinsics, length_m * 1000.0)
    return rig, report, views, path, time.process_time() - t0 - render_s


def wand_canter_indicators(tmp: Path, *, rig: str = "wide", seed: int = 1, quick: bool = False,
                           wand_frames: int = 240) -> dict:
    """A canter's indicators with the wand-calibrated rig against the board-calibrated one (issue 35).

    The same rendered ride is analysed twice: as it comes (its board clips calibrate the rig) and with
    the rig from :func:`_wand_rig`. Returns each indicator's two values and their relative difference (%),
    and the largest difference.
    """
    import numpy as np

    from saddlescope.arena.rig import make_rig
    from saddlescope.io.synth_writer import write_ride_bundle
    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    ride = Path(tmp) / f"wand_vs_board_{rig}"
    if not (ride / "ride.json").is_file():
        write_ride_bundle(ride, gait="canter", seed=seed, rig=rig, extras=False,
                          **quick_ride(quick))
    srig = make_rig(rig, np.random.default_rng(np.random.SeedSequence([int(seed), 0x5ADD1E]).spawn(8)[0]))
    wand_rig = _wand_rig(srig, seed, wand_frames if not quick else wand_frames // 2, 1.0)[0]
    board = analyze_bundle(ride)["indicators"]
    wand = analyze_bundle(ride, rig=wand_rig)["indicators"]
    truth = json.loads((ride / "truth.json").read_text()).get("indicators", {})
    out = {}
    for key, b in board.items():
        w, t = wand.get(key), truth.get(key)
        if isinstance(b, (int, float)) and isinstance(w, (int, float)) and b:
            out[key] = {"board": b, "wand": w, "difference_pct": round(100 * (w - b) / abs(b), 3)}
            if isinstance(t, (int, float)) and t:  # each calibration's error against the arena's exact answer
                out[key].update({"truth": t, "board_error_pct": round(100 * (b - t) / abs(t), 3),
                                 "wand_error_pct": round(100 * (w - t) / abs(t), 3)})
    worst = max((abs(v["difference_pct"]) for v in out.values()), default=float("nan"))
    closer = sum(abs(v["wand_error_pct"]) <= abs(v["board_error_pct"]) for v in out.values() if "truth" in v)
    return {"wand_canter_indicators": out, "wand_canter_worst_difference_pct": worst,
            "wand_canter_closer_to_truth": closer, "wand_canter_compared": sum("truth" in v for v in out.values())}


def wand_vs_board(tmp: Path, *, rig: str = "wide", seed: int = 1, quick: bool = False,
                  wand_frames: int = 240, length_m: float = 1.0) -> dict:
    """A rig calibrated from a wand and close-up board views against the full board calibration (issue 35).

    The board calibration is the pipeline's calibration stage on a rendered synthetic ride's board clips
    (as :func:`calibration_vs_decode`); the wand calibration uses the same arena rig: each lens from 40
    close-up views of an A3 board (:func:`saddlescope.arena.wand.close_up_board_views`), the poses and scale
    from ``wand_frames`` rendered frames of a 1 m wand waved through the riding volume by each camera
    (:func:`saddlescope.arena.wand.render_wand_frames`), ends found by :func:`track_wand_ends`. Both rigs are
    compared with the arena's exact cameras and checked on the same independent board views in the volume.

    Returns
    -------
    dict ``wand_vs_board`` with, for ``board`` and ``wand``: per-camera pose errors, baseline errors (mm),
    ``board_square_error_mm`` (and pct), and for the wand its length check; the ratios wand/board of the
    square error and of the largest baseline error; the wand calibration's CPU time.
    """
    import numpy as np

    from saddlescope.arena.content import BOARD
    from saddlescope.arena.rig import make_rig
    from saddlescope.core.calibration.checks import metric_checks
    from saddlescope.core.params import PipelineParams
    from saddlescope.core.pipeline.setup import calibrate_from_clips, synchronise
    from saddlescope.io.bundle import open_bundle
    from saddlescope.io.clip_source import BundleClips
    from saddlescope.io.synth_writer import write_ride_bundle

    ride = Path(tmp) / f"wand_vs_board_{rig}"
    write_ride_bundle(ride, gait="canter", seed=seed, rig=rig, extras=False,
                      **quick_ride(quick))
    with open_bundle(ride) as bundle:
        clips = BundleClips(bundle.clip_paths)
        offsets, first_frame = synchronise(clips, bundle.meta, ["calibration"])
        board_rig, _ = calibrate_from_clips(clips, BOARD, offsets["calibration"], first_frame["calibration"],
                                            PipelineParams())
    # the scene's rig, drawn as build_scene draws it
    r_rig = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5ADD1E]).spawn(8)[0])
    srig = make_rig(rig, r_rig)
    wand_rig, wand_report, views, path, wand_cpu_s = _wand_rig(
        srig, seed, wand_frames if not quick else wand_frames // 2, length_m)
    check_views = _volume_board_views(srig, np.random.default_rng(seed + 2000))
    from saddlescope.core.types import Rig

    truth = Rig(srig.cameras)
    out: dict = {"rig": rig, "seed": seed, "wand_frames": len(path.ends_w), "wand_length_m": length_m,
                 "wand_views": {r: len(v) for r, v in views.items()}, "wand_cpu_s": round(wand_cpu_s, 2)}
    for label, r in (("board", board_rig), ("wand", wand_rig)):
        checks, _, _ = metric_checks(r, check_views, BOARD)
        out[label] = {"cameras": _pose_errors(r, truth), "baseline_error_mm": _baseline_errors_mm(r, truth),
                      "board_square_error_mm": round(checks["board_square_error_mm"], 4),
                      "board_square_error_pct": round(checks["board_square_error_pct"], 4),
                      "board_scale_error_pct": round(checks["board_scale_error_pct"], 4)}
    out["wand"].update({k: round(float(v), 3) for k, v in wand_rig.checks.items()})
    out["wand"]["bundle"] = wand_report["bundle"]
    out["wand"]["findings"] = [f.code for f in wand_rig.flags]
    out["square_error_wand_vs_board"] = round(out["wand"]["board_square_error_mm"]
                                              / max(out["board"]["board_square_error_mm"], 1e-9), 3)
    worst = {k: max(abs(v) for v in out[k]["baseline_error_mm"].values()) for k in ("board", "wand")}
    out["worst_baseline_error_mm"] = worst
    return {"wand_vs_board": out}


if __name__ == "__main__":  # python -m saddlescope.bench.calibration RIDE [REPEATS]: one line of JSON
    print(json.dumps(calibration_stage_s(Path(sys.argv[1]), repeats=int(sys.argv[2]) if len(sys.argv) > 2 else 1)))


def _scene_board_views(scene, noise_px: float, rng) -> dict:
    """Each camera's exact views of the scene's calibration board poses (+ pixel noise), whole boards only."""
    import numpy as np

    from saddlescope.arena.content import BOARD
    from saddlescope.core.calibration.views import BoardView

    obj_m = BOARD.object_points_mm() / 1000.0
    ids = np.arange(len(obj_m))
    out: dict = {}
    for role, view in scene.views.items():
        w, h = view.size
        views = []
        for i, (r_bw, o_w) in enumerate(scene.contents["calibration"].poses):
            xy = view.project(o_w + obj_m @ r_bw.T)
            if np.all(np.isfinite(xy)) and xy[:, 0].min() > 3 and xy[:, 1].min() > 3 and xy[:, 0].max() < w - 4 \
                    and xy[:, 1].max() < h - 4:
                views.append(BoardView(i, xy + rng.normal(0, noise_px, xy.shape), ids))
        out[role] = views
    return out


def _samples_beyond(rig, hull_by_cam: dict, xy_by_cam: dict) -> dict:
    """Per camera: the share of marker samples outside the hull (pointPolygonTest) and beyond the lens reach radius."""
    import numpy as np

    from saddlescope.core.pipeline.setup import outside_coverage
    from saddlescope.core.triangulation.lens_reach import board_reach_px
    from saddlescope.core.types import ImageTracks

    tracks = {c: ImageTracks(camera=c, xy_px=xy, frame_index=np.arange(len(xy))) for c, xy in xy_by_cam.items()}
    hull_share = outside_coverage(tracks,
                                  {c: {"hull_px": h} for c, h in hull_by_cam.items()})
    out = {}
    for cam, xy in xy_by_cam.items():
        pts = xy.reshape(-1, 2)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        reach = 1.1 * board_reach_px(rig.cameras[cam], hull_by_cam[cam])  # lens_reach's margin
        radius = np.linalg.norm(pts - rig.cameras[cam].K[:2, 2], axis=1)
        out[cam] = {"outside_hull": round(hull_share[cam], 4), "beyond_reach": round(float(np.mean(radius > reach)), 4),
                    "reach_px": round(reach, 1)}
    return out


def _lens_error_px(est, true, xy, reach_px: float | None) -> dict:
    """The estimated lens's ray error (px at the focal length) at pixels ``xy`` (N, 2), median and 95th percentile."""
    import numpy as np

    from saddlescope.core.camera_model import undistort_normalized
    from saddlescope.core.triangulation.lens_reach import undistort_within_reach

    got, _ = undistort_within_reach(est, xy, reach_px)
    err = np.linalg.norm(got - undistort_normalized(true, xy), axis=1) * true.K[0, 0]
    err = err[np.isfinite(err)]
    return {"median": round(float(np.median(err)), 2), "p95": round(float(np.percentile(err, 95)), 2)} if err.size \
        else {}


def _wand_views_exact(srig, path, noise_px: float, rng) -> dict:
    """WandView lists from the ends' exact pixels (+ noise), frames where both ends are in the image."""
    import numpy as np

    from saddlescope.arena.wand import true_wand_pixels
    from saddlescope.core.calibration.wand import WandView

    out = {}
    for role in srig.cameras:
        xy = true_wand_pixels(srig, path, role)
        ok = np.all(np.isfinite(xy), axis=(1, 2))
        out[role] = [WandView(int(f), xy[f] + rng.normal(0, noise_px, (2, 2))) for f in np.flatnonzero(ok)]
    return out


def wand_refines_band(*, seeds: tuple[int, ...] = (1013, 1015, 2041, 2043), band: float = 0.6, wand_frames: int = 480,
                      length_m: float = 1.0, along_track: bool = True) -> dict:
    """A rig whose board reached only the middle band, refined by a wand pass: the extrapolated share (issue 35).

    For each partial-view canter (``wide_partial`` rig, 4-6 m/s, the board through ``band`` of the volume, 30
    poses; the coverage table's band-0.6 seeds, build 1013 and 1015, held-out 2041 and 2043): the rig is
    calibrated from the board's exact corner projections (0.15 px noise) as the ride's board clip shows them,
    then refined by a 1 m wand waved through the whole volume as the pipeline's ``board+wand`` way does
    (:func:`~saddlescope.core.calibration.wand_refinement.refine_board_rig`: the board's views and the wand's
    ends adjusted together, kept where the held-out checks are no worse; its ends' exact pixels, 0.2 px noise). The
    motion clip's exact marker pixels are then checked against where each calibration's lens is known: the
    board's corners alone, then the board's and the wand's ends. Reported per ride: the share of marker
    samples outside the region (the convex hull, as ``quality.markers_outside_board_fraction``) and beyond
    the lens reach radius (as :mod:`~saddlescope.core.triangulation.lens_reach`), the largest over the
    cameras, before and after; the lens's ray error at the samples beyond the board's reach against the
    arena's true lens (px), before (the reach-limited model) and after; and a fresh wand's length error.
    ``along_track=False`` waves the wand through the calibration volume only (as the ``wand`` section's path).
    Geometry only: no clip is rendered (detection's part is in the ``wand`` section).
    """
    rides = {seed: _band_ride(seed, band, wand_frames, length_m, along_track) for seed in seeds}
    ratios = [r["beyond_reach_max"]["after"] / max(r["beyond_reach_max"]["before"], 1e-9) for r in rides.values()]
    return {"wand_refines_band": {"band": band, "rides": rides, "beyond_reach_ratio_max": round(max(ratios), 3)}}


def _band_ride(seed: int, band: float, wand_frames: int, length_m: float, along_track: bool) -> dict:
    """One ride of :func:`wand_refines_band`."""
    import numpy as np

    from saddlescope.arena import build_scene
    from saddlescope.arena.clips import true_marker_pixels
    from saddlescope.arena.content import BOARD
    from saddlescope.arena.wand import wand_path
    from saddlescope.core.calibration import calibrate_rig
    from saddlescope.core.calibration.wand import wand_length_errors
    from saddlescope.core.calibration.wand_refinement import refine_board_rig
    from saddlescope.core.pipeline.setup import board_coverage

    rng = np.random.default_rng(seed + 7000)
    scene = build_scene(gait="canter", seed=seed, rig="wide_partial", board_band=band, speed_range_m_s=(4.0, 6.0),
                        calibration_poses=30, extras=False)
    srig = scene.rig
    board_views = _scene_board_views(scene, 0.15, rng)
    sizes = {r: srig.cameras[r].image_size for r in srig.cameras}
    board_rig, _ = calibrate_rig(board_views, BOARD, sizes)
    # the wand walked along the track the horse takes through the three views (its markers' x range)
    xy_w = scene.contents["motion"].markers_w(scene.timings["motion"].frame_times("left"))[..., 0]
    track = (float(np.nanmin(xy_w)), float(np.nanmax(xy_w))) if along_track else None
    wand = _wand_views_exact(srig, wand_path(srig, rng, n_frames=wand_frames, length_m=length_m,
                                             track_x_m=track), 0.2, rng)
    board_hull = {r: board_coverage(v, sizes[r])["hull_px"] for r, v in board_views.items()}
    # the product's step: the board's views and the wand's ends together, kept where the held-out checks agree
    refined, report = refine_board_rig(board_rig, board_views, BOARD, wand, length_m * 1000.0,
                                       board_hull_px=board_hull)
    check = _wand_views_exact(srig, wand_path(srig, np.random.default_rng(seed + 9000), n_frames=240,
                                              length_m=length_m, track_x_m=track), 0.2, rng)
    xy = {r: true_marker_pixels(scene, r, "motion")["xy_px"] for r in srig.cameras}
    both_hull = {r: c["hull_px"] for r, c in report.get("lens_coverage", {}).items()} or board_hull
    before = _samples_beyond(board_rig, board_hull, xy)
    after = _samples_beyond(refined, both_hull, xy)
    lens = {}
    for r in srig.cameras:
        pts = xy[r].reshape(-1, 2)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        far = pts[np.linalg.norm(pts - board_rig.cameras[r].K[:2, 2], axis=1) > before[r]["reach_px"]]
        if len(far):
            true = srig.cameras[r]
            lens[r] = {"samples": len(far),
                       "before": _lens_error_px(board_rig.cameras[r], true, far, before[r]["reach_px"] / 1.1),
                       "after": _lens_error_px(refined.cameras[r], true, far, after[r]["reach_px"] / 1.1)}
    length = {k: float(np.sqrt(np.mean(wand_length_errors(rg, check, length_m * 1000.0) ** 2)))
              for k, rg in (("before", board_rig), ("after", refined))}
    return {
        "outside_hull_max": {"before": max(v["outside_hull"] for v in before.values()),
                             "after": max(v["outside_hull"] for v in after.values())},
        "beyond_reach_max": {"before": max(v["beyond_reach"] for v in before.values()),
                             "after": max(v["beyond_reach"] for v in after.values())},
        "per_camera": {"before": before, "after": after}, "lens_error_beyond_board_px": lens,
        "check_wand_length_rms_mm": {k: round(v, 2) for k, v in length.items()},
        "wand_frames_seen": {r: len(v) for r, v in wand.items()}, "refinement": report.get("refinement"),
        "kept": refined.wand_refinement.kept if refined.wand_refinement else None,
        "reason": refined.wand_refinement.reason if refined.wand_refinement else None}


def _beyond_reach_share(scene, reach_px: dict) -> dict[str, float]:
    """Per camera, the share of the motion clip's exact marker samples beyond the lens reach (times 1.1).

    The margin is lens_reach's: beyond it the ride's lens model is continued with k1 alone.
    """
    import numpy as np

    from saddlescope.arena.clips import true_marker_pixels

    out = {}
    for role, cam in scene.rig.cameras.items():
        pts = true_marker_pixels(scene, role, "motion")["xy_px"].reshape(-1, 2)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if role in reach_px and len(pts):
            radius = np.linalg.norm(pts - cam.K[:2, 2], axis=1)
            out[role] = round(float(np.mean(radius > 1.1 * reach_px[role])), 4)
    return out


def _ride_errors(result: dict, truth: dict) -> dict:
    """W_b, W_k r.m.s., VDV, speed and stride frequency of a result against the truth (%), with its window."""
    from saddlescope.bench.coverage import truth_indicators

    ref = truth_indicators(result, truth)
    keys = ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vel_x_avg_kmh", "stride_frequency_hz")
    codes = [f["code"] for f in result["quality"]["findings"]]
    return {"error_pct": {k: round(100 * (result["indicators"][k] / ref[k] - 1), 2) for k in keys if ref.get(k)},
            "outside_region": {c: round(v, 4) for c, v in result["quality"]["markers_outside_board_fraction"].items()},
            "window_s": result["window"]["duration_s"], "guessed_depth": "calibration.guessed_depth" in codes,
            "too_uncertain": "indicators.too_uncertain" in codes}


def wand_refines_band_rendered(tmp: Path, *, seed: int = 2041, band: float = 0.6, wand_s: float = 24.0,
                               size: tuple[int, int] | None = None) -> dict:
    """A partial-view canter rendered with a wand walked along the track: the band's board alone against board+wand.

    The coverage table's ride (``wide_partial`` rig, 1280x720 at 50 fps unless ``size``, a canter at 4-6 m/s, 30
    board stops through the middle ``band`` of the volume) written with ``calibration="board+wand"`` (the board
    walk and ``wand_s`` seconds of a 1 m wand walked along the stretch of track the markers cross, after a flash),
    then analysed twice with :func:`~saddlescope.services.analysis.ride_bundle.analyze_bundle`: as the board walk
    alone (ride.json's calibration overridden to ``board``) and as ``board+wand`` (the pipeline's refinement and its
    choice). Per analysis: the share of the exact marker samples beyond each camera's lens reach (the board's,
    or the board's and the wand's where the refinement was kept), the result's share outside the region reached,
    W_b / W_k / VDV / speed / stride frequency against the truth, the window, and the refinement's choice.
    """
    from saddlescope.arena import build_scene
    from saddlescope.io.synth_writer import write_ride_bundle
    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    ride = Path(tmp) / f"board_wand_{seed}"
    t0 = time.perf_counter()
    if not (ride / "ride.json").is_file():
        write_ride_bundle(ride, gait="canter", seed=seed, rig="wide_partial", size=size, board_band=band,
                          speed_range_m_s=(4.0, 6.0), calibration_poses=30, extras=False, calibration="board+wand",
                          wand_s=wand_s)
    out: dict = {"seed": seed, "band": band, "wand_s": wand_s, "render_s": round(time.perf_counter() - t0, 1)}
    truth = json.loads((ride / "truth.json").read_text())
    results = {}
    for label, overrides in (("board", {"calibration": {"method": "board"}}), ("board+wand", None)):
        t0 = time.perf_counter()
        results[label] = analyze_bundle(ride, meta_overrides=overrides)
        out[label] = {**_ride_errors(results[label], truth), "analyse_s": round(time.perf_counter() - t0, 1)}
    choice = results["board+wand"]["calibration"]["wand_refinement"]
    scene = build_scene(gait="canter", seed=seed, rig="wide_partial", size=size, board_band=band,
                        speed_range_m_s=(4.0, 6.0), calibration_poses=30, extras=False)
    out["board"]["beyond_reach"] = _beyond_reach_share(scene, choice["board"]["reach_px"])
    kept = choice["refined"] if choice["kept"] else choice["board"]
    out["board+wand"]["beyond_reach"] = _beyond_reach_share(scene, kept["reach_px"])
    out["board+wand"]["calibration_s"] = results["board+wand"]["timings_s"].get("calibration")
    out["board"]["calibration_s"] = results["board"]["timings_s"].get("calibration")
    out["refinement"] = choice
    return {"wand_refines_band_rendered": out}

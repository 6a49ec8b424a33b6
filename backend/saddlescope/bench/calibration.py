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

__all__ = ["calibration_check_clips_s", "calibration_stage_s", "calibration_vs_decode"]


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
                      **({"duration_s": 3.0, "calibration_poses": 40} if quick else {}))
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
    from saddlescope.services.calibration_check import check_calibration_clips

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


if __name__ == "__main__":  # python -m saddlescope.bench.calibration RIDE [REPEATS]: one line of JSON
    print(json.dumps(calibration_stage_s(Path(sys.argv[1]), repeats=int(sys.argv[2]) if len(sys.argv) > 2 else 1)))

"""Write a synthetic ride bundle (CONTRACTS section 1) with its exact answer, truth.json.

The geometry, motion and frames come from :mod:`saddlescope.arena`; this module only
encodes the clips (H.264 MP4) and writes ride.json and truth.json.
"""

from __future__ import annotations

import json
from pathlib import Path

from saddlescope.arena import RenderOptions, build_scene, build_truth, render_clip_frames, ride_manifest
from saddlescope.core.errors import InputError
from saddlescope.io.video_writer import write_h264


def dump_json(data: dict, path: Path) -> None:
    """Deterministic JSON (same data -> same bytes)."""
    path.write_text(json.dumps(data, indent=1, allow_nan=False) + "\n", encoding="utf-8")


def write_ride_bundle(
    out_dir: Path,
    *,
    gait: str = "canter",
    seed: int = 0,
    rig: str = "thesis",
    size: tuple[int, int] | None = None,
    fps: float | None = None,
    duration_s: float | None = None,
    calibration_poses: int = 90,
    extras: bool = True,
    crf: int | None = None,
    options: RenderOptions | None = None,
    board_band: float | None = None,
    speed_range_m_s: tuple[float, float] | None = None,
    passes: int | None = None,
    on_progress=None,
) -> Path:
    """Render and write a synthetic ride bundle into ``out_dir``; returns out_dir.

    Writes ride.json, truth.json and {calibration, plumb, static, motion}/{left, middle, right}.mp4,
    plus freefall/ and board_distance/ when ``extras`` (listed in ride.json "extra_clips").
    ``calibration_poses`` (default 90, as the thesis) and ``extras=False`` make small bundles for
    tests; ``board_band`` and ``speed_range_m_s`` are :func:`~saddlescope.arena.build_scene`'s (a
    board carried only through the middle of the volume, a faster canter); ``on_progress(fraction,
    stage)`` is called after each clip. ``crf`` overrides the compression the ride's options ask for
    (``RenderOptions.crf``, 20 by default; 28 is a phone's). ``passes`` (1-6, default the options', 1)
    films a ride of that many passes in front of the cameras in the one motion clip (issue 38).
    """
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a folder")
    scene = build_scene(
        gait=gait,
        seed=seed,
        rig=rig,
        size=size,
        fps=fps,
        duration_s=duration_s,
        calibration_poses=calibration_poses,
        extras=extras,
        options=options,
        board_band=board_band,
        speed_range_m_s=speed_range_m_s,
        passes=passes,
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    crf = scene.options.crf if crf is None else int(crf)
    manifest = ride_manifest(scene)
    jobs = [
        (kind, role, rel)
        for group in ("clips", "extra_clips")
        for kind, paths in manifest.get(group, {}).items()
        for role, rel in paths.items()
    ]
    for i, (kind, role, rel) in enumerate(jobs):
        path = out_dir / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        timing = scene.timings[kind]
        stamps = timing.frame_times(role) if role in timing.late_s else None
        n = write_h264(path, render_clip_frames(scene, role, kind), fps=scene.fps, crf=crf, frame_times_s=stamps)
        if n != scene.timings[kind].n_frames[role]:
            raise InputError(f"{rel}: wrote {n} frames, expected {scene.timings[kind].n_frames[role]}")
        if on_progress is not None:
            on_progress((i + 1) / len(jobs), f"{kind}/{role}")
    dump_json(manifest, out_dir / "ride.json")
    truth = build_truth(scene)
    truth["truth"]["nuisances"]["crf"] = crf  # what the clips were written with
    dump_json(truth, out_dir / "truth.json")
    return out_dir


__all__ = ["write_ride_bundle", "dump_json"]

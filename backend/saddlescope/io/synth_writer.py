"""Write a synthetic ride bundle (CONTRACTS section 1) with its exact answer, truth.json.

The geometry, motion and frames come from :mod:`saddlescope.arena`; this module only
encodes the clips (H.264 MP4) and writes ride.json and truth.json.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

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
    calibration: str = "board",
    wand_s: float = 24.0,
    wand_length_m: float = 1.0,
    close_up_poses: int = 30,
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

    ``calibration="wand"`` writes a wand calibration instead of the board walk (issue 35): ``wand/`` (a
    wand of ``wand_length_m`` waved through the volume for ``wand_s`` seconds, after a sync flash) and
    ``close_up/`` (``close_up_poses`` frames of an A3 board held close to each camera), ride.json's
    ``calibration`` ``{"method": "wand", "wand_length_m": ...}`` and the close-up board as its ``board``.
    ``calibration="board+wand"`` keeps the board walk and adds ``wand/``: the wand walked along the stretch of
    track the horse's markers cross (``wand_path(track_x_m=...)``), ride.json's ``calibration``
    ``{"method": "board+wand", "wand_length_m": ...}``.
    """
    if calibration not in ("board", "wand", "board+wand"):
        raise InputError(f"calibration {calibration!r} is not 'board', 'wand' or 'board+wand'")
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a folder")
    scene = build_scene(gait=gait, seed=seed, rig=rig, size=size, fps=fps, duration_s=duration_s,
                        calibration_poses=calibration_poses, extras=extras, options=options, board_band=board_band,
                        speed_range_m_s=speed_range_m_s, passes=passes)
    out_dir.mkdir(parents=True, exist_ok=True)
    crf = scene.options.crf if crf is None else int(crf)
    manifest = ride_manifest(scene)
    if calibration == "wand":
        manifest["clips"].pop("calibration")
    _write_clips(out_dir, scene, manifest, crf=crf, on_progress=on_progress)
    if calibration != "board":
        _write_wand_clips(out_dir, scene, manifest, crf=crf, wand_s=wand_s, length_m=wand_length_m,
                          close_up_poses=close_up_poses if calibration == "wand" else None)
    dump_json(manifest, out_dir / "ride.json")
    truth = build_truth(scene)
    truth["truth"]["nuisances"]["crf"] = crf  # what the clips were written with
    dump_json(truth, out_dir / "truth.json")
    return out_dir


def _write_clips(out_dir: Path, scene, manifest: dict, *, crf: int, on_progress=None) -> None:
    """Every clip the manifest lists (clips and extra clips), each checked for its frame count."""
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


def _track_stretch_m(scene) -> tuple[float, float]:
    """The stretch of track (world x, m) the horse's markers cross in the motion clip."""
    x = scene.contents["motion"].markers_w(scene.timings["motion"].frame_times("left"))[..., 0]
    return float(np.nanmin(x)), float(np.nanmax(x))


def _write_wand_clips(out_dir: Path, scene, manifest: dict, *, crf: int, wand_s: float, length_m: float,
                      close_up_poses: int | None) -> None:
    """The wand's clips (``wand/``, and ``close_up/`` unless ``close_up_poses`` is None) and their part of ride.json.

    With close-ups, a wand calibration (the wand waved through the calibration volume); without, the wand that
    refines the board walk (``board+wand``), walked along the track the horse takes.
    """
    from saddlescope.arena.wand import (
        CLOSE_UP_BOARD,
        render_close_up_frames,
        render_wand_clip,
        wand_clip_timing,
        wand_path,
    )
    from saddlescope.core.calibration.boards import board_to_meta

    rng = np.random.default_rng([scene.seed, 0x3A9D])
    path_fps = 10.0  # the path's own sampling (smooth): the clip is rendered at the rig's rate from it
    track = _track_stretch_m(scene) if close_up_poses is None else None
    path = wand_path(scene.rig, rng, n_frames=max(int(round(wand_s * path_fps)), 20), fps=path_fps, length_m=length_m,
                     track_x_m=track)
    timing = wand_clip_timing(path, rng, fps=scene.fps)
    for role in scene.rig.cameras:
        clips = [("wand", render_wand_clip(scene.rig, path, timing, role, rng=rng))]
        if close_up_poses is not None:
            clips.append(("close_up", render_close_up_frames(scene.rig, role, rng=rng, n_poses=close_up_poses)))
        for kind, frames in clips:
            rel = f"{kind}/{role}.mp4"
            (out_dir / rel).parent.mkdir(parents=True, exist_ok=True)
            write_h264(out_dir / rel, frames, fps=scene.fps, crf=crf)
            manifest["clips"].setdefault(kind, {})[role] = rel
    if close_up_poses is not None:
        manifest["board"] = board_to_meta(CLOSE_UP_BOARD)
    manifest["calibration"] = {"method": "wand" if close_up_poses is not None else "board+wand",
                               "wand_length_m": float(length_m)}
    manifest["frames"]["wand"] = dict(timing.n_frames)


__all__ = ["write_ride_bundle", "dump_json"]

"""Calibration from files: frames from videos or image globs, the ``calibrate`` command, TOML/JSON I/O.

- :func:`calibrate_sources` is the body of ``saddlescope calibrate``: one source per camera (a video,
  a folder of numbered images, or an image glob such as ``"calib/left_*.png"``); one camera gives
  intrinsics, two or more also extrinsics (stereo pairs + joint bundle adjustment).
- the ``calibration`` object of the result JSON is written and read by
  :mod:`saddlescope.io.rig_document` (one serialiser for results, rigs and this command).
- :func:`write_anipose_toml` / :func:`read_anipose_toml`: the TOML of anipose / aniposelib, which
  Pose2Sim and FreeMoCap also read: one ``[cam_N]`` table per camera with ``name``, ``size``
  ([width, height]), ``matrix`` (3x3), ``distortions`` (k1, k2, p1, p2, k3), ``rotation`` (Rodrigues
  vector, 3) and ``translation``, world to camera ``x_c = R X + t``. anipose keeps translations in the
  unit of its board's square (usually mm); Pose2Sim's ``Calib.toml`` uses metres: pass ``units="m"``.
- :func:`rig_from_caliscope_toml`: caliscope's ``camera_array.toml`` / ``config.toml`` (rotation as a
  3x3 matrix, translation in metres, world to camera) and :func:`board_from_caliscope_toml` for its
  ``charuco.toml``.

Every rig read is re-expressed relative to its first camera (SaddleScope's convention: the first /
left camera at identity, ``x_cam = R @ x_first + t_mm``).
"""

from __future__ import annotations

import glob
import json
import math
import re
import time
import tomllib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from saddlescope.core.calibration import (
    BoardFinder,
    BoardView,
    calibrate_intrinsics,
    calibrate_rig,
    select_instants,
)
from saddlescope.core.calibration.boards import DEFAULT_BOARD_KIND, board_to_meta, charuco, make_board
from saddlescope.core.calibration.detection import squares_hint
from saddlescope.core.calibration.wand import calibrate_wand, track_wand_ends
from saddlescope.core.errors import CalibrationError, InputError, SyncError, VideoError
from saddlescope.core.findings import Finding
from saddlescope.core.sync import flash_interval, offsets_from_intervals
from saddlescope.core.types import Board, Camera, Rig
from saddlescope.io.rig_document import checked_matrix, distortion5, rig_to_dict
from saddlescope.io.video import IMAGE_SUFFIXES, frame_brightness, iter_gray_frames, probe_video

_GLOB_CHARS = set("*?[")


# --------------------------------------------------------------------------------------------------
# Sources: videos, image folders, image globs
# --------------------------------------------------------------------------------------------------


def _natural_key(path: str):
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", path)]


def source_images(source: str) -> list[str] | None:
    """Image files of an image glob (or one image path), naturally sorted; None for a video/folder."""
    if _GLOB_CHARS & set(source):
        return sorted(glob.glob(source), key=_natural_key)
    if Path(source).suffix.lower() in IMAGE_SUFFIXES and Path(source).is_file():
        return [source]
    return None


def iter_source_frames(source: str, *, camera: str, start: int = 0, step: int = 1
                       ) -> Iterator[tuple[int, np.ndarray]]:
    """Yield (index, grey frame (H, W) uint8) from a video, an image folder or an image glob.

    Raises
    ------
    InputError
        An image glob matching nothing.
    VideoError
        Unreadable or truncated files, naming the camera.
    """
    images = source_images(source)
    if images is None:
        try:
            yield from iter_gray_frames(source, start=start, step=step)
        except VideoError as exc:
            raise VideoError(f"calibration clip of the {camera} camera: {exc}") from None
        return
    if not images:
        raise InputError(f"calibration source of the {camera} camera: no file matches {source!r}")
    for i in range(start, len(images), step):
        img = cv2.imread(images[i], cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise VideoError(f"calibration image of the {camera} camera {images[i]}: not a readable image")
        yield i, img


def _probe(source: str, camera: str) -> dict:
    images = source_images(source)
    if images is not None:
        if not images:
            raise InputError(f"calibration source of the {camera} camera: no file matches {source!r}")
        return {"kind": "images", "frame_count": len(images), "fps": None}
    try:
        info = probe_video(source)
    except VideoError as exc:
        raise VideoError(f"calibration clip of the {camera} camera: {exc}") from None
    return {"kind": "video", "frame_count": info.frame_count, "fps": info.fps,
            "size": (info.width, info.height)}


def detect_source_views(source: str, board: Board, *, camera: str, start: int = 0, step: int = 1,
                        key_offset: int = 0, inverted: bool | None = None
                        ) -> tuple[list[BoardView], tuple[int, int] | None, int]:
    """Board views in a source's frames start, start + step, ...

    Each view's ``frame`` is the frame index minus ``key_offset`` (the sync offset, so that views of
    different cameras at the same instant share a key).

    Returns
    -------
    views, image_size (width, height), number of frames searched

    Raises
    ------
    InputError
        Frames of different sizes in one source (naming the camera and frame).
    """
    # still images are few: search each thoroughly; video frames are many: the quick detectors
    finder = BoardFinder(board, inverted=inverted, thorough=source_images(source) is not None)
    views: list[BoardView] = []
    size = None
    n = 0
    for index, gray in iter_source_frames(source, camera=camera, start=start, step=step):
        n += 1
        this = (int(gray.shape[1]), int(gray.shape[0]))
        if size is None:
            size = this
        elif this != size:
            raise InputError(f"calibration source of the {camera} camera: frame {index} is "
                             f"{this[0]}x{this[1]} px but earlier frames are {size[0]}x{size[1]} px")
        found = finder(gray)
        if found is not None:
            views.append(BoardView(int(index) - key_offset, found[0], found[1]))
    return views, size, n


# --------------------------------------------------------------------------------------------------
# The `calibrate` command
# --------------------------------------------------------------------------------------------------


def _sync_offsets(sources: Mapping[str, str], probes: Mapping[str, dict], sync) -> tuple[dict, dict]:
    """Integer frame offsets per camera for the calibration clips, and a description for the report."""
    cams = list(sources)
    zero = {c: 0.0 for c in cams}
    if len(cams) == 1:
        return zero, {"method": "single camera"}
    if isinstance(sync, Mapping):
        missing = [c for c in cams if c not in sync]
        if missing:
            raise SyncError(f"calibration clip: no sync offset given for camera(s) {', '.join(missing)}")
        ref = float(sync[cams[0]])
        return {c: float(sync[c]) - ref for c in cams}, {"method": "offsets"}
    kinds = {p["kind"] for p in probes.values()}
    if sync == "none" or kinds == {"images"}:
        return zero, {"method": "none", "note": "frames paired by their index in each source"}
    if sync not in ("auto", "flash"):
        raise InputError(f"sync {sync!r} is not 'auto', 'flash', 'none' or a dict of offsets")
    if "images" in kinds:
        raise InputError("calibration sources mix videos and image globs: their frames cannot be paired")
    intervals, errors = {}, {}
    for cam, src in sources.items():
        try:
            brightness = frame_brightness(src)
        except VideoError as exc:
            raise VideoError(f"calibration clip of the {cam} camera: {exc}") from None
        try:
            intervals[cam] = flash_interval(brightness, clip="calibration", camera=cam)
        except SyncError as exc:
            errors[cam] = str(exc)
    if not intervals and sync == "auto":
        return zero, {"method": "none", "note": "no sync flash in any calibration clip: clips taken as "
                                                "already synchronised (frame k of each is the same instant)"}
    if errors:
        raise SyncError(next(iter(errors.values())))
    offsets = offsets_from_intervals(intervals, reference=cams[0])
    return offsets, {"method": "flash", "offsets": dict(offsets)}


def calibrate_sources(sources: Mapping[str, str], *, pattern: tuple[int, int], square_mm: float,
                      board_kind: str = DEFAULT_BOARD_KIND, board_options: Mapping[str, Any] | None = None,
                      toml_out: str | Path | None = None,
                      fix_k3: bool | None = None, max_views: int = 60, max_candidates: int = 300,
                      sync: str | Mapping[str, float] = "auto", inverted: bool | None = None,
                      same_size: bool = True,
                      intrinsics: Mapping[str, Camera] | None = None) -> dict:
    """Calibrate cameras from their sources; the body of ``saddlescope calibrate``.

    Parameters
    ----------
    sources : dict camera name -> video path, image folder, or image glob (the first camera is the
        reference of the extrinsics)
    pattern : (cols, rows)
        Inner corners of the board (OpenCV's pattern size). For ChArUco too: a board of 5 x 7 squares
        is pattern (4, 6).
    square_mm : float
    board_kind : one of :data:`~saddlescope.core.calibration.boards.BOARD_KINDS`
    board_options : the kind's own fields (ChArUco's dictionary, marker_mm, legacy; ``GET /api/board-types``)
    inverted : ChArUco printed white-on-black; None tries both.
    toml_out : path, optional
        Also write an anipose-style TOML (mm).
    max_views : int
        At most this many instants are used, chosen to spread the board over each image and its tilts.
    max_candidates : int
        Videos are sampled at about this many frames (every k-th frame).
    sync : "auto", "flash", "none" or dict camera -> offset in frames
        How to pair frames of different videos: "auto" measures the sync flash and, when no clip has
        one, takes the clips as already synchronised. Image globs are paired by their sorted order.
    same_size : bool
        Require every camera to have the same image size (SaddleScope's three identical cameras).
    intrinsics : dict camera name -> Camera, optional
        Known intrinsics of some cameras (:func:`read_intrinsics`): held, only those cameras' poses fitted.

    Returns
    -------
    dict
        :func:`rig_to_dict` (``cameras`` with each ``lens_model``, ``extrinsics``, ``checks``, ``flags``,
        ``pairs``) plus ``board``, ``sync``, ``views`` (per camera: searched, detected, used, partial, dropped
        frames, residual std) and ``timings_s``.
    """
    t0 = time.perf_counter()
    if not sources:
        raise InputError("no camera given: use --camera NAME=SOURCE")
    board = make_board(board_kind, pattern, square_mm, **dict(board_options or {}))
    sources = {str(k): str(v) for k, v in sources.items()}
    frames = _common_frames(sources, sync, max_candidates)
    t_sync = time.perf_counter()
    views, sizes, searched = _detect_sources(sources, board, frames, inverted=inverted, same_size=same_size)
    t_detect = time.perf_counter()
    chosen = set(select_instants(views, board, sizes, max_instants=max_views))
    used = {cam: [v for v in vs if v.frame in chosen] for cam, vs in views.items()}
    rig, report = calibrate_rig(used, board, sizes, fix_k3=fix_k3, given_intrinsics=intrinsics)
    t_cal = time.perf_counter()

    result = _calibration_result(rig, report, board, frames, views, searched)
    result["timings_s"] = {"sync": t_sync - t0, "detection": t_detect - t_sync,
                           "calibration": t_cal - t_detect, "total": time.perf_counter() - t0}
    if toml_out:
        write_anipose_toml(rig, toml_out)
    return result


def _close_up_intrinsics(close_ups: Mapping[str, str], board: Board, max_views: int) -> dict[str, Camera]:
    """Each camera's lens from its close-up board clip (every camera alone, no poses)."""
    lenses = {}
    for cam, src in close_ups.items():
        probe = _probe(src, cam)
        step = max(1, math.ceil(probe["frame_count"] / 300))
        views, size, _ = detect_source_views(src, board, camera=cam, step=step)
        if size is None or not views:
            cols, rows = board.inner_corners
            raise CalibrationError(f"no calibration board ({board.kind} {cols}x{rows} inner corners) found in "
                                   f"the close-up clip of the {cam} camera ({src})")
        chosen = set(select_instants({cam: views}, board, {cam: size}, max_instants=max_views))
        lenses[cam], _ = calibrate_intrinsics([v for v in views if v.frame in chosen], board, size, camera=cam,
                                              clip="close-up")
    return lenses


def calibrate_wand_sources(sources: Mapping[str, str], *, wand_length_m: float,
                           intrinsics: Mapping[str, Camera] | None = None,
                           close_ups: Mapping[str, str] | None = None, board: Board | None = None,
                           sync: str | Mapping[str, float] = "auto", max_frames: int = 600, max_views: int = 40,
                           toml_out: str | Path | None = None) -> dict:
    """Calibrate cameras from a wand waved through the volume; the body of ``saddlescope calibrate --wand``.

    Parameters
    ----------
    sources : dict camera name -> the wand clip (video, image folder or glob); the first is the reference
    wand_length_m : float
        The distance between the wand's two markers' centres, metres.
    intrinsics : dict camera name -> Camera, optional
        Known lenses (:func:`read_intrinsics`).
    close_ups, board : optional
        Close-up board clips per camera for the lenses not given, and the board they show.
    max_frames : int
        The wand clips are sampled at about this many common frames.

    Returns
    -------
    dict
        :func:`rig_to_dict` plus ``wand`` (length, frames with both ends per camera, the adjustment's numbers),
        ``sync`` and ``timings_s``.
    """
    t0 = time.perf_counter()
    if not sources:
        raise InputError("no camera given: use --camera NAME=WAND_CLIP")
    sources = {str(k): str(v) for k, v in sources.items()}
    lenses = dict(intrinsics or {})
    need = [c for c in sources if c not in lenses]
    if need:
        if not close_ups or board is None or any(c not in close_ups for c in need):
            raise InputError(f"camera(s) {', '.join(need)} need their lenses: give a close-up board clip "
                             "(--close-up NAME=CLIP with --pattern and --square) or --intrinsics NAME=FILE")
        lenses.update(_close_up_intrinsics({c: close_ups[c] for c in need}, board, max_views))
    frames = _common_frames(sources, sync, max_frames)
    t_lens = time.perf_counter()
    views = {}
    for cam, src in sources.items():
        off = frames["offsets"][cam]
        shifted = ((i - off, g) for i, g in iter_source_frames(src, camera=cam, start=frames["first"] + off,
                                                                step=frames["step"]))
        views[cam] = track_wand_ends(shifted)
        if not views[cam]:
            raise CalibrationError(f"the wand's two ends were never both seen in the {cam} camera's clip ({src})")
    t_track = time.perf_counter()
    rig, report = calibrate_wand(views, lenses, wand_length_m * 1000.0)
    result = rig_to_dict(rig)
    result["wand"] = {"length_m": wand_length_m, "frames_with_both_ends": {c: len(v) for c, v in views.items()},
                      "first_pair": report["first_pair"], "bundle": report["bundle"]}
    result["sync"] = {**frames["sync_info"], "frame_offsets": frames["offsets"], "frame_step": frames["step"]}
    result["timings_s"] = {"lenses": t_lens - t0, "wand_ends": t_track - t_lens,
                           "calibration": time.perf_counter() - t_track, "total": time.perf_counter() - t0}
    if toml_out:
        write_anipose_toml(rig, toml_out)
    return result


def _common_frames(sources: Mapping[str, str], sync, max_candidates: int) -> dict:
    """How the sources' frames are paired.

    Returns ``offsets`` (int frames per camera), ``first`` (the first common frame), ``step`` (every
    k-th frame, about ``max_candidates`` of them) and ``sync_info`` (for the report).
    """
    probes = {cam: _probe(src, cam) for cam, src in sources.items()}
    fps = {c: p["fps"] for c, p in probes.items() if p["fps"]}
    if len(set(round(f, 3) for f in fps.values())) > 1:
        listing = ", ".join(f"{c} {f:g} fps" for c, f in fps.items())
        raise SyncError(f"calibration clips have different frame rates ({listing})")
    offsets, sync_info = _sync_offsets(sources, probes, sync)
    int_offsets = {c: int(round(o)) for c, o in offsets.items()}
    first = max(0, max(-o for o in int_offsets.values()))
    n_common = min(p["frame_count"] - int_offsets[c] for c, p in probes.items()) - first
    if n_common <= 0:
        raise SyncError("calibration clips do not overlap in time after applying the sync offsets "
                        f"{int_offsets}")
    step = max(1, math.ceil(n_common / max_candidates))
    return {"offsets": int_offsets, "first": first, "step": step, "sync_info": sync_info}


def _detect_sources(sources: Mapping[str, str], board: Board, frames: Mapping, *, inverted: bool | None,
                    same_size: bool) -> tuple[dict[str, list[BoardView]], dict[str, tuple[int, int]], dict[str, int]]:
    """Board views, image size and number of frames searched per camera, on the common frames.

    Raises
    ------
    VideoError
        A source without a readable frame.
    CalibrationError
        A camera that never sees the board.
    InputError
        Cameras of different image sizes where ``same_size``.
    """
    views, sizes, searched = {}, {}, {}
    offsets = frames["offsets"]
    for cam, src in sources.items():
        views[cam], size, searched[cam] = detect_source_views(
            src, board, camera=cam, start=frames["first"] + offsets[cam], step=frames["step"],
            key_offset=offsets[cam], inverted=inverted)
        if size is None:
            raise VideoError(f"calibration clip of the {cam} camera: no frame could be read from {src}")
        sizes[cam] = size
        if not views[cam]:
            cols, rows = board.inner_corners
            raise CalibrationError(f"no calibration board ({board.kind} {cols}x{rows} inner "
                                   f"corners) found in the calibration clip of the {cam} camera ({src})"
                                   + _squares_hint(src, board, cam, frames, inverted=inverted))
    if same_size and len(set(sizes.values())) > 1:
        listing = ", ".join(f"{c} {w}x{h}" for c, (w, h) in sizes.items())
        raise InputError(f"calibration cameras have different image sizes ({listing}); the rig needs "
                         f"cameras of one resolution")
    return views, sizes, searched


def _squares_hint(source: str, board: Board, camera: str, frames: Mapping, *, inverted: bool | None) -> str:
    """"; " and :func:`~saddlescope.core.calibration.detection.squares_hint` on a fifth of the candidate frames."""
    try:
        grays = (gray for _, gray in iter_source_frames(source, camera=camera, start=int(frames["first"]),
                                                        step=5 * int(frames["step"])))
        hint = squares_hint(grays, board, inverted=inverted)
    except (VideoError, InputError):
        return ""
    return f"; {hint}" if hint else ""


def _calibration_result(rig: Rig, report: dict, board: Board, frames: Mapping,
                        views: Mapping[str, list[BoardView]], searched: Mapping[str, int]) -> dict:
    """:func:`rig_to_dict` plus ``board``, ``sync``, ``views`` per camera and ``bundle``."""
    result = rig_to_dict(rig)
    result["board"] = board_to_meta(board)
    result["sync"] = {**frames["sync_info"], "frame_offsets": frames["offsets"], "frame_step": frames["step"]}
    result["views"] = {
        cam: {"searched": searched[cam], "detected": len(views[cam]),
              "used": report["intrinsics"][cam]["n_views"],
              "partial": report.get("n_partial_views", {}).get(cam, 0),
              "dropped_frames": report["intrinsics"][cam]["dropped_frames"],
              "residual_std_px": report["intrinsics"][cam]["residual_std_px"],
              "intrinsic_rms_px": report["intrinsics"][cam]["rms_px"]}
        for cam in views}
    if report["bundle"] is not None:
        keys = ("rms_px", "rms_px_by_camera", "n_observations", "n_dropped", "n_instants", "iterations")
        result["bundle"] = {k: report["bundle"][k] for k in keys}
    return result


# --------------------------------------------------------------------------------------------------
# TOML: anipose / Pose2Sim / FreeMoCap, caliscope
# --------------------------------------------------------------------------------------------------

_UNIT_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}


def _toml(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        v = float(value)
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    raise InputError(f"cannot write {type(value).__name__} to TOML")


def _relative_to_first(world: dict[str, tuple]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """World-to-camera poses (R, t) -> poses relative to the first camera."""
    names = list(world)
    R0, t0 = world[names[0]]
    out = {}
    for n, (R, t) in world.items():
        Rr = R @ R0.T
        out[n] = (Rr, t - Rr @ t0)
    return out


def write_anipose_toml(rig: Rig, path: str | Path, *, units: str = "mm") -> Path:
    """Write the rig as anipose's calibration TOML (``[cam_0]`` ... and ``[metadata]``).

    The world frame is the first camera's; translations in ``units`` ("mm" for anipose, "m" for
    Pose2Sim).
    """
    if units not in _UNIT_MM:
        raise InputError(f"units {units!r} not one of {', '.join(_UNIT_MM)}")
    scale = 1.0 / _UNIT_MM[units]
    lines = []
    for i, (name, cam) in enumerate(rig.cameras.items()):
        lines += [f"[cam_{i}]", f"name = {_toml(name)}",
                  f"size = {_toml([int(cam.image_size[0]), int(cam.image_size[1])])}",
                  f"matrix = {_toml(np.asarray(cam.K, np.float64))}",
                  f"distortions = {_toml(distortion5(cam.dist, f'camera {name} dist'))}",
                  f"rotation = {_toml(cam.rvec)}",
                  f"translation = {_toml(np.asarray(cam.t_mm, np.float64) * scale)}",
                  "fisheye = false", ""]
    rms = [c.rms_px for c in rig.cameras.values() if c.rms_px is not None]
    lines += ["[metadata]", f"adjusted = {_toml(bool(rig.checks.get('bundle_rms_px') is not None))}",
              f"error = {_toml(float(np.mean(rms)) if rms else 0.0)}", f"units = {_toml(units)}",
              'written_by = "saddlescope"']
    for k, v in rig.checks.items():
        lines.append(f"check_{k} = {_toml(float(v))}")
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _rotation(rot: np.ndarray, what: str) -> np.ndarray:
    """A Rodrigues vector (3,) or a rotation matrix (3, 3) as a matrix; checked to be a rotation."""
    if rot.size == 3:
        R = cv2.Rodrigues(checked_matrix(rot.ravel(), (3,), what))[0]
    else:
        R = checked_matrix(rot, (3, 3), what)
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-5) or np.linalg.det(R) < 0:
        raise InputError(f"{what} is not a rotation matrix")
    return R


def _load_toml(path: str | Path) -> dict:
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None


def read_anipose_toml(path: str | Path, *, units: str | None = None) -> Rig:
    """Read an anipose / aniposelib / Pose2Sim / FreeMoCap calibration TOML into a Rig.

    ``units`` of the translations: "mm" (anipose's default, board squares in mm), "m" (Pose2Sim),
    or None: taken from ``[metadata] units`` when present, else "mm".
    """
    data = _load_toml(path)
    meta = data.get("metadata", {}) if isinstance(data.get("metadata"), Mapping) else {}
    units = units or meta.get("units", "mm")
    if units not in _UNIT_MM:
        raise InputError(f"{path}: units {units!r} not one of {', '.join(_UNIT_MM)}")
    scale = _UNIT_MM[units]
    world, intr = {}, {}
    for key, c in data.items():
        if key == "metadata" or not isinstance(c, Mapping):
            continue
        name = str(c.get("name", key))
        if c.get("fisheye", False):
            raise InputError(f"{path}: camera {name} uses the fisheye model, which SaddleScope does "
                             f"not support")
        K = checked_matrix(c.get("matrix"), (3, 3), f"{path}: camera {name} matrix")
        dist = distortion5(c.get("distortions", [0, 0, 0, 0]), f"{path}: camera {name} distortions")
        size = c.get("size")
        if not isinstance(size, list) or len(size) != 2:
            raise InputError(f"{path}: camera {name} size must be [width, height]")
        rot = np.asarray(c.get("rotation", [0, 0, 0]), np.float64)
        R = _rotation(rot, f"{path}: camera {name} rotation")
        t = checked_matrix(c.get("translation", [0, 0, 0]), (3,), f"{path}: camera {name} translation") * scale
        world[name] = (R, t)
        intr[name] = (K, dist, (int(size[0]), int(size[1])))
    if not world:
        raise InputError(f"{path}: no camera tables found")
    rel = _relative_to_first(world)
    return Rig({n: Camera(n, intr[n][0], intr[n][1], intr[n][2], R=rel[n][0], t_mm=rel[n][1]) for n in world})


def rig_from_caliscope_toml(path: str | Path) -> Rig:
    """Read caliscope's ``camera_array.toml`` (``[cameras.N]``) or ``config.toml`` (``[cam_N]``).

    caliscope stores world-to-camera poses ``x_c = R X + t`` with R a 3x3 matrix and t in metres; the
    rig is re-expressed relative to the first camera that is not ignored, in mm. Cameras are named
    ``cam_<id>``.

    Raises
    ------
    InputError
        No cameras, or a camera without extrinsics (caliscope has not run its extrinsic stage).
    """
    data = _load_toml(path)
    if isinstance(data.get("cameras"), Mapping):
        tables = {f"cam_{k}": v for k, v in data["cameras"].items()}
    else:
        tables = {k: v for k, v in data.items() if re.fullmatch(r"cam_\d+", k) and isinstance(v, Mapping)}
    tables = dict(sorted(tables.items(), key=lambda kv: int(kv[0].split("_")[1])))
    world, intr = {}, {}
    for name, c in tables.items():
        if c.get("ignore", False):
            continue
        name = f"cam_{c.get('cam_id', name.split('_')[1])}"
        if "rotation" not in c or "translation" not in c:
            raise InputError(f"{path}: camera {name} has no extrinsics (rotation/translation); run "
                             f"caliscope's extrinsic calibration first")
        K = checked_matrix(c.get("matrix"), (3, 3), f"{path}: camera {name} matrix")
        dist = distortion5(c.get("distortions", [0, 0, 0, 0, 0]), f"{path}: camera {name} distortions")
        size = c.get("size")
        if not isinstance(size, list) or len(size) != 2:
            raise InputError(f"{path}: camera {name} size must be [width, height]")
        rot = np.asarray(c["rotation"], np.float64)
        R = _rotation(rot, f"{path}: camera {name} rotation")
        t = checked_matrix(c["translation"], (3,), f"{path}: camera {name} translation") * 1000.0
        world[name] = (R, t)
        intr[name] = (K, dist, (int(size[0]), int(size[1])), c.get("error"))
    if not world:
        raise InputError(f"{path}: no cameras found")
    rel = _relative_to_first(world)
    return Rig({n: Camera(n, intr[n][0], intr[n][1], intr[n][2], R=rel[n][0], t_mm=rel[n][1],
                          rms_px=None if intr[n][3] is None else float(intr[n][3])) for n in world})


def board_from_caliscope_toml(path: str | Path) -> tuple[Board, bool]:
    """The board of caliscope's ``charuco.toml`` (or the ``[charuco]`` table of ``config.toml``), and its polarity.

    ``columns`` x ``rows`` are squares; the square is ``square_size_override_cm`` when present, else
    ``board_width`` / ``columns`` in ``units``; markers are ``aruco_scale`` of a square.
    """
    data = _load_toml(path)
    c = data.get("charuco", data)
    try:
        cols, rows = int(c["columns"]), int(c["rows"])
        if c.get("square_size_override_cm"):
            square_mm = float(c["square_size_override_cm"]) * 10.0
        else:
            per_unit = {"inch": 25.4, "cm": 10.0, "mm": 1.0}[c.get("units", "inch")]
            square_mm = float(c["board_width"]) * per_unit / cols
        board = make_board(charuco.KIND, (cols - 1, rows - 1), square_mm, dictionary=str(c["dictionary"]),
                           marker_mm=float(c.get("aruco_scale", 0.75)) * square_mm)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{path}: not a caliscope ChArUco description ({exc})") from None
    return board, bool(c.get("inverted", False))


def _toml_flavour(data: Mapping) -> str:
    """"caliscope" (``[cameras.N]``, or ``[cam_N]`` with 3x3 rotations) or "anipose" (Rodrigues vectors)."""
    if isinstance(data.get("cameras"), Mapping):
        return "caliscope"
    tables = [v for v in data.values() if isinstance(v, Mapping) and "matrix" in v]
    if tables and all(np.asarray(t.get("rotation", [0, 0, 0]), dtype=object).size == 9 for t in tables):
        return "caliscope"
    return "anipose"


def _camera_spread(rig: Rig) -> float:
    """The largest distance between two camera centres, in the rig's translation unit."""
    centres = [-(cam.R.T @ np.asarray(cam.t_mm, np.float64)) for cam in rig.cameras.values()]
    return max((float(np.linalg.norm(a - b)) for a in centres for b in centres), default=0.0)


def read_calibration_toml(path: str | Path, *, units: str | None = None) -> tuple[Rig, list[Finding]]:
    """A calibration TOML of anipose, Pose2Sim, FreeMoCap or caliscope as a Rig in mm, with notes.

    caliscope's files (``[cameras.N]`` or 3x3 rotations) are in metres. anipose-style files are in
    ``units`` when given, else their ``[metadata] units``, else judged from the cameras' spread:
    Pose2Sim's ``Calib.toml`` (metres, no units stated) puts cameras a few units apart, anipose's
    (board squares in mm) hundreds to thousands: a spread under 50 is read as metres, with a note.

    Parameters
    ----------
    path : str or Path
        The TOML file.
    units : {"mm", "cm", "m"}, optional
        The translations' unit of an anipose-style file.

    Returns
    -------
    rig : Rig
        Translations in mm, relative to the first camera.
    notes : list of Finding
        How the units were chosen where the file did not state them (``calibration.units_guessed``).
    """
    data = _load_toml(path)
    name = Path(path).name
    if _toml_flavour(data) == "caliscope":
        return rig_from_caliscope_toml(path), []
    meta = data.get("metadata", {}) if isinstance(data.get("metadata"), Mapping) else {}
    if units or meta.get("units"):
        return read_anipose_toml(path, units=units), []
    rig_mm = read_anipose_toml(path, units="mm")
    spread = _camera_spread(rig_mm)
    if 0 < spread < 50.0:
        return (read_anipose_toml(path, units="m"),
                [Finding("calibration.units_guessed",
                         f"{name} states no units; its cameras are {spread:.2f} apart, so its translations were "
                         "read as metres (Pose2Sim's unit); set calibration_units in ride.json if they are not",
                         {"camera_spread": spread})])
    return rig_mm, [Finding("calibration.units_guessed",
                            f"{name} states no units; its translations were read as mm (anipose's usual unit, the "
                            f"cameras {spread:.0f} mm apart); set calibration_units in ride.json if they are not",
                            {"camera_spread_mm": spread})]


def _lens_of(name: str, entry: Mapping, what: str) -> Camera:
    """A camera's intrinsics from a ``{"K", "dist", "image_size"}`` object (the result document's camera)."""
    K = checked_matrix(entry.get("K"), (3, 3), f"{what}: camera {name} K")
    dist = distortion5(entry.get("dist", [0, 0, 0, 0, 0]), f"{what}: camera {name} dist")
    size = entry.get("image_size")
    if not isinstance(size, list | tuple) or len(size) != 2:
        raise InputError(f"{what}: camera {name} image_size must be [width, height]")
    return Camera(name, K, dist, (int(size[0]), int(size[1])))


def read_intrinsics(path: str | Path) -> dict[str, Camera]:
    """Cameras' intrinsics from an earlier calibration or a lens profile, by camera name.

    Reads an anipose / Pose2Sim / FreeMoCap / caliscope TOML (:func:`read_calibration_toml`), SaddleScope's
    calibration JSON (``saddlescope calibrate --json`` or a result's ``calibration``: ``cameras`` by name)
    or a JSON lens profile of one camera (``{"K": 3x3, "dist": [k1, k2, p1, p2, k3], "image_size": [w, h]}``,
    returned under the name "").

    Raises
    ------
    InputError
        A file that is none of these, or whose matrices are malformed.
    """
    path = Path(path)
    if path.suffix.lower() == ".toml":
        rig, _ = read_calibration_toml(path)
        return {n: Camera(n, c.K, c.dist, c.image_size) for n, c in rig.cameras.items()}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a TOML or JSON calibration ({exc})") from None
    if isinstance(data, Mapping) and isinstance(data.get("calibration"), Mapping):
        data = data["calibration"]  # a whole result document
    if isinstance(data, Mapping) and isinstance(data.get("cameras"), Mapping) and data["cameras"]:
        return {str(n): _lens_of(str(n), c, str(path)) for n, c in data["cameras"].items() if isinstance(c, Mapping)}
    if isinstance(data, Mapping) and "K" in data:
        return {"": _lens_of("", data, str(path))}
    raise InputError(f"{path}: no camera intrinsics found (expected 'cameras' with K, dist and image_size, "
                     "or one lens profile with K, dist and image_size)")


def intrinsics_for_cameras(specs: list[tuple[str, str]], cameras: list[str]) -> dict[str, Camera]:
    """Given intrinsics by camera from ``--intrinsics [NAME=]FILE`` options.

    ``NAME=FILE``: camera NAME's intrinsics are the file's camera of that name, or its only camera;
    ``FILE`` alone: every calibrated camera whose name the file has.

    Raises
    ------
    InputError
        A NAME that is not calibrated, or a file without a matching camera.
    """
    out: dict[str, Camera] = {}
    for name, file in specs:
        lenses = read_intrinsics(file)
        if name:
            if name not in cameras:
                raise InputError(f"--intrinsics {name}={file}: there is no camera {name} "
                                 f"(cameras: {', '.join(cameras)})")
            lens = lenses.get(name) or (next(iter(lenses.values())) if len(lenses) == 1 else None)
            if lens is None:
                raise InputError(f"{file} has no camera {name} (it has {', '.join(lenses)}): name one with a lens "
                                 "profile of one camera or a file that has this camera")
            out[name] = Camera(name, lens.K, lens.dist, lens.image_size)
            continue
        matched = [n for n in cameras if n in lenses]
        if not matched:
            raise InputError(f"{file} has none of the cameras {', '.join(cameras)} (it has {', '.join(lenses)}): "
                             "use --intrinsics NAME=FILE")
        out.update({n: Camera(n, lenses[n].K, lenses[n].dist, lenses[n].image_size) for n in matched})
    return out

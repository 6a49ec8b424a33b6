"""Use case: calibrate a rig once from its three calibration clips, for every ride of that rig.

The same code the pipeline runs inside `analyze_bundle` when a ride brings its own calibration clips
(`saddlescope.core.pipeline.synchronise` and `calibrate_from_clips`), so a ride analysed with the
rig's stored calibration gets the same numbers as `saddlescope analyze` on a bundle holding those
calibration clips.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from saddlescope.core.calibration.boards import board_from_meta
from saddlescope.core.calibration.wand import wand_length_problem
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.pipeline import (
    PipelineParams,
    calibrate_from_clips,
    frame_clocks,
    synchronise_clips,
)
from saddlescope.core.pipeline.wand_setup import calibrate_from_wand_clips, refine_from_wand_clips
from saddlescope.core.types import CAMERA_ROLES, Rig
from saddlescope.io.clip_source import BundleClips
from saddlescope.io.rig_document import rig_from_dict, rig_to_dict
from saddlescope.io.threads import single_threaded_numerics


def calibrate_clips(
    paths: Mapping[str, Path],
    *,
    board: Mapping[str, Any],
    sync: Mapping[str, Any] | None = None,
    params: PipelineParams | None = None,
    on_progress: Callable[[float, str], None] | None = None,
) -> dict[str, Any]:
    """Calibrate three cameras from their calibration clips.

    Parameters
    ----------
    paths : dict camera role -> Path
        The calibration clip of each camera (left, middle, right).
    board : dict
        ride.json's ``board`` section (kind, inner_corners, square_mm, ...).
    sync : dict, optional
        ride.json's ``sync`` section (default: the flash).

    Returns
    -------
    dict
        The result's ``calibration`` object (CONTRACTS section 2) plus ``n_views`` per camera.

    Raises
    ------
    CalibrationError
        A camera's clip is missing, or the board was not seen often enough.
    """
    return _board_walk(paths, None, board=board, wand_length_m=None, sync=sync, params=params,
                       on_progress=on_progress)


def calibrate_board_and_wand_clips(
    paths: Mapping[str, Path],
    wand_paths: Mapping[str, Path],
    *,
    board: Mapping[str, Any],
    wand_length_m: float,
    sync: Mapping[str, Any] | None = None,
    params: PipelineParams | None = None,
    on_progress: Callable[[float, str], None] | None = None,
) -> dict[str, Any]:
    """Calibrate three cameras from their board walk, refined by a wand where that helps (issue 35, ``board+wand``).

    As :func:`calibrate_clips`, then the wand's clips (``wand_paths``, filmed at once after a flash, the wand
    walked along the track) refine the poses and each lens's k1, k2; the refined rig is kept only where the
    checks it did not fit are no worse (:mod:`saddlescope.core.calibration.wand_refinement`). The calibration
    also holds ``wand_refinement`` (kept or not, why, its sentence), ``lens_coverage`` (where a kept
    refinement's lens is known) and ``wand`` (length, frames with both ends, where they went).

    Raises
    ------
    InputError
        A wand length outside `WAND_LENGTH_RANGE_M`; CalibrationError: a clip missing, the board not seen.
    """
    if problem := wand_length_problem(wand_length_m):
        raise InputError(problem)
    return _board_walk(paths, wand_paths, board=board, wand_length_m=float(wand_length_m), sync=sync, params=params,
                       on_progress=on_progress)


def _missing_clips(kind: str, paths: Mapping[str, Path]) -> None:
    missing = [role for role in CAMERA_ROLES if role not in paths]
    if missing:
        raise CalibrationError(f"no {kind} clip of the {', '.join(missing)} camera")


def _board_walk(paths: Mapping[str, Path], wand_paths: Mapping[str, Path] | None, *, board: Mapping[str, Any],
                wand_length_m: float | None, sync: Mapping[str, Any] | None, params: PipelineParams | None,
                on_progress: Callable[[float, str], None] | None) -> dict[str, Any]:
    """The board walk's calibration object, refined by the wand's clips where given."""
    _missing_clips("calibration", paths)
    sets = {"calibration": {role: Path(paths[role]) for role in CAMERA_ROLES}}
    if wand_paths is not None:
        _missing_clips("wand", wand_paths)
        sets["wand"] = {role: Path(wand_paths[role]) for role in CAMERA_ROLES}
    meta = {"board": dict(board), "sync": dict(sync or {"method": "flash"})}
    params = params or PipelineParams()
    if on_progress is not None:
        on_progress(0.0, "sync")
    with (BundleClips(sets) as clips, single_threaded_numerics()):  # a hand-over no pass took up is closed at the end
        offsets, first_frame, methods = synchronise_clips(clips, meta, list(sets))
        if wand_paths is not None and methods.get("wand") not in ("flash", "offsets"):
            raise CalibrationError("the wand clips show no sync flash: film the flash before walking the wand")
        clocks, _ = frame_clocks(clips, ["calibration"])
        if on_progress is not None:
            on_progress(0.2, "board views")
        board_model = board_from_meta(meta["board"])
        rig, report = calibrate_from_clips(
            clips, board_model, offsets["calibration"], first_frame["calibration"], params,
            clocks=clocks.get("calibration"),
            sync_from_board=methods["calibration"] == "motion",  # no flash: the board's motion
        )
        if "sync" in report:
            offsets["calibration"] = report.pop("sync").offsets
        if wand_paths is not None and wand_length_m is not None:
            if on_progress is not None:
                on_progress(0.7, "wand")
            rig, report = refine_from_wand_clips(clips, rig, report, board_model, 1000.0 * wand_length_m,
                                                 offsets["wand"], first_frame["wand"], params)
    calibration = rig_to_dict(rig)
    calibration["n_views"] = report.get("n_views")
    # Where the board has been in each image (the distortion is only known there): the rig page draws it.
    calibration["board_coverage"] = report.get("board_coverage")
    calibration["board_corners_px"] = report.get("board_corners_px")
    calibration["sync"] = {kind: {c: float(v) for c, v in offsets[kind].items()} for kind in sets}
    if wand_paths is not None:
        calibration["wand"] = {"length_m": wand_length_m, "frames_with_both_ends": report.get("wand_views"),
                               "coverage": report.get("wand_coverage"), "bundle": report.get("wand")}
        if report.get("lens_coverage"):  # a kept refinement: its lens is known where the wand's ends went too
            calibration["lens_coverage"] = report["lens_coverage"]
    return calibration


def calibrate_wand_clips(
    wand_paths: Mapping[str, Path],
    close_up_paths: Mapping[str, Path],
    *,
    board: Mapping[str, Any],
    wand_length_m: float,
    sync: Mapping[str, Any] | None = None,
    params: PipelineParams | None = None,
    on_progress: Callable[[float, str], None] | None = None,
) -> dict[str, Any]:
    """Calibrate three cameras from a wand calibration's clips (issue 35): as a ride bundle's ``wand`` way.

    ``wand_paths``: each camera's wand clip (filmed at once, after the flash); ``close_up_paths``: each
    camera's close-up board clip (``board`` is that board); ``wand_length_m`` between the markers' centres.
    Returns the result's ``calibration`` object plus ``n_views`` (close-up views), ``board_coverage`` (where
    the close-up boards reached), ``wand`` (length, frames with both ends, the adjustment's numbers).

    Raises
    ------
    InputError
        A wand length outside `WAND_LENGTH_RANGE_M` (core.calibration.wand); CalibrationError: a clip missing,
        the board or the wand not seen.
    """
    if problem := wand_length_problem(wand_length_m):
        raise InputError(problem)
    for kind, paths in (("wand", wand_paths), ("close-up", close_up_paths)):
        missing = [role for role in CAMERA_ROLES if role not in paths]
        if missing:
            raise CalibrationError(f"no {kind} clip of the {', '.join(missing)} camera")
    meta = {"sync": dict(sync or {"method": "flash"})}
    if on_progress is not None:
        on_progress(0.0, "sync")
    with (BundleClips({"wand": {r: Path(wand_paths[r]) for r in CAMERA_ROLES},
                       "close_up": {r: Path(close_up_paths[r]) for r in CAMERA_ROLES}}) as clips,
          single_threaded_numerics()):
        offsets, first_frame, methods = synchronise_clips(clips, meta, ["wand"])
        if methods.get("wand") not in ("flash", "offsets"):
            raise CalibrationError("the wand clips show no sync flash: film the flash before waving the wand")
        if on_progress is not None:
            on_progress(0.2, "lenses and wand")
        rig, report = calibrate_from_wand_clips(clips, board_from_meta(dict(board)), 1000.0 * float(wand_length_m),
                                                offsets["wand"], first_frame["wand"], params or PipelineParams())
    calibration = rig_to_dict(rig)
    calibration["n_views"] = report.get("n_views")
    calibration["board_coverage"] = report.get("board_coverage")
    calibration["board_corners_px"] = report.get("board_corners_px")
    calibration["wand"] = {"length_m": float(wand_length_m), "frames_with_both_ends": report.get("wand_views"),
                           "coverage": report.get("wand_coverage"), "bundle": report.get("wand")}
    calibration["sync"] = {"wand": {c: float(v) for c, v in offsets["wand"].items()}}
    return calibration


def rig_from_calibration(calibration: Mapping[str, Any]) -> Rig:
    """The `Rig` of a stored ``calibration`` object (as `calibrate_clips` returns)."""
    return rig_from_dict(calibration)


def calibration_quality(calibration: Mapping[str, Any]) -> dict[str, Any]:
    """The figures a user checks first: flags, metric checks and each camera's r.m.s. error."""
    return {
        "flags": list(calibration.get("flags") or []),
        "checks": dict(calibration.get("checks") or {}),
        "rms_px": {name: cam.get("rms_px") for name, cam in (calibration.get("cameras") or {}).items()},
        "ok": not calibration.get("flags"),
    }

"""A ride's rig from a wand calibration's clips (issue 35 item 3): the ``wand`` and ``close_up`` clip sets.

Or (the ``board+wand`` way) the board walk's rig refined by the ``wand`` clips: :func:`refine_from_wand_clips`.

Each camera's lens comes from its ``close_up`` clip (a small board filmed close to that camera alone, no
sync needed); the poses and the scale come from the ``wand`` clips, filmed by the cameras at once and
synchronised like every other clip set (the flash, or given offsets). The wand's ends are put on the
first camera's clock by interpolating each camera's track at the fractional frame the offset names: a
wand waved at 1 m/s moves 17 mm in half a frame at 30 fps, far more than the calibration's error.
"""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from saddlescope.core import calibration as calib
from saddlescope.core.calibration.wand import WandView, calibrate_wand, track_wand_ends
from saddlescope.core.calibration.wand_refinement import refine_board_rig
from saddlescope.core.errors import CalibrationError
from saddlescope.core.params import PipelineParams
from saddlescope.core.pipeline.inputs import ClipReader, Progress
from saddlescope.core.pipeline.setup import _per_camera_in_threads, board_corner_sample, board_coverage
from saddlescope.core.types import Board, Camera, Rig

__all__ = ["calibrate_from_wand_clips", "refine_from_wand_clips", "wand_coverage", "wand_on_reference_clock",
           "wand_views_from_clips"]

MAX_CLOSE_UP_VIEWS = 40  # views per lens: the close-up clip's board spread over the image


def wand_on_reference_clock(views: list[WandView], offset_frames: float) -> list[WandView]:
    """One camera's wand views at the first camera's frames: frame j is this camera's frame j + offset.

    Linear interpolation between the two frames around j + offset, only where both are in one followed
    segment (the ends' labels agree); elsewhere no view.
    """
    by_frame = {v.frame: v for v in views}
    if not by_frame:
        return []
    lo, hi = min(by_frame), max(by_frame)
    out = []
    for j in range(int(np.floor(lo - offset_frames)), int(np.ceil(hi - offset_frames)) + 1):
        k = j + offset_frames
        k0 = int(np.floor(k))
        a, b = by_frame.get(k0), by_frame.get(k0 + 1)
        w = k - k0
        if a is not None and w < 1e-9:
            out.append(WandView(j, a.ends_px.copy(), a.segment))
        elif a is not None and b is not None and a.segment == b.segment:
            out.append(WandView(j, (1 - w) * a.ends_px + w * b.ends_px, a.segment))
    return out


def wand_coverage(views: list[WandView], image_size: tuple[int, int]) -> dict:
    """The image region the wand's ends reached (convex hull) and its share of the image, as :func:`board_coverage`."""
    pts = np.concatenate([v.ends_px for v in views]).astype(np.float32)
    hull = cv2.convexHull(pts).reshape(-1, 2)
    return {"hull_px": hull.astype(float).round(1).tolist(),
            "area_fraction": float(cv2.contourArea(hull) / (image_size[0] * image_size[1]))}


def _close_up_lens(clips: ClipReader, cam: str, board: Board) -> tuple[Camera, list, tuple[int, int]]:
    """One camera's lens from its close-up board clip (the camera alone)."""
    frames = clips.gray_frames("close_up", cam)
    # each frame its own pose (the board held still, then moved): searched whole, not tracked from the last
    views, size = calib.detect_board_views(frames, board, track=False)
    size = size or clips.image_size("close_up", cam)
    if not views:
        cols, rows = board.inner_corners
        raise CalibrationError(f"no calibration board ({board.kind}, {cols}x{rows} inner corners) found in the "
                               f"close-up clip of the {cam} camera: film the board ride.json names close to it")
    chosen = set(calib.select_instants({cam: views}, board, {cam: size}, max_instants=MAX_CLOSE_UP_VIEWS))
    used = [v for v in views if v.frame in chosen]
    lens, _ = calib.calibrate_intrinsics(used, board, size, camera=cam, clip="close-up")
    return lens, used, size


def wand_views_from_clips(clips: ClipReader, offsets: Mapping[str, float], first_frame: Mapping[str, int],
                          params: PipelineParams, *, every_camera: bool = True) -> dict[str, list[WandView]]:
    """Each camera's wand ends in its ``wand`` clip, from the flash on, put on the first camera's clock.

    Raises
    ------
    CalibrationError
        With ``every_camera``, a camera whose clip never shows both ends (without, its list is empty).
    """
    cams = clips.cameras("wand")
    base = max(first_frame.get(c, 0) - int(round(offsets.get(c, 0.0))) for c in cams)

    def ends(cam: str) -> tuple[list[WandView], None]:
        start = max(0, base + int(round(offsets.get(cam, 0.0))))
        return track_wand_ends(clips.gray_frames("wand", cam, start=start)), None

    tracked = _per_camera_in_threads(cams, ends, None, params.threads)
    views = {c: wand_on_reference_clock(tracked[c][0], float(offsets.get(c, 0.0))) for c in cams}
    for cam in cams:
        if not views[cam] and every_camera:
            raise CalibrationError(f"the wand's two ends were never both seen in the wand clip of the {cam} camera "
                                   "(two bright markers, nothing else as bright in view)")
    return views


def calibrate_from_wand_clips(clips: ClipReader, board: Board, wand_length_mm: float, offsets: Mapping[str, float],
                              first_frame: Mapping[str, int], params: PipelineParams,
                              progress: Progress | None = None) -> tuple[Rig, dict]:
    """Calibrate the rig from the ``close_up`` clips (lenses) and the ``wand`` clips (poses and scale).

    Parameters
    ----------
    board : Board
        The board of the close-up clips (ride.json's ``board``).
    wand_length_mm : float
        The distance between the wand's two markers' centres.
    offsets, first_frame : mapping of camera
        The wand clip's frame offsets against the first camera and first frame after the flash.

    Returns
    -------
    rig : Rig
        Its checks hold the wand's length check (``wand_length_rms_mm``, ...).
    report : dict
        ``n_views`` (close-up views per camera), ``board_coverage`` (where the close-up boards reached:
        the lens is known there, the reach the lens check uses), ``wand_coverage``, ``wand_views`` (frames
        with both ends per camera, on the first camera's clock) and ``wand`` (the adjustment's numbers).
    """
    cams = clips.cameras("wand")
    missing = [c for c in cams if c not in clips.cameras("close_up")]
    if missing:
        raise CalibrationError(f"no close-up clip for the {', '.join(missing)} camera: each camera's lens comes from "
                               "the board filmed close to it")
    lenses = _per_camera_in_threads(cams, lambda c: _close_up_lens(clips, c, board), progress, params.threads)
    views = wand_views_from_clips(clips, offsets, first_frame, params)
    rig, report = calibrate_wand(views, {c: lenses[c][0] for c in cams}, wand_length_mm)
    sizes = {c: lenses[c][2] for c in cams}
    out = {"n_views": {c: len(lenses[c][1]) for c in cams},
           "board_coverage": {c: board_coverage(lenses[c][1], sizes[c]) for c in cams},
           "board_corners_px": {c: board_corner_sample(lenses[c][1]) for c in cams},
           "wand_coverage": {c: wand_coverage(views[c], sizes[c]) for c in cams},
           "wand_views": {c: len(views[c]) for c in cams}, "wand": report["bundle"],
           "method": "wand"}
    return rig, out


def refine_from_wand_clips(clips: ClipReader, rig: Rig, board_report: Mapping, board: Board, wand_length_mm: float,
                           offsets: Mapping[str, float], first_frame: Mapping[str, int], params: PipelineParams
                           ) -> tuple[Rig, dict]:
    """The board walk's rig refined by the ``wand`` clips where that helps (issue 35: the ``board+wand`` way).

    ``board_report``: :func:`~saddlescope.core.pipeline.setup.calibrate_from_clips`'s (its ``board_views``
    and ``board_coverage``); ``offsets`` and ``first_frame``: the wand clips'. The refinement and the choice
    are :func:`~saddlescope.core.calibration.wand_refinement.refine_board_rig`'s; a camera without wand
    clips keeps the board's lens and pose.

    Returns
    -------
    rig : Rig
        The refined rig, or the board's; its ``wand_refinement`` says which and why.
    report : dict
        ``board_report`` without its views, plus ``wand_coverage``, ``wand_views``, ``wand`` (the refinement's
        stages, where it ran), ``method`` "board+wand" and, where the refined rig is kept, ``lens_coverage``
        (where the board's corners and the wand's ends went: the ride's lens reach).
    """
    out = {k: v for k, v in board_report.items() if k != "board_views"}
    # a camera that never saw both ends keeps the board's lens (its refinement is then the other cameras')
    views = wand_views_from_clips(clips, offsets, first_frame, params, every_camera=False)
    hulls = {c: cov["hull_px"] for c, cov in (board_report.get("board_coverage") or {}).items()}
    refined, report = refine_board_rig(rig, board_report["board_views"], board, views, wand_length_mm,
                                       board_hull_px=hulls, max_square_error_pct=params.max_square_error_pct)
    sizes = {c: rig.cameras[c].image_size for c in views if c in rig.cameras}
    out.update({"wand_coverage": {c: wand_coverage(views[c], sizes[c]) for c in sizes if views[c]},
                "wand_views": {c: len(views[c]) for c in views},
                "wand": (report.get("refinement") or {}).get("bundle"), "method": "board+wand"})
    if "lens_coverage" in report:
        out["lens_coverage"] = report["lens_coverage"]
    return refined, out

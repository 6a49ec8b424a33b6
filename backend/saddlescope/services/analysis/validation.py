"""Use case: the thesis's validation experiments on a ride bundle's extra clips.

The clips are the free fall and the board distances, measured with the rig of that ride.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from saddlescope.core import calibration as calib
from saddlescope.core.calibration.boards import board_from_meta
from saddlescope.core.pipeline import still_views, synchronise
from saddlescope.core.types import Rig
from saddlescope.core.validation import board_point_distances, detect_spots, measure_free_fall
from saddlescope.io.bundle import open_bundle
from saddlescope.io.clip_source import BundleClips


def run_validation(bundle_path: Path | str, rig: Rig, *, board_points: dict | None = None) -> dict:
    """Free-fall gravity and board point distances from the bundle's ``extra_clips`` (those present)."""
    out: dict = {}
    with open_bundle(Path(bundle_path)) as bundle, BundleClips(bundle.extra_clip_paths) as clips:
        kinds = [k for k in ("freefall", "board_distance") if clips.has(k)]
        offsets, first = synchronise(clips, {"sync": {"method": "flash"}}, kinds)
        if "freefall" in kinds:
            cams = clips.cameras("freefall")
            spots = {c: detect_spots(clips.gray_frames("freefall", c, start=first["freefall"][c])) for c in cams}
            out["freefall"] = measure_free_fall(rig, spots, offsets["freefall"], clips.fps("freefall", cams[0]))
        if "board_distance" in kinds:
            board = board_from_meta(bundle.meta.get("board"))
            cols, rows = board.inner_corners
            points = board_points or {"A": (0, 0), "B": (cols - 1, 0), "C": (0, rows - 1), "D": (cols - 1, rows - 1)}
            views = {}
            for c in clips.cameras("board_distance"):
                found, _ = calib.detect_board_views(clips.gray_frames("board_distance", c,
                                                                      start=first["board_distance"][c]), board)
                off = offsets["board_distance"].get(c, 0.0)
                views[c] = [replace(v, frame=int(round(v.frame - off))) for v in still_views(found, 1)]
            out["board_distance"] = board_point_distances(rig, views, board, points)
    return out

"""Which way a rig is calibrated: the board walk, a wand with close-up boards, or both (issue 35, item 3).

The board walk refined by a wand (``board+wand``) is the way whenever a rig has both its board walk's and its
wand's clips and the wand's length: the refinement is kept only where it helps, so asking costs nothing but
the wand's tracking.

A rig's ``calibrate_rig`` job, its "Calibrate" request and the upload that completes a clip set all ask
the same question: with the clips the rig has, its board and its wand length, which way, and with which
clips? The answer names the clips' storage keys; a way that cannot run is refused in words.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal, cast

from saddlescope.core.errors import InputError
from saddlescope.core.types import CAMERA_ROLES
from saddlescope.db.repositories import Conflict

__all__ = ["CALIBRATION_WAYS", "CalibrationWay", "choose_calibration_way"]

CALIBRATION_WAYS = ("board", "wand", "board+wand")
Way = Literal["board", "wand", "board+wand"]


@dataclass(frozen=True)
class CalibrationWay:
    """How a rig is to be calibrated: ``board``, ``wand`` or ``board+wand``.

    The calibration clips; the wand and close-up clips; or the calibration clips refined by the wand clips.

    ``clips``: clip kind -> camera -> storage key of the clips it uses; ``wand_length_m`` for the ways with a wand.
    """

    method: Way
    clips: dict[str, dict[str, str]] = field(default_factory=dict)
    wand_length_m: float | None = None


def _cameras_of(recordings: Iterable) -> dict[str, dict[str, str]]:
    by_kind: dict[str, dict[str, str]] = {}
    for r in recordings:
        by_kind.setdefault(r.clip_kind, {})[r.camera_role] = r.path
    return by_kind


def _missing(kind: str, words: str, have: dict[str, str]) -> str | None:
    absent = [role for role in CAMERA_ROLES if role not in have]
    return f"the {words} of the {', '.join(absent)} camera{'s' if len(absent) > 1 else ''}" if absent else None


def _default_way(clips: dict[str, dict[str, str]], wand_length_m: float | None) -> Way:
    """The way a rig's clips allow without being asked: both with a wand's length, else the wand's, else the board's."""
    complete = {k for k in ("calibration", "wand", "close_up") if set(CAMERA_ROLES) <= set(clips.get(k, {}))}
    if wand_length_m is not None and {"calibration", "wand"} <= complete:
        return "board+wand"
    if wand_length_m is not None and {"wand", "close_up"} <= complete:
        return "wand"
    return "board"


def choose_calibration_way(rig, recordings: Iterable, method: str | None = None) -> CalibrationWay:
    """The way rig `rig` is calibrated with its clips `recordings`, and the clips it uses.

    `method` None: the board walk refined by the wand when the rig has its calibration and wand clips of all
    three cameras and a wand length; else the wand way when it has its wand and close-up clips and a wand
    length; else the board walk. Raises `InputError` (an unknown way, a wand way without its length) or
    `Conflict` (clips or the board missing), each in words a club can act on.
    """
    if method is not None and method not in CALIBRATION_WAYS:
        raise InputError(f"there is no {method!r} way to calibrate; choose 'board', 'wand' or 'board+wand'")
    clips = _cameras_of(recordings)
    label = f"rig {rig.id} ({rig.name})"
    way = _default_way(clips, rig.wand_length_m) if method is None else cast(Way, method)
    if not rig.board:
        what = "the close-up board" if way == "wand" else "the calibration board"
        raise Conflict(f"{label} cannot be calibrated yet: describe {what} its clips show (the board's size "
                       "and squares) first")
    if way == "board":
        missing = _missing("calibration", "calibration clip", clips.get("calibration", {}))
        if missing:
            raise Conflict(f"{label} cannot be calibrated with the board walk yet: upload {missing} first, "
                           "or calibrate with a wand")
        return CalibrationWay("board", {"calibration": clips["calibration"]})
    if rig.wand_length_m is None:
        raise InputError(f"{label}: give the wand's length first (in metres, between the centres of its two "
                         "markers, e.g. 1.0) to calibrate with a wand")
    kinds = ("wand", "close_up") if way == "wand" else ("calibration", "wand")
    words = {"wand": "wand clip", "close_up": "close-up clip", "calibration": "calibration clip"}
    missing_words = [m for k in kinds if (m := _missing(k, words[k], clips.get(k, {})))]
    if missing_words:
        how = "with a wand" if way == "wand" else "with the board walk refined by the wand"
        raise Conflict(f"{label} cannot be calibrated {how} yet: upload {' and '.join(missing_words)} first")
    return CalibrationWay(way, {k: clips[k] for k in kinds}, wand_length_m=float(rig.wand_length_m))

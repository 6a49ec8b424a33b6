"""Which way a rig is calibrated: the board walk, or a wand with close-up boards (issue 35, item 3).

A rig's ``calibrate_rig`` job, its "Calibrate" request and the upload that completes a clip set all ask
the same question: with the clips the rig has, its board and its wand length, which way, and with which
clips? The answer names the clips' storage keys; a way that cannot run is refused in words.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Literal

from saddlescope.core.errors import InputError
from saddlescope.core.types import CAMERA_ROLES
from saddlescope.db.repositories import Conflict

__all__ = ["CALIBRATION_WAYS", "CalibrationWay", "choose_calibration_way"]

CALIBRATION_WAYS = ("board", "wand")
Way = Literal["board", "wand"]


@dataclass(frozen=True)
class CalibrationWay:
    """How a rig is to be calibrated: ``board`` (calibration clips) or ``wand`` (wand and close-up clips).

    ``clips``: clip kind -> camera -> storage key of the clips it uses; ``wand_length_m`` for the wand way.
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


def choose_calibration_way(rig, recordings: Iterable, method: str | None = None) -> CalibrationWay:
    """The way rig `rig` is calibrated with its clips `recordings`, and the clips it uses.

    `method` None: the wand way when the rig has its wand and close-up clips of all three cameras and a
    wand length, else the board walk. Raises `InputError` (an unknown way, a wand way without its length)
    or `Conflict` (clips or the board missing), each in words a club can act on.
    """
    if method is not None and method not in CALIBRATION_WAYS:
        raise InputError(f"there is no {method!r} way to calibrate; choose 'board' or 'wand'")
    clips = _cameras_of(recordings)
    label = f"rig {rig.id} ({rig.name})"
    wand_ready = all(set(CAMERA_ROLES) <= set(clips.get(k, {})) for k in ("wand", "close_up"))
    if method is None:
        method = "wand" if wand_ready and rig.wand_length_m is not None else "board"
    if not rig.board:
        what = "the close-up board" if method == "wand" else "the calibration board"
        raise Conflict(f"{label} cannot be calibrated yet: describe {what} its clips show (the board's size "
                       "and squares) first")
    if method == "board":
        missing = _missing("calibration", "calibration clip", clips.get("calibration", {}))
        if missing:
            raise Conflict(f"{label} cannot be calibrated with the board walk yet: upload {missing} first, "
                           "or calibrate with a wand")
        return CalibrationWay("board", {"calibration": clips["calibration"]})
    if rig.wand_length_m is None:
        raise InputError(f"{label}: give the wand's length first (in metres, between the centres of its two "
                         "markers, e.g. 1.0) to calibrate with a wand")
    missing_words = [m for m in (_missing("wand", "wand clip", clips.get("wand", {})),
                                 _missing("close_up", "close-up clip", clips.get("close_up", {}))) if m]
    if missing_words:
        raise Conflict(f"{label} cannot be calibrated with a wand yet: upload {' and '.join(missing_words)} "
                       "first")
    return CalibrationWay("wand", {"wand": clips["wand"], "close_up": clips["close_up"]},
                          wand_length_m=float(rig.wand_length_m))

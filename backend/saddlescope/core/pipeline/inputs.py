"""What the pipeline reads and reports: the clips, and where progress goes.

The core opens no files: frames come from a :class:`ClipReader` (``saddlescope.io.clip_source``
provides one over a ride bundle), and progress goes to an ``on_progress(fraction, stage)`` callback so
the core never knows about jobs or queues.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol, cast

import numpy as np

from saddlescope.core.calibration.wand import wand_length_problem
from saddlescope.core.errors import InputError

__all__ = ["CALIBRATION_METHODS", "STAGE_WEIGHTS", "CalibrationSpec", "ClipReader", "Progress", "calibration_spec",
           "cameras_at_once"]

# How a ride's clips calibrate its rig (ride.json ``calibration.method``, issue 35): the board walk; a wand
# with close-up boards; or the board walk refined by a wand walked along the track.
CALIBRATION_METHODS: tuple[str, ...] = ("board", "wand", "board+wand")
CalibrationMethod = Literal["board", "wand", "board+wand"]


@dataclass(frozen=True)
class CalibrationSpec:
    """ride.json's ``calibration``: the way (:data:`CALIBRATION_METHODS`) and, with a wand, its length (m)."""

    method: CalibrationMethod = "board"
    wand_length_m: float | None = None

    @property
    def clip_kinds(self) -> tuple[str, ...]:
        """The clip sets the way calibrates from and synchronises (a wand's close-ups are each camera alone)."""
        return {"board": ("calibration",), "wand": ("wand",), "board+wand": ("calibration", "wand")}[self.method]

    @property
    def wand_length_mm(self) -> float | None:
        """The wand's length in mm (None: no wand)."""
        return None if self.wand_length_m is None else 1000.0 * self.wand_length_m


def calibration_spec(meta: Mapping[str, Any]) -> CalibrationSpec:
    """The typed ``calibration`` of ride.json (absent: the board walk), or an InputError saying what is wrong."""
    cal = meta.get("calibration")
    if cal is None:
        return CalibrationSpec()
    if not isinstance(cal, Mapping):
        raise InputError(f"ride.json: calibration must be an object such as {{\"method\": \"board+wand\", "
                         f"\"wand_length_m\": 1.0}}, got {cal!r}")
    method = cal.get("method", "board")
    if method not in CALIBRATION_METHODS:
        raise InputError(f"ride.json: calibration.method {method!r} is not one of {', '.join(CALIBRATION_METHODS)} "
                         "(the board walk; a wand with close-up boards; the board walk refined by a wand)")
    if method == "board":
        return CalibrationSpec()
    if cal.get("wand_length_m") is None:
        raise InputError(f"ride.json: calibration.method {method!r} needs calibration.wand_length_m, the distance "
                         "between the wand's two markers' centres in metres (e.g. 1.0)")
    if problem := wand_length_problem(cal["wand_length_m"]):
        raise InputError(f"ride.json: calibration.wand_length_m: {problem}")
    return CalibrationSpec(cast(CalibrationMethod, method), float(cal["wand_length_m"]))

# Share of the total progress each stage reports (rough wall-time shares on the thesis rig).
STAGE_WEIGHTS: dict[str, float] = {"sync": 0.15, "calibration": 0.35, "detection": 0.3,
                                   "triangulation": 0.05, "kinematics": 0.1, "indicators": 0.05}


def cameras_at_once(n_cameras: int, threads: int | None) -> int:
    """How many cameras' passes (decoder and search, one thread each) run at once within a thread budget.

    Every camera at once where the budget has more than one thread, up to twice the budget: three
    cameras on two cores then share them and finish together, where two at a time left the third to run
    alone on one core (makespan 1.5 against 2 cameras' time; issue 28). The threads cannot use more CPU
    than the budget's cores; memory stays bounded by the budget (a decoder and a frame per camera).
    A budget of one runs them one after another; None (no budget) runs every camera at once.
    """
    if threads is None:
        return max(1, n_cameras)
    return 1 if threads <= 1 else max(1, min(n_cameras, 2 * threads))


class ClipReader(Protocol):
    """What the pipeline needs of a ride's clips (``saddlescope.io.clip_source.BundleClips``)."""

    def has(self, kind: str) -> bool:
        """Whether the ride has clip set ``kind`` ("calibration", "plumb", "static", "motion")."""

    def cameras(self, kind: str) -> list[str]:
        """The cameras of clip set ``kind``, the reference (left) camera first."""

    def fps(self, kind: str, camera: str) -> float:
        """The clip's nominal frame rate."""

    def frame_count(self, kind: str, camera: str) -> int:
        """The clip's number of frames."""

    def image_size(self, kind: str, camera: str) -> tuple[int, int]:
        """The clip's (width, height) in pixels."""

    def brightness(self, kind: str, camera: str) -> np.ndarray:
        """Each frame's mean brightness, shape (F,): the sync flash is found in it.

        It may cover only the first F' <= F frames: up to a settled stretch after the flash.
        """

    def band_brightness(self, kind: str, camera: str) -> tuple[np.ndarray, np.ndarray]:
        """Each frame's brightness per band of rows, (F', B) over :meth:`brightness`'s frames.

        With each band's mean row height as a share of the image's height (B,), 0 top: a rolling shutter's flash
        sweeps down them.

        Optional: a reader without it gives no readout estimate (readouts then come from ride.json or are 0).
        """

    def frame_times(self, kind: str, camera: str) -> np.ndarray | None:
        """Each frame's timestamp (F,) s for a variable-rate clip (phones), None for an even one."""

    def gray_frames(self, kind: str, camera: str, start: int = 0, stop: int | None = None,
                    step: int = 1) -> Iterator[tuple[int, np.ndarray]]:
        """(frame index, grey image (H, W) uint8) from ``start`` to ``stop`` every ``step`` frames."""


@dataclass
class Progress:
    """Reports the whole analysis's progress as each stage's share of it, and times the stages."""

    callback: Callable[[float, str], None] | None
    done: float = 0.0
    timings_s: dict = field(default_factory=dict)

    def stage(self, name: str, fraction_of_stage: float) -> None:
        """Report ``fraction_of_stage`` (0-1) of stage ``name`` done."""
        if self.callback is not None:
            self.callback(min(1.0, self.done + STAGE_WEIGHTS[name] * fraction_of_stage), name)

    def finish(self, name: str, started: float, *, seconds: float | None = None) -> None:
        """Record stage ``name`` as done, timed from ``started`` (or ``seconds`` when given)."""
        self.timings_s[name] = round(time.perf_counter() - started if seconds is None else seconds, 4)
        self.done += STAGE_WEIGHTS[name]
        self.stage(name, 0.0)

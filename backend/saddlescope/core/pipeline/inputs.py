"""What the pipeline reads and reports: the clips, and where progress goes.

The core opens no files: frames come from a :class:`ClipReader` (``saddlescope.io.clip_source``
provides one over a ride bundle), and progress goes to an ``on_progress(fraction, stage)`` callback so
the core never knows about jobs or queues.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

__all__ = ["STAGE_WEIGHTS", "ClipReader", "Progress", "cameras_at_once"]

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

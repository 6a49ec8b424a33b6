"""Clip timing of the synthetic arena: frame counts, camera start offsets, the sync flash, phone clocks.

Every clip has its own clock, the left camera's: left frame k is at t = k / fps. Camera c's frame k
shows the instant t = (k - offset_c) / fps (offset = how many frames later an instant appears in that
camera). Frame instants are exposure midpoints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

__all__ = [
    "FLASH_PLATEAU_FRAMES",
    "FLASH_RAMP_FRAMES",
    "VFR_DROP_RATE",
    "VFR_JITTER_FRAMES",
    "ClipTiming",
    "clip_timing",
    "variable_rate",
]

FLASH_RAMP_FRAMES, FLASH_PLATEAU_FRAMES = 2.0, 1.5
VFR_JITTER_FRAMES = 0.2  # a phone's frame intervals wander by this much either way
VFR_DROP_RATE = 0.03  # and it drops this share of frames (a double interval)


@dataclass(frozen=True)
class ClipTiming:
    """Frame counts, per-camera offsets (frames) and the sync flash of one clip (left-clip seconds)."""

    kind: str
    fps: float
    n_left: int
    offsets: dict[str, float]
    n_frames: dict[str, int]
    flash_on_s: float
    flash_off_s: float
    flash_ramp_s: float
    content_start_s: float
    # per camera, how much later than its even clock each frame was taken (s): a phone's variable
    # frame rate (RenderOptions.variable_frame_rate); empty for even clips
    late_s: dict[str, np.ndarray] = field(default_factory=dict)

    def frame_times(self, role: str) -> np.ndarray:
        """Instants of every frame of camera ``role``.

        Returns
        -------
        ndarray of shape (n_frames[role],)
            Left-clip seconds.
        """
        even = (np.arange(self.n_frames[role]) - self.offsets[role]) / self.fps
        return even + self.late_s[role] if role in self.late_s else even

    @property
    def left_times(self) -> np.ndarray:
        """Instants of the left camera's frames, shape (n_left,), left-clip seconds."""
        return np.arange(self.n_left) / self.fps


def clip_timing(
    kind: str,
    rng: np.random.Generator,
    fps: float,
    content_s: float,
    *,
    total_s: float | None = None,
    min_total_s: float = 0.0,
) -> ClipTiming:
    """Random camera start offsets, a flash after every camera has started, then the content.

    The clip holds ``content_s`` of content after the flash (or lasts exactly ``total_s``, or at
    least ``min_total_s``).
    """
    off_s = rng.uniform(-0.15, 0.35, 2)
    offsets = {"left": 0.0, "middle": float(off_s[0] * fps), "right": float(off_s[1] * fps)}
    last_start = max(0.0, *(-o / fps for o in offsets.values()))
    ramp = FLASH_RAMP_FRAMES / fps
    on = last_start + float(rng.uniform(0.12, 0.22))
    off = on + ramp + FLASH_PLATEAU_FRAMES / fps
    content_start = off + ramp + 0.15
    if total_s is None:
        n_left = int(math.ceil(max(content_start + content_s, min_total_s) * fps - 1e-9))
    else:
        n_left = int(round(total_s * fps))
    n_frames = {"left": n_left}
    for role in ("middle", "right"):
        n_frames[role] = int(math.floor(n_left + offsets[role])) + int(rng.integers(0, 4))
    return ClipTiming(kind, fps, n_left, offsets, n_frames, on, off, ramp, content_start)


def variable_rate(timing: ClipTiming, rng: np.random.Generator) -> ClipTiming:
    """The middle and right cameras as phones at a variable frame rate.

    From two frames after the sync flash, each frame is late by its jitter plus the frames dropped
    before it. The left camera keeps the even clock that the truth is written on. The returned
    timing's ``late_s[role]`` has shape (n_frames[role],), seconds.
    """
    late = {}
    for role in ("middle", "right"):
        n = timing.n_frames[role]
        k0 = int(math.ceil((timing.flash_off_s + timing.flash_ramp_s) * timing.fps + timing.offsets[role])) + 2
        k = np.arange(n)
        dropped = np.cumsum(rng.random(n) < VFR_DROP_RATE)
        jitter = rng.uniform(-VFR_JITTER_FRAMES, VFR_JITTER_FRAMES, n)
        late[role] = np.where(k >= k0, (dropped - dropped[min(k0, n - 1)] + jitter) / timing.fps, 0.0)
    return replace(timing, late_s=late)

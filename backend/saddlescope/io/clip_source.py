"""The clips of a ride bundle as the core pipeline reads them (``core.pipeline.ClipReader``).

The core never opens files; this adapter gives it grey frames, brightness curves and clip facts,
probing each clip once and checking the three cameras of a clip set agree on fps and size.
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import cache
from pathlib import Path

import numpy as np

from saddlescope.core.errors import VideoError
from saddlescope.io.video import VideoInfo, frame_brightness, iter_gray_frames, probe_video


class BundleClips:
    """Clip reader over ``paths[kind][camera] -> Path`` (a video file or an image folder)."""

    def __init__(self, paths: dict[str, dict[str, Path]], *, fps_hint: float | None = None):
        self.paths = {kind: {cam: Path(p) for cam, p in cams.items()} for kind, cams in paths.items()}
        self.fps_hint = fps_hint
        self._info = cache(self._probe)
        self._brightness = cache(self._mean_brightness)

    def kinds(self) -> list[str]:
        return list(self.paths)

    def cameras(self, kind: str) -> list[str]:
        return list(self.paths.get(kind, {}))

    def has(self, kind: str) -> bool:
        return bool(self.paths.get(kind))

    def path(self, kind: str, camera: str) -> Path:
        try:
            return self.paths[kind][camera]
        except KeyError:
            raise VideoError(f"no {kind} clip for camera {camera}") from None

    def _probe(self, kind: str, camera: str) -> VideoInfo:
        try:
            return probe_video(self.path(kind, camera), fps_hint=self.fps_hint)
        except VideoError as exc:
            raise VideoError(f"{kind} clip of the {camera} camera: {exc}") from None

    def info(self, kind: str, camera: str) -> VideoInfo:
        return self._info(kind, camera)

    def fps(self, kind: str, camera: str) -> float:
        return self.info(kind, camera).fps

    def frame_times(self, kind: str, camera: str) -> np.ndarray | None:
        """Each frame's presentation time (s) for a variable-rate clip; None for an even one."""
        info = self.info(kind, camera)
        return info.frame_times_s if info.variable_frame_rate else None

    def frame_count(self, kind: str, camera: str) -> int:
        return self.info(kind, camera).frame_count

    def image_size(self, kind: str, camera: str) -> tuple[int, int]:
        info = self.info(kind, camera)
        return info.width, info.height

    def gray_frames(self, kind: str, camera: str, start: int = 0, stop: int | None = None,
                    step: int = 1) -> Iterator[tuple[int, np.ndarray]]:
        try:
            yield from iter_gray_frames(self.path(kind, camera), start=start, stop=stop, step=step)
        except VideoError as exc:
            raise VideoError(f"{kind} clip of the {camera} camera: {exc}") from None

    def _mean_brightness(self, kind: str, camera: str) -> np.ndarray:
        try:
            return frame_brightness(self.path(kind, camera))
        except VideoError as exc:
            raise VideoError(f"{kind} clip of the {camera} camera: {exc}") from None

    def brightness(self, kind: str, camera: str) -> np.ndarray:
        return self._brightness(kind, camera)

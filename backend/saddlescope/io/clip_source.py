"""The clips of a ride bundle as the core pipeline reads them (``core.pipeline.ClipReader``).

The core never opens files; this adapter gives it grey frames, brightness curves and clip facts,
probing each clip once (from its packets, no decoding) and caching what it learns per clip.

The sync flash is filmed at the start of a clip set, so a clip's brightness is read only until its
flash has been found and followed by a settled stretch (:func:`brightness_until_flash`): the stages
after sync start decoding after the flash, and the frames before it are the only ones decoded twice.
Decoder threads come out of the analysis's thread budget, shared by the clips decoded at once.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import closing, contextmanager
from functools import cache
from pathlib import Path

import numpy as np

from saddlescope.core.errors import SyncError, VideoError
from saddlescope.core.sync import MIN_FRAMES, flash_interval
from saddlescope.io.video import VideoInfo, iter_gray_frames, probe_video

__all__ = ["BundleClips", "brightness_until_flash"]

BRIGHTNESS_DOWNSCALE = 8  # every 8th pixel of every 8th row: the mean of a 1080p frame from 32k samples


def brightness_until_flash(frames, fps: float, *, clip: str, camera: str, min_s: float = 1.0,
                           settle_s: float = 0.5, check_every_s: float = 0.25) -> np.ndarray:
    """Mean brightness of each frame (F',) from ``frames`` ((index, grey image) from frame 0), read until
    the sync flash is found (:func:`saddlescope.core.sync.flash_interval`) with ``settle_s`` of frames
    after its end, and at least ``min_s`` read; the whole clip when no flash is found (known offsets).

    A flash is looked for every ``check_every_s``; the first bright interval that passes the flash
    detector's tests wins, where the whole clip would give the largest rise: a sync flash is filmed
    first, before the ride, so the two agree on a clip filmed as docs/filming.md asks.
    """
    values: list[float] = []
    check_at = max(MIN_FRAMES, int(round(min_s * fps)))
    settle = max(5, int(round(settle_s * fps)))
    for _, img in frames:
        values.append(float(img[::BRIGHTNESS_DOWNSCALE, ::BRIGHTNESS_DOWNSCALE].mean()))
        if len(values) >= check_at:
            check_at += max(1, int(round(check_every_s * fps)))
            try:
                _, end = flash_interval(np.asarray(values), clip=clip, camera=camera)
            except SyncError:
                continue
            if len(values) - end >= settle:
                break
    return np.asarray(values, dtype=np.float64)


class BundleClips:
    """Clip reader over ``paths[kind][camera] -> Path`` (a video file or an image folder)."""

    def __init__(self, paths: dict[str, dict[str, Path]], *, fps_hint: float | None = None,
                 threads: int | None = None, whole_clip_brightness: bool = False):
        """``threads``: the decoders' share of the thread budget (None: FFmpeg's choice); the clips
        decoded at once split it. ``whole_clip_brightness``: read every frame's brightness, not only
        up to the flash."""
        self.paths = {kind: {cam: Path(p) for cam, p in cams.items()} for kind, cams in paths.items()}
        self.fps_hint = fps_hint
        self.threads = threads
        self.whole_clip_brightness = whole_clip_brightness
        self._info = cache(self._probe)
        self._brightness = cache(self._mean_brightness)
        self._lock = threading.Lock()
        self._open_decoders = 0

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
            return probe_video(self.path(kind, camera), fps_hint=self.fps_hint, decode_tail=False)
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

    @contextmanager
    def _decoder_threads(self) -> Iterator[int | None]:
        """This decoder's share of the budget: the budget over the decoders open now (this one too)."""
        with self._lock:
            self._open_decoders += 1
            share = None if self.threads is None else max(1, self.threads // self._open_decoders)
        try:
            yield share
        finally:
            with self._lock:
                self._open_decoders -= 1

    def gray_frames(self, kind: str, camera: str, start: int = 0, stop: int | None = None,
                    step: int = 1) -> Iterator[tuple[int, np.ndarray]]:
        with self._decoder_threads() as threads:
            try:
                yield from iter_gray_frames(self.path(kind, camera), start=start, stop=stop, step=step,
                                            threads=threads)
            except VideoError as exc:
                raise VideoError(f"{kind} clip of the {camera} camera: {exc}") from None

    def _mean_brightness(self, kind: str, camera: str) -> np.ndarray:
        with closing(self.gray_frames(kind, camera)) as frames:  # closes the decoder when read only in part
            if self.whole_clip_brightness:
                return np.asarray([float(img[::BRIGHTNESS_DOWNSCALE, ::BRIGHTNESS_DOWNSCALE].mean())
                                   for _, img in frames], dtype=np.float64)
            return brightness_until_flash(frames, self.fps(kind, camera), clip=kind, camera=camera)

    def brightness(self, kind: str, camera: str) -> np.ndarray:
        """Each frame's mean grey level (F',) up to the settled end of the sync flash (the whole clip
        when it holds none, or with ``whole_clip_brightness``); cached per clip."""
        return self._brightness(kind, camera)

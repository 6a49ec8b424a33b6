"""The clips of a ride bundle as the core pipeline reads them (``core.pipeline.ClipReader``).

The core never opens files; this adapter gives it grey frames, brightness curves and clip facts,
probing each clip once (from its packets, no decoding) and caching what it learns per clip.

The sync flash is filmed at the start of a clip set, so a clip's brightness is read only until its
flash has been found and followed by a settled stretch (:func:`brightness_until_flash`). The stages
after sync start after the flash: so that they do not decode the clip's start again, the sync pass
hands its open decoder over, with the frames it read after the flash (a :class:`_Handoff`, within a
memory budget shared by every clip; a clip over the budget is decoded again from its start or its
keyframe). Decoder threads come out of the analysis's thread budget, shared by the clips decoded at once.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Generator, Iterator
from contextlib import closing, contextmanager
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from saddlescope.core.errors import SyncError, VideoError
from saddlescope.core.sync import MIN_FRAMES, flash_interval
from saddlescope.io.malloc import limit_frame_memory, release_freed_memory
from saddlescope.io.video import VideoInfo, iter_gray_frames, probe_video

__all__ = ["HANDOFF_BUDGET_MB", "ROW_BANDS", "BundleClips", "RowBands", "brightness_until_flash"]

BRIGHTNESS_DOWNSCALE = 8  # every 8th pixel of every 8th row: the mean of a 1080p frame from 32k samples
ROW_BANDS = 16  # bands of rows whose own brightness shows a rolling shutter's flash sweeping down the frame
# Frames the sync passes may keep for the next pass of their clips, all clips together: 1080p60 clips
# keep 40-90 MB each (their frames from the flash's end to where the sync pass stopped), 640x480 ones a
# tenth of that; a 2160p clip up to 270 MB while its sync pass reads, so with this budget one at a time.
HANDOFF_BUDGET_MB = 384.0


SYNC_MIN_S, SYNC_SETTLE_S, SYNC_CHECK_EVERY_S = 1.0, 0.5, 0.25


class RowBands:
    """Each frame's mean brightness per band of rows (:data:`ROW_BANDS` bands), from the brightness pass's samples."""

    def __init__(self) -> None:
        self.values: list[np.ndarray] = []
        self.edges: np.ndarray | None = None
        self.row_fraction = np.zeros(0)

    def add(self, sampled: np.ndarray, height: int) -> None:
        """One frame's sampled pixels (every ``BRIGHTNESS_DOWNSCALE``-th row and column) of a ``height``-row image."""
        row_means = sampled.mean(axis=1, dtype=np.float64)
        if self.edges is None:
            n = min(ROW_BANDS, len(row_means))
            self.edges = np.linspace(0, len(row_means), n + 1).round().astype(np.int64)
            rows = np.arange(len(row_means)) * BRIGHTNESS_DOWNSCALE + 0.5
            self.row_fraction = np.array([rows[a:b].mean() for a, b in zip(self.edges[:-1], self.edges[1:],
                                                                             strict=True)]) / height
        sums = np.add.reduceat(row_means, self.edges[:-1])
        self.values.append(sums / np.diff(self.edges))

    def curves(self) -> tuple[np.ndarray, np.ndarray]:
        """(brightness (F', B), each band's mean row height as a share of the image's height (B,))."""
        return (np.asarray(self.values, dtype=np.float64).reshape(len(self.values), -1), self.row_fraction)


def brightness_until_flash(frames, fps: float, *, clip: str, camera: str, min_s: float = SYNC_MIN_S,
                           settle_s: float = SYNC_SETTLE_S, check_every_s: float = SYNC_CHECK_EVERY_S,
                           bands: RowBands | None = None) -> np.ndarray:
    """Mean brightness of each frame (F',) from ``frames`` ((index, grey image) from frame 0).

    Read until the sync flash is found (:func:`saddlescope.core.sync.flash_interval`) with ``settle_s`` of frames
    after its end, and at least ``min_s`` read.
    The whole clip when no flash is found (known offsets).

    A flash is looked for every ``check_every_s``; the first bright interval that passes the flash
    detector's tests wins, where the whole clip would give the largest rise: a sync flash is filmed
    first, before the ride, so the two agree on a clip filmed as docs/filming.md asks. ``bands``
    collects each frame's brightness per band of rows from the same samples (a rolling shutter's readout).
    """
    values: list[float] = []
    check_at = max(MIN_FRAMES, int(round(min_s * fps)))
    settle = max(5, int(round(settle_s * fps)))
    for _, img in frames:
        sampled = img[::BRIGHTNESS_DOWNSCALE, ::BRIGHTNESS_DOWNSCALE]
        values.append(float(sampled.mean()))
        if bands is not None:
            bands.add(sampled, img.shape[0])
        if len(values) >= check_at:
            check_at += max(1, int(round(check_every_s * fps)))
            try:
                _, end = flash_interval(np.asarray(values), clip=clip, camera=camera)
            except SyncError:
                continue
            if len(values) - end >= settle:
                break
    return np.asarray(values, dtype=np.float64)


@dataclass
class _Handoff:
    """A clip's open decoder where its sync pass stopped, and the frames that pass read after the flash."""

    frames: list[tuple[int, np.ndarray]]  # (index, grey image copy), consecutive indices
    rest: Iterator[tuple[int, np.ndarray]]  # the decoder, yielding from frames[-1][0] + 1 on
    nbytes: int

    def close(self) -> None:
        close = getattr(self.rest, "close", None)  # a generator (a peek's frames have none)
        if close is not None:
            close()


def _frames_kept(fps: float) -> int:
    """Frames a sync pass may have read since the flash ended (what the next pass starts after).

    It stops at least ``min_s`` in and at most a check interval after the flash has settled.
    """
    return int(math.ceil(max(SYNC_MIN_S, SYNC_SETTLE_S + SYNC_CHECK_EVERY_S) * fps)) + 2


class BundleClips:
    """Clip reader over ``paths[kind][camera] -> Path`` (a video file or an image folder)."""

    def __init__(self, paths: dict[str, dict[str, Path]], *, fps_hint: float | None = None,
                 threads: int | None = None, whole_clip_brightness: bool = False,
                 handoff_budget_mb: float = HANDOFF_BUDGET_MB):
        """``threads``: the decoders' share of the thread budget (None: FFmpeg's choice).

        The clips decoded at once split it. ``whole_clip_brightness``: read every frame's brightness, not only
        up to the flash. ``handoff_budget_mb``: the frames sync passes keep for the next pass (0: none).
        :meth:`close` (or ``with``) closes the decoders of hand-overs not taken up.
        """
        self.paths = {kind: {cam: Path(p) for cam, p in cams.items()} for kind, cams in paths.items()}
        self.fps_hint = fps_hint
        self.threads = threads
        self.whole_clip_brightness = whole_clip_brightness
        self._info = cache(self._probe)
        self._brightness = cache(self._mean_brightness)
        self._bands: dict[tuple[str, str], RowBands] = {}  # filled by the brightness passes
        self._lock = threading.Lock()
        self._open_decoders = 0
        self._handoff_budget = float(handoff_budget_mb) * 1e6
        self._handoff_bytes = 0.0  # kept or reserved by sync passes reading now
        self._handoffs: dict[tuple[str, str], _Handoff] = {}
        self._closed = False  # after close(), a pass still reading hands nothing over
        limit_frame_memory()  # before the analysis starts its threads: frames freed are given back (issue 39)

    def __enter__(self) -> BundleClips:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Close the decoders handed over by sync passes and not taken up (their frames are dropped)."""
        with self._lock:  # a sync pass still reading keeps its reservation (it releases it itself)
            handoffs, self._handoffs, self._closed = list(self._handoffs.values()), {}, True
            self._handoff_bytes -= sum(handoff.nbytes for handoff in handoffs)
        for handoff in handoffs:
            handoff.close()
        release_freed_memory()  # the clips' frames are dropped: the next job starts from a small process

    def kinds(self) -> list[str]:
        """The clip sets there are (the ride's and the extra ones)."""
        return list(self.paths)

    def cameras(self, kind: str) -> list[str]:
        """The cameras with a clip of `kind`."""
        return list(self.paths.get(kind, {}))

    def has(self, kind: str) -> bool:
        """Whether there is any clip of `kind`."""
        return bool(self.paths.get(kind))

    def path(self, kind: str, camera: str) -> Path:
        """The file of the `kind` clip of `camera`; `VideoError` when there is none."""
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
        """The clip's container facts (probed once, cached)."""
        return self._info(kind, camera)

    def fps(self, kind: str, camera: str) -> float:
        """The clip's frame rate (Hz)."""
        return self.info(kind, camera).fps

    def frame_times(self, kind: str, camera: str) -> np.ndarray | None:
        """Each frame's presentation time (s) for a variable-rate clip; None for an even one."""
        info = self.info(kind, camera)
        return info.frame_times_s if info.variable_frame_rate else None

    def frame_count(self, kind: str, camera: str) -> int:
        """The clip's number of frames."""
        return self.info(kind, camera).frame_count

    def image_size(self, kind: str, camera: str) -> tuple[int, int]:
        """The clip's (width, height) in pixels."""
        info = self.info(kind, camera)
        return info.width, info.height

    @contextmanager
    def _decoder_threads(self) -> Iterator[int | None]:
        """The decoder's share of the budget: the budget over the decoders open now (this one too)."""
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
        """Grey frames ``(index, image)`` of one clip from `start` to `stop` (the end when None) every `step`.

        Frames the sync pass already read are served from its hand-over rather than decoded again.
        """
        handoff = self._take_handoff(kind, camera, start, stop)
        if handoff is not None:
            yield from _from_handoff(handoff, start, stop, step)
            return
        yield from self._decoded(kind, camera, start, stop, step)

    def _take_handoff(self, kind: str, camera: str, start: int, stop: int | None) -> _Handoff | None:
        """The sync pass's hand-over when it can serve frames ``start``-``stop``.

        A request within its frames (a peek at the first frame) leaves it for the next pass, an earlier start
        drops it.
        """
        with self._lock:
            handoff = self._handoffs.get((kind, camera))
            if handoff is None:
                return None
            first, last = handoff.frames[0][0], handoff.frames[-1][0]
            if start >= first and stop is not None and stop <= last + 1:
                return _Handoff([f for f in handoff.frames if start <= f[0] < stop], iter(()), 0)
            del self._handoffs[(kind, camera)]
            self._handoff_bytes -= handoff.nbytes
        if start < first:
            handoff.close()
            return None
        return handoff

    def _decoded(self, kind: str, camera: str, start: int, stop: int | None,
                 step: int) -> Generator[tuple[int, np.ndarray], None, None]:
        with self._decoder_threads() as threads:
            try:
                yield from iter_gray_frames(self.path(kind, camera), start=start, stop=stop, step=step,
                                            threads=threads)
            except VideoError as exc:
                raise VideoError(f"{kind} clip of the {camera} camera: {exc}") from None

    def _mean_brightness(self, kind: str, camera: str) -> np.ndarray:
        bands = self._bands.setdefault((kind, camera), RowBands())
        if self.whole_clip_brightness:
            with closing(self._decoded(kind, camera, 0, None, 1)) as frames:
                means = []
                for _, img in frames:
                    sampled = img[::BRIGHTNESS_DOWNSCALE, ::BRIGHTNESS_DOWNSCALE]
                    means.append(float(sampled.mean()))
                    bands.add(sampled, img.shape[0])
                return np.asarray(means, dtype=np.float64)
        fps = self.fps(kind, camera)
        width, height = self.image_size(kind, camera)
        reserved = _frames_kept(fps) * float(width * height)
        with self._lock:  # room to keep this pass's last frames for the next pass?
            keep = self._handoff_bytes + reserved <= self._handoff_budget
            if not keep:
                reserved = 0.0
            self._handoff_bytes += reserved
        frames = self._decoded(kind, camera, 0, None, 1)
        kept: deque = deque(maxlen=_frames_kept(fps) if keep else 0)

        def tapped() -> Iterator[tuple[int, np.ndarray]]:
            for index, img in frames:
                if keep:
                    kept.append((index, img.copy()))  # the decoder reuses its buffers
                yield index, img

        nbytes = 0
        try:
            values = brightness_until_flash(tapped(), fps, clip=kind, camera=camera, bands=bands)
            handoff = self._handoff_after_flash(values, kept, frames, kind, camera) if keep else None
            if handoff is not None:
                with self._lock:
                    if not self._closed:
                        nbytes = handoff.nbytes
                        self._handoffs[(kind, camera)] = handoff
            return values
        finally:
            with self._lock:
                self._handoff_bytes -= reserved - nbytes
            if not nbytes:
                frames.close()

    def _handoff_after_flash(self, values: np.ndarray, kept: deque, frames, kind: str,
                             camera: str) -> _Handoff | None:
        """The frames read after the flash's end, and the open decoder.

        None where there is nothing to hand over (no flash, the whole clip read, or the frames after the flash
        not all kept).
        """
        if not kept or len(values) >= self.frame_count(kind, camera):
            return None
        try:
            _, end = flash_interval(values, clip=kind, camera=camera)
        except SyncError:
            return None
        after = [f for f in kept if f[0] > end]
        if not after or after[0][0] > int(math.ceil(end)) + 1:
            return None  # the next pass starts before the frames kept
        return _Handoff(after, frames, sum(img.nbytes for _, img in after))

    def brightness(self, kind: str, camera: str) -> np.ndarray:
        """Each frame's mean grey level (F',) up to the settled end of the sync flash.

        The whole clip when it holds none, or with ``whole_clip_brightness``. Cached per clip.
        """
        return self._brightness(kind, camera)

    def band_brightness(self, kind: str, camera: str) -> tuple[np.ndarray, np.ndarray]:
        """Each frame's brightness per band of rows (F', B) over :meth:`brightness`'s frames.

        With each band's mean row height as a share of the image's height (B,): read in the same pass.
        """
        self.brightness(kind, camera)
        return self._bands[(kind, camera)].curves()


def _from_handoff(handoff: _Handoff, start: int, stop: int | None, step: int) -> Iterator[tuple[int, np.ndarray]]:
    """Frames ``start``, ``start + step``, ... < ``stop`` from a hand-over: its frames, then its decoder's."""
    try:
        for source in (handoff.frames, handoff.rest):
            for index, img in source:
                if stop is not None and index >= stop:
                    return
                if index >= start and not (index - start) % step:
                    yield index, img
    finally:
        handoff.close()

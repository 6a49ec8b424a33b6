"""Reading clips: a video file any FFmpeg build decodes (PyAV), or a folder of numbered images.

Frames come out as grey uint8 arrays of shape (H, W). For YUV video that is the Y (luma) plane read in
place from the decoded frame, so detection costs little more than decoding (no colour conversion).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import av
import cv2
import numpy as np

from saddlescope.core.errors import VideoError
from saddlescope.io.malloc import limit_frame_memory

IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm"}
_PLANAR_LUMA = {"yuv420p", "yuvj420p", "yuv422p", "yuvj422p", "yuv444p", "yuvj444p", "nv12", "nv21", "gray",
                "yuv420p10le"}

# A motion clip of one image is a still, not a ride: no motion to measure (refused when it is uploaded).
MIN_MOTION_FRAMES = 2


@dataclass(frozen=True)
class VideoInfo:
    """What a clip is: frame rate, frame count, resolution, codec."""

    path: Path
    fps: float
    frame_count: int
    width: int
    height: int
    codec: str
    duration_s: float
    # phones record at a variable frame rate: frames are then not 1/fps apart, and ``fps`` is the
    # nominal rate (see frame_clock) rather than the average
    variable_frame_rate: bool = False
    frame_times_s: np.ndarray | None = field(default=None, compare=False, repr=False)  # (frame_count,)

    def as_dict(self) -> dict:
        """The facts as a JSON-ready document (frame times left out)."""
        out = {"path": str(self.path), "fps": self.fps, "frame_count": self.frame_count,
               "width": self.width, "height": self.height, "codec": self.codec,
               "duration_s": self.duration_s}
        if self.variable_frame_rate and self.frame_times_s is not None:
            dt_ms = np.diff(self.frame_times_s) * 1000.0
            out["variable_frame_rate"] = True
            out["frame_interval_ms"] = {"min": float(dt_ms.min()), "median": float(np.median(dt_ms)),
                                        "max": float(dt_ms.max())}
        return out


STANDARD_RATES = (23.976, 24.0, 25.0, 29.97, 30.0, 48.0, 50.0, 59.94, 60.0, 90.0, 100.0, 119.88, 120.0, 240.0)
# frame intervals further than this (fraction of the median interval) from even make a clip variable
# rate; below it the timestamps' own rounding (1/15360 s ticks and the like) is all there is
VFR_TOLERANCE = 0.02


def frame_clock(times_s, average_fps: float) -> tuple[bool, float]:
    """Whether presentation times ``times_s`` (F,) are uneven, and the clip's nominal frame rate.

    Even clips keep their container rate. For uneven ones (dropped frames, a phone's variable rate)
    the nominal rate counts frame slots: each interval is a whole number of median intervals (a drop
    is two), and the slope of the stamps over their slots is the nominal interval (jittered stamps
    average out: 60 frames tell 30 from 29.97 fps). Within 0.02 % of a standard rate the
    rate is that one, so that cameras set alike report the same number.
    """
    t = np.asarray(times_s, dtype=np.float64)
    if t.size < 3:
        return False, average_fps
    dt = np.diff(t)
    median = float(np.median(dt))
    if median <= 0 or float(np.max(np.abs(dt - median))) <= VFR_TOLERANCE * median:
        return False, average_fps
    slot = np.concatenate([[0.0], np.cumsum(np.maximum(np.round(dt / median), 1.0))])
    rate = 1.0 / float(np.polyfit(slot, t, 1)[0])  # the stamps' line over their slots
    nearest = min(STANDARD_RATES, key=lambda r: abs(r - rate))
    return True, (nearest if abs(nearest - rate) <= 2e-4 * nearest else rate)


def _image_files(folder: Path) -> list[Path]:
    files = [p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()]

    def key(p: Path):
        nums = re.findall(r"\d+", p.stem)
        return (int(nums[-1]) if nums else -1, p.name)

    return sorted(files, key=key)


def _open(path: Path):
    try:
        return av.open(str(path), mode="r")
    except (av.error.FFmpegError, OSError, UnicodeDecodeError) as exc:
        raise VideoError(f"{path}: not a readable video ({exc.__class__.__name__}: {exc})") from None


def too_short_for(clip_kind: str, info: VideoInfo) -> str | None:
    """Why a clip is too short for its kind, in words (None: long enough)."""
    if clip_kind == "motion" and info.frame_count < MIN_MOTION_FRAMES:
        return (f"it has {info.frame_count} frame(s); a motion clip needs at least {MIN_MOTION_FRAMES} "
                "(a video of the horse moving, not a still)")
    return None


def probe_video(path: Path | str, *, fps_hint: float | None = None, decode_tail: bool = True) -> VideoInfo:
    """Check a clip decodes and read its fps, frame count and resolution.

    The frames are counted from the demuxed packets (no decoding: reading a clip's packets costs a
    small fraction of decoding them), and the last group of pictures is decoded, so a truncated file
    is caught here rather than half-way through a job. Where the packets cannot stand for the frames
    (no timestamps, or a count that disagrees with the container's), every frame is decoded instead.
    ``fps_hint`` is used for image folders (default 30).

    ``decode_tail=False`` skips decoding the last group of pictures (the size is then the stream's): for
    the analysis, whose clips were checked so when they were uploaded and which decodes every frame
    anyway. A phone clip's last GOP is one or two seconds of frames: decoding it for every clip of a
    ride cost a quarter of decoding the ride once (issue 28). A cut-off packet is still caught here.
    """
    path = Path(path)
    if not path.exists():
        raise VideoError(f"{path}: file not found")
    if path.is_dir():
        return _probe_images(path, fps_hint)
    if path.stat().st_size == 0:
        raise VideoError(f"{path}: empty file (0 bytes)")
    with _open(path) as container:
        if not container.streams.video:
            raise VideoError(f"{path}: has no video stream")
        stream = container.streams.video[0]
        rate = stream.average_rate or stream.guessed_rate or stream.base_rate
        if not rate or float(rate) <= 0:
            raise VideoError(f"{path}: frame rate unknown")
        fps = float(rate)
        codec = stream.codec_context.name
        counted = _count_packets(container, stream, path, decode_tail=decode_tail)
    times: Sequence[float | None]  # presentation times, None where a frame has none
    if counted is None:
        n_frames, (width, height), times = _decode_all(path)
    else:
        n_frames, (width, height), times = counted
    if width <= 0 or height <= 0:
        raise VideoError(f"{path}: frame size unknown")
    frame_times: np.ndarray | None = None
    variable = False
    if all(t is not None for t in times):
        stamps = np.asarray(times, dtype=np.float64)
        # timestamps that do not increase say nothing about timing: the frames are taken as even
        if np.all(np.diff(stamps) > 0):
            variable, fps = frame_clock(stamps, fps)
            frame_times = stamps
    duration = (float(frame_times[-1] - frame_times[0]) + 1.0 / fps if variable and frame_times is not None
                else n_frames / fps)
    return VideoInfo(path, fps, n_frames, int(width), int(height), codec, duration,
                     variable_frame_rate=variable, frame_times_s=frame_times)


def _probe_images(path: Path, fps_hint: float | None) -> VideoInfo:
    files = _image_files(path)
    if not files:
        raise VideoError(f"{path}: folder holds no numbered images ({', '.join(sorted(IMAGE_SUFFIXES))})")
    first = cv2.imread(str(files[0]), cv2.IMREAD_GRAYSCALE)
    if first is None:
        raise VideoError(f"{files[0]}: not a readable image")
    fps = float(fps_hint or 30.0)
    return VideoInfo(path, fps, len(files), first.shape[1], first.shape[0], "images", len(files) / fps)


def _count_packets(container, stream, path: Path, *, max_tail_s: float = 2.0,
                   decode_tail: bool = True) -> tuple[int, tuple[int, int], list[float]] | None:
    """Frame count, size and presentation times (s) from the packets, the last GOP decoded; None: decode all.

    One packet is one frame for the codecs phones and cameras write (H.264, HEVC, MJPEG, ...); the
    container's own count, where it states one, must agree, and every packet must carry a timestamp.
    A packet cut short by the end of the file is flagged corrupt by the demuxer. The last GOP is decoded
    when it is at most ``max_tail_s`` long (phones: a keyframe every second or two); a longer one
    (a synthetic clip's single GOP) would cost a whole decode, so then only its first frame is.
    """
    packets = _packet_pts(container, stream, path)
    if packets is None:
        return None
    pts, last_key = packets
    stated = int(stream.frames or 0)
    if (stated and stated != len(pts)) or last_key < 0 or len(set(pts)) != len(pts) or stream.time_base is None:
        return None
    base = float(stream.time_base)
    if not decode_tail:
        size = (int(stream.codec_context.width or 0), int(stream.codec_context.height or 0))
        if size[0] > 0 and size[1] > 0:
            return len(pts), size, [p * base for p in sorted(pts)]
    # the last group of pictures decoded from its keyframe: a cut-off or corrupt tail fails here
    # (an open GOP's leading pictures, shown before the keyframe, need the GOP before it: not counted)
    key_pts = pts[last_key]
    tail = sum(p >= key_pts for p in pts[last_key:])
    rate = float(stream.average_rate or stream.guessed_rate or 30)
    if tail > max_tail_s * rate:
        key_pts, tail = min(pts), 1
    size = _decode_tail(container, stream, path, key_pts, tail)
    return len(pts), size, [p * base for p in sorted(pts)]


def _packet_pts(container, stream, path: Path) -> tuple[list[int], int] | None:
    """Each packet's timestamp (decode order) and the index of the last keyframe; None: a packet has none."""
    pts: list[int] = []
    last_key = -1  # index (decode order) of the last keyframe packet
    try:
        for packet in container.demux(stream):
            if packet.size == 0 and packet.pts is None:
                continue  # the demuxer's flush packet
            if packet.pts is None:
                return None
            if packet.is_corrupt:
                raise VideoError(f"{path}: truncated or corrupt at frame {len(pts)} (a packet is cut short)")
            if packet.is_keyframe:
                last_key = len(pts)
            pts.append(int(packet.pts))
    except (av.error.FFmpegError, ValueError) as exc:
        if not pts:
            raise VideoError(f"{path}: no frame decodes ({exc})") from None
        raise VideoError(f"{path}: truncated or corrupt after frame {len(pts)} ({exc})") from None
    if not pts:
        raise VideoError(f"{path}: no frame decodes (empty or truncated video)")
    return pts, last_key


def _decode_tail(container, stream, path: Path, key_pts: int, tail: int) -> tuple[int, int]:
    """The frame size, from decoding the `tail` frames from the keyframe at `key_pts`; `VideoError` if fewer decode."""
    size = (0, 0)
    n_tail = 0
    try:
        container.seek(key_pts, stream=stream, backward=True, any_frame=False)
        for frame in container.decode(stream):
            if frame.pts is not None and frame.pts >= key_pts:
                n_tail += 1
                size = (frame.width, frame.height)
                if n_tail >= tail:
                    break
    except (av.error.FFmpegError, ValueError) as exc:
        raise VideoError(f"{path}: truncated or corrupt near the end ({exc})") from None
    if n_tail < tail:
        raise VideoError(f"{path}: truncated or corrupt: only {n_tail} of the last {tail} frames decode")
    return size


def _decode_all(path: Path) -> tuple[int, tuple[int, int], list[float | None]]:
    """Frame count, size and presentation times from decoding every frame (clips without usable packets)."""
    n_decoded = 0
    size = (0, 0)
    times: list[float | None] = []
    with _open(path) as container:
        stream = container.streams.video[0]
        try:
            for frame in container.decode(stream):
                n_decoded += 1
                size = (frame.width, frame.height)
                times.append(frame.time)
        except (av.error.FFmpegError, ValueError) as exc:
            if n_decoded == 0:
                raise VideoError(f"{path}: no frame decodes ({exc})") from None
            raise VideoError(f"{path}: truncated or corrupt after frame {n_decoded} ({exc})") from None
    if n_decoded == 0:
        raise VideoError(f"{path}: no frame decodes (empty or truncated video)")
    return n_decoded, size, times


def _luma(frame) -> np.ndarray:
    """The Y plane of a decoded frame as (H, W) uint8, without colour conversion where possible."""
    fmt = frame.format.name
    if fmt in _PLANAR_LUMA and not fmt.endswith("10le"):
        plane = frame.planes[0]
        buf = np.frombuffer(plane, np.uint8).reshape(-1, plane.line_size)
        return buf[: frame.height, : frame.width]
    return frame.to_ndarray(format="gray")


def iter_gray_frames(path: Path | str, start: int = 0, stop: int | None = None,
                     step: int = 1, *, threads: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """Yield (frame index, grey frame of shape (H, W), uint8) for frames start, start+step, ... < stop.

    ``threads``: FFmpeg's decoder threads (frame and slice threading); None lets FFmpeg choose (one
    per host core, which a container's CPU quota does not limit), 1 decodes in this thread alone.
    The yielded array may be a view into the decoder's buffer: copy it to keep it past the next
    iteration.
    """
    path = Path(path)
    if step < 1:
        raise ValueError("step must be >= 1")
    limit_frame_memory()  # freed frames go back to the system, however the threads interleave (issue 39)
    if path.is_dir():
        files = _image_files(path)
        for i in range(start, len(files) if stop is None else min(stop, len(files)), step):
            img = cv2.imread(str(files[i]), cv2.IMREAD_GRAYSCALE)
            if img is None:
                raise VideoError(f"{files[i]}: not a readable image")
            yield i, img
        return
    with _open(path) as container:
        if not container.streams.video:
            raise VideoError(f"{path}: has no video stream")
        stream = container.streams.video[0]
        stream.thread_type = "AUTO"
        if threads is not None:
            stream.thread_count = max(1, int(threads))
        plan = _seek_plan(path, start) if start > 0 else None
        if plan is None:
            yield from _decode_from_start(container, stream, path, start, stop, step)
        else:
            yield from _decode_from_key(container, stream, path, start, stop, step, *plan)


def _decode_from_start(container, stream, path: Path, start: int, stop: int | None,
                       step: int) -> Iterator[tuple[int, np.ndarray]]:
    """Frames counted from the clip's first (every frame before ``start`` decoded and dropped)."""
    index = -1
    try:
        for frame in container.decode(stream):
            index += 1
            if index < start or (index - start) % step:
                continue
            if stop is not None and index >= stop:
                break
            yield index, _luma(frame)
    except (av.error.FFmpegError, ValueError) as exc:
        raise VideoError(f"{path}: decoding failed after frame {index} ({exc})") from None


def _seek_plan(path: Path, start: int) -> tuple[int, list[int]] | None:
    """(keyframe pts to seek to, every frame's pts in display order) for decoding from frame ``start``.

    None when the packets cannot index the frames exactly (then decode from the first frame).

    Read from the packets alone (no decoding): one packet per frame with a timestamp, the same rule
    as :func:`probe_video`. The keyframe is the last one shown at or before frame ``start``. The packets
    are read through a container of their own, so the decoding one stays at the clip's start.
    """
    pts: list[int] = []
    keys: list[int] = []
    try:
        with _open(path) as container:
            stream = container.streams.video[0]
            for packet in container.demux(stream):
                if packet.size == 0 and packet.pts is None:
                    continue  # the demuxer's flush packet
                if packet.pts is None or packet.is_corrupt:
                    return None
                pts.append(int(packet.pts))
                if packet.is_keyframe:
                    keys.append(int(packet.pts))
            stated = int(stream.frames or 0)
    except (av.error.FFmpegError, ValueError, VideoError):
        return None
    if not pts or len(set(pts)) != len(pts) or (stated and stated != len(pts)) or start >= len(pts):
        return None
    pts.sort()
    target = pts[start]
    before = [k for k in keys if k <= target]
    if not before or max(before) == pts[0]:
        return None  # the only keyframe before it is the first frame: decoding from the start is the same
    return max(before), pts


def _decode_from_key(container, stream, path: Path, start: int, stop: int | None, step: int,
                     key_pts: int, pts: list[int]) -> Iterator[tuple[int, np.ndarray]]:
    """Frames from ``start`` on, decoding from the keyframe before it (the frames before that are not decoded twice).

    Each frame's index is its timestamp's rank among all the packets'.
    """
    rank = {p: i for i, p in enumerate(pts)}
    expected = start
    try:
        container.seek(key_pts, stream=stream, backward=True, any_frame=False)
        for frame in container.decode(stream):
            if frame.pts is None or frame.pts not in rank:
                raise VideoError(f"{path}: a frame decoded after seeking has no timestamp of the clip's packets "
                                 f"(pts {frame.pts})")
            index = rank[frame.pts]
            if index < expected:
                continue  # before the start frame (or an open GOP's leading picture)
            if index != expected:
                raise VideoError(f"{path}: frame {expected} is missing after seeking (got frame {index})")
            expected += 1
            if stop is not None and index >= stop:
                break
            if (index - start) % step:
                continue
            yield index, _luma(frame)
    except (av.error.FFmpegError, ValueError) as exc:
        raise VideoError(f"{path}: decoding failed after frame {expected - 1} ({exc})") from None


def read_gray_frames(path: Path | str, indices) -> dict[int, np.ndarray]:
    """Decode the wanted frames (copies), keyed by index."""
    wanted = sorted(set(int(i) for i in indices))
    if not wanted:
        return {}
    out: dict[int, np.ndarray] = {}
    want = set(wanted)
    for i, img in iter_gray_frames(path, start=wanted[0], stop=wanted[-1] + 1):
        if i in want:
            out[i] = img.copy()
    return out


def frame_brightness(path: Path | str, *, downscale: int = 8) -> np.ndarray:
    """Mean grey level of every frame (F,), from the luma plane sampled on a coarse grid (for sync)."""
    values = [float(img[::downscale, ::downscale].mean()) for _, img in iter_gray_frames(path)]
    return np.asarray(values)


def fps_fraction(fps: float) -> Fraction:
    """A frame rate as a fraction for encoders (29.97 -> 30000/1001)."""
    for den in (1, 1001, 1000):
        num = fps * den
        if abs(num - round(num)) < 1e-6:
            return Fraction(int(round(num)), den)
    return Fraction(fps).limit_denominator(100000)

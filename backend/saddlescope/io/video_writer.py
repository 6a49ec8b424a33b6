"""Writing grey frames as H.264 video (PyAV / libx264, yuv420p), as a phone or camcorder would.

Grey levels 0-255 become limited-range luma (16-235, BT.601 "tv" range) with neutral chroma, so
players, OpenCV and PyAV decode them back to about the same grey levels; the raw Y plane holds
16 + 219 * grey / 255.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import av
import numpy as np

from saddlescope.core.errors import InputError, VideoError
from saddlescope.io.video import fps_fraction

_LUT = np.round(16.0 + np.arange(256) * (219.0 / 255.0)).astype(np.uint8)


def gray_to_yuv420p(frame: np.ndarray) -> np.ndarray:
    """uint8 (H, W) grey -> yuv420p planes stacked as (H * 3 / 2, W), limited range, neutral chroma."""
    h, w = frame.shape
    out = np.full((h * 3 // 2, w), 128, np.uint8)
    out[:h] = _LUT[frame]
    return out


def write_h264(
    path: Path | str, frames: Iterable[np.ndarray], *, fps: float, crf: int = 20, preset: str = "veryfast"
) -> int:
    """Encode uint8 grey frames (H, W) (H, W even) to an H.264 MP4; returns the number of frames written.

    ``crf`` is libx264's constant rate factor (18 near-transparent, 23 default, 28 visibly lossy).
    """
    path = Path(path)
    if not 0 <= int(crf) <= 51:
        raise InputError(f"crf must be 0-51, got {crf}")
    n = 0
    try:
        with av.open(str(path), mode="w") as container:
            stream = None
            for frame in frames:
                img = np.asarray(frame)
                if img.dtype != np.uint8 or img.ndim != 2:
                    raise InputError(
                        f"{path.name}: frames must be uint8 (H, W) grey, got {img.dtype} {img.shape}"
                    )
                h, w = img.shape
                if stream is None:
                    if h % 2 or w % 2:
                        raise InputError(f"{path.name}: frame size {w}x{h} must be even for yuv420p")
                    stream = container.add_stream("libx264", rate=fps_fraction(fps))
                    stream.width, stream.height = w, h
                    stream.pix_fmt = "yuv420p"
                    stream.options = {"crf": str(int(crf)), "preset": preset}
                elif (w, h) != (stream.width, stream.height):
                    raise InputError(
                        f"{path.name}: frame {n} is {w}x{h}, expected {stream.width}x{stream.height}"
                    )
                vf = av.VideoFrame.from_ndarray(gray_to_yuv420p(img), format="yuv420p")
                vf.pts = n
                for packet in stream.encode(vf):
                    container.mux(packet)
                n += 1
            if stream is None:
                raise InputError(f"{path.name}: no frames to write")
            for packet in stream.encode():
                container.mux(packet)
    except (av.error.FFmpegError, OSError) as exc:
        raise VideoError(f"{path}: could not write video ({exc})") from None
    return n

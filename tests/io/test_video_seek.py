"""Reading from a start frame by seeking to the keyframe before it: the same frames, the same indices."""

from pathlib import Path

import av
import numpy as np
import pytest

from saddlescope.io import video
from saddlescope.io.video import iter_gray_frames


def _write_clip(path: Path, n: int, *, gop: int, b_frames: int, codec: str = "libx264",
                size=(96, 64), fps: int = 30) -> None:
    """A clip of ``n`` frames of different noise (no two alike), a keyframe every ``gop`` frames."""
    w, h = size
    rng = np.random.default_rng(7)
    container = av.open(str(path), "w")
    stream = container.add_stream(codec, rate=fps)
    stream.width, stream.height = w, h
    stream.pix_fmt = "yuvj420p" if codec == "mjpeg" else "yuv420p"
    if codec == "libx264":
        stream.options = {"crf": "18", "g": str(gop), "keyint_min": str(gop), "bf": str(b_frames),
                          "sc_threshold": "0"}
    for _ in range(n):
        img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        for packet in stream.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
            container.mux(packet)
    for packet in stream.encode():
        container.mux(packet)
    container.close()


def _all_frames(path: Path) -> list[np.ndarray]:
    frames = [img.copy() for _, img in iter_gray_frames(path)]
    assert len(frames) > 0
    return frames


@pytest.mark.parametrize("b_frames", [0, 2])
def test_seeked_frames_equal_decoded_frames(tmp_path, b_frames):
    path = tmp_path / "clip.mp4"
    _write_clip(path, 60, gop=8, b_frames=b_frames)
    every = _all_frames(path)
    assert len(every) == 60
    for start in (1, 7, 8, 9, 15, 16, 31, 40, 59):
        plan = video._seek_plan(path, start)
        if start >= 8:  # a keyframe after the first lies before it: the decoder seeks there
            assert plan is not None and plan[0] > plan[1][0]
        got = [(i, img.copy()) for i, img in iter_gray_frames(path, start=start)]
        assert [i for i, _ in got] == list(range(start, 60))
        for i, img in got:
            assert np.array_equal(img, every[i]), f"frame {i} read from start {start} differs"
    # stop and step keep their meaning after a seek
    assert [i for i, _ in iter_gray_frames(path, start=17, stop=30, step=4)] == [17, 21, 25, 29]
    assert list(iter_gray_frames(path, start=60)) == []


def test_single_gop_clip_decodes_from_the_start(tmp_path):
    path = tmp_path / "one_gop.mp4"
    _write_clip(path, 30, gop=300, b_frames=2)
    assert video._seek_plan(path, 20) is None  # the only keyframe is the first frame
    every = _all_frames(path)
    got = list(iter_gray_frames(path, start=20))
    assert [i for i, _ in got] == list(range(20, 30))
    assert all(np.array_equal(img, every[i]) for i, img in got)


def test_intra_only_clip_seeks_to_the_frame_itself(tmp_path):
    path = tmp_path / "mjpeg.avi"
    _write_clip(path, 25, gop=1, b_frames=0, codec="mjpeg")
    every = _all_frames(path)
    plan = video._seek_plan(path, 13)
    assert plan is not None and plan[0] == plan[1][13]
    got = list(iter_gray_frames(path, start=13, stop=16))
    assert [i for i, _ in got] == [13, 14, 15]
    assert all(np.array_equal(img, every[i]) for i, img in got)

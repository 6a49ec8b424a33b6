"""Video reading: probe, grey frames, image folders and bad files."""

from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from saddlescope.core.errors import InputError, VideoError
from saddlescope.io.video import frame_brightness, iter_gray_frames, probe_video, read_gray_frames


def _write_clip(path: Path, n: int = 20, size=(160, 120), fps: int = 30) -> np.ndarray:
    w, h = size
    container = av.open(str(path), "w")
    stream = container.add_stream("libx264", rate=fps)
    stream.width, stream.height, stream.pix_fmt = w, h, "yuv420p"
    stream.options = {"crf": "10"}
    levels = np.linspace(20, 230, n).astype(np.uint8)
    for level in levels:
        img = np.full((h, w, 3), level, np.uint8)
        for packet in stream.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
            container.mux(packet)
    for packet in stream.encode():
        container.mux(packet)
    container.close()
    return levels


def test_probe_and_read_grey(tmp_path):
    path = tmp_path / "clip.mp4"
    levels = _write_clip(path)
    info = probe_video(path)
    assert (info.fps, info.frame_count, info.width, info.height) == (30.0, 20, 160, 120)
    frames = list(iter_gray_frames(path))
    assert [i for i, _ in frames] == list(range(20))
    assert frames[0][1].shape == (120, 160) and frames[0][1].dtype == np.uint8
    # the luma of a flat grey RGB frame is the grey level (within limited-range rounding)
    means = frame_brightness(path, downscale=4)
    assert np.all(np.abs(means - (16 + levels.astype(float) * 219 / 255)) < 3)
    picked = read_gray_frames(path, [3, 7])
    assert sorted(picked) == [3, 7]
    assert [i for i, _ in iter_gray_frames(path, start=5, stop=11, step=3)] == [5, 8]


def test_image_folder(tmp_path):
    for i in (1, 2, 10):
        cv2.imwrite(str(tmp_path / f"{i:04d}.png"), np.full((40, 50), i * 10, np.uint8))
    info = probe_video(tmp_path, fps_hint=25)
    assert (info.frame_count, info.width, info.height, info.fps) == (3, 50, 40, 25.0)
    assert [int(img[0, 0]) for _, img in iter_gray_frames(tmp_path)] == [10, 20, 100]


def test_bad_files(tmp_path):
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    with pytest.raises(VideoError, match="empty file"):
        probe_video(empty)
    text = tmp_path / "notes.mp4"
    text.write_text("this is not a video\n" * 50)
    with pytest.raises(VideoError, match="notes.mp4"):
        probe_video(text)
    with pytest.raises(VideoError, match="not found"):
        probe_video(tmp_path / "missing.mp4")
    good = tmp_path / "good.mp4"
    _write_clip(good, n=40)
    data = good.read_bytes()
    truncated = tmp_path / "truncated.mp4"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(VideoError, match="truncated.mp4"):
        probe_video(truncated)
    with pytest.raises(VideoError, match="no numbered images"):
        probe_video(tmp_path / "emptydir" if (tmp_path / "emptydir").mkdir() is None else None)


def test_a_phones_variable_frame_rate_is_read_from_the_timestamps(tmp_path):
    from saddlescope.io.video_writer import write_h264

    rng = np.random.default_rng(3)
    # the sensor's frame slots, every 17th dropped, each frame stamped up to a fifth of a frame off
    slots = np.concatenate([[0.0], np.cumsum(np.where(np.arange(59) % 17 == 8, 2.0, 1.0))])
    times = (slots + rng.uniform(-0.2, 0.2, 60)) / 30.0
    path = tmp_path / "phone.mp4"
    frames = [np.full((48, 64), 10 + 3 * i, np.uint8) for i in range(60)]
    assert write_h264(path, frames, fps=30.0, frame_times_s=times) == 60
    info = probe_video(path)
    assert info.variable_frame_rate and info.frame_count == 60
    # the nominal rate, not the average (60 frames in 2.1 s); two seconds of jittered stamps fix it
    # to a tenth of a percent
    assert info.fps == pytest.approx(30.0, rel=2e-3)
    np.testing.assert_allclose(info.frame_times_s - info.frame_times_s[0], times - times[0], atol=2e-5)
    facts = info.as_dict()
    assert facts["variable_frame_rate"] and facts["frame_interval_ms"]["max"] > 55.0
    # an even clip stays even, at its container rate
    even = tmp_path / "even.mp4"
    write_h264(even, frames, fps=29.97)
    info = probe_video(even)
    assert not info.variable_frame_rate and info.fps == pytest.approx(29.97, abs=1e-6)
    assert "variable_frame_rate" not in info.as_dict()
    with pytest.raises(InputError, match="increase"):
        write_h264(tmp_path / "bad.mp4", frames[:3], fps=30.0, frame_times_s=[0.0, 0.1, 0.1])


def test_the_analysis_probe_reads_packets_only_and_still_refuses_a_cut_file(tmp_path):
    """decode_tail=False (the analysis's clip reader) gives what the full probe gives, without decoding."""
    path = tmp_path / "clip.mp4"
    _write_clip(path, n=40, size=(176, 144))
    full, packets = probe_video(path), probe_video(path, decode_tail=False)
    assert (packets.fps, packets.frame_count, packets.width, packets.height) == (
        full.fps, full.frame_count, full.width, full.height) == (30.0, 40, 176, 144)
    np.testing.assert_array_equal(packets.frame_times_s, full.frame_times_s)
    truncated = tmp_path / "cut.mp4"
    truncated.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(VideoError, match="cut.mp4"):
        probe_video(truncated, decode_tail=False)


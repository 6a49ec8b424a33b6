"""The worker's thread budget (cgroup CPU quota, never the host's core count) and the probe without decoding."""

from __future__ import annotations

import numpy as np
import pytest
from integration_services import write_noise_clip

from saddlescope.core.errors import VideoError
from saddlescope.io import threads
from saddlescope.io.clip_source import BundleClips, brightness_until_flash
from saddlescope.io.video import iter_gray_frames, probe_video


def test_cgroup_v2_quota_is_read_and_rounded_up(tmp_path, monkeypatch):
    (tmp_path / "cpu.max").write_text("150000 100000\n")
    assert threads.cgroup_cpu_quota(tmp_path) == pytest.approx(1.5)
    monkeypatch.setattr(threads, "_affinity_cpus", lambda: 64)  # a big host: the quota wins
    assert threads.default_worker_threads(tmp_path) == 2
    (tmp_path / "cpu.max").write_text("max 100000\n")
    assert threads.cgroup_cpu_quota(tmp_path) is None
    assert threads.default_worker_threads(tmp_path) == 64  # no quota: the CPUs this process may use


def test_cgroup_v1_quota_and_a_quota_above_the_cpus_allowed(tmp_path, monkeypatch):
    (tmp_path / "cpu").mkdir()
    (tmp_path / "cpu" / "cpu.cfs_quota_us").write_text("400000\n")
    (tmp_path / "cpu" / "cpu.cfs_period_us").write_text("100000\n")
    assert threads.cgroup_cpu_quota(tmp_path) == pytest.approx(4.0)
    monkeypatch.setattr(threads, "_affinity_cpus", lambda: 2)
    assert threads.default_worker_threads(tmp_path) == 2
    (tmp_path / "cpu" / "cpu.cfs_quota_us").write_text("-1\n")
    assert threads.cgroup_cpu_quota(tmp_path) is None
    assert threads.cgroup_cpu_quota(tmp_path / "nothing-here") is None


def test_the_setting_overrides_the_quota_and_is_checked(monkeypatch):
    from saddlescope.settings import ConfigurationError, load_settings

    monkeypatch.setenv("SADDLESCOPE_WORKER_THREADS", "3")
    assert load_settings().resolved_worker_threads == 3
    monkeypatch.delenv("SADDLESCOPE_WORKER_THREADS")
    assert load_settings().resolved_worker_threads == threads.default_worker_threads() >= 1
    with pytest.raises(ConfigurationError, match="worker_threads"):
        load_settings(worker_threads=0)


def test_probe_counts_the_packets_as_decoding_would(tmp_path):
    path = tmp_path / "gop.mp4"
    write_noise_clip(path, 75, gop=10)  # B-frames and a keyframe every 10 frames: the last GOP is decoded
    info = probe_video(path)
    decoded = [i for i, _ in iter_gray_frames(path, threads=1)]
    assert info.frame_count == len(decoded) == 75
    assert (info.width, info.height, info.fps) == (64, 48, 30.0)
    assert info.duration_s == pytest.approx(75 / 30)


def test_probe_finds_a_clip_cut_short_with_its_index_in_front(tmp_path):
    good = tmp_path / "good.mp4"
    write_noise_clip(good, 90, gop=30, faststart=True)  # a phone's layout: the index first, all frames listed
    data = good.read_bytes()
    for fraction in (0.5, 0.99):
        cut = tmp_path / f"cut{fraction}.mp4"
        cut.write_bytes(data[: int(len(data) * fraction)])
        with pytest.raises(VideoError, match=f"cut{fraction}.mp4: truncated or corrupt"):
            probe_video(cut)


def test_brightness_is_read_until_the_flash_has_settled(tmp_path):
    path = tmp_path / "flash.mp4"
    write_noise_clip(path, 150, flash=(20, 24))
    part = brightness_until_flash(iter_gray_frames(path), 30.0, clip="motion", camera="left")
    assert 30 <= len(part) <= 48  # a second at least, half a second after the flash, not the whole clip
    clips = BundleClips({"motion": {"left": path}}, threads=2)
    assert np.array_equal(clips.brightness("motion", "left"), part)
    whole = BundleClips({"motion": {"left": path}}, whole_clip_brightness=True).brightness("motion", "left")
    assert len(whole) == 150 and np.array_equal(whole[: len(part)], part)
    dark = tmp_path / "dark.mp4"
    write_noise_clip(dark, 40)  # no flash (offsets given in ride.json): every frame is read
    assert len(brightness_until_flash(iter_gray_frames(dark), 30.0, clip="motion", camera="left")) == 40


def test_open_decoders_share_the_thread_budget(tmp_path):
    path = tmp_path / "c.mp4"
    write_noise_clip(path, 5)
    clips = BundleClips({"motion": {"left": path, "right": path}}, threads=4)
    with clips._decoder_threads() as first, clips._decoder_threads() as second:
        assert (first, second) == (4, 2)
    with clips._decoder_threads() as alone:
        assert alone == 4
    assert BundleClips({}, threads=None)._decoder_threads().__enter__() is None

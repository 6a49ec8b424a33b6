"""Decoded frames are bounded however slow their consumers are, and freed ones go back to the system (issue 39)."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import pytest
from integration_services import write_noise_clip

from saddlescope.io import clip_source
from saddlescope.io.clip_source import BundleClips
from saddlescope.io.malloc import mapped_bytes

CAMERAS = ("left", "middle", "right")


class _Counted:
    """Frames each pass's decoder has handed out, and those its consumer has finished with."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.produced: dict[str, set[int]] = {}  # frame indices each clip's decoders handed out
        self.consumed: dict[str, int] = {}  # of those, the frames their consumers finished with
        self.most_ahead = 0  # the largest produced - consumed of one pass seen at any moment

    def wrap(self, decoder):
        def counted(path, *args, **kwargs):
            key = str(path)
            for item in decoder(path, *args, **kwargs):
                with self.lock:
                    self.produced.setdefault(key, set()).add(item[0])
                    ahead = len(self.produced[key]) - self.consumed.get(key, 0)
                    self.most_ahead = max(self.most_ahead, ahead)
                yield item
        return counted

    def done(self, path, index: int) -> None:
        with self.lock:  # a frame from a sync pass's hand-over was not decoded by this pass
            if index in self.produced.get(str(path), ()):
                self.consumed[str(path)] = self.consumed.get(str(path), 0) + 1


def test_slow_consumers_cannot_make_the_decoders_hold_more_frames(tmp_path, monkeypatch):
    paths = {cam: tmp_path / f"{cam}.mp4" for cam in CAMERAS}
    for path in paths.values():
        write_noise_clip(path, 90, flash=(10, 13))
    counted = _Counted()
    monkeypatch.setattr(clip_source, "iter_gray_frames", counted.wrap(clip_source.iter_gray_frames))
    frame_mb = 64 * 48 / 1e6
    budget_mb = 33 * frame_mb  # room for one sync pass's hand-over, not two

    def slow_pass(clips: BundleClips, cam: str) -> None:
        for index, img in clips.gray_frames("motion", cam, start=20):
            time.sleep(0.002)  # a search slower than the decoder (a busy host)
            assert img.shape == (48, 64)
            seen[cam].append(index)
            counted.done(paths[cam], index)

    with BundleClips({"motion": paths}, threads=2, handoff_budget_mb=budget_mb) as clips:
        sync = [threading.Thread(target=clips.brightness, args=("motion", cam)) for cam in CAMERAS]
        for t in sync:
            t.start()
        for t in sync:
            t.join()
        held = sum(len(h.frames) for h in clips._handoffs.values())
        assert clips._handoff_bytes <= budget_mb * 1e6 and held <= 33  # the hand-overs stay within the budget
        counted.produced.clear()
        counted.most_ahead = 0
        seen: dict[str, list[int]] = {cam: [] for cam in CAMERAS}
        passes = [threading.Thread(target=slow_pass, args=(clips, cam)) for cam in CAMERAS]
        for t in passes:
            t.start()
        for t in passes:
            t.join()
    assert all(seen[cam] == list(range(20, 90)) for cam in CAMERAS)  # every frame from 20 on, in order
    assert sum(counted.consumed.values()) >= 3 * (70 - 33)  # most of them decoded by these passes
    # a decoder hands out a frame only when its consumer asks for the next: never one ahead of it
    assert counted.most_ahead == 1


_ALLOCATE = """
import numpy as np
from saddlescope.io.clip_source import BundleClips
from saddlescope.io.malloc import mapped_bytes
BundleClips({})  # what an analysis, a calibration or a check opens before it decodes
frame = np.ones(3840 * 2160, np.uint8)  # a 2160p grey frame
del frame  # freed: glibc as shipped would now serve the next one from a heap, and keep it there
before = mapped_bytes()
frame = np.ones(3840 * 2160, np.uint8)
print(mapped_bytes() - before)
"""


def test_a_frame_freed_is_given_back_to_the_system_once_clips_are_opened():
    if mapped_bytes() is None:
        pytest.skip("the C library is not glibc 2.33 or later (no mallinfo2 to read)")
    out = subprocess.run([sys.executable, "-c", _ALLOCATE], capture_output=True, text=True, check=True,
                         env={"PATH": "/usr/bin:/bin", "PYTHONPATH": ":".join(sys.path)})
    # the second 2160p frame is mapped alone (unmapped when freed), not taken from a heap that keeps it
    assert int(out.stdout.strip()) >= 3840 * 2160

"""Detection runs the cameras in parallel within the thread budget, with the same tracks as one by one."""

from __future__ import annotations

import threading
import time

import integration_services
import numpy as np
import pytest

from saddlescope.core.errors import DetectionError
from saddlescope.core.pipeline.detection import detect_clip, per_camera

short_canter_ride = integration_services.short_canter_ride


def test_per_camera_keeps_order_errors_and_the_budget():
    running, peak = [0], [0]
    lock = threading.Lock()
    together = threading.Barrier(4, timeout=30)  # passes only when four cameras run at once

    def work(cam):
        with lock:
            running[0] += 1
            peak[0] = max(peak[0], running[0])
        if together is not None:
            together.wait()
        else:
            time.sleep(0.05)  # long enough for the pool's threads to overlap
        with lock:
            running[0] -= 1
        if cam == "b":
            raise DetectionError("no markers in b")
        return cam.upper()

    got = per_camera(["a", "b", "c", "d"], work, 2)  # every camera at once, up to twice the budget
    assert list(got) == ["a", "b", "c", "d"]
    assert got["a"] == "A" and got["d"] == "D"
    assert isinstance(got["b"], DetectionError) and "no markers in b" in str(got["b"])
    together = None
    peak[0] = 0
    per_camera(list("acefgh"), work, 2)
    assert peak[0] <= 4  # never more than twice the budget
    peak[0] = 0
    per_camera(["a", "c"], work, 1)
    assert peak[0] == 1

    def broken(cam):
        raise ValueError("a bug, not a missed marker")

    with pytest.raises(ValueError, match="a bug"):
        per_camera(["a", "c"], broken, 2)


@pytest.mark.slow
def test_parallel_detection_gives_the_same_tracks(short_canter_ride):
    # the ride test_pipeline analyses (rendered once per run): only its static shot is tracked here
    from saddlescope.core import pipeline as P
    from saddlescope.io.bundle import open_bundle
    from saddlescope.io.clip_source import BundleClips

    with open_bundle(short_canter_ride) as bundle:
        clips = BundleClips(bundle.clip_paths)
        tracks = {threads: detect_clip(clips, "static", 4, {}, P.PipelineParams(threads=threads))[0]
                  for threads in (1, 3)}
    assert list(tracks[1]) == list(tracks[3]) and len(tracks[1]) == 3
    for cam in tracks[1]:
        assert np.array_equal(tracks[1][cam].frame_index, tracks[3][cam].frame_index)
        assert np.array_equal(tracks[1][cam].xy_px, tracks[3][cam].xy_px, equal_nan=True)
        assert np.isfinite(tracks[1][cam].xy_px).mean() > 0.5  # from frame 0: the flash frames hold none


class _MovingDots:
    """A clip reader of three cameras' motion clips: three bright dots moving on a dark, noisy floor."""

    def __init__(self, n_frames: int | None = 40, delay_s: float = 0.0):
        self.n_frames, self.delay_s, self.served = n_frames, delay_s, 0

    def cameras(self, kind):
        return ["left", "middle", "right"]

    def gray_frames(self, kind, camera, start=0, stop=None, step=1):
        rng = np.random.default_rng({"left": 1, "middle": 2, "right": 3}[camera])
        i = start
        while self.n_frames is None or i < self.n_frames:
            img = rng.integers(10, 30, (120, 160), dtype=np.uint8)
            for k, (x0, y0) in enumerate(((30, 40), (60, 50), (90, 45))):
                x, y = x0 + 1.5 * i, y0 + 8 * np.sin(0.3 * i + k)
                yy, xx = np.mgrid[0:120, 0:160]
                img[(xx - x) ** 2 + (yy - y) ** 2 <= 9] = 230
            self.served += 1
            time.sleep(self.delay_s)
            yield i, img
            i += step


def test_motion_tracked_ahead_is_what_detection_would_track_and_can_be_cancelled():
    from saddlescope.core import pipeline as P
    from saddlescope.core.pipeline.detection import EarlyMotionTracks, motion_tracks_alone

    params = P.PipelineParams(threads=2)
    first = {"left": 0, "middle": 2, "right": 1}
    direct = motion_tracks_alone(_MovingDots(), first, params, 3)
    early = EarlyMotionTracks(_MovingDots(), first, params, 3)
    assert early.result() is None  # not started: detection searches itself
    early.start()
    ahead = early.result()
    assert list(ahead) == list(direct) == ["left", "middle", "right"]
    for cam in direct:
        assert np.isfinite(direct[cam].xy_px).all(axis=(1, 2)).mean() > 0.75  # found once seen moving
        assert np.array_equal(ahead[cam].frame_index, direct[cam].frame_index)
        assert np.array_equal(ahead[cam].xy_px, direct[cam].xy_px, equal_nan=True)
    endless = _MovingDots(n_frames=None, delay_s=0.002)
    early = EarlyMotionTracks(endless, first, params, 3)
    early.start()
    time.sleep(0.2)
    started = time.perf_counter()
    early.cancel()  # an earlier stage failed: the tracking stops at its next frame
    assert time.perf_counter() - started < 5.0
    served = endless.served
    time.sleep(0.1)
    assert endless.served == served > 0
    # as the analysis uses it: a stage failing before detection takes the tracks stops them too
    endless = _MovingDots(n_frames=None, delay_s=0.002)
    with pytest.raises(RuntimeError, match="calibration failed"):
        with EarlyMotionTracks(endless, first, params, 3) as early:
            early.start()
            time.sleep(0.1)
            raise RuntimeError("calibration failed")
    served = endless.served
    time.sleep(0.1)
    assert endless.served == served > 0

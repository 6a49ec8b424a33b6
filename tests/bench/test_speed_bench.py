"""`saddlescope bench`'s speed keys (issue 28): decoding once, the analysis against it, rides per core-hour
and peak memory. Sanity only: the numbers exist and hang together (no timed assertion)."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope import bench
from saddlescope.io.video_writer import write_h264


def _ride_of_clips(root, frames_per_kind: dict[str, int], size=(96, 64), fps=30.0):
    rng = np.random.default_rng(0)
    for kind, n in frames_per_kind.items():
        (root / kind).mkdir(parents=True)
        for cam in ("left", "middle", "right"):
            write_h264(root / kind / f"{cam}.mp4",
                       (rng.integers(0, 255, (size[1], size[0]), dtype=np.uint8) for _ in range(n)), fps=fps)
    return root


def test_decode_once_decodes_every_frame_of_every_clip(tmp_path):
    ride = _ride_of_clips(tmp_path, {"calibration": 12, "static": 9, "motion": 15})
    out = bench.decode_once(ride)
    assert out["frames"] == 3 * (12 + 9 + 15)
    assert out["clip_s"] == pytest.approx(3 * (12 + 9 + 15) / 30.0)
    assert out["seconds"] > 0
    assert bench.decode_once(ride, kinds=("motion",))["frames"] == 45


def test_speed_keys_name_every_ride_and_say_none_where_one_failed():
    speed = {"640x480": {"ratio": 3.0, "ratio_cpu": 2.5, "decode_once_s": 1.0, "analysis_s": 3.0,
                         "rides_per_core_hour": 90.0, "stage_vs_decode": {"sync": 0.5}},
             "1920x1080": {"error": "SyncError: no flash"}}
    keys = bench.speed_keys(speed)
    for name in ("640x480", "1920x1080"):
        for key in ("analysis_vs_decode_", "decode_once_s_", "analysis_s_", "stages_vs_decode_"):
            assert key + name in keys
    assert keys["analysis_vs_decode_640x480"] == 3.0
    assert keys["analysis_vs_decode_cpu_640x480"] == 2.5  # beside the wall-time ratio: steadier under load
    assert keys["analysis_vs_decode_cpu_1920x1080"] is None
    assert keys["stages_vs_decode_640x480"] == {"sync": 0.5}
    assert keys["analysis_vs_decode_1920x1080"] is None
    assert keys["whole_analysis_vs_clip_duration_1920x1080"] is None
    assert keys["rides_per_core_hour_1920x1080"] is None
    assert keys["peak_rss_mb_2160p30"] is None  # not measured (quick)
    assert keys["peak_rss_mb_2160p30_loaded"] is None and keys["peak_rss_loaded_vs_quiet_2160p30"] is None


def test_the_2160p_peak_under_load_stands_beside_the_quiet_one():
    speed = {"3840x2160": {"peak_rss_mb": 800.0, "loaded": {"peak_rss_mb": 840.0, "busy_loops": 6},
                           "loaded_vs_quiet": 1.05}}
    keys = bench.speed_keys(speed)
    assert (keys["peak_rss_mb_2160p30"], keys["peak_rss_mb_2160p30_loaded"]) == (800.0, 840.0)
    assert keys["peak_rss_loaded_vs_quiet_2160p30"] == 1.05


def test_busy_loops_spin_while_the_block_runs_and_are_gone_after():
    import os
    import time

    from saddlescope.bench.analysis import busy_loops

    with busy_loops(2) as pids:
        assert len(pids) == 2
        time.sleep(0.3)
        for pid in pids:  # running (R) or runnable, each a separate process of ours
            with open(f"/proc/{pid}/stat") as stat:
                assert stat.read().split()[2] in "RS"
    for pid in pids:
        assert not os.path.exists(f"/proc/{pid}") or open(f"/proc/{pid}/stat").read().split()[2] == "Z"


@pytest.mark.slow  # a child Python importing the package: seconds on a loaded machine
def test_peak_memory_of_a_ride_that_cannot_be_analysed_is_a_clear_error(tmp_path):
    out = bench.peak_rss_analysis(tmp_path / "no-such-ride")
    assert "peak_rss_mb" not in out
    assert out["error"].startswith("the analysis failed (exit 1)")
    assert "no-such-ride" in out["error"]


@pytest.mark.slow
def test_analysis_against_decoding_once_on_a_short_thesis_ride(tmp_path):
    from rendered_rides import cached_ride_bundle

    # 20 calibration poses (as the API tests' tiny ride): the keys and their relations are checked, not the
    # accuracy, and the ride is calibrated twice (the analysis and its peak-memory child)
    ride = cached_ride_bundle(tmp_path / "ride", gait="canter", seed=1, rig="thesis", extras=False,
                              duration_s=3.0, calibration_poses=20)
    out = bench.analysis_vs_decode(ride)
    assert out["ratio"] == pytest.approx(out["analysis_s"] / out["decode_once_s"])
    assert out["decode_once_s"] == min(out["decode_once_s_runs"])
    assert out["ratio_cpu"] == pytest.approx(out["cpu_s"] / out["decode_once_cpu_s"]) and out["decode_once_cpu_s"] > 0
    assert set(out["stage_vs_decode"]) >= {"sync", "calibration", "detection", "total"}
    assert out["stage_vs_decode"]["total"] == pytest.approx(out["timings_s"]["total"] / out["decode_once_s"])
    # the ride without its calibration costs less CPU than with it, and a core-hour holds some rides
    assert 0 < out["cpu_ride_without_calibration_s"] < out["cpu_s"]
    per_ride = out["cpu_calibration_s"] / 10 + out["cpu_ride_without_calibration_s"]
    assert out["rides_per_core_hour"] == pytest.approx(3600.0 / per_ride)
    assert out["vs_clip_duration"] == pytest.approx(out["analysis_s"] / out["clip_duration_s"])
    assert out["frames"] > 0
    rss = bench.peak_rss_analysis(ride)
    assert "error" not in rss, rss
    assert 50 < rss["peak_rss_mb"] < 4096  # a Python process with numpy, OpenCV and PyAV, far below a GB

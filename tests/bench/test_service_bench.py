"""`saddlescope bench`'s service benchmarks in their quick sizes: they run, measure what they say, and a
streamed upload really keeps the server's memory flat (no timing is asserted: the machine is shared)."""

from __future__ import annotations

import pytest

from saddlescope.bench import service as service_bench

pytestmark = pytest.mark.slow
MIB = 1024**2


@pytest.mark.parametrize("mode", ["multipart", "raw"])
def test_a_large_upload_does_not_grow_the_server(mode):
    out = service_bench.upload_memory(128 * MIB, mode=mode)
    assert out["status"] == 422 and "is not a usable video" in out["detail"]  # streamed whole, then probed
    assert out["samples"] > 0 and out["rss_peak_mb"] >= out["rss_before_mb"]
    # a server that buffered the body would grow by its 128 MiB
    assert out["growth_mb"] < 64, out


def test_leaderboard_latency_reports_percentiles():
    out = service_bench.leaderboard_latency(500, repeats=3)
    for part in ("service", "service_json_indicator", "http"):
        assert out[part]["n"] == 3 and 0 < out[part]["p50_ms"] <= out[part]["p95_ms"] <= out[part]["max_ms"]
    assert out["rides"] == 500 and out["gaits"] == ["canter"] and isinstance(out["ok"], bool)


def test_concurrent_readers_while_a_job_runs():
    out = service_bench.concurrent_reads(1.5, clients=4, samples=100)
    assert out["errors"] == 0 and out["requests"] > 0 and out["n"] == out["requests"]
    assert out["job"]["kind"] == "selftest" and out["job"]["status_at_end"] in ("queued", "running", "done")


def test_readers_with_and_without_a_login_flood_report_side_by_side():
    from saddlescope.bench.load import readers_and_login_flood

    out = readers_and_login_flood(1.5, clients=4, flood_clients=3, samples=100, quick=True)
    assert out["quick"] and "instead of 60 s" in out["note"]
    for part in ("readers", "readers_with_login_flood"):
        assert {"requests", "errors", "p50_ms", "p95_ms", "p99_ms"} <= set(out[part]) and out[part]["requests"] > 0
    assert out["login_flood"]["requests"] > 0 and set(out["login_flood"]["statuses"]) <= {"401", "429", "503"}
    assert out["p95_ratio_flood_vs_plain"] is None or out["p95_ratio_flood_vs_plain"] > 0
    assert out["job"]["kind"] == "selftest" and isinstance(out["ok"], bool)


def test_a_real_video_upload_is_accepted_and_measured(tmp_path):
    from saddlescope.bench.load import real_video

    video = real_video(tmp_path / "big.avi", 8 * MIB)
    assert video.stat().st_size >= 8 * MIB
    out = service_bench.upload_memory(video=video)
    assert out["status"] == 200 and out["real_video"] and out["size_mb"] >= 8, out
    assert out["samples"] > 0 and out["growth_mb"] is not None
    from saddlescope.bench.load import load_table

    table = load_table({"load": {
        "readers": {"requests": 1, "errors": 0, "p50_ms": 1.0, "p95_ms": 2.0, "p99_ms": 3.0},
        "readers_with_login_flood": {"requests": 1, "errors": 0, "p50_ms": 1.0, "p95_ms": 2.0, "p99_ms": 3.0},
        "p95_ratio_flood_vs_plain": 1.0, "login_flood": {"requests": 5, "share_429": 0.8}, "note": None},
        "upload_memory_real_video": out})
    assert "answered 429" in table and "memory growth" in table

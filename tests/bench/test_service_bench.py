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

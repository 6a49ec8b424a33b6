"""The web service under load, side by side in one run (issue 25), for `saddlescope bench`.

- `readers_and_login_flood`: one real server; (a) `clients` readers of a ride's result for `duration_s`
  while a job runs, then (b) the same readers while `flood_clients` clients send wrong passwords to the
  sign-in as fast as they can. Readers' errors and p50/p95/p99 of both, the ratio of the p95s (goal:
  within 2x), and the flood's share answered 429.
- `run_all(quick=...)`: every service benchmark (`bench.service`) and the two above, with a table.
- `real_video(path, size_bytes)`: a real MJPEG AVI of about `size_bytes` (noise frames, which JPEG
  cannot shrink), the video a large-upload benchmark sends so the server accepts it as a video.
"""

from __future__ import annotations

import asyncio
import os
import sys
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from saddlescope.bench.service import (
    MIB,
    _analysed_ride,
    _percentiles,
    _scratch,
    _start_job,
    bench_server,
    concurrent_reads,
    leaderboard_latency,
    prepare_database,
    upload_memory,
)

__all__ = ["load_table", "readers_and_login_flood", "real_video", "run_all"]


def real_video(path: Path, size_bytes: int, *, fps: int = 30, size: tuple[int, int] = (1280, 720)) -> Path:
    """Write an MJPEG AVI of noise frames until it holds about `size_bytes` (a real, decodable video).

    A few frames are encoded once (noise: JPEG cannot shrink it) and their packets muxed again and again,
    so a gigabyte takes seconds, not the minutes of encoding every frame.
    """
    import av

    rng = np.random.default_rng(0)
    with av.open(str(path), "w", format="avi") as container:
        stream = container.add_stream("mjpeg", rate=fps)
        stream.width, stream.height, stream.pix_fmt = size[0], size[1], "yuvj420p"
        packets = []
        for _ in range(8):
            image = rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8)
            frame = av.VideoFrame.from_ndarray(image, format="rgb24").reformat(format="yuvj420p")
            packets += [bytes(p) for p in stream.encode(frame)]
        packets += [bytes(p) for p in stream.encode(None)]
        written, i = 0, 0
        while i < 2 or written < size_bytes:
            packet = av.Packet(packets[i % len(packets)])
            packet.stream, packet.pts, packet.dts = stream, i, i
            packet.time_base = stream.codec_context.time_base
            container.mux(packet)
            written += len(packets[i % len(packets)])
            i += 1
    return path


async def _readers(base_url: str, headers: dict, path: str, clients: int, duration_s: float) -> dict[str, Any]:
    latencies: list[float] = []
    errors: list[str] = []

    async def reader(client: httpx.AsyncClient, deadline: float) -> None:
        while time.monotonic() < deadline:
            t0 = time.perf_counter()
            try:
                response = await client.get(path)
                if response.status_code == 200:
                    latencies.append(time.perf_counter() - t0)
                else:
                    errors.append(f"HTTP {response.status_code}")
            except httpx.HTTPError as exc:
                errors.append(type(exc).__name__)

    limits = httpx.Limits(max_connections=clients, max_keepalive_connections=clients)
    t0 = time.perf_counter()
    async with httpx.AsyncClient(base_url=base_url, headers=headers, timeout=60, limits=limits) as client:
        deadline = time.monotonic() + duration_s
        await asyncio.gather(*(reader(client, deadline) for _ in range(clients)))
    elapsed = time.perf_counter() - t0
    return {"clients": clients, "duration_s": elapsed, "requests": len(latencies) + len(errors),
            "errors": len(errors), "error_kinds": sorted(set(errors))[:5],
            "requests_per_s": (len(latencies) + len(errors)) / elapsed, **_percentiles(latencies)}


async def _flood(base_url: str, clients: int, stop: asyncio.Event) -> dict[str, Any]:
    statuses: dict[str, int] = {}

    async def flooder(client: httpx.AsyncClient, n: int) -> None:
        while not stop.is_set():
            try:
                response = await client.post("/api/auth/login", data={
                    "username": "bench@bench.example", "password": f"wrong guess {n}"})
                key = str(response.status_code)
            except httpx.HTTPError as exc:
                key = type(exc).__name__
            statuses[key] = statuses.get(key, 0) + 1

    limits = httpx.Limits(max_connections=clients, max_keepalive_connections=clients)
    async with httpx.AsyncClient(base_url=base_url, timeout=60, limits=limits) as client:
        await asyncio.gather(*(flooder(client, n) for n in range(clients)))
    total = sum(statuses.values())
    return {"clients": clients, "requests": total, "statuses": statuses,
            "share_429": statuses.get("429", 0) / total if total else None}


def readers_and_login_flood(duration_s: float = 60.0, *, clients: int = 50, flood_clients: int = 40,
                            job_bundle: Path | None = None, samples: int = 600,
                            quick: bool = False) -> dict[str, Any]:
    """(a) readers while a job runs, then (b) the same with a sign-in flood, on one server."""
    with _scratch("saddlescope-bench-load-") as root:
        url = prepare_database(root)
        ride_id = _analysed_ride(root, url, samples)
        path = f"/api/rides/{ride_id}/result?max_points=2000"
        with bench_server(root, url) as server:
            job = _start_job(server, job_bundle, 2 * duration_s + 10)
            plain = asyncio.run(_readers(server.base_url, server.headers, path, clients, duration_s))

            async def flooded() -> tuple[dict, dict]:
                stop = asyncio.Event()
                flood_task = asyncio.create_task(_flood(server.base_url, flood_clients, stop))
                await asyncio.sleep(min(2.0, duration_s / 10))  # the flood is under way before timing starts
                readers = await _readers(server.base_url, server.headers, path, clients, duration_s)
                stop.set()
                return readers, await flood_task

            with_flood, flood = asyncio.run(flooded())
            job_view = httpx.get(f"{server.base_url}/api/jobs/{job}", headers=server.headers).json()
    ratio = (with_flood["p95_ms"] / plain["p95_ms"]) if plain["p95_ms"] and with_flood["p95_ms"] else None
    return {
        "quick": quick,
        "note": f"quick mode: {duration_s:g} s per phase instead of 60 s" if quick else None,
        "readers": plain,
        "readers_with_login_flood": with_flood,
        "login_flood": flood,
        "p95_ratio_flood_vs_plain": ratio,
        "job": {"kind": job_view.get("kind"), "status_at_end": job_view.get("status"),
                "stage_at_end": job_view.get("stage")},
        "goals": {"errors": 0, "p95_ratio_max": 2.0, "flood_answered": 429},
        "ok": plain["errors"] == 0 and with_flood["errors"] == 0 and ratio is not None and ratio <= 2.0
        and (flood["share_429"] or 0) > 0.5,
    }


def run_all(*, quick: bool = False) -> dict[str, Any]:
    """The service benchmarks (quick: 64 MiB uploads, 2,000 rides, readers for 5 s instead of 60 s).

    `load`: 50 readers while a job runs (an analysis of a synthetic ride; quick: a selftest job), then the
    same with 40 clients flooding the sign-in (`bench.load`); `upload_memory_real_video`: a 1 GB real
    video uploaded (quick: 64 MiB). A table of the load figures goes to stderr.
    """
    out: dict[str, Any] = {"load_avg_start": list(os.getloadavg())}
    out["upload_memory"] = upload_memory(64 * MIB if quick else 1024**3)
    with _scratch("saddlescope-bench-video-") as root:
        video = real_video(root / "big.avi", 64 * MIB if quick else 10**9)
        out["upload_memory_real_video"] = upload_memory(video=video)
        bundle = None
        if not quick:
            from saddlescope.io.synth_writer import write_ride_bundle

            bundle = write_ride_bundle(root / "ride", gait="canter", seed=7, duration_s=6.0)
        out["load"] = readers_and_login_flood(5.0 if quick else 60.0, job_bundle=bundle, quick=quick)
    out["leaderboard"] = leaderboard_latency(2_000 if quick else 10_000, repeats=20 if quick else 100)
    out["concurrent_reads"] = concurrent_reads(3.0 if quick else 30.0, clients=10 if quick else 50)
    out["load_avg_end"] = list(os.getloadavg())
    print(load_table(out), file=sys.stderr)
    return out


def load_table(out: dict[str, Any]) -> str:
    """The load figures of `run_all` as a plain table."""
    load, up = out["load"], out["upload_memory_real_video"]
    rows: list[tuple[str, ...]] = [("", "requests", "errors", "p50 ms", "p95 ms", "p99 ms")]
    for name, part in (("readers, job running", load["readers"]),
                       ("readers + login flood", load["readers_with_login_flood"])):
        rows.append((name, str(part["requests"]), str(part["errors"]),
                     *(f"{part[k]:.0f}" if part[k] is not None else "-" for k in ("p50_ms", "p95_ms", "p99_ms"))))
    lines = ["  ".join(f"{c:>22}" if i == 0 else f"{c:>9}" for i, c in enumerate(r)) for r in rows]
    ratio = load["p95_ratio_flood_vs_plain"]
    share = load["login_flood"]["share_429"]
    lines.append(f"p95 with flood / without: {ratio:.2f} (goal <= 2)" if ratio else "p95 ratio: -")
    lines.append(f"login flood: {load['login_flood']['requests']} requests, "
                 f"{100 * (share or 0):.1f} % answered 429")
    lines.append(f"upload of a real video ({up['size_mb']:.0f} MiB): status {up['status']}, "
                 f"API memory growth {up['growth_mb']:.1f} MB (goal < 100)")
    if load.get("note"):
        lines.append(load["note"])
    return "\n".join(lines)

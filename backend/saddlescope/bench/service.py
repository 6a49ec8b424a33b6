"""Benchmarks of the web service, for `saddlescope bench` (each returns a plain dict).

- `upload_memory`: a real ``saddlescope serve`` process receives a large upload (1 GiB by default)
  streamed by httpx; the server's resident memory is sampled from ``/proc`` while the bytes flow.
- `leaderboard_latency`: the club leaderboard over many rides (10,000 by default), timed in process
  (the service function) and over HTTP against a real server.
- `concurrent_reads`: many clients (50) read a ride's result for a while (30 s) while a job runs;
  errors and latency percentiles.
- `bench.load.run_all(quick=...)`: these and the load figures; quick mode uses small sizes and a few seconds.

Every server runs in embedded mode in a throw-away folder (SQLite, storage), so nothing of the user's
data is touched. Timings are wall times on a shared machine: read them next to the load average.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from saddlescope.core.types import GAITS
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Club, Horse, Result, Ride, Rider
from saddlescope.db.session import make_engine, make_session_factory, session_scope
from saddlescope.services.accounts.users import create_club
from saddlescope.services.results.documents import store_with_result, uncertain_reason_of

MIB = 1024**2
PASSWORD = "benchmark password"


# --- a throw-away server ---------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def rss_bytes(pid: int) -> int:
    """Resident set size of a process (Linux ``/proc``)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    raise OSError(f"no VmRSS for process {pid}")


@dataclass
class BenchServer:
    """A running ``saddlescope serve`` (embedded mode) and a signed-in account of its bench club."""

    process: subprocess.Popen
    base_url: str
    root: Path
    headers: dict[str, str]

    @property
    def pid(self) -> int:
        return self.process.pid


def prepare_database(root: Path) -> str:
    """A migrated SQLite database in `root` with the bench club and its admin; returns the URL."""
    url = f"sqlite:///{root / 'db.sqlite'}"
    upgrade_to_head(url)
    engine = make_engine(url)
    try:
        with session_scope(make_session_factory(engine)) as session:
            create_club(session, club_name="Bench club", email="bench@bench.example", password=PASSWORD)
    finally:
        engine.dispose()
    return url


@contextlib.contextmanager
def bench_server(
    root: Path, database_url: str, *, max_upload_bytes: int = 8 * 1024**3, startup_timeout_s: float = 180.0,
    extra_env: dict[str, str] | None = None,
) -> Iterator[BenchServer]:
    """Start ``saddlescope serve`` on a free port for a prepared database; stop it afterwards.

    `extra_env`: more settings for the server (e.g. ``SADDLESCOPE_STORAGE_URL`` for object storage).
    """
    port = _free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("SADDLESCOPE_")}
    env.update(
        SADDLESCOPE_DATABASE_URL=database_url,
        SADDLESCOPE_STORAGE_DIR=str(root / "storage"),
        SADDLESCOPE_MAX_UPLOAD_BYTES=str(max_upload_bytes),
        PYTHONUNBUFFERED="1",
        **(extra_env or {}),
    )
    log = (root / "serve.log").open("wb")
    code = "import sys; from saddlescope.cli import main; sys.exit(main(sys.argv[1:]))"
    process = subprocess.Popen(
        [sys.executable, "-c", code, "serve", "--host", "127.0.0.1", "--port", str(port)],
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
        cwd=root,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + startup_timeout_s
        while True:
            if process.poll() is not None:
                raise RuntimeError(
                    f"saddlescope serve exited with {process.returncode}: "
                    f"{(root / 'serve.log').read_text()[-2000:]}"
                )
            try:
                if httpx.get(f"{base}/api/health", timeout=2).status_code in (200, 503):
                    break
            except httpx.TransportError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"saddlescope serve did not start within {startup_timeout_s} s")
            time.sleep(0.2)
        login = httpx.post(
            f"{base}/api/auth/login",
            data={"username": "bench@bench.example", "password": PASSWORD},
            timeout=30,
        )
        login.raise_for_status()
        yield BenchServer(process, base, root, {"Authorization": f"Bearer {login.json()['access_token']}"})
    finally:
        process.terminate()
        try:
            process.wait(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=5)
        log.close()


@contextlib.contextmanager
def _scratch(prefix: str) -> Iterator[Path]:
    root = Path(tempfile.mkdtemp(prefix=prefix))
    try:
        yield root
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _percentiles(samples_s: list[float]) -> dict[str, float | int | None]:
    if not samples_s:
        return {"n": 0, "p50_ms": None, "p95_ms": None, "p99_ms": None, "max_ms": None, "mean_ms": None}
    ms = np.asarray(samples_s) * 1e3
    return {
        "n": int(ms.size),
        "p50_ms": float(np.percentile(ms, 50)),
        "p95_ms": float(np.percentile(ms, 95)),
        "p99_ms": float(np.percentile(ms, 99)),
        "max_ms": float(ms.max()),
        "mean_ms": float(ms.mean()),
    }


# --- 1. upload memory --------------------------------------------------------------------------------


def _generated_bytes(total: int, chunk: int) -> Iterator[bytes]:
    """`total` bytes in chunks (a few distinct blocks reused: generation costs nothing)."""
    blocks = [secrets.token_bytes(chunk) for _ in range(4)]
    sent = 0
    i = 0
    while sent < total:
        block = blocks[i % 4][: min(chunk, total - sent)]
        sent += len(block)
        i += 1
        yield block


def _file_chunks(path: Path, chunk: int) -> Iterator[bytes]:
    with path.open("rb") as stream:
        while block := stream.read(chunk):
            yield block


def _multipart(total: int, chunk: int, boundary: str) -> Iterator[bytes]:
    yield (
        f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="big.mp4"\r\n'
        "Content-Type: video/mp4\r\n\r\n"
    ).encode()
    yield from _generated_bytes(total, chunk)
    yield f"\r\n--{boundary}--\r\n".encode()


def _upload_body(video: Path | None, mode: str, size_bytes: int, chunk_bytes: int) -> tuple[Iterator[bytes], str]:
    if video is not None:
        return _file_chunks(Path(video), chunk_bytes), "application/octet-stream"
    if mode == "multipart":
        boundary = secrets.token_hex(12)
        return _multipart(size_bytes, chunk_bytes, boundary), f"multipart/form-data; boundary={boundary}"
    return _generated_bytes(size_bytes, chunk_bytes), "application/octet-stream"


def upload_memory(
    size_bytes: int = 1024**3,
    *,
    mode: str = "multipart",
    chunk_bytes: int = MIB,
    sample_interval_s: float = 0.05,
    video: Path | None = None,
    extra_env: dict[str, str] | None = None,
) -> dict[str, Any]:
    """Stream `size_bytes` of generated bytes to a real server and watch its resident memory.

    Without `video` the bytes are no video, so once stored the clip is refused (422) by the probe: the
    point is the server's memory while they stream (`growth_mb` = peak RSS during the upload - RSS
    before). With `video` (a real video file, e.g. `bench.load.real_video`) that file is sent instead
    and the server accepts it (200): the memory of the whole path, probe and registration included.

    Parameters
    ----------
    size_bytes : int
        Upload size (default 1 GiB).
    mode : {"multipart", "raw"}
        A browser-style multipart form, or the raw bytes as the body (`extra_env`: more server settings).
    """
    if video is not None:
        size_bytes, mode = Path(video).stat().st_size, "raw"
    if mode not in ("multipart", "raw"):
        raise ValueError(f"mode must be 'multipart' or 'raw', got {mode!r}")
    with _scratch("saddlescope-bench-upload-") as root:
        url = prepare_database(root)
        with bench_server(root, url, max_upload_bytes=size_bytes + 16 * MIB, extra_env=extra_env) as server:
            h = server.headers
            horse = httpx.post(f"{server.base_url}/api/horses", json={"name": "Big"}, headers=h).json()
            rider = httpx.post(f"{server.base_url}/api/riders", json={"name": "Big"}, headers=h).json()
            ride = httpx.post(
                f"{server.base_url}/api/rides",
                headers=h,
                json={"horse_id": horse["id"], "rider_id": rider["id"], "gait": "walk", "direction": "CW"},
            ).json()
            before = rss_bytes(server.pid)
            samples: list[int] = []
            stop = threading.Event()

            def sample() -> None:
                while not stop.is_set():
                    with contextlib.suppress(OSError):
                        samples.append(rss_bytes(server.pid))
                    stop.wait(sample_interval_s)

            sampler = threading.Thread(target=sample, daemon=True)
            sampler.start()
            body, content_type = _upload_body(video, mode, size_bytes, chunk_bytes)
            t0 = time.perf_counter()
            response = httpx.put(
                f"{server.base_url}/api/rides/{ride['id']}/clips/motion/left",
                content=body,
                headers={**h, "Content-Type": content_type},
                timeout=None,
            )
            elapsed = time.perf_counter() - t0
            stop.set()
            sampler.join()
            peak = max(samples + [rss_bytes(server.pid)])
    return {
        "size_mb": size_bytes / MIB,
        "mode": mode,
        "real_video": video is not None,
        "status": response.status_code,
        "detail": response.json().get("detail")
        if response.headers.get("content-type", "").startswith("application/json")
        else None,
        "rss_before_mb": before / MIB,
        "rss_peak_mb": peak / MIB,
        "growth_mb": (peak - before) / MIB,
        "seconds": elapsed,
        "throughput_mb_s": size_bytes / MIB / elapsed,
        "samples": len(samples),
        "limit_mb": 100.0,
        "ok": (peak - before) / MIB < 100.0,
    }


# --- 2. leaderboard ----------------------------------------------------------------------------------


def fill_rides(
    database_url: str, n_rides: int, *, n_horses: int = 60, gaits: tuple[str, ...] = GAITS, seed: int = 0
) -> int:
    """Add `n_rides` analysed rides (indicators drawn at random, gaits among `gaits`) to the bench club.

    Returns the club's id.
    """
    from sqlalchemy import insert, select

    from saddlescope.core.vibration import CONTRACT_KEYS

    rng = np.random.default_rng(seed)
    engine = make_engine(database_url)
    try:
        with session_scope(make_session_factory(engine)) as session:
            club_id = int(session.scalar(select(Club.id).where(Club.name == "Bench club")) or 0)
            session.execute(
                insert(Horse), [{"club_id": club_id, "name": f"Horse {i:03d}"} for i in range(n_horses)]
            )
            session.execute(
                insert(Rider), [{"club_id": club_id, "name": f"Rider {i:02d}"} for i in range(20)]
            )
            horse_ids = session.scalars(select(Horse.id).where(Horse.club_id == club_id)).all()
            rider_ids = session.scalars(select(Rider.id).where(Rider.club_id == club_id)).all()
            rides: list[dict[str, Any]] = [
                {
                    "club_id": club_id,
                    "horse_id": int(rng.choice(horse_ids)),
                    "rider_id": int(rng.choice(rider_ids)),
                    "gait": str(rng.choice(gaits)),
                    "direction": "CW",
                    "status": "analysed",
                    "notes": "",
                    "meta": {},
                }
                for _ in range(n_rides)
            ]
            session.execute(insert(Ride), rides)
            ride_ids = session.scalars(select(Ride.id).where(Ride.club_id == club_id).order_by(Ride.id)).all()
            results = []
            for ride_id in ride_ids:
                indicators = {key: float(rng.uniform(0.1, 10.0)) for key in CONTRACT_KEYS}
                results.append(
                    {
                        "club_id": club_id,
                        "ride_id": ride_id,
                        "indicators": indicators,
                        **{
                            k: indicators[k]
                            for k in (
                                "acc_y_wb_rms",
                                "acc_y_wk_rms",
                                "vdv_y_wb",
                                "vdv_y_wk",
                                "vel_x_avg_kmh",
                                "amplitude_y_m",
                                "stride_frequency_hz",
                            )
                        },
                    }
                )
            session.execute(insert(Result), results)
            return club_id
    finally:
        engine.dispose()


def leaderboard_latency(
    n_rides: int = 10_000,
    *,
    repeats: int = 100,
    http: bool = True,
    indicator: str = "acc_y_wb_rms",
    one_gait: bool = True,
) -> dict[str, Any]:
    """Latency of the club leaderboard over `n_rides` rides: in process, and over HTTP (real server).

    With `one_gait` (the worst case) every ride is a canter and each ranking covers all of them;
    otherwise the rides are spread over the four gaits and the repeats cycle through them. Also times
    an indicator without its own column (read from the JSON of every result) for comparison.
    """
    from saddlescope.services.comparisons.analytics import club_leaderboard

    with _scratch("saddlescope-bench-leaderboard-") as root:
        url = prepare_database(root)
        gaits = ("canter",) if one_gait else GAITS
        club_id = fill_rides(url, n_rides, gaits=gaits)
        engine = make_engine(url)
        sessions = make_session_factory(engine)
        timings: dict[str, list[float]] = {"column": [], "json": []}
        try:
            for i in range(repeats):
                for key, name in (("column", indicator), ("json", "t_a8_limit_wb_h")):
                    with sessions() as session:
                        t0 = time.perf_counter()
                        club_leaderboard(session, club_id=club_id, gait=gaits[i % len(gaits)], indicator=name)
                        timings[key].append(time.perf_counter() - t0)
        finally:
            engine.dispose()
        out: dict[str, Any] = {
            "rides": n_rides,
            "indicator": indicator,
            "gaits": list(gaits),
            "service": _percentiles(timings["column"]),
            "service_json_indicator": _percentiles(timings["json"]),
        }
        if http:
            with (
                bench_server(root, url) as server,
                httpx.Client(base_url=server.base_url, headers=server.headers) as client,
            ):
                client.get(
                    "/api/leaderboard", params={"gait": gaits[0], "indicator": indicator}
                ).raise_for_status()
                samples = []
                for i in range(repeats):
                    t0 = time.perf_counter()
                    client.get(
                        "/api/leaderboard", params={"gait": gaits[i % len(gaits)], "indicator": indicator}
                    ).raise_for_status()
                    samples.append(time.perf_counter() - t0)
                out["http"] = _percentiles(samples)
    out["limit_p95_ms"] = 50.0
    out["ok"] = out["service"]["p95_ms"] < 50.0 and (not http or out["http"]["p95_ms"] < 50.0)
    return out


# --- 3. concurrent readers while a job runs ----------------------------------------------------------------


def _synthetic_result(samples: int) -> dict[str, Any]:
    """A result document with `samples` samples per series (100 fps) for the readers to fetch."""
    fps = 100.0
    seconds = samples / fps
    t = np.arange(samples) / fps
    xyz = np.stack([np.sin(t), np.cos(t), 0.1 * t], axis=1)
    series = xyz.tolist()
    return {
        "format": "saddlescope.result/1",
        "fps": fps,
        "period_s": 0.6,
        "window": {"start_s": 0.0, "duration_s": seconds},
        "calibration": {"cameras": {}, "checks": {}, "flags": []},
        "saddle": {
            "t_s": t.tolist(),
            "position_m": series,
            "velocity_m_s": series,
            "acceleration_m_s2": series,
        },
        "angular": {"omega_rad_s": series, "alpha_rad_s2": series, "singularity_index": 0.1},
        "markers": {"names": ["M1", "M2", "M3"], "position_m": [[p, p, p] for p in series]},
        "indicators": {"acc_y_wb_rms": 2.5, "vdv_y_wb": 9.1},
        "quality": {"flags": []},
        "timings_s": {"total": 1},
    }


def _analysed_ride(root: Path, database_url: str, samples: int) -> int:
    """One ride of the bench club with a stored result (written as the analyze stage would)."""
    from sqlalchemy import select

    from saddlescope.db.repositories import ResultRepository
    from saddlescope.storage import FileStorage, stage_output_key

    engine = make_engine(database_url)
    try:
        with session_scope(make_session_factory(engine)) as session:
            club_id = int(session.scalar(select(Club.id).where(Club.name == "Bench club")) or 0)
            horse = Horse(club_id=club_id, name="Reader")
            rider = Rider(club_id=club_id, name="Reader")
            session.add_all([horse, rider])
            session.flush()
            ride = Ride(
                club_id=club_id,
                horse_id=horse.id,
                rider_id=rider.id,
                gait="canter",
                direction="CW",
                status="analysed",
                notes="",
                meta={},
            )
            session.add(ride)
            session.flush()
            key = f"{stage_output_key(ride.id, 'analyze')}/result.json"
            document = _synthetic_result(samples)
            storage = FileStorage(root / "storage")
            storage.write_bytes(key, json.dumps(document).encode())
            store_with_result(storage, key, document)  # its derived series and page beside it, as commit_result
            ResultRepository(session).replace_for_ride(
                club_id=club_id,
                ride_id=ride.id,
                job_id=None,
                indicators=document["indicators"],
                result_key=key,
                code_version="bench",
                uncertain_reason=uncertain_reason_of(document),
            )
            return ride.id
    finally:
        engine.dispose()


def concurrent_reads(
    duration_s: float = 30.0,
    *,
    clients: int = 50,
    job_bundle: Path | None = None,
    samples: int = 600,
    max_points: int = 2000,
) -> dict[str, Any]:
    """`clients` concurrent readers of a ride's result for `duration_s` while a job runs.

    The ride's result has `samples` samples per series (a real two-stride window at 30-100 fps has
    40-150; 600 is generous); every reader fetches it whole (`max_points`).

    The job is the analysis of `job_bundle` (a ride bundle folder or zip: real CPU load) when given,
    else a ``selftest`` job lasting the whole run. Returns requests, errors (non-200 or transport),
    requests per second and latency percentiles, and whether the job was still running at the end.
    """
    with _scratch("saddlescope-bench-readers-") as root:
        url = prepare_database(root)
        ride_id = _analysed_ride(root, url, samples)
        with bench_server(root, url) as server:
            job = _start_job(server, job_bundle, duration_s)
            latencies: list[float] = []
            errors: list[str] = []

            async def reader(client: httpx.AsyncClient, deadline: float) -> None:
                while time.monotonic() < deadline:
                    t0 = time.perf_counter()
                    try:
                        response = await client.get(
                            f"/api/rides/{ride_id}/result", params={"max_points": max_points}
                        )
                        if response.status_code != 200:
                            errors.append(f"HTTP {response.status_code}")
                        else:
                            latencies.append(time.perf_counter() - t0)
                    except httpx.HTTPError as exc:
                        errors.append(type(exc).__name__)

            async def run() -> None:
                limits = httpx.Limits(max_connections=clients, max_keepalive_connections=clients)
                async with httpx.AsyncClient(
                    base_url=server.base_url, headers=server.headers, timeout=60, limits=limits
                ) as client:
                    deadline = time.monotonic() + duration_s
                    await asyncio.gather(*(reader(client, deadline) for _ in range(clients)))

            t0 = time.perf_counter()
            asyncio.run(run())
            elapsed = time.perf_counter() - t0
            job_view = httpx.get(f"{server.base_url}/api/jobs/{job}", headers=server.headers).json()
    return {
        "clients": clients,
        "samples": samples,
        "duration_s": elapsed,
        "requests": len(latencies) + len(errors),
        "errors": len(errors),
        "error_kinds": sorted(set(errors))[:5],
        "requests_per_s": (len(latencies) + len(errors)) / elapsed,
        **_percentiles(latencies),
        "job": {
            "kind": job_view.get("kind"),
            "status_at_end": job_view.get("status"),
            "progress_at_end": job_view.get("progress"),
        },
        "ok": not errors,
    }


def _start_job(server: BenchServer, bundle: Path | None, duration_s: float) -> int:
    h = server.headers
    if bundle is None:
        steps = max(1, int(duration_s / 0.5) + 2)
        created = httpx.post(
            f"{server.base_url}/api/jobs",
            headers=h,
            json={"kind": "selftest", "payload": {"steps": min(steps, 1000), "delay_s": 0.5}},
        )
        created.raise_for_status()
        return created.json()["id"]
    bundle = Path(bundle)
    if bundle.is_dir():
        from saddlescope.io.bundle import write_bundle_zip

        zip_path = server.root / "bench-ride.zip"
        write_bundle_zip(bundle, zip_path)
        bundle = zip_path
    with bundle.open("rb") as stream:
        created = httpx.post(
            f"{server.base_url}/api/rides/bundle",
            headers=h,
            timeout=300,
            files={"file": (bundle.name, stream, "application/zip")},
        )
    created.raise_for_status()
    return created.json()["job_id"]


__all__ = [
    "upload_memory",
    "leaderboard_latency",
    "concurrent_reads",
    "bench_server",
    "fill_rides",
    "rss_bytes",
]

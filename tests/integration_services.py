"""Test helpers of the service layer: real PostgreSQL, Redis and Celery worker fixtures, tiny bundles.

Import the fixtures into a test module by assignment (``pg_database_url = integration_services.
pg_database_url``). Without ``CI=true`` a missing service skips its tests with the reason; under CI
it fails them. Each run gets its own PostgreSQL database and Redis db number, so parallel runs do
not collide, and a summary at the end of the run names the services the tests really used.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import IN_CI, PROJECT_ROOT

PG_HOST, PG_PORT = "127.0.0.1", 5432
PG_USERS = ("postgres", "root")
REDIS_HOST, REDIS_PORT = "127.0.0.1", 6379
REDIS_DBS = range(9, 16)  # away from db 0, which a developer's own services may use
VENV_BIN = Path(sys.executable).parent
TEST_SECRET = "integration-test-secret-" + secrets.token_hex(8)


def require_service(name: str, detail: str) -> None:
    """Skip (or, under CI, fail) a test whose service is unreachable."""
    message = f"{name} is not reachable: {detail}"
    if IN_CI:
        pytest.fail(f"{message} (CI=true requires it)")
    pytest.skip(f"{message} (set CI=true to make this a failure)")


class _ServiceReport:
    """Collects one line per real service used and prints them in the terminal summary."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def pytest_terminal_summary(self, terminalreporter) -> None:
        if self.lines:
            terminalreporter.section("SaddleScope integration services used")
            for line in self.lines:
                terminalreporter.write_line(line)


def report_service(config: pytest.Config, line: str) -> None:
    plugin = config.pluginmanager.get_plugin("saddlescope-service-report")
    if plugin is None:
        plugin = _ServiceReport()
        config.pluginmanager.register(plugin, "saddlescope-service-report")
    if line not in plugin.lines:
        plugin.lines.append(line)


# --- PostgreSQL -----------------------------------------------------------------------------------


def _pg_admin():
    import psycopg

    errors = []
    for user in PG_USERS:
        try:
            conn = psycopg.connect(
                host=PG_HOST, port=PG_PORT, user=user, dbname="test", connect_timeout=3, autocommit=True
            )
        except psycopg.OperationalError as exc:
            errors.append(f"as {user}: {str(exc).strip().splitlines()[0]}")
            continue
        return conn, user
    require_service("PostgreSQL", f"{PG_HOST}:{PG_PORT} database 'test' ({'; '.join(errors)})")
    raise AssertionError("unreachable")


@pytest.fixture(scope="module")
def pg_database_url(request):
    """SQLAlchemy URL of a fresh, empty PostgreSQL database, dropped after the module."""
    conn, user = _pg_admin()
    name = f"saddlescope_test_{os.getpid()}_{secrets.token_hex(4)}"
    with conn:
        version = conn.execute("SHOW server_version").fetchone()[0]
        conn.execute(f'CREATE DATABASE "{name}"')
        report_service(
            request.config,
            f"PostgreSQL {version} at {PG_HOST}:{PG_PORT} (user {user}), "
            f"throw-away databases saddlescope_test_*",
        )
        try:
            yield f"postgresql+psycopg://{user}@{PG_HOST}:{PG_PORT}/{name}"
        finally:
            from saddlescope.db.session import engine_for

            engine_for.cache_clear()
            # FORCE: pools of engines still open in this process must not keep the database alive.
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


# --- Redis ----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def redis_url(request):
    """URL of a Redis database number no other run is using (claimed with a lock key), flushed after."""
    import redis

    claimed = None
    for db in REDIS_DBS:
        client = redis.Redis(host=REDIS_HOST, port=REDIS_PORT, db=db, socket_connect_timeout=3)
        try:
            if client.set("saddlescope-test-lock", os.getpid(), nx=True, ex=3600):
                if client.dbsize() == 1:  # only our lock: nobody else uses this db
                    claimed = (db, client)
                    break
                client.delete("saddlescope-test-lock")
        except redis.exceptions.ConnectionError as exc:
            require_service("Redis", f"{REDIS_HOST}:{REDIS_PORT}: {exc}")
        client.close()
    if claimed is None:
        require_service("Redis", f"every test db {REDIS_DBS.start}-{REDIS_DBS.stop - 1} is in use")
    db, client = claimed
    version = client.info("server")["redis_version"]
    report_service(request.config, f"Redis {version} at {REDIS_HOST}:{REDIS_PORT} (db {db})")
    try:
        yield f"redis://{REDIS_HOST}:{REDIS_PORT}/{db}"
    finally:
        client.flushdb()
        client.close()


@contextlib.contextmanager
def own_redis_server(folder: Path):
    """A redis-server of the caller's own on a free port (to stop it without stopping others' Redis):
    yields ``(process, url)``; terminated at the end."""
    import redis

    binary = shutil.which("redis-server")
    if binary is None:
        require_service("redis-server", "the redis-server program is not installed")
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    proc = subprocess.Popen([binary, "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--appendonly",
                             "no", "--dir", str(folder)], stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    url = f"redis://127.0.0.1:{port}/0"
    client = redis.Redis.from_url(url, socket_connect_timeout=1)
    try:
        for _ in range(200):  # wait until it answers (no timing asserted)
            try:
                client.ping()
                break
            except redis.ConnectionError:
                if proc.poll() is not None:
                    require_service("redis-server", f"exited with {proc.returncode}")
                time.sleep(0.05)
        yield proc, url
    finally:
        client.close()
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=10)


# --- a real Celery worker -------------------------------------------------------------------------


def service_env(*, database_url: str, storage_dir: Path, broker_url: str | None = None) -> dict[str, str]:
    """Environment of a SaddleScope child process (server or worker) for these services."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SADDLESCOPE_")}
    if "SADDLESCOPE_PASSWORD_HASHING" in os.environ:  # tests/conftest.py: the cheapest Argon2 for tests
        env["SADDLESCOPE_PASSWORD_HASHING"] = os.environ["SADDLESCOPE_PASSWORD_HASHING"]
    env.update(
        SADDLESCOPE_DATABASE_URL=database_url,
        SADDLESCOPE_STORAGE_DIR=str(storage_dir),
        SADDLESCOPE_SECRET_KEY=TEST_SECRET,
        PYTHONUNBUFFERED="1",
    )
    if broker_url is not None:
        env["SADDLESCOPE_BROKER_URL"] = broker_url
    return env


def stop_process(proc: subprocess.Popen, *, timeout_s: float = 15.0) -> None:
    """Terminate a child we started (SIGTERM, then SIGKILL if it lingers)."""
    if proc.poll() is not None:
        return
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5)


@contextlib.contextmanager
def run_celery_worker(*, database_url: str, broker_url: str, storage_dir: Path, log_path: Path,
                      app: str = "saddlescope_worker.app", extra_env: dict[str, str] | None = None,
                      config: pytest.Config | None = None):
    """A real ``celery worker`` process (solo pool) until the block ends; yields the Popen.

    `app` is the module holding the Celery app (a test module may wrap ours, e.g. to install the
    stand-in analysis); `extra_env` is added to the worker's environment (PYTHONPATH, ...).
    """
    env = service_env(database_url=database_url, storage_dir=storage_dir, broker_url=broker_url)
    env.update(extra_env or {})
    name = f"saddlescope-test-{os.getpid()}-{secrets.token_hex(3)}@%h"
    start = log_path.stat().st_size if log_path.exists() else 0  # a restarted worker appends to the log
    with log_path.open("ab") as log:
        proc = subprocess.Popen(
            [
                str(VENV_BIN / "celery"),
                "-A",
                app,
                "worker",
                "--pool=solo",
                "-c",
                "1",
                "-Q",
                "saddlescope",
                "-n",
                name,
                "--loglevel=INFO",
                "--without-gossip",
                "--without-mingle",
                "--without-heartbeat",
            ],
            cwd=PROJECT_ROOT,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    try:
        deadline = time.monotonic() + 90
        while b" ready." not in log_path.read_bytes()[start:]:
            if proc.poll() is not None:
                pytest.fail(
                    f"the Celery worker exited with {proc.returncode}:\n{log_path.read_text()[-3000:]}"
                )
            if time.monotonic() > deadline:
                pytest.fail(f"the Celery worker was not ready after 90 s:\n{log_path.read_text()[-3000:]}")
            time.sleep(0.2)
        if config is not None:
            import celery

            report_service(
                config,
                f"Celery {celery.__version__} worker process pid {proc.pid} (solo pool, real broker "
                "round trips)",
            )
        yield proc
    finally:
        stop_process(proc)


@pytest.fixture(scope="module")
def celery_worker(request, pg_database_url, redis_url, tmp_path_factory):
    """A real ``celery worker`` process (solo pool) on the test database and Redis db.

    Yields a dict with the URLs, the shared storage folder and the worker's log path.
    """
    from saddlescope.db.migrate import upgrade_to_head

    upgrade_to_head(pg_database_url)
    root = tmp_path_factory.mktemp("celery")
    storage_dir = root / "storage"
    log_path = root / "worker.log"
    with run_celery_worker(database_url=pg_database_url, broker_url=redis_url, storage_dir=storage_dir,
                           log_path=log_path, config=request.config) as proc:
        yield {
            "database_url": pg_database_url,
            "broker_url": redis_url,
            "storage_dir": storage_dir,
            "log_path": log_path,
            "process": proc,
        }


# --- a tiny synthetic ride (real H.264 clips with markers, flash, board) ----------------------------


def built_once_per_run(tmp_path_factory, name: str, build: Callable[[Path], object]) -> Path:
    """The folder `<run's temp root>/<name>`, made by `build(folder)` for the first test asking for it.

    A session fixture assigned into several modules is a fixture of each module (pytest runs it once
    per module), and each pytest-xdist worker is a session of its own: the folder is shared through
    the run's temporary root under a lock instead. Tests must treat it as read-only."""
    from rendered_rides import built_once

    base = tmp_path_factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base  # xdist: the run's root
    with built_once(root / name, build) as folder:  # another worker may be building it: it waits
        return folder


@pytest.fixture(scope="session")
def tiny_ride(tmp_path_factory) -> Path:
    """A short synthetic ride bundle (2.5 s, 20 calibration poses, no extras), written once per run."""
    from rendered_rides import cached_ride_bundle

    return built_once_per_run(tmp_path_factory, "tiny-ride", lambda folder: cached_ride_bundle(
        folder / "ride", gait="canter", seed=3, duration_s=2.5, calibration_poses=20, extras=False)) / "ride"


@pytest.fixture(scope="session")
def short_canter_ride(tmp_path_factory) -> Path:
    """A 3 s thesis-rig canter (seed 4, the default 90 calibration poses, the extra clips), written once
    per run: tests/core/pipeline/test_pipeline.py analyses it against its truth, test_parallel_detection
    tracks its static shot with one thread and with three. Read-only."""
    from rendered_rides import cached_ride_bundle

    return built_once_per_run(tmp_path_factory, "short-canter-seed4", lambda folder: cached_ride_bundle(
        folder / "canter", gait="canter", seed=4, rig="thesis", duration_s=3.0, extras=True)) / "canter"


# --- tiny inputs ----------------------------------------------------------------------------------


def write_tiny_clip(
    path: Path, *, frames: int = 5, size: tuple[int, int] = (64, 48), fps: float = 30.0, shade: int = 0
) -> Path:
    """A real (MJPEG AVI) video of `frames` grey frames of `size` (w, h) px (`shade` brightens them all)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, size)
    if not writer.isOpened():
        raise RuntimeError(f"OpenCV cannot write {path}")
    for i in range(frames):
        writer.write(np.full((size[1], size[0], 3), min(255, 40 + 10 * i + shade), np.uint8))
    writer.release()
    return path


def write_noise_clip(path, n=60, *, gop=None, faststart=False, flash=None) -> None:
    """An H.264 clip (PyAV) of `n` 64x48 frames of seeded noise; `gop` frames between keyframes, `faststart`
    (the index first), `flash` (first, end) frames brightened by 150."""
    import av

    container = av.open(str(path), "w", options={"movflags": "faststart"} if faststart else {})
    stream = container.add_stream("libx264", rate=30)
    stream.width, stream.height, stream.pix_fmt = 64, 48, "yuv420p"
    stream.options = {"crf": "18", **({"g": str(gop)} if gop else {})}
    rng = np.random.default_rng(1)
    for i in range(n):
        img = rng.integers(40, 60, (48, 64, 3), dtype=np.uint8)
        if flash is not None and flash[0] <= i < flash[1]:
            img = img + 150
        for packet in stream.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
            container.mux(packet)
    for packet in stream.encode():
        container.mux(packet)
    container.close()


def mp4_with_a_free_box(source: Path, dest: Path, note: str) -> Path:
    """`source` (an MP4) with a trailing ISO BMFF ``free`` box holding `note`: the same video, other bytes.

    Every reader skips ``free`` boxes, so it decodes frame for frame as `source`; its content hash is its own
    (the same clips never make two rides of a club, so a test's second ride needs clips of its own).
    """
    dest.parent.mkdir(parents=True, exist_ok=True)
    dest.write_bytes(source.read_bytes() + free_box(note))
    return dest


def free_box(note: str) -> bytes:
    """An ISO BMFF ``free`` box holding `note` (MP4 readers skip it wherever it is)."""
    payload = note.encode()
    return (8 + len(payload)).to_bytes(4, "big") + b"free" + payload


def zip_with_a_flipped_byte(data: bytes, name: str) -> bytes:
    """`data` (a zip of stored members) with one byte inside member `name` changed: its CRC no longer matches."""
    import io
    import zipfile

    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        info = zf.getinfo(name)
    at = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra) + info.compress_size // 2
    return data[:at] + bytes([data[at] ^ 0xFF]) + data[at + 1:]


_bundles_written = itertools.count()


def write_tiny_bundle(folder: Path, *, gait: str = "walk", frames: int = 5) -> Path:
    """A ride bundle (CONTRACTS section 1) of tiny clips; the plumb clips are image folders.

    Each bundle's motion clips are its own (a shade no other bundle of this run has, up to 120 bundles, nor
    a plain `write_tiny_clip`): the same motion clips never make two rides of a club.
    """
    shade = 1 + next(_bundles_written) % 120  # never 0: unlike any plain `write_tiny_clip`
    clips: dict[str, dict[str, str]] = {}
    for kind in ("calibration", "plumb", "static", "motion"):
        clips[kind] = {}
        for role in ("left", "middle", "right"):
            if kind == "plumb":
                rel = f"{kind}/{role}"
                for i in range(frames):
                    (folder / rel).mkdir(parents=True, exist_ok=True)
                    cv2.imwrite(str(folder / rel / f"{i + 1:04d}.png"), np.full((48, 64), 30 * i, np.uint8))
            else:
                rel = f"{kind}/{role}.avi"
                write_tiny_clip(folder / rel, frames=frames, shade=shade if kind == "motion" else 0)
            clips[kind][role] = rel
    meta = {
        "format": "saddlescope.ride/1",
        "cameras": ["left", "middle", "right"],
        "board": {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0},
        "sync": {"method": "flash"},
        "markers": {"horse": 3, "plumb": 2, "saddle": 1},
        "horse": {"name": "Horse 2", "breed": "Dutch", "birth_year": 1999, "height_m": 1.73},
        "rider": {"name": "Rider B"},
        "gait": gait,
        "direction": "CCW",
        "clips": clips,
    }
    (folder / "ride.json").write_text(json.dumps(meta, indent=2))
    return folder


# --- a client signed in as a user ----------------------------------------------------------------------


class Api:
    """A TestClient with a bearer token: ``api.get("/horses")`` calls ``/api/horses``."""

    def __init__(self, client, token: str | None = None) -> None:
        self.client = client
        self.headers = {"Authorization": f"Bearer {token}"} if token else {}

    def request(self, method: str, path: str, **kwargs):
        headers = {**self.headers, **kwargs.pop("headers", {})}
        return self.client.request(method, f"/api{path}", headers=headers, **kwargs)

    def get(self, path, **kw):
        return self.request("GET", path, **kw)

    def post(self, path, **kw):
        return self.request("POST", path, **kw)

    def put(self, path, **kw):
        return self.request("PUT", path, **kw)

    def patch(self, path, **kw):
        return self.request("PATCH", path, **kw)

    def delete(self, path, **kw):
        return self.request("DELETE", path, **kw)

    def ok(self, method: str, path: str, status: int = 200, **kw):
        """The JSON of a call that must answer `status` (fails with the body otherwise)."""
        response = self.request(method, path, **kw)
        assert response.status_code == status, (
            f"{method} {path}: {response.status_code} {response.text[:500]}")
        is_json = response.content and "json" in response.headers.get("content-type", "")
        return response.json() if is_json else response

    def wait_job(self, job_id: int, *, timeout_s: float = 60.0) -> tuple[dict, list[dict]]:
        """Poll a job until finished; (last view, every view seen)."""
        return poll_job(lambda: self.ok("GET", f"/jobs/{job_id}"), job_id, timeout_s=timeout_s)


def poll_job(view: Callable[[], dict], job_id: int, *, timeout_s: float = 60.0) -> tuple[dict, list[dict]]:
    """Call `view()` (the job as the API shows it) until the job is finished; (last view, every view seen).

    The pauses between polls grow from 50 ms to a tenth of a second: a poll is a request the test process
    serves (at 20 a second for a minute-long job they took a tenth of a core), and a quarter second's pause
    made the quick tier's many short jobs wait longer than it saved.
    """
    seen: list[dict] = []
    deadline, pause = time.monotonic() + timeout_s, 0.05
    while time.monotonic() < deadline:
        seen.append(view())
        if seen[-1]["status"] in ("done", "failed", "cancelled"):
            return seen[-1], seen
        time.sleep(pause)
        pause = min(0.1, pause * 1.5)
    pytest.fail(f"job {job_id} not finished after {timeout_s} s: {seen[-1] if seen else None}")


_counter = iter(range(1, 10**9))


def new_club(client, *, name: str | None = None, password: str = "correct horse 1") -> tuple[Api, dict]:
    """Register a fresh club (its first admin) and sign in; (api, {"club", "user", "email", "password"})."""
    n = next(_counter)
    name = name or f"Club {n}-{os.getpid()}-{time.monotonic_ns()}"
    email = f"admin{n}.{time.monotonic_ns()}@club.example"
    created = client.post("/api/clubs", json={"club_name": name, "email": email, "password": password})
    assert created.status_code == 201, created.text
    return sign_in(client, email, password), {**created.json(), "email": email, "password": password}


def sign_in(client, email: str, password: str) -> Api:
    response = client.post("/api/auth/login", data={"username": email, "password": password})
    assert response.status_code == 200, response.text
    client.cookies.clear()  # bearer only: a test's cookie must not authenticate the next one
    return Api(client, response.json()["access_token"])


def add_member(admin: Api, *, role: str = "member", password: str = "member password") -> tuple[Api, dict]:
    n = next(_counter)
    email = f"member{n}.{time.monotonic_ns()}@club.example"
    user = admin.ok("POST", "/users", 201, json={"email": email, "password": password, "role": role})
    return sign_in(admin.client, email, password), user

"""The multi-host set-up (issue 26, part 5): `cluster`, one per test module, torn down even when a test fails.

Not a conftest.py: a second module named `conftest` would shadow tests/conftest.py, which test modules
import by that name. A test module takes the fixture by assignment (``cluster = hosts.cluster``).

Hosts (network namespaces, `netns.py`): ``pg`` (PostgreSQL), ``redis`` (Redis, append-only), ``s3``
(SeaweedFS), ``api`` (`saddlescope serve`), ``w1`` and ``w2`` (Celery workers running the stand-in
analysis of the API tests, made slow on demand), ``api2`` and ``api3`` (API replicas a drill starts),
``client`` (where the test's own HTTP and SQL clients live). Each host has its own SADDLESCOPE_HOST_NAME
(the namespaces share the machine's host name and pids) and the stale time is `STALE_AFTER_S`. Every
host has its own folders; nothing is shared but the network. Under CI=true the set-up must run (root is
available); elsewhere it skips with the reason where namespaces cannot be made.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import integration_services
import netns
import pytest

TEST_SECRET = integration_services.TEST_SECRET
IN_CI = os.environ.get("CI", "").lower() in {"1", "true", "yes"}  # as tests/conftest.py reads it
PROJECT_ROOT = Path(__file__).resolve().parents[2]
READY_TIMEOUT_S = 90.0
# Short, so a cut-off worker loses its job within seconds (production: 180 s); heartbeats every 1.5 s.
STALE_AFTER_S = 6.0


class NsHttp:
    """An httpx client whose every request runs inside the client host (quacks like a TestClient)."""

    def __init__(self, thread: netns.NetnsThread, base_url: str) -> None:
        self.thread = thread
        self.http = httpx.Client(base_url=base_url, timeout=30.0)

    @property
    def cookies(self):
        return self.http.cookies

    def request(self, method: str, url: str, **kwargs):
        return self.thread.call(self.http.request, method, url, **kwargs)

    def get(self, url: str, **kwargs):
        return self.request("GET", url, **kwargs)

    def post(self, url: str, **kwargs):
        return self.request("POST", url, **kwargs)

    def close(self) -> None:
        self.thread.call(self.http.close)


@dataclass
class Cluster:
    network: netns.Network
    root: Path
    client: netns.NetnsThread
    s3_keys: tuple[str, str]
    bucket: str = ""
    services: dict[str, netns.Service] = field(default_factory=dict)
    workers: dict[str, netns.Service] = field(default_factory=dict)
    pg_host: str = "pg"
    pg_root: Path | None = None  # the PostgreSQL data folders (owned by `postgres`, outside pytest's tmp)

    @property
    def database_url(self) -> str:
        return self.database_url_on(self.pg_host)

    def database_url_on(self, host: str) -> str:
        return f"postgresql+psycopg://postgres@{self.network.address(host)}:{netns.PG_PORT}/postgres"

    @property
    def broker_url(self) -> str:
        return f"redis://{self.network.address('redis')}:{netns.REDIS_PORT}/0"

    @property
    def s3_endpoint_url(self) -> str:
        return f"http://{self.network.address('s3')}:{netns.S3_PORT}"

    @property
    def api_url(self) -> str:
        return self.api_url_on("api")

    def api_url_on(self, host: str, port: int = netns.API_PORT) -> str:
        return f"http://{self.network.address(host)}:{port}"

    def env(self, host: str, **extra: str) -> dict[str, str]:
        """A SaddleScope process's environment on `host`: its own storage folder, the bucket, the services."""
        env = integration_services.service_env(database_url=self.database_url, broker_url=self.broker_url,
                                               storage_dir=self.root / host / "storage")
        tests = PROJECT_ROOT / "tests"
        env.update(
            SADDLESCOPE_STORAGE_URL=f"s3://{self.bucket}/club-data", SADDLESCOPE_S3_ENDPOINT_URL=self.s3_endpoint_url,
            AWS_ACCESS_KEY_ID=self.s3_keys[0], AWS_SECRET_ACCESS_KEY=self.s3_keys[1], AWS_DEFAULT_REGION="us-east-1",
            SADDLESCOPE_OPEN_REGISTRATION="true", SADDLESCOPE_RECOVERY_INTERVAL_S="2",
            SADDLESCOPE_REQUEUE_AFTER_S="4", SADDLESCOPE_WORKER_THREADS="1",
            # Every host its own name: the namespaces share the machine's host name and its pids.
            SADDLESCOPE_HOST_NAME=host, SADDLESCOPE_STALE_AFTER_S=str(STALE_AFTER_S),
            PYTHONPATH=os.pathsep.join([str(tests / "api"), str(tests), os.environ.get("PYTHONPATH", "")]),
            TMPDIR=str(self.root / host / "tmp"))
        (self.root / host / "tmp").mkdir(parents=True, exist_ok=True)
        env.update(extra)
        return env

    def start_api(self, host: str = "api", **extra_env: str) -> netns.Service:
        """`saddlescope serve` on `host` (registered as the service named `host`); waits until healthy."""
        log_path = self.root / host / "api.log"
        proc = netns.spawn(self.network, host, [sys.executable, "-m", "saddlescope.cli", "serve", "--host",
                                                self.network.address(host), "--port", str(netns.API_PORT)],
                           log_path=log_path, env=self.env(host, **extra_env), cwd=PROJECT_ROOT)
        service = netns.Service("api", host, proc, log_path, netns.API_PORT)
        self.services[host] = service
        deadline = time.monotonic() + READY_TIMEOUT_S
        while self.client.call(_health, self.api_url_on(host)) != 200:
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"the API did not answer /api/health in {READY_TIMEOUT_S:.0f} s "
                            f"(exit {proc.poll()}); its log ends:\n{netns.tail(log_path)}")
            time.sleep(0.3)
        return service

    def start_worker(self, host: str, *, delay_s: float = 0.0, real: bool = False) -> netns.Service:
        """A Celery worker (solo pool) on `host`, waiting until ready: the stand-in analysis taking `delay_s`
        (the drills time their faults on it), or with `real` SaddleScope's own worker and pipeline."""
        log_path = self.root / host / "worker.log"
        start = log_path.stat().st_size if log_path.exists() else 0
        app = "saddlescope_worker.app" if real else "standin_worker"
        args = [str(netns.VENV_BIN / "celery"), "-A", app, "worker", "--pool=solo", "-c", "1",
                "-Q", "saddlescope", "-n", f"ssmh-{host}-{secrets.token_hex(2)}@%h", "--loglevel=INFO",
                "--without-gossip", "--without-mingle", "--without-heartbeat"]
        proc = netns.spawn(self.network, host, args, log_path=log_path,
                           env=self.env(host, STANDIN_DELAY_S=str(delay_s)), cwd=PROJECT_ROOT)
        deadline = time.monotonic() + READY_TIMEOUT_S
        while b" ready." not in log_path.read_bytes()[start:]:
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"the worker on {host} was not ready in {READY_TIMEOUT_S:.0f} s "
                            f"(exit {proc.poll()}); its log ends:\n{netns.tail(log_path)}")
            time.sleep(0.2)
        service = netns.Service("worker", host, proc, log_path, 0)
        self.workers[host] = service
        return service

    def stop_workers(self) -> None:
        for service in self.workers.values():
            service.stop(timeout_s=15)
        self.workers.clear()

    def http(self, host: str = "api", thread: netns.NetnsThread | None = None) -> NsHttp:
        """An HTTP client of the API on `host`, run from the client host (on `thread`, else the shared one)."""
        return NsHttp(thread or self.client, self.api_url_on(host))

    def restart_store(self) -> netns.Service:
        """SeaweedFS started again on its host with its folder (the bucket and what it holds survive)."""
        service = netns.start_weed(self.network, "s3", self.root / "s3", *self.s3_keys)
        self.services["s3"] = service
        return service

    def s3(self, fn_name: str, **kwargs):
        """One S3 call (`fn_name` of a boto3 client, e.g. head_object) on the bucket, from the client host."""
        return self.client.call(_s3_call, self.s3_endpoint_url, self.s3_keys, fn_name,
                                {"Bucket": self.bucket, **kwargs})

    def sql(self, statement: str, *, host: str | None = None, **params) -> list[tuple]:
        """Rows of a query on the current primary (or on `host`'s server), run from the client host."""
        return self.client.call(_sql, self.database_url_on(host or self.pg_host), statement, params)

    def teardown(self) -> None:
        for service in [*self.workers.values(), *reversed(list(self.services.values()))]:
            with contextlib.suppress(Exception):
                service.stop(timeout_s=10)


def _health(url: str) -> int:
    try:
        return httpx.get(f"{url}/api/health", timeout=3).status_code
    except httpx.HTTPError:
        return 0


def _sql(url: str, statement: str, params: dict) -> list[tuple]:
    from sqlalchemy import create_engine, text

    engine = create_engine(url, pool_pre_ping=True)
    try:
        with engine.connect() as connection:
            return [tuple(row) for row in connection.execute(text(statement), params)]
    finally:
        engine.dispose()


def _s3_client(endpoint_url: str, keys: tuple[str, str]):
    import boto3
    from botocore.config import Config

    return boto3.client("s3", endpoint_url=endpoint_url, aws_access_key_id=keys[0], aws_secret_access_key=keys[1],
                        region_name="us-east-1", config=Config(retries={"max_attempts": 1}, connect_timeout=2,
                                                                 read_timeout=5, s3={"addressing_style": "path"}))


def _s3_call(endpoint_url: str, keys: tuple[str, str], fn_name: str, kwargs: dict):
    return getattr(_s3_client(endpoint_url, keys), fn_name)(**kwargs)


def _make_bucket(endpoint_url: str, keys: tuple[str, str], name: str, timeout_s: float) -> None:
    from botocore.exceptions import BotoCoreError, ClientError

    client = _s3_client(endpoint_url, keys)
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            client.create_bucket(Bucket=name)
            return
        except (BotoCoreError, ClientError) as error:
            if time.monotonic() > deadline:
                raise RuntimeError(f"SeaweedFS did not make bucket {name} in {timeout_s:.0f} s: {error}") from error
            time.sleep(0.5)


def _upgrade(url: str) -> None:
    from saddlescope.db.migrate import upgrade_to_head

    upgrade_to_head(url)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """PostgreSQL, Redis, SeaweedFS and the API each on its own host; workers are started by the tests."""
    try:
        netns.check_available()
    except (netns.NetnsUnavailable, RuntimeError) as reason:
        if IN_CI:
            pytest.fail(f"the multi-host test must run under CI=true: {reason}")
        pytest.skip(f"multi-host set-up not possible here: {reason}")
    root = tmp_path_factory.mktemp("multihost")
    network = netns.Network()
    pg_root = None
    cluster = None
    try:
        network.create(list(netns.ADDRESSES))
        client = netns.NetnsThread(network.ns("client"))
        cluster = Cluster(network, root, client, ("mh" + secrets.token_hex(6), secrets.token_hex(16)))
        pg_root = netns.pg_root()
        cluster.pg_root = pg_root
        cluster.services["pg"] = netns.start_postgres(network, "pg", pg_root / "pg")
        cluster.services["redis"] = netns.start_redis(network, "redis", root / "redis")
        cluster.services["s3"] = netns.start_weed(network, "s3", root / "s3", *cluster.s3_keys)
        cluster.bucket = f"rides-{secrets.token_hex(3)}"
        client.call(_make_bucket, cluster.s3_endpoint_url, cluster.s3_keys, cluster.bucket, 60.0)
        client.call(_upgrade, cluster.database_url)
        cluster.start_api()
        yield cluster
    finally:
        if cluster is not None:
            cluster.teardown()
            cluster.client.close()
        network.destroy()
        if pg_root is not None:
            shutil.rmtree(pg_root, ignore_errors=True)

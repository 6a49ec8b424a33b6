"""The two ways SaddleScope runs, as one module-scoped fixture each API test module can use.

``embedded``: SQLite, jobs in threads of the test process (the stand-in analysis applies).
``celery``: PostgreSQL, Redis and a real Celery worker process running the stand-in analysis.
Without the services the celery variant skips (fails under CI=true), as the other integration tests.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from pathlib import Path

import integration_services
import pytest
from api_helpers import ThreadQueue, standin_installed
from fastapi.testclient import TestClient

from conftest import PROJECT_ROOT
from saddlescope.api import create_app
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.settings import Settings, load_settings, with_embedded_secret

MAX_UPLOAD_BYTES = 16 * 1024**2
ENGINES = ["embedded", pytest.param("celery", marks=[pytest.mark.integration, pytest.mark.slow])]
# A bucket of a real SeaweedFS (tests/s3_server.py): a server of its own, so an integration test (`make test`
# runs it; `make test-fast` leaves it out).
EMBEDDED_S3 = pytest.param("embedded-s3", marks=pytest.mark.integration)
CELERY_S3 = pytest.param("celery-s3", marks=[pytest.mark.integration, pytest.mark.slow])


@dataclass
class Env:
    engine: str
    settings: Settings
    client: TestClient
    worker: object | None = None
    log_path: Path | None = None


def standin_worker_env(delay_s: float = 0.0) -> dict[str, str]:
    tests = PROJECT_ROOT / "tests"
    path = os.pathsep.join([str(tests / "api"), str(tests), os.environ.get("PYTHONPATH", "")])
    return {"PYTHONPATH": path, "STANDIN_DELAY_S": str(delay_s)}


@dataclass
class _Param:
    """`request` with another `param` (an engine variant run as its base engine)."""

    request: object
    param: str

    def getfixturevalue(self, name: str):
        return self.request.getfixturevalue(name)

    @property
    def config(self):
        return self.request.config


@contextlib.contextmanager
def s3_storage_env(request, settings: dict):
    """Point `settings` (overrides) at a fresh bucket of the session's SeaweedFS (`tests/s3_server.py`), with its
    credentials in the environment (boto3 reads them there) while the block runs."""
    server = request.getfixturevalue("s3_server")
    settings.update(storage_url=f"s3://{server.new_bucket('api')}/club-data", s3_endpoint_url=server.endpoint_url)
    saved = {name: os.environ.get(name) for name in server.environ()}
    os.environ.update(server.environ())
    try:
        yield server
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def open_env(request, tmp_path_factory, *, worker: bool = True, **overrides):
    """Yield an `Env` for ``request.param`` ("embedded" or "celery"), torn down after the module."""
    if request.param in ("embedded-s3", "celery-s3"):  # clips and results in a bucket of a real SeaweedFS
        with s3_storage_env(request, overrides):
            base = request.param.removesuffix("-s3")
            yield from open_env(_Param(request, base), tmp_path_factory, worker=worker, **overrides)
        return
    root = tmp_path_factory.mktemp(f"api-{request.param}")
    common = dict(storage_dir=str(root / "storage"), max_upload_bytes=MAX_UPLOAD_BYTES, **overrides)
    if request.param == "embedded":
        # The secret the app will sign with (embedded mode generates its own beside the storage).
        settings = with_embedded_secret(load_settings(database_url=f"sqlite:///{root / 'db.sqlite'}", **common))
        queue = ThreadQueue(settings)
        with (
            standin_installed(),
            TestClient(create_app(settings, queue=queue, open_registration=True)) as client,
        ):
            yield Env("embedded", settings, client)
        return
    database_url = request.getfixturevalue("pg_database_url")
    broker_url = request.getfixturevalue("redis_url")
    upgrade_to_head(database_url)
    settings = load_settings(
        database_url=database_url,
        broker_url=broker_url,
        secret_key=integration_services.TEST_SECRET,
        **common,
    )
    log_path = root / "worker.log"
    worker_disk, worker_env = Path(settings.storage_dir), standin_worker_env()
    if settings.storage_url:  # object storage: the worker shares no folder with the API, only the bucket
        worker_disk = root / "worker-own-disk"
        worker_env.update(SADDLESCOPE_STORAGE_URL=settings.storage_url,
                          SADDLESCOPE_S3_ENDPOINT_URL=settings.s3_endpoint_url or "",
                          **{k: v for k, v in os.environ.items() if k.startswith("AWS_")})
    if worker:
        with integration_services.run_celery_worker(
            database_url=database_url,
            broker_url=broker_url,
            storage_dir=worker_disk,
            log_path=log_path,
            app="standin_worker",
            extra_env=worker_env,
            config=request.config,
        ) as proc:
            with TestClient(create_app(settings, open_registration=True)) as client:
                yield Env("celery", settings, client, proc, log_path)
        return
    with TestClient(create_app(settings, open_registration=True)) as client:
        yield Env("celery", settings, client)

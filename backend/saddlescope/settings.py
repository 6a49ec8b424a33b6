"""The one settings object. This is the only module that reads environment variables.

Every variable starts with ``SADDLESCOPE_``:

``SADDLESCOPE_DATABASE_URL``
    SQLAlchemy URL; default a SQLite file ``./var/saddlescope.db`` (PostgreSQL in production:
    ``postgresql+psycopg://user:pass@host/db``).
``SADDLESCOPE_BROKER_URL``
    Unset: *embedded mode*, jobs run in a small local process pool inside the server. Set (e.g.
    ``redis://host:6379/0``): jobs go to Celery workers over that broker.
``SADDLESCOPE_STORAGE_DIR``
    Where uploaded videos and result arrays live (default ``./var/storage``).
``SADDLESCOPE_MAX_UPLOAD_BYTES``
    Largest accepted upload (default 4 GiB).
``SADDLESCOPE_SECRET_KEY``
    Signs tokens and session cookies. The built-in default is refused outside embedded mode.
    In embedded mode, left unset, a random secret is generated on first start and kept in
    ``secret_key`` beside the storage directory (mode 0600). A weak secret (short, or of too few
    different characters) is refused at start-up.
``SADDLESCOPE_TOKEN_LIFETIME_S``
    How long an access token stays valid (default 12 h).
``SADDLESCOPE_COOKIE_SECURE``
    ``auto`` (default: Secure when the request came over https, after the forwarded headers of the
    trusted proxies ``SADDLESCOPE_FORWARDED_ALLOW_IPS``), ``true`` or ``false``.
``SADDLESCOPE_LOGIN_MAX_FAILURES`` / ``SADDLESCOPE_LOGIN_LOCKOUT_S``
    Failed sign-ins per account (and, times four, per client address) before sign-in is locked for
    the lock-out time.
``SADDLESCOPE_STALE_AFTER_S`` / ``SADDLESCOPE_HEARTBEAT_S``
    A running job silent this long (no heartbeat, by the database's clock) has lost its worker and is
    run again by another (default 180 s); its worker beats this often (default: 10 s, or a quarter of the
    stale time when that is shorter).
``SADDLESCOPE_HOST_NAME``
    This machine's name in a job's ``host:pid`` (default the host name); it must differ between hosts
    that share a host name but not their processes, since a job of this host whose process is gone is lost
    at once.
``SADDLESCOPE_PASSWORD_HASHING``
    Argon2id's parameters: ``rfc9106-low-memory`` (default: RFC 9106's second recommendation, 64 MiB
    and 3 passes, about 0.15 s of a core per hash or sign-in) or ``cheapest-for-tests`` (argon2-cffi's
    cheapest, for test suites that sign in thousands of times; never for a club's server: the server
    logs a warning). A password hashed one way is re-hashed the other way at its next sign-in.
``SADDLESCOPE_WORKER_THREADS``
    Threads one analysis may use (its camera threads, PyAV's decoders, OpenCV). Unset: the CPUs the
    worker's cgroup quota gives it (``io.threads.default_worker_threads``), never the host's core count.
"""

from __future__ import annotations

import functools
import os
import secrets
import socket
import subprocess
from pathlib import Path
from typing import Literal

from pydantic import Field, SecretStr, ValidationError, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from saddlescope import __version__
from saddlescope.core.errors import SaddleScopeError

# A development-only secret: fine on a laptop where nothing is exposed, refused with a broker.
DEFAULT_SECRET_KEY = "saddlescope-embedded-development-secret-change-me"
GIB = 1024**3
MIN_SECRET_LENGTH = 16
MIN_SECRET_DISTINCT = 8


class ConfigurationError(SaddleScopeError):
    """The settings are invalid (bad URL, default secret in a deployment, ...)."""


class Settings(BaseSettings):
    """Configuration of one SaddleScope process (server, worker or command)."""

    model_config = SettingsConfigDict(env_prefix="SADDLESCOPE_", extra="ignore", frozen=True)

    database_url: str = "sqlite:///./var/saddlescope.db"
    broker_url: str | None = None
    storage_dir: Path = Path("./var/storage")
    # Where clips and results live: unset, a path or file://PATH keeps the folder tree (storage_dir);
    # s3://BUCKET[/PREFIX] an S3-compatible object store (credentials: AWS_ACCESS_KEY_ID / _SECRET_ACCESS_KEY).
    storage_url: str | None = None
    s3_endpoint_url: str | None = None  # e.g. http://127.0.0.1:8333 (SeaweedFS, MinIO); None: AWS
    # The store's address as the browser reaches it, for pre-signed part URLs (direct uploads) when the
    # servers reach it by another name (a compose network's http://seaweedfs:8333); None: s3_endpoint_url.
    s3_public_endpoint_url: str | None = None
    # Resumable uploads sent by the client straight to the bucket (pre-signed part URLs); None: whenever
    # the storage is a bucket. False keeps them streaming through the API (PATCH chunks).
    direct_uploads: bool | None = None
    max_upload_bytes: int = Field(default=4 * GIB, gt=0)
    # Below this much free space on the storage folder's disk /api/health says the storage is "degraded".
    storage_min_free_bytes: int = Field(default=GIB, ge=0)
    # Largest JSON request body (uploads are streamed as raw bytes or multipart, not JSON).
    max_json_body_bytes: int = Field(default=2 * 1024**2, gt=0)
    # An open resumable upload that receives nothing for this long is removed with its bytes.
    upload_expiry_s: int = Field(default=24 * 3600, gt=0)
    secret_key: SecretStr = SecretStr(DEFAULT_SECRET_KEY)
    token_lifetime_s: int = Field(default=12 * 3600, gt=0)
    # Where the generated embedded secret is kept (default: ``secret_key`` beside the storage dir).
    secret_key_file: Path | None = None
    cookie_secure: Literal["auto", "true", "false"] = "auto"
    # Proxies whose X-Forwarded-Proto/For are believed (uvicorn's forwarded_allow_ips).
    forwarded_allow_ips: str = "127.0.0.1"
    # Sign-in back-off (services/accounts/login_guard.py): after this many wrong passwords for one account from
    # one address, a wait of `login_backoff_s` doubling with each further one up to `login_lockout_s`;
    # counts expire `login_window_s` after their first failure. An address gets 4 times as many.
    login_max_failures: int = Field(default=10, ge=1)
    login_backoff_s: int = Field(default=30, ge=1)
    login_lockout_s: int = Field(default=15 * 60, ge=1)
    login_window_s: int = Field(default=3600, ge=1)
    # Argon2id's parameters (services/accounts/users.py PASSWORD_HASHING): RFC 9106's low-memory ones, or
    # the library's cheapest for test suites.
    password_hashing: Literal["rfc9106-low-memory", "cheapest-for-tests"] = "rfc9106-low-memory"
    # Argon2 runs in its own small pool; more waiting sign-ins than the queue holds get 503.
    hash_workers: int = Field(default=2, ge=1, le=32)
    hash_queue: int = Field(default=16, ge=1)
    # Processes of the embedded runner; 1 keeps a laptop responsive while a ride is analysed.
    embedded_workers: int = Field(default=1, ge=1, le=64)
    # Longest a whole job (all its stages, one Celery task) may run.
    job_time_limit_s: int = Field(default=6 * 3600, gt=0)
    # How long the broker keeps a delivered, unacknowledged task before handing it out again (None: twice
    # `stale_after_s`, at least 5 min). A killed worker's task is re-delivered within this; a slow but
    # healthy job's copy is refused by the fencing (its heartbeat is fresh), so a job never runs twice.
    broker_visibility_timeout_s: int | None = Field(default=None, ge=10)
    # Workers look this often for lost jobs: running ones whose worker died, queued ones a broker
    # forgot (restarted with nothing persisted) and queued longer than `requeue_after_s`.
    recovery_interval_s: float = Field(default=60.0, gt=0)
    # How often each worker sweeps abandoned uploads and partial writes (`services.uploads.intake.sweep_abandoned`)
    sweep_interval_s: float = Field(default=3600.0, gt=0)
    requeue_after_s: float = Field(default=120.0, gt=0)
    # A running job without a heartbeat for this long (database clock) is handed to another worker;
    # heartbeats come every `heartbeat_s` (None: 10 s, or a quarter of the stale time when shorter).
    stale_after_s: float = Field(default=180.0, gt=0)
    heartbeat_s: float | None = Field(default=None, gt=0)
    # This machine's name in a job's host:pid (None: socket.gethostname()).
    host_name: str | None = Field(default=None, min_length=1, max_length=200, pattern=r"^[^:\s]+$")
    # None: migrate to the newest schema at start-up in embedded mode only (a deployment runs the
    # one-shot `migrate` service instead).
    auto_migrate: bool | None = None
    # POST /api/clubs open to anyone (None: open in embedded mode and for a deployment's first club)
    open_registration: bool | None = None
    code_version: str | None = None
    # Threads of one analysis (None: the cgroup's CPU quota, see `resolved_worker_threads`).
    worker_threads: int | None = Field(default=None, ge=1, le=256)

    @model_validator(mode="after")
    def _check(self) -> Settings:
        if self.broker_url is not None and not self.broker_url.strip():
            raise ValueError("SADDLESCOPE_BROKER_URL is set but empty; unset it for embedded mode")
        if not self.embedded and self.secret_key.get_secret_value() == DEFAULT_SECRET_KEY:
            raise ValueError(
                "SADDLESCOPE_SECRET_KEY must be set to your own random value when SADDLESCOPE_BROKER_URL "
                "is set (the built-in development secret is only accepted in embedded mode)")
        secret = self.secret_key.get_secret_value()
        if len(secret) < MIN_SECRET_LENGTH:
            raise ValueError(f"SADDLESCOPE_SECRET_KEY is too short (at least {MIN_SECRET_LENGTH} characters)")
        if len(set(secret)) < MIN_SECRET_DISTINCT:
            raise ValueError(
                f"SADDLESCOPE_SECRET_KEY is too weak (it has fewer than {MIN_SECRET_DISTINCT} different "
                "characters); use a random value, e.g. `python -c 'import secrets; print(secrets.token_urlsafe(32))'`")
        if self.heartbeat_s is not None and self.heartbeat_s * 2 > self.stale_after_s:
            raise ValueError(
                f"SADDLESCOPE_HEARTBEAT_S ({self.heartbeat_s:g} s) must be at most half of SADDLESCOPE_STALE_AFTER_S "
                f"({self.stale_after_s:g} s), or a live worker's job would be taken for lost")
        if not self.database_url.strip():
            raise ValueError("SADDLESCOPE_DATABASE_URL is empty")
        return self

    @property
    def embedded(self) -> bool:
        """True when no broker is configured: jobs run in a local process pool."""
        return self.broker_url is None

    @property
    def uses_default_secret(self) -> bool:
        """True while the built-in development secret is in place (embedded mode, not yet resolved)."""
        return self.secret_key.get_secret_value() == DEFAULT_SECRET_KEY

    @property
    def resolved_secret_key_file(self) -> Path:
        """The file of the generated embedded secret."""
        return self.secret_key_file or self.storage_dir.parent / "secret_key"

    @property
    def migrate_on_start(self) -> bool:
        """Whether the server upgrades the database schema on start (by default: embedded mode only)."""
        return self.embedded if self.auto_migrate is None else self.auto_migrate

    @property
    def visibility_timeout_s(self) -> int:
        """Broker visibility timeout.

        Past the stale time, so a re-delivered task finds its dead worker's heartbeat stale and takes the job
        over (`JobRepository.mark_running`); minutes, not hours.
        """
        if self.broker_visibility_timeout_s is not None:
            return self.broker_visibility_timeout_s
        return max(300, int(2 * self.stale_after_s))

    @property
    def resolved_heartbeat_s(self) -> float:
        """How often a running job's worker writes its heartbeat."""
        return self.heartbeat_s if self.heartbeat_s is not None else min(10.0, self.stale_after_s / 4)

    @property
    def resolved_host_name(self) -> str:
        """The machine's name in the ``host:pid`` a job records."""
        return self.host_name or socket.gethostname()

    @property
    def resolved_worker_threads(self) -> int:
        """The analysis's thread budget: the setting, else the CPUs the worker's cgroup allows."""
        from saddlescope.io.threads import default_worker_threads

        return self.worker_threads or default_worker_threads()

    @property
    def resolved_code_version(self) -> str:
        """The code version a job records: the setting, else the package version (with the git commit in a checkout)."""
        return self.code_version or _code_version()


@functools.cache
def _code_version() -> str:
    """Package version plus the git commit when run from a checkout (recorded on every job)."""
    repo = Path(__file__).resolve().parents[2]
    if (repo / ".git").exists():
        try:
            out = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", "HEAD"],
                                 capture_output=True, text=True, timeout=5, check=False)
        except (OSError, subprocess.SubprocessError):
            return __version__
        if out.returncode == 0 and out.stdout.strip():
            return f"{__version__}+g{out.stdout.strip()}"
    return __version__


def load_settings(**overrides) -> Settings:
    """Read the settings from the environment (overrides win), as a `ConfigurationError` if invalid."""
    try:
        return Settings(**overrides)
    except ValidationError as exc:
        details = "; ".join(
            (f"{'.'.join(str(p) for p in err['loc'])}: " if err["loc"] else "") + err["msg"].removeprefix(
                "Value error, ")
            for err in exc.errors())
        raise ConfigurationError(f"invalid settings: {details}") from None


def with_embedded_secret(settings: Settings) -> Settings:
    """`settings` with the built-in secret replaced by this installation's own (embedded mode).

    The first start writes a random secret to `Settings.resolved_secret_key_file` (mode 0600); later
    starts read it back, so sign-ins survive a restart and no two installations share a key.
    """
    if not settings.uses_default_secret:
        return settings
    path = settings.resolved_secret_key_file
    try:
        secret = path.read_text(encoding="utf-8").strip() if path.exists() else ""
        if not secret:
            path.parent.mkdir(parents=True, exist_ok=True)
            secret = secrets.token_urlsafe(48)
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                handle.write(secret + "\n")
        os.chmod(path, 0o600)
    except OSError as exc:
        raise ConfigurationError(f"cannot read or create the secret key file {path}: {exc}; set "
                                 "SADDLESCOPE_SECRET_KEY instead") from None
    return load_settings(**{**settings.model_dump(), "secret_key": secret})


@functools.cache
def get_settings() -> Settings:
    """The process-wide settings, read once from the environment."""
    return load_settings()

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
``SADDLESCOPE_TOKEN_LIFETIME_S``
    How long an access token stays valid (default 12 h).
"""

from __future__ import annotations

import functools
import subprocess
from pathlib import Path

from pydantic import Field, SecretStr, ValidationError, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from saddlescope import __version__
from saddlescope.core.errors import SaddleScopeError

# A development-only secret: fine on a laptop where nothing is exposed, refused with a broker.
DEFAULT_SECRET_KEY = "saddlescope-embedded-development-secret-change-me"
GIB = 1024**3


class ConfigurationError(SaddleScopeError):
    """The settings are invalid (bad URL, default secret in a deployment, ...)."""


class Settings(BaseSettings):
    """Configuration of one SaddleScope process (server, worker or command)."""

    model_config = SettingsConfigDict(env_prefix="SADDLESCOPE_", extra="ignore", frozen=True)

    database_url: str = "sqlite:///./var/saddlescope.db"
    broker_url: str | None = None
    storage_dir: Path = Path("./var/storage")
    max_upload_bytes: int = Field(default=4 * GIB, gt=0)
    # Largest JSON request body (uploads are streamed as raw bytes or multipart, not JSON).
    max_json_body_bytes: int = Field(default=2 * 1024**2, gt=0)
    # An open resumable upload that receives nothing for this long is removed with its bytes.
    upload_expiry_s: int = Field(default=24 * 3600, gt=0)
    secret_key: SecretStr = SecretStr(DEFAULT_SECRET_KEY)
    token_lifetime_s: int = Field(default=12 * 3600, gt=0)
    # Processes of the embedded runner; 1 keeps a laptop responsive while a ride is analysed.
    embedded_workers: int = Field(default=1, ge=1, le=64)
    # Longest a whole job (all its stages, one Celery task) may run; the broker's visibility timeout
    # is set above it so a slow but healthy job is never handed to a second worker.
    job_time_limit_s: int = Field(default=6 * 3600, gt=0)
    # None: migrate to the newest schema at start-up in embedded mode only (a deployment runs the
    # one-shot `migrate` service instead).
    auto_migrate: bool | None = None
    # POST /api/clubs open to anyone (None: open in embedded mode and for a deployment's first club)
    open_registration: bool | None = None
    code_version: str | None = None

    @model_validator(mode="after")
    def _check(self) -> Settings:
        if self.broker_url is not None and not self.broker_url.strip():
            raise ValueError("SADDLESCOPE_BROKER_URL is set but empty; unset it for embedded mode")
        if not self.embedded and self.secret_key.get_secret_value() == DEFAULT_SECRET_KEY:
            raise ValueError(
                "SADDLESCOPE_SECRET_KEY must be set to your own random value when SADDLESCOPE_BROKER_URL "
                "is set (the built-in development secret is only accepted in embedded mode)")
        if len(self.secret_key.get_secret_value()) < 16:
            raise ValueError("SADDLESCOPE_SECRET_KEY is too short (at least 16 characters)")
        if not self.database_url.strip():
            raise ValueError("SADDLESCOPE_DATABASE_URL is empty")
        return self

    @property
    def embedded(self) -> bool:
        """True when no broker is configured: jobs run in a local process pool."""
        return self.broker_url is None

    @property
    def migrate_on_start(self) -> bool:
        return self.embedded if self.auto_migrate is None else self.auto_migrate

    @property
    def visibility_timeout_s(self) -> int:
        """Broker visibility timeout: longer than the longest job, hence than any stage (plus margin)."""
        return int(self.job_time_limit_s * 1.25) + 600

    @property
    def resolved_code_version(self) -> str:
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


@functools.cache
def get_settings() -> Settings:
    """The process-wide settings, read once from the environment."""
    return load_settings()

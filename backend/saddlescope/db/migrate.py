"""Alembic from Python: build the schema at start-up (embedded mode) and in tests.

The migrations live in ``backend/alembic``; ``alembic.ini`` at the repository top points there, so
``alembic upgrade head`` from the repository top does the same as `upgrade_to_head`.
"""

from __future__ import annotations

from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Engine

__all__ = ["ALEMBIC_DIR", "alembic_config", "current_revision", "head_revision", "upgrade_to_head"]

ALEMBIC_DIR = Path(__file__).resolve().parents[2] / "alembic"


def alembic_config(database_url: str | None = None) -> Config:
    """An Alembic config for our migrations; `database_url` overrides the settings object's URL."""
    if not (ALEMBIC_DIR / "env.py").exists():
        raise FileNotFoundError(ALEMBIC_DIR / "env.py")
    config = Config()
    config.set_main_option("script_location", str(ALEMBIC_DIR))
    if database_url is not None:
        config.attributes["database_url"] = database_url
    return config


def upgrade_to_head(database_url: str | None = None) -> None:
    """Apply every migration not yet applied (a no-op on an up-to-date database)."""
    command.upgrade(alembic_config(database_url), "head")


def head_revision() -> str | None:
    """The newest migration's revision."""
    return ScriptDirectory.from_config(alembic_config()).get_current_head()


def current_revision(engine: Engine) -> str | None:
    """The revision the database is at (None: not migrated yet)."""
    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()

"""Alembic environment: the URL comes from the settings object, the target from our models.

A caller may pass a URL in ``config.attributes["database_url"]`` (tests, `upgrade_to_head`);
otherwise `saddlescope.settings.get_settings().database_url` is used, as everywhere else.
"""

from __future__ import annotations

from alembic import context
from sqlalchemy import Connection

from saddlescope.db.models import Base
from saddlescope.db.session import make_engine
from saddlescope.settings import get_settings

__all__ = ["run_migrations_offline", "run_migrations_online"]

config = context.config
target_metadata = Base.metadata


def _database_url() -> str:
    return config.attributes.get("database_url") or get_settings().database_url


def _configure(connection: Connection | None = None, url: str | None = None) -> None:
    dialect = connection.dialect.name if connection is not None else url.split(":", 1)[0]
    context.configure(
        connection=connection,
        url=url,
        target_metadata=target_metadata,
        compare_type=True,
        # SQLite cannot ALTER constraints in place; batch mode rebuilds the table instead.
        render_as_batch=dialect.startswith("sqlite"),
        literal_binds=connection is None,
    )


def run_migrations_offline() -> None:
    """Write the migrations' SQL instead of running it (``alembic upgrade head --sql``)."""
    _configure(url=_database_url())
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    """Run the migrations on the caller's connection, or on a new engine for the URL."""
    connection = config.attributes.get("connection")
    if connection is not None:
        _configure(connection)
        with context.begin_transaction():
            context.run_migrations()
        return
    engine = make_engine(_database_url())
    try:
        with engine.connect() as conn:
            if conn.dialect.name == "sqlite":
                # A batch rebuild drops and recreates a table; with foreign keys enforced, dropping a table
                # that others reference (rides, riders) deletes their rows by ON DELETE CASCADE, or fails.
                # The pragma only takes effect outside a transaction, so before the migrations' one.
                conn.exec_driver_sql("PRAGMA foreign_keys=OFF")
                conn.commit()
            _configure(conn)
            with context.begin_transaction():
                context.run_migrations()
    finally:
        engine.dispose()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()

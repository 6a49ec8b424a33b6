"""Engines and sessions: SQLite in WAL mode with foreign keys on, PostgreSQL as it is."""

from __future__ import annotations

import functools
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from sqlalchemy import Engine, create_engine, event, make_url, text
from sqlalchemy.engine import URL
from sqlalchemy.exc import ArgumentError
from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import InputError

__all__ = [
    "engine_for", "make_engine", "make_session_factory", "ping", "session_factory_for", "session_scope",
]


def _parse_url(database_url: str) -> URL:
    try:
        return make_url(database_url)
    except ArgumentError:
        raise InputError(
            f"database URL {database_url!r} is not a SQLAlchemy URL "
            "(e.g. sqlite:///./var/saddlescope.db or postgresql+psycopg://user@host/db)") from None


def _on_sqlite_connect(dbapi_connection, connection_record) -> None:
    cursor = dbapi_connection.cursor()
    # WAL lets the API read while a worker process writes; busy_timeout waits for the writer
    # instead of failing with "database is locked".
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute("PRAGMA busy_timeout=30000")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.close()


def make_engine(database_url: str, *, echo: bool = False, pool_size: int | None = None) -> Engine:
    """An engine for `database_url`; creates the folder of a SQLite file if needed.

    `pool_size`: connections kept open (default SQLAlchemy's 5, plus 10 more on demand); the API sizes
    it to the sessions it lets run at once.
    """
    url = _parse_url(database_url)
    pool = {"pool_size": pool_size, "max_overflow": 10} if pool_size else {}
    if url.get_backend_name() == "sqlite":
        if url.database and url.database != ":memory:" and not url.database.startswith("file:"):
            Path(url.database).expanduser().parent.mkdir(parents=True, exist_ok=True)
        in_memory = not url.database or url.database == ":memory:"
        engine = create_engine(url, echo=echo, connect_args={"check_same_thread": False},
                               **({} if in_memory else pool))
        event.listen(engine, "connect", _on_sqlite_connect)
        return engine
    # pre_ping: a worker idle for hours must not fail on a connection the server closed.
    return create_engine(url, echo=echo, pool_pre_ping=True, **pool)


def make_session_factory(engine: Engine) -> sessionmaker[Session]:
    """Sessions on `engine` whose objects stay readable after commit (API responses, job bodies)."""
    return sessionmaker(bind=engine, expire_on_commit=False)


@functools.cache
def engine_for(database_url: str) -> Engine:
    """One engine per URL and process (worker processes reuse it across tasks)."""
    return make_engine(database_url)


def session_factory_for(database_url: str) -> sessionmaker[Session]:
    """Sessions on this process's engine for `database_url`."""
    return make_session_factory(engine_for(database_url))


def ping(engine: Engine) -> None:
    """Run a trivial query (raises SQLAlchemyError when the database is unreachable)."""
    with engine.connect() as conn:
        conn.execute(text("SELECT 1"))


@contextmanager
def session_scope(factory: sessionmaker[Session]) -> Iterator[Session]:
    """A session that commits on success and rolls back on any error."""
    session = factory()
    try:
        yield session
        session.commit()
    except BaseException:
        session.rollback()
        raise
    finally:
        session.close()

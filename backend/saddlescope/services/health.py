"""Health checks of the parts a server needs: database, job broker, storage."""

from __future__ import annotations

from typing import Any

from sqlalchemy import Engine
from sqlalchemy.exc import SQLAlchemyError

from saddlescope.db.migrate import current_revision, head_revision
from saddlescope.db.session import ping
from saddlescope.services.queue import JobQueue
from saddlescope.storage import Storage

__all__ = ["check_database", "check_queue", "check_storage", "health_report"]


def check_database(engine: Engine) -> tuple[bool, str]:
    """Connect, run a query, and check the schema is at the newest migration."""
    try:
        ping(engine)
        revision = current_revision(engine)
    except SQLAlchemyError as exc:
        return False, f"{engine.dialect.name} unreachable: {type(exc).__name__}: {str(exc).splitlines()[0]}"
    head = head_revision()
    if revision != head:
        return False, (f"{engine.dialect.name}: schema at revision {revision or 'none'}, expected {head}; "
                       "run `alembic upgrade head`")
    version = ".".join(str(v) for v in (engine.dialect.server_version_info or ())[:3])
    return True, f"{engine.dialect.name} {version}, schema at revision {revision}"


def check_storage(storage: Storage) -> tuple[bool, str]:
    """Whether the storage folder can be written, with what was found."""
    try:
        return True, storage.check()
    except OSError as exc:
        return False, f"{storage.root}: {exc}"


def check_queue(queue: JobQueue) -> tuple[bool, str]:
    """Whether the job queue (embedded pool or Celery broker) answers, with what it said."""
    return queue.health()


def health_report(engine: Engine, queue: JobQueue, storage: Storage) -> dict[str, Any]:
    """``{"status": "ok"|"error", "parts": {name: {"ok", "detail"}}}``."""
    parts = {}
    for name, (ok, detail) in (("database", check_database(engine)), ("broker", check_queue(queue)),
                               ("storage", check_storage(storage))):
        parts[name] = {"ok": ok, "status": "ok" if ok else "error", "detail": detail}
    return {"status": "ok" if all(p["ok"] for p in parts.values()) else "error", "mode": queue.mode,
            "parts": parts}

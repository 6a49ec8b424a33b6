"""Health checks of the parts a server needs: database, job broker, storage."""

from __future__ import annotations

from typing import Any

from sqlalchemy import Engine
from sqlalchemy.exc import SQLAlchemyError

from saddlescope.db.migrate import current_revision, head_revision
from saddlescope.db.session import ping
from saddlescope.services.queue import JobQueue
from saddlescope.storage import Storage

__all__ = ["PART_TROUBLE", "check_database", "check_queue", "check_storage", "health_report", "public_report"]


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
    """Whether the store (the folder, or the S3 bucket) can be written and read, with what was found."""
    try:
        return True, storage.check()
    except OSError as exc:
        return False, f"{storage.describe()}: {exc}"


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


# What a part being down means for a club, in its words (the public answer names no path or version).
PART_TROUBLE = {
    "database": "the database does not answer or is not up to date, so nothing can be shown or saved",
    "broker": "the job queue does not answer, so new analyses cannot start",
    "storage": "the file storage cannot be written, so clips cannot be uploaded",
}


def public_report(report: dict[str, Any]) -> dict[str, Any]:
    """What anyone may see: ok or degraded in one line, each part ok or not; no paths, versions or mode.

    The details (the storage folder, the database server's version, the broker's address) help an
    attacker more than a member, so they stay in ``/api/health/details`` for admins.
    """
    down = [name for name, part in report["parts"].items() if not part["ok"]]
    summary = ("Service OK" if not down
               else "Service degraded: " + "; ".join(PART_TROUBLE.get(name, f"{name} is not ok") for name in down))
    parts = {name: {"ok": part["ok"], "status": part["status"]} for name, part in report["parts"].items()}
    return {"status": report["status"], "summary": summary, "parts": parts}

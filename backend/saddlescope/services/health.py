"""Health checks of the parts a server needs: database, job broker, storage.

A part is "ok", "degraded" (it works, but not for long: the storage folder's disk nearly full) or "error".
Only an error makes the whole service "error" (503, so a load balancer stops sending requests); a
degraded part makes it "degraded" with 200, since reading still works.
"""

from __future__ import annotations

import shutil
from typing import Any

from sqlalchemy import Engine
from sqlalchemy.exc import SQLAlchemyError

from saddlescope.db.migrate import current_revision, head_revision
from saddlescope.db.session import ping
from saddlescope.services.jobs.queue import JobQueue
from saddlescope.storage import FileStorage, Storage

__all__ = ["PART_TROUBLE", "STORAGE_LOW", "check_database", "check_queue", "check_storage", "health_report",
           "public_report", "storage_free_bytes"]


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


def storage_free_bytes(storage: Storage) -> int | None:
    """Free bytes on the disk of a folder store (None for a bucket: its space is the provider's)."""
    if not isinstance(storage, FileStorage):
        return None
    try:
        return shutil.disk_usage(storage.root).free
    except OSError:
        return None


def check_storage(storage: Storage, min_free_bytes: int = 0) -> tuple[str, str, int | None]:
    """(status, what was found, free bytes): whether the store can be written and read, and has room.

    "degraded" when the folder's disk has less than `min_free_bytes` free: uploads and results will soon
    be refused (507) though everything stored can still be read.
    """
    try:
        detail = storage.check()
    except OSError as exc:
        return "error", f"{storage.describe()}: {exc}", storage_free_bytes(storage)
    free_bytes = storage_free_bytes(storage)
    if free_bytes is not None and free_bytes < min_free_bytes:
        return "degraded", (f"{storage.describe()}: only {free_bytes / 1024**2:.0f} MiB free, below the "
                            f"{min_free_bytes / 1024**2:.0f} MiB of SADDLESCOPE_STORAGE_MIN_FREE_BYTES"), free_bytes
    return "ok", detail, free_bytes


def check_queue(queue: JobQueue) -> tuple[bool, str]:
    """Whether the job queue (embedded pool or Celery broker) answers, with what it said."""
    return queue.health()


def _overall(statuses: list[str]) -> str:
    return "error" if "error" in statuses else "degraded" if "degraded" in statuses else "ok"


def health_report(engine: Engine, queue: JobQueue, storage: Storage, *, min_free_bytes: int = 0) -> dict[str, Any]:
    """``{"status": "ok"|"degraded"|"error", "parts": {name: {"ok", "status", "detail"}}}``.

    The storage part also has ``free_bytes`` (None for a bucket).
    """
    parts: dict[str, dict[str, Any]] = {}
    for name, (ok, detail) in (("database", check_database(engine)), ("broker", check_queue(queue))):
        parts[name] = {"ok": ok, "status": "ok" if ok else "error", "detail": detail}
    state, detail, free_bytes = check_storage(storage, min_free_bytes)
    parts["storage"] = {"ok": state == "ok", "status": state, "detail": detail, "free_bytes": free_bytes}
    return {"status": _overall([p["status"] for p in parts.values()]), "mode": queue.mode, "parts": parts}


# What a part being down means for a club, in its words (the public answer names no path or version).
PART_TROUBLE = {
    "database": "the database does not answer or is not up to date, so nothing can be shown or saved",
    "broker": "the job queue does not answer, so new analyses cannot start",
    "storage": "the file storage cannot be written, so clips cannot be uploaded",
}
STORAGE_LOW = "the file storage is nearly full, so uploads and new results may be refused"


def public_report(report: dict[str, Any]) -> dict[str, Any]:
    """What anyone may see: ok or degraded in one line, each part ok or not; no paths, versions or mode.

    The details (the storage folder, the database server's version, the broker's address) help an
    attacker more than a member, so they stay in ``/api/health/details`` for admins.
    """
    troubles = [STORAGE_LOW if part["status"] == "degraded" else PART_TROUBLE.get(name, f"{name} is not ok")
                 for name, part in report["parts"].items() if not part["ok"]]
    summary = "Service OK" if not troubles else "Service degraded: " + "; ".join(troubles)
    parts = {name: {key: part[key] for key in ("ok", "status", "free_bytes") if key in part}
             for name, part in report["parts"].items()}
    return {"status": report["status"], "summary": summary, "parts": parts}

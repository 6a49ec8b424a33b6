"""A part that does not answer, or a full disk, as a status and a sentence a club understands.

Every route shares these answers (registered once in `api/app.py`): the database, the job broker or the
object store not answering is 503 with ``Retry-After``; a full disk or quota is 507. The driver's own
message (an address, a path) goes to the log, not to the caller.
"""

from __future__ import annotations

import errno
import logging
from dataclasses import dataclass

import botocore.exceptions
import kombu.exceptions
import redis.exceptions
import sqlalchemy.exc
from fastapi import FastAPI, Request, status
from fastapi.responses import JSONResponse

__all__ = ["BROKER_DOWN", "DATABASE_DOWN", "DISK_FULL", "STORE_DOWN", "Outage", "add_outage_handlers",
           "disk_full", "outage_of"]

log = logging.getLogger(__name__)

# errno values of "no room left": the disk (ENOSPC) or the user's quota (EDQUOT).
NO_SPACE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})
# SQLite's and PostgreSQL's own words for a full disk (SQLITE_FULL; SQLSTATE 53100 disk_full).
DB_FULL_WORDS = ("database or disk is full", "no space left on device")


@dataclass(frozen=True)
class Outage:
    """What the caller is told: a status, a sentence, and when to try again (s; 0: no header)."""

    part: str
    status_code: int
    detail: str
    retry_after_s: int

    def response(self) -> JSONResponse:
        """The JSON answer ``{"detail": ...}`` with ``Retry-After`` when there is one."""
        headers = {"Retry-After": str(self.retry_after_s)} if self.retry_after_s else None
        return JSONResponse({"detail": self.detail}, status_code=self.status_code, headers=headers)


DATABASE_DOWN = Outage("database", status.HTTP_503_SERVICE_UNAVAILABLE,
                       "The database is not answering; try again in a minute.", 60)
BROKER_DOWN = Outage("broker", status.HTTP_503_SERVICE_UNAVAILABLE,
                     "The job queue is not answering, so analyses cannot start now; try again in a minute.", 60)
STORE_DOWN = Outage("storage", status.HTTP_503_SERVICE_UNAVAILABLE,
                    "The file store is not answering; try again in a minute.", 60)
DISK_FULL = Outage("storage", status.HTTP_507_INSUFFICIENT_STORAGE,
                   "The server's disk is full, so nothing was saved; ask the club's administrator to free "
                   "space, then try again.", 0)

# Raised by the drivers when their server does not answer (connection refused or lost, time-out).
DATABASE_ERRORS: tuple[type[Exception], ...] = (
    sqlalchemy.exc.OperationalError,  # refused, closed, SQLite locked or unable to open
    sqlalchemy.exc.InterfaceError,  # a connection the server dropped
    sqlalchemy.exc.TimeoutError,  # no pooled connection came free
)
BROKER_ERRORS: tuple[type[Exception], ...] = (
    redis.exceptions.ConnectionError, redis.exceptions.TimeoutError, kombu.exceptions.OperationalError,
)
# What escapes the store's own `StoreUnavailable` (which keeps its sentence and Retry-After: api/app.py).
STORE_ERRORS: tuple[type[Exception], ...] = (
    botocore.exceptions.ConnectionError, botocore.exceptions.HTTPClientError,
)


def disk_full(exc: BaseException | None) -> bool:
    """Whether `exc`, or an error it was raised from, says there is no room left (disk or quota)."""
    seen = 0
    while exc is not None and seen < 5:  # the OS error may be the cause of a driver's or a store's error
        if isinstance(exc, OSError) and exc.errno in NO_SPACE_ERRNOS:
            return True
        if isinstance(exc, sqlalchemy.exc.OperationalError) and any(
                word in str(exc.orig).lower() for word in DB_FULL_WORDS):
            return True
        # The cause, or the error being handled when it was raised (``raise ... from None`` keeps that).
        exc, seen = exc.__cause__ or exc.__context__ or getattr(exc, "orig", None), seen + 1
    return False


def outage_of(exc: BaseException) -> Outage | None:
    """The outage `exc` means, or None for any other error."""
    if disk_full(exc):
        return DISK_FULL
    if isinstance(exc, DATABASE_ERRORS):
        return DATABASE_DOWN
    if isinstance(exc, BROKER_ERRORS):
        return BROKER_DOWN
    if isinstance(exc, STORE_ERRORS):
        return STORE_DOWN
    return None


def add_outage_handlers(app: FastAPI) -> None:
    """Answer every route's outage and full-disk errors as `outage_of` says (other OS errors stay 500)."""

    async def handler(request: Request, exc: Exception) -> JSONResponse:
        outage = outage_of(exc)
        if outage is None:
            raise exc  # not an outage: the server error it is (logged with its traceback)
        log.warning("%s %s answered %d (%s): %s: %s", request.method, request.url.path, outage.status_code,
                    outage.part, type(exc).__name__, exc)
        return outage.response()

    for error in (*DATABASE_ERRORS, *BROKER_ERRORS, *STORE_ERRORS, OSError):
        app.add_exception_handler(error, handler)

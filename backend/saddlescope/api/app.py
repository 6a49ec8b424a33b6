"""The FastAPI application factory.

``create_app(settings)`` wires one settings object to one engine, one storage and one job queue,
mounts a router per resource under ``/api``, OpenAPI at ``/docs`` and the dashboard (``frontend/``)
at ``/``.
"""

from __future__ import annotations

import asyncio
import logging
import os
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import DataError, IntegrityError, SQLAlchemyError
from starlette.concurrency import run_in_threadpool

from saddlescope import __version__
from saddlescope.api.limits import JsonBodyLimit
from saddlescope.api.outages import DISK_FULL, add_outage_handlers, disk_full
from saddlescope.api.security_headers import SecurityHeaders
from saddlescope.api.static import DashboardFiles
from saddlescope.core.errors import SaddleScopeError
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.repositories import BadQuery, Conflict, JobRepository, NotFound
from saddlescope.db.session import make_engine, make_session_factory, session_scope
from saddlescope.services.accounts.login_guard import HashPool, HashPoolBusy, LoginThrottled, make_login_guard
from saddlescope.services.accounts.users import AuthError, Forbidden, use_password_hashing
from saddlescope.services.jobs.lifecycle import JobStateError
from saddlescope.services.jobs.queue import JobQueue, QueueUnavailable, make_queue
from saddlescope.services.uploads.intake import IncompleteUpload, sweep_abandoned
from saddlescope.settings import Settings, get_settings, with_embedded_secret
from saddlescope.storage import StoreUnavailable, TooLarge, open_storage

__all__ = ["ERROR_STATUS", "FRONTEND_DIR", "create_app"]

log = logging.getLogger(__name__)

REQUEST_SESSIONS = 16  # below the 40 request threads, so a request holding a connection finds a thread
FRONTEND_DIR = Path(__file__).resolve().parents[3] / "frontend"


def _resume_unfinished(app: FastAPI) -> None:
    """Embedded mode: jobs a stopped server left queued or running are run again (stages are idempotent)."""
    try:
        with session_scope(app.state.sessions) as session:
            jobs = JobRepository(session)
            job_ids = [job.id for job in jobs.unfinished()]
            for job in jobs.running():  # its runner was the stopped server's pool: back in the queue
                jobs.requeue_lost(job.id, host=job.host)
    except SQLAlchemyError as exc:
        # Start anyway: /api/health then says what is wrong with the database.
        log.warning("cannot look for unfinished jobs: %s", exc)
        return
    for job_id in job_ids:
        log.info("resuming job %s left unfinished by an earlier server", job_id)
        app.state.queue.submit(job_id)
    # No worker sweeps in embedded mode: what a stopped server left half-written goes at its next start.
    try:
        swept = sweep_abandoned(app.state.sessions, app.state.storage,
                                max_age_s=app.state.settings.upload_expiry_s)
    except (SQLAlchemyError, OSError) as exc:
        log.warning("cannot sweep abandoned uploads: %s", exc)
        return
    if any(swept.values()):
        log.info("swept what was abandoned: %s", ", ".join(f"{what} {n}" for what, n in swept.items()))


def _use_password_hashing(settings: Settings) -> None:
    """Argon2's parameters from the settings; a warning where they are the test suites' cheapest."""
    use_password_hashing(settings.password_hashing)
    if settings.password_hashing == "cheapest-for-tests":
        log.warning("SADDLESCOPE_PASSWORD_HASHING=cheapest-for-tests: passwords are hashed with Argon2's cheapest "
                    "parameters, which are for test suites only; unset it on a club's server")


def create_app(settings: Settings | None = None, *, queue: JobQueue | None = None,
               open_registration: bool | None = None) -> FastAPI:
    """The SaddleScope web application for `settings` (default: from the environment).

    In embedded mode (no broker) the schema is migrated to the newest revision at start-up and
    jobs run in a local process pool; with a broker they go to Celery workers. `open_registration`:
    whether anyone may create a club (POST /api/clubs); by default open in embedded mode and for
    the first club of a deployment (``settings.open_registration`` where the settings have it).
    """
    settings = with_embedded_secret(settings or get_settings())
    _use_password_hashing(settings)
    if open_registration is None:
        open_registration = getattr(settings, "open_registration", None)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        app.state.db_slots = asyncio.Semaphore(REQUEST_SESSIONS)  # bound to this server's event loop
        if settings.migrate_on_start:
            await run_in_threadpool(upgrade_to_head, settings.database_url)
        app.state.queue = queue or make_queue(settings)
        if settings.embedded:
            await run_in_threadpool(_resume_unfinished, app)
        try:
            yield
        finally:
            app.state.queue.close()
            app.state.hash_pool.close()
            app.state.engine.dispose()

    app = FastAPI(title="SaddleScope", version=__version__, lifespan=lifespan, docs_url="/docs",
                  openapi_url="/openapi.json",
                  description="Saddle kinematics and rider whole-body vibration from three ordinary cameras.")
    app.state.settings = settings
    # Requests with a database session at once (api/deps.py `_session`); the engine keeps a connection
    # for each, and for the hash pool's and job runner's sessions besides.
    app.state.db_slots = asyncio.Semaphore(REQUEST_SESSIONS)
    app.state.engine = make_engine(settings.database_url,
                                   pool_size=REQUEST_SESSIONS + settings.hash_workers + 4)
    app.state.sessions = make_session_factory(app.state.engine)
    app.state.storage = open_storage(settings)
    app.state.open_registration = open_registration
    app.state.login_guard = make_login_guard(settings)
    # Each Argon2 check uses several cores (4 lanes): at most one per two cores, or a sign-in flood takes
    # the CPU from every reader.
    hash_workers = min(settings.hash_workers, max(1, (os.cpu_count() or 2) // 2))
    app.state.hash_pool = HashPool(hash_workers, settings.hash_queue)
    # Set here too so routes work when the lifespan is not run; the lifespan replaces it.
    app.state.queue = queue

    _add_error_handlers(app)
    app.add_middleware(JsonBodyLimit, max_bytes=settings.max_json_body_bytes)
    app.add_middleware(SecurityHeaders, settings=settings)  # outermost of ours: on every answer

    from saddlescope.api.routers import (
        auth,
        comparisons,
        grades,
        health,
        horse_profile,
        horses,
        jobs,
        mocap,
        readiness,
        reports,
        riders,
        rides,
        rigs,
        saddles,
        share_links,
        shared,
        similarity,
        uploads,
    )

    for module in (health, auth, horses, horse_profile, riders, rigs, rides, readiness, mocap, uploads, grades,
                   comparisons, similarity, jobs, reports, saddles, share_links):
        app.include_router(module.router, prefix="/api")
    app.include_router(shared.router)  # /shared/<token>: what a share link opens, without an account
    _mount_dashboard(app)
    return app


def _mount_dashboard(app: FastAPI) -> None:
    if FRONTEND_DIR.is_dir():
        app.mount("/", DashboardFiles(directory=FRONTEND_DIR, html=True), name="frontend")
    else:
        log.warning("no dashboard: %s does not exist", FRONTEND_DIR)


# Each error class answers with one status and its message as {"detail": ...}; the most specific
# class wins (FastAPI looks the handlers up along the exception's MRO).
ERROR_STATUS: dict[type[Exception], int] = {
    NotFound: status.HTTP_404_NOT_FOUND,
    Conflict: status.HTTP_409_CONFLICT,
    BadQuery: status.HTTP_422_UNPROCESSABLE_CONTENT,
    AuthError: status.HTTP_401_UNAUTHORIZED,
    Forbidden: status.HTTP_403_FORBIDDEN,
    TooLarge: status.HTTP_413_CONTENT_TOO_LARGE,
    IncompleteUpload: status.HTTP_409_CONFLICT,
    JobStateError: status.HTTP_409_CONFLICT,
    QueueUnavailable: status.HTTP_503_SERVICE_UNAVAILABLE,
    LoginThrottled: status.HTTP_429_TOO_MANY_REQUESTS,
    HashPoolBusy: status.HTTP_503_SERVICE_UNAVAILABLE,
    StoreUnavailable: status.HTTP_503_SERVICE_UNAVAILABLE,  # the object store does not answer
    SaddleScopeError: status.HTTP_422_UNPROCESSABLE_CONTENT,  # bad input: a clip, a bundle, a value
}


def _validation_message(exc: RequestValidationError) -> str:
    """Pydantic's errors as one sentence naming each field ("body.gait: Input should be 'walk', ...")."""
    parts = []
    for err in exc.errors()[:5]:
        where = ".".join(str(p) for p in err.get("loc", ()))
        message = err.get("msg", "invalid")
        if err.get("type") == "enum":  # name the refused value first; the indicators' list is long
            field = str(err["loc"][-1]) if err.get("loc") else "value"
            hint = "GET /api/indicators lists them" if field == "indicator" else message
            message = f"unknown {field} {err.get('input')!r}; {hint}"
        parts.append(f"{where}: {message}".removeprefix(": "))
    return "; ".join(parts) or "invalid request"


def _add_error_handlers(app: FastAPI) -> None:
    def respond(code: int):
        async def handler(request: Request, exc: Exception) -> JSONResponse:
            if disk_full(exc):  # e.g. a bundle that could not be unpacked for want of space: not bad input
                return DISK_FULL.response()
            headers = {"WWW-Authenticate": "Bearer"} if code == status.HTTP_401_UNAUTHORIZED else None
            if retry_after_s := getattr(exc, "retry_after_s", None):
                headers = {"Retry-After": str(retry_after_s)}
            body: dict[str, object] = {"detail": str(exc)}
            if isinstance(existing := getattr(exc, "existing_ride_id", None), int):
                body["ride_id"] = existing  # the same clips again: the ride they already are
            if isinstance(offset := getattr(exc, "offset_bytes", None), int):
                # a chunk at the wrong offset: where to resume, as every answer of the upload says it
                body["offset_bytes"] = offset
                headers = {**(headers or {}), "Upload-Offset": str(offset)}
            return JSONResponse(body, status_code=code, headers=headers)

        return handler

    for error, code in ERROR_STATUS.items():
        app.add_exception_handler(error, respond(code))
    # A database, broker or store that does not answer: 503; a full disk: 507 (api/outages.py).
    add_outage_handlers(app)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, exc: RequestValidationError) -> JSONResponse:
        # One readable sentence (as every other error), the structured list under "errors".
        return JSONResponse({"detail": _validation_message(exc), "errors": _jsonable(exc.errors())},
                            status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)

    @app.exception_handler(IntegrityError)
    async def integrity(request: Request, exc: IntegrityError) -> JSONResponse:
        # Two requests raced for the same unique name, or a row vanished meanwhile.
        log.info("integrity error answered with 409: %s", exc.orig)
        return JSONResponse({"detail": "the change conflicts with data stored meanwhile; reload and try "
                                       "again"},
                            status_code=status.HTTP_409_CONFLICT)

    @app.exception_handler(DataError)
    async def data_error(request: Request, exc: DataError) -> JSONResponse:
        log.info("data error answered with 422: %s", exc.orig)
        return JSONResponse({"detail": "a value is out of range or not storable (e.g. too large a number)"},
                            status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)


def _jsonable(errors) -> list:
    from fastapi.encoders import jsonable_encoder

    return jsonable_encoder([{k: v for k, v in e.items() if k in ("loc", "msg", "type")} for e in errors])

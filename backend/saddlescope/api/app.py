"""The FastAPI application factory.

``create_app(settings)`` wires one settings object to one engine, one storage and one job queue,
mounts a router per resource under ``/api``, OpenAPI at ``/docs`` and the dashboard (``frontend/``)
at ``/``.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, Request, status
from fastapi.responses import JSONResponse
from fastapi.staticfiles import StaticFiles
from sqlalchemy.exc import SQLAlchemyError
from starlette.concurrency import run_in_threadpool

from saddlescope import __version__
from saddlescope.core.errors import SaddleScopeError
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.repositories import JobRepository, NotFound
from saddlescope.db.session import make_engine, make_session_factory, session_scope
from saddlescope.jobs import JobQueue, QueueUnavailable, make_queue
from saddlescope.settings import Settings, get_settings
from saddlescope.storage import Storage

log = logging.getLogger(__name__)

FRONTEND_DIR = Path(__file__).resolve().parents[3] / "frontend"


def _resume_unfinished(app: FastAPI) -> None:
    """Embedded mode: jobs a stopped server left queued or running are run again (stages are idempotent)."""
    try:
        with session_scope(app.state.sessions) as session:
            job_ids = [job.id for job in JobRepository(session).unfinished()]
    except SQLAlchemyError as exc:
        # Start anyway: /api/health then says what is wrong with the database.
        log.warning("cannot look for unfinished jobs: %s", exc)
        return
    for job_id in job_ids:
        log.info("resuming job %s left unfinished by an earlier server", job_id)
        app.state.queue.submit(job_id)


def create_app(settings: Settings | None = None, *, queue: JobQueue | None = None) -> FastAPI:
    """The SaddleScope web application for `settings` (default: from the environment).

    In embedded mode (no broker) the schema is migrated to the newest revision at start-up and
    jobs run in a local process pool; with a broker they go to Celery workers.
    """
    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        if settings.migrate_on_start:
            await run_in_threadpool(upgrade_to_head, settings.database_url)
        app.state.queue = queue or make_queue(settings)
        if settings.embedded:
            await run_in_threadpool(_resume_unfinished, app)
        try:
            yield
        finally:
            app.state.queue.close()
            app.state.engine.dispose()

    app = FastAPI(title="SaddleScope", version=__version__, lifespan=lifespan, docs_url="/docs",
                  openapi_url="/openapi.json",
                  description="Saddle kinematics and rider whole-body vibration from three ordinary cameras.")
    app.state.settings = settings
    app.state.engine = make_engine(settings.database_url)
    app.state.sessions = make_session_factory(app.state.engine)
    app.state.storage = Storage(settings.storage_dir)
    # Set here too so routes work when the lifespan is not run; the lifespan replaces it.
    app.state.queue = queue

    _add_error_handlers(app)

    from saddlescope.api.routers import health, jobs

    app.include_router(health.router, prefix="/api")
    app.include_router(jobs.router, prefix="/api")
    if FRONTEND_DIR.is_dir():
        app.mount("/", StaticFiles(directory=FRONTEND_DIR, html=True), name="frontend")
    else:
        log.warning("no dashboard: %s does not exist", FRONTEND_DIR)
    return app


def _add_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(NotFound)
    async def not_found(request: Request, exc: NotFound) -> JSONResponse:
        return JSONResponse({"detail": str(exc)}, status_code=status.HTTP_404_NOT_FOUND)

    @app.exception_handler(QueueUnavailable)
    async def queue_unavailable(request: Request, exc: QueueUnavailable) -> JSONResponse:
        return JSONResponse({"detail": str(exc)}, status_code=status.HTTP_503_SERVICE_UNAVAILABLE)

    @app.exception_handler(SaddleScopeError)
    async def bad_input(request: Request, exc: SaddleScopeError) -> JSONResponse:
        return JSONResponse({"detail": str(exc)}, status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)

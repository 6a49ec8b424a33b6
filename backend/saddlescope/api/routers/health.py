"""GET /api/health: database, broker and storage, each ok or error with a detail."""

from __future__ import annotations

from fastapi import APIRouter, Response, status
from starlette.concurrency import run_in_threadpool

from saddlescope import __version__
from saddlescope.api.deps import EngineDep, QueueDep, StorageDep
from saddlescope.api.schemas import HealthOut
from saddlescope.services.health import health_report

__all__ = ["router"]

router = APIRouter(tags=["health"])


@router.get("/health", response_model=HealthOut,
            responses={503: {"model": HealthOut, "description": "a part is not ok"}})
async def health(engine: EngineDep, queue: QueueDep, storage: StorageDep, response: Response) -> HealthOut:
    """Whether the database, the job queue and the storage answer (503 when a part does not)."""
    # The checks block (sockets, disk); keep them off the event loop.
    report = await run_in_threadpool(health_report, engine, queue, storage)
    if report["status"] != "ok":
        response.status_code = status.HTTP_503_SERVICE_UNAVAILABLE
    return HealthOut(version=__version__, **report)

"""GET /api/health (anyone: ok or degraded in one line) and /api/health/details (admins: paths, versions)."""

from __future__ import annotations

from fastapi import APIRouter, Response, status
from starlette.concurrency import run_in_threadpool

from saddlescope import __version__
from saddlescope.api.deps import AdminClubDep, EngineDep, QueueDep, SettingsDep, StorageDep
from saddlescope.api.routers.common import ERRORS
from saddlescope.api.schemas import HealthOut, HealthSummaryOut
from saddlescope.services.health import health_report, public_report

__all__ = ["router"]

router = APIRouter(tags=["health"])


def _report(settings, engine, queue, storage) -> dict:
    return health_report(engine, queue, storage, min_free_bytes=settings.storage_min_free_bytes)


@router.get("/health", response_model=HealthSummaryOut, response_model_exclude_none=True,
            responses={503: {"model": HealthSummaryOut, "description": "a part is not ok"}})
async def health(
    settings: SettingsDep, engine: EngineDep, queue: QueueDep, storage: StorageDep, response: Response
) -> HealthSummaryOut:
    """Whether the database, the job queue and the storage answer (503 when a part does not).

    A storage disk with less free space than ``SADDLESCOPE_STORAGE_MIN_FREE_BYTES`` is "degraded" (200:
    reading still works), with the free bytes.

    No sign-in needed (load balancers probe it), so it says only ok or not: the storage folder, the
    versions and the broker's address are in ``/api/health/details``, for club admins.
    """
    # The checks block (sockets, disk); keep them off the event loop.
    report = await run_in_threadpool(_report, settings, engine, queue, storage)
    if report["status"] == "error":
        response.status_code = status.HTTP_503_SERVICE_UNAVAILABLE
    return HealthSummaryOut(**public_report(report))


@router.get("/health/details", response_model=HealthOut, responses=ERRORS)
async def health_details(
    club: AdminClubDep, settings: SettingsDep, engine: EngineDep, queue: QueueDep, storage: StorageDep
) -> HealthOut:
    """Each part with what it said: database version and schema revision, queue mode, storage folder.

    Admins only. Answers 200 whatever the parts say (``status`` tells): the question was answered.
    """
    report = await run_in_threadpool(_report, settings, engine, queue, storage)
    return HealthOut(version=__version__, summary=public_report(report)["summary"], **report)

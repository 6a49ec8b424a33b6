"""Jobs: create one (it is queued at once), read its status, progress and timings, cancel it."""

from __future__ import annotations

from fastapi import APIRouter, status
from starlette.concurrency import run_in_threadpool

from saddlescope.api.deps import QueueDep, SessionDep, SessionFactoryDep
from saddlescope.api.schemas import ErrorOut, JobCreate, JobKindOut, JobOut
from saddlescope.services.job_service import cancel_job, get_job, job_as_dict, submit_job
from saddlescope.services.stages import JOB_KINDS

router = APIRouter(prefix="/jobs", tags=["jobs"])


@router.post("", status_code=status.HTTP_201_CREATED, response_model=JobOut,
             responses={404: {"model": ErrorOut}, 422: {"model": ErrorOut}, 503: {"model": ErrorOut}})
async def create(body: JobCreate, sessions: SessionFactoryDep, queue: QueueDep) -> JobOut:
    """Create a job and hand it to a worker (embedded pool or Celery)."""
    job_id = await run_in_threadpool(submit_job, sessions, queue, kind=body.kind, ride_id=body.ride_id,
                                     rig_id=body.rig_id, payload=body.payload)
    with sessions() as session:
        return JobOut(**job_as_dict(get_job(session, job_id)))


@router.get("/kinds", response_model=list[JobKindOut])
def kinds() -> list[JobKindOut]:
    """The job kinds this server knows, with their stages in order."""
    return [JobKindOut(name=k.name, stages=list(k.stages), needs_ride=k.needs_ride, description=k.description)
            for k in JOB_KINDS.values()]


@router.get("/{job_id}", response_model=JobOut, responses={404: {"model": ErrorOut}})
def read(job_id: int, session: SessionDep) -> JobOut:
    """Status, stage, progress (0-1), per-stage timings and error of a job."""
    return JobOut(**job_as_dict(get_job(session, job_id)))


@router.post("/{job_id}/cancel", response_model=JobOut, responses={404: {"model": ErrorOut}})
def cancel(job_id: int, session: SessionDep) -> JobOut:
    """Cancel a queued or running job (a running one stops at its next progress report)."""
    return JobOut(**job_as_dict(cancel_job(session, job_id)))

"""Jobs: create one (it is queued at once), list them, read status, progress and timings, cancel, retry."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from fastapi import APIRouter, Depends, Query, status
from starlette.concurrency import run_in_threadpool

from saddlescope.api.deps import ClubDep, ClubScope, QueueDep, SessionFactoryDep, SettingsDep
from saddlescope.api.routers.common import ERRORS, Id, Paging, QueryId, page_of, paging_sorted_by, sort_enum
from saddlescope.api.schemas import ErrorOut, JobCreate, JobKindOut, JobOut, Page
from saddlescope.db.repositories import Job, JobRepository
from saddlescope.db.session import session_scope
from saddlescope.services.jobs.lifecycle import cancel_job, get_job, job_as_dict, job_note, retry_job, submit_job
from saddlescope.services.jobs.stages import JOB_KINDS

__all__ = ["JobKindName", "JobSort", "JobStatusName", "job_out", "router"]

router = APIRouter(prefix="/jobs", tags=["jobs"])
JobStatusName = Literal["queued", "running", "done", "failed", "cancelled"]
if TYPE_CHECKING:
    JobKindName = str
else:  # the job kinds as a Literal the OpenAPI lists (built from JOB_KINDS at import)
    JobKindName = Literal[tuple(JOB_KINDS)]
JobSort = sort_enum("JobSort", JobRepository.sort_fields)
JobPaging = Annotated[Paging, Depends(paging_sorted_by(JobSort, "-id"))]


def job_out(job: Job, owner_id: int | None = None) -> JobOut:
    """The public view of a job (`owner_id`: who made its ride, who may cancel and retry it)."""
    return JobOut(**{**job_as_dict(job), "owner_id": owner_id})


class _AskOnce:
    """The queue, asked at most once per request whether workers are alive (a ping takes time)."""

    def __init__(self, queue) -> None:
        self._queue = queue
        self._alive: list = []

    def workers_alive(self) -> bool | None:
        if not self._alive:
            ask = getattr(self._queue, "workers_alive", None)
            self._alive.append(ask() if ask is not None else None)
        return self._alive[0]


_GAIT_WORDS = {"walk": "walk", "sitting_trot": "sitting trot", "rising_trot": "rising trot", "canter": "canter"}


def _ride_labels(club: ClubScope, ride_ids: list[int]) -> dict[int, str]:
    """Ride id -> "Bramble, sitting trot": the ride as the club names it."""
    return {ride_id: f"{horse}, {_GAIT_WORDS.get(gait, gait.replace('_', ' '))}"
            for ride_id, (horse, gait) in club.rides.horses_and_gaits(ride_ids).items()}


def _owners(club: ClubScope, jobs) -> dict[int, int | None]:
    return club.rides.creators_of([job.ride_id for job in jobs if job.ride_id is not None])


def _ride_owner(club: ClubScope, job_id: int) -> int | None:
    """Who made the job's ride (None for a job without a ride, or a ride whose maker is not recorded)."""
    ride_id = get_job(club.session, job_id, club_id=club.club_id).ride_id
    return club.rides.creator_of(ride_id) if ride_id is not None else None


@router.get("", response_model=Page[JobOut], responses=ERRORS)
def list_jobs(
    club: ClubDep,
    queue: QueueDep,
    settings: SettingsDep,
    paging: JobPaging,
    ride_id: QueryId = None,
    rig_id: QueryId = None,
    status_: Annotated[JobStatusName | None, Query(alias="status")] = None,
    kind: JobKindName | None = None,
) -> dict:
    """The club's jobs, newest first; filter by ride, rig, status and kind.

    Each says how far it is (`progress_percent`, `stage_label` in plain words) and, while queued or
    running, what it waits for (`note`, e.g. "waiting for a worker: ...").
    """
    page = club.jobs.list_page(
        ride_id=ride_id,
        rig_id=rig_id,
        status=status_,
        kind=kind,
        sort=paging.sort,
        limit=paging.limit,
        offset=paging.offset,
    )
    owners = _owners(club, page.items)
    labels = _ride_labels(club, [job.ride_id for job in page.items if job.ride_id is not None])
    asked = _AskOnce(queue)
    notes = {job.id: job_note(club.session, job, asked, stale_after_s=settings.stale_after_s)
             for job in page.items if job.status in ("queued", "running")}
    return page_of(page, lambda job: JobOut(**{**job_as_dict(job), "owner_id": owners.get(job.ride_id),
                                               "note": notes.get(job.id), "ride_label": labels.get(job.ride_id)}))


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    response_model=JobOut,
    responses={**ERRORS, 503: {"model": ErrorOut}},
)
async def create(body: JobCreate, club: ClubDep, sessions: SessionFactoryDep, queue: QueueDep) -> JobOut:
    """Create a job and hand it to a worker (embedded pool or Celery); selftest jobs are for admins."""
    if body.kind == "selftest":
        club.require("job.selftest")
    club_id = club.club_id
    club.session.rollback()
    job_id = await run_in_threadpool(
        submit_job,
        sessions,
        queue,
        kind=body.kind,
        ride_id=body.ride_id,
        rig_id=body.rig_id,
        payload=body.payload,
        club_id=club_id,
    )
    with session_scope(sessions) as session:
        return job_out(get_job(session, job_id))


@router.get("/kinds", response_model=list[JobKindOut], responses=ERRORS)
def kinds(club: ClubDep) -> list[JobKindOut]:
    """The job kinds this server knows, with their stages in order."""
    return [
        JobKindOut(name=k.name, stages=list(k.stages), needs_ride=k.needs_ride, description=k.description)
        for k in JOB_KINDS.values()
    ]


@router.get("/{job_id}", response_model=JobOut, responses=ERRORS)
def read(job_id: Id, club: ClubDep, queue: QueueDep, settings: SettingsDep) -> JobOut:
    """Status, stage, progress (0-1), per-stage timings and error of a job.

    `note` says "waiting for a worker: ..." when no worker is alive or the job's worker stopped.
    """
    job = get_job(club.session, job_id, club_id=club.club_id)
    owner = club.rides.creator_of(job.ride_id) if job.ride_id is not None else None
    note = job_note(club.session, job, queue, stale_after_s=settings.stale_after_s)
    label = _ride_labels(club, [job.ride_id]).get(job.ride_id) if job.ride_id is not None else None
    return JobOut(**{**job_as_dict(job), "note": note, "owner_id": owner, "ride_label": label})


@router.post("/{job_id}/cancel", response_model=JobOut, responses=ERRORS)
def cancel(job_id: Id, club: ClubDep) -> JobOut:
    """Cancel a queued or running job (a running one stops at its next progress report).

    An admin, or the member who made the job's ride (docs/permissions.md).
    """
    owner = _ride_owner(club, job_id)
    club.require("job.cancel", owner_id=owner)
    return job_out(cancel_job(club.session, job_id, club_id=club.club_id), owner)


@router.post(
    "/{job_id}/retry",
    response_model=JobOut,
    responses={
        **ERRORS,
        409: {"model": ErrorOut, "description": "not failed or cancelled"},
        503: {"model": ErrorOut},
    },
)
async def retry(job_id: Id, club: ClubDep, sessions: SessionFactoryDep, queue: QueueDep) -> JobOut:
    """Run a failed or cancelled job again (same id; the uploads were kept); an admin or the ride's maker."""
    owner = _ride_owner(club, job_id)
    club.require("job.retry", owner_id=owner)
    club_id = club.club_id
    club.session.rollback()
    await run_in_threadpool(retry_job, sessions, queue, job_id, club_id=club_id)
    with session_scope(sessions) as session:
        return job_out(get_job(session, job_id), owner)

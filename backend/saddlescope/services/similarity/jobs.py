"""Queue the comparisons a similarity list still needs as one ``similarity`` job (reusing a running one).

Apart from `saddlescope.services.similarity.club` so the stage registry (which runs the job) does not import
the job service (which submits it).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from saddlescope.db.enums import JobStatus
from saddlescope.db.repositories import JobRepository, ordered_pair
from saddlescope.db.session import session_scope
from saddlescope.services.jobs.lifecycle import get_job, job_as_dict, submit_job
from saddlescope.services.similarity.club import JOB_KIND

__all__ = ["queue_pairs"]


def queue_pairs(sessions: sessionmaker[Session], queue, pairs: Sequence[tuple[int, int]], *, club_id: int,
                markers: str, span: str) -> dict[str, Any]:
    """Hand the missing `pairs` to a worker as a similarity job; returns the job's public view.

    A queued or running similarity job of the club that covers these pairs already is returned
    instead of a new one (a page polling the list must not start a job per poll).
    """
    wanted = {ordered_pair(*p) for p in pairs}
    with session_scope(sessions) as session:
        for job in JobRepository(session, club_id=club_id).unfinished():
            payload = dict(job.payload or {})
            if (job.kind == JOB_KIND and payload.get("markers") == markers and payload.get("span") == span
                    and wanted <= {tuple(p) for p in payload.get("pairs") or []}
                    and job.status in (JobStatus.QUEUED.value, JobStatus.RUNNING.value)):
                return job_as_dict(job)
    job_id = submit_job(sessions, queue, kind=JOB_KIND, club_id=club_id,
                        payload={"markers": markers, "span": span, "pairs": [list(p) for p in sorted(wanted)]})
    with session_scope(sessions) as session:
        return job_as_dict(get_job(session, job_id))

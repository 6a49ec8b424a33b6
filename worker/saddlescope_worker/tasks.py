"""Thin tasks: take an id, call the service, let the jobs table carry progress and outcome."""

from __future__ import annotations

from sqlalchemy.exc import OperationalError

from saddlescope.services.jobs.queue import RUN_JOB_TASK
from saddlescope.services.jobs.runner import RETRY, STORE_RETRY_S
from saddlescope.services.jobs.runner import run_job as run_job_body
from saddlescope_worker.app import app


@app.task(name=RUN_JOB_TASK, bind=True, autoretry_for=(OperationalError,), retry_backoff=5,
          retry_backoff_max=120, max_retries=5, ignore_result=True)
def run_job(self, job_id: int) -> str:
    """Run job `job_id` (idempotent: a finished job is left alone, an interrupted one re-run).

    Transient errors are retried: a lost database connection (here), and a file store that did not
    answer (the runner queued the job again with the reason and bounds its attempts; run it after a
    pause; past the retries left here, the worker's sweep of long-queued jobs sends it again). A job's
    own errors end it as failed in the jobs table.
    """
    status = run_job_body(int(job_id))
    if status == RETRY:
        raise self.retry(countdown=STORE_RETRY_S)
    return status

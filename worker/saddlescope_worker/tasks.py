"""Thin tasks: take an id, call the service, let the jobs table carry progress and outcome."""

from __future__ import annotations

from sqlalchemy.exc import OperationalError

from saddlescope.services.queue import RUN_JOB_TASK
from saddlescope.services.runner import run_job as run_job_body
from saddlescope_worker.app import app


@app.task(name=RUN_JOB_TASK, autoretry_for=(OperationalError,), retry_backoff=5, retry_backoff_max=120,
          max_retries=5, ignore_result=True)
def run_job(job_id: int) -> str:
    """Run job `job_id` (idempotent: a finished job is left alone, an interrupted one re-run).

    Only a lost database connection is retried (a known transient error); a job's own errors end
    it as failed in the jobs table.
    """
    return run_job_body(int(job_id))

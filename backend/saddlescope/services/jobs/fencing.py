"""The error that stops a stale run: its job was taken over by a newer attempt (fenced jobs, issue 26)."""

from __future__ import annotations

__all__ = ["JobFenced"]


class JobFenced(Exception):
    """Raised when this run's attempt no longer holds its job (another worker took it over): stop, write nothing."""

    def __init__(self, job_id: int, attempt: int) -> None:
        super().__init__(f"job {job_id}: attempt {attempt} was taken over by a newer attempt")
        self.job_id, self.attempt = job_id, attempt

"""The Celery application (``celery -A saddlescope_worker.app worker`` or ``saddlescope worker``).

Long, CPU-heavy jobs: late acknowledgement and rejection on a lost worker (a crashed job is run
again, stages are idempotent), prefetch 1 (a busy worker never hoards jobs), JSON only, and a
broker visibility timeout of minutes (a killed worker's task is delivered again soon; a copy of a
healthy long job is refused by the fencing while its heartbeat is fresh). One task runs one whole job;
a task never waits on another task.
"""

from __future__ import annotations

import logging
import threading
import time

from celery import Celery
from celery.signals import worker_ready, worker_shutdown
from sqlalchemy.exc import SQLAlchemyError

from saddlescope.io.malloc import limit_frame_memory
from saddlescope.services.jobs.queue import QUEUE_NAME, RUN_JOB_TASK, celery_config
from saddlescope.settings import ConfigurationError, Settings, get_settings

log = logging.getLogger(__name__)

def create_celery(settings: Settings) -> Celery:
    """A Celery app configured from `settings` (the broker URL must be set)."""
    limit_frame_memory()  # before the pool starts (its forked processes inherit it): frames given back (issue 39)
    app = Celery("saddlescope", include=["saddlescope_worker.tasks"])
    app.conf.update(celery_config(settings))
    app.conf.worker_concurrency = 1  # one job per worker process; scale with more workers
    app.conf.worker_send_task_events = False
    return app


def _settings_for_worker() -> Settings:
    settings = get_settings()
    if settings.embedded:
        raise ConfigurationError(
            "a Celery worker needs SADDLESCOPE_BROKER_URL (e.g. redis://localhost:6379/0); without a broker, "
            "`saddlescope serve` runs jobs itself in embedded mode")
    return settings


app = create_celery(get_settings())
_stop_recovery = threading.Event()


def recover_once(settings: Settings | None = None) -> list[int]:
    """Send again the jobs a dead worker or a forgetful broker lost; returns their ids.

    Running jobs whose worker is gone (`saddlescope.services.jobs.runner.recover_lost_jobs`), and jobs
    queued longer than ``requeue_after_s`` that the broker does not hold (a Redis restarted with
    nothing persisted; `resend_queued_jobs`).
    """
    from saddlescope.db.session import session_factory_for
    from saddlescope.services.jobs.queue import broker_job_ids
    from saddlescope.services.jobs.runner import recover_lost_jobs, resend_queued_jobs

    settings = settings or get_settings()
    sessions = session_factory_for(settings.database_url)

    def submit(job_id: int) -> None:
        app.send_task(RUN_JOB_TASK, args=[job_id], queue=QUEUE_NAME)

    recovered = recover_lost_jobs(sessions, submit, stale_after_s=settings.stale_after_s,
                                  here=settings.resolved_host_name)
    return recovered + resend_queued_jobs(sessions, submit, older_than_s=settings.requeue_after_s,
                                          known=broker_job_ids(app))


def sweep_once(settings: Settings | None = None) -> dict[str, int]:
    """Remove abandoned uploads and partial writes (`saddlescope.services.uploads.intake.sweep_abandoned`)."""
    from saddlescope.db.session import session_factory_for
    from saddlescope.services.uploads.intake import sweep_abandoned
    from saddlescope.storage import open_storage

    settings = settings or get_settings()
    swept = sweep_abandoned(session_factory_for(settings.database_url), open_storage(settings),
                            max_age_s=settings.upload_expiry_s)
    if any(swept.values()):
        log.info("swept what was abandoned for %.0f h: %s", settings.upload_expiry_s / 3600,
                 ", ".join(f"{what} {n}" for what, n in swept.items()))
    return swept


def _recovery_loop() -> None:
    settings = get_settings()
    next_sweep = time.monotonic()  # a sweep at start, then one per sweep_interval_s
    while True:
        try:
            recover_once()
            if time.monotonic() >= next_sweep:
                next_sweep = time.monotonic() + settings.sweep_interval_s
                sweep_once()
        except SQLAlchemyError as exc:  # the database is down: try again at the next round
            log.warning("looking for lost jobs failed: %s", exc)
        except Exception:  # the broker or the store is down or restarting: the loop must outlive it
            log.exception("looking for lost jobs or sweeping failed")
        if _stop_recovery.wait(settings.recovery_interval_s):
            return


@worker_ready.connect
def _start_recovery(**_: object) -> None:
    # A thread: the solo pool runs tasks in the main thread, which must not wait for this.
    _stop_recovery.clear()
    threading.Thread(target=_recovery_loop, name="saddlescope-recover-lost-jobs", daemon=True).start()


@worker_shutdown.connect
def _stop_recovery_loop(**_: object) -> None:
    _stop_recovery.set()


def run_worker(argv: list[str] | None = None) -> int:
    """Run a worker in this process until it is stopped; returns the exit status."""
    _settings_for_worker()
    args = ["worker", "--loglevel=INFO", "-Q", QUEUE_NAME, *(argv or [])]
    try:
        app.worker_main(args)
    except SystemExit as exc:
        return int(exc.code or 0) if isinstance(exc.code, int | None) else 1
    return 0

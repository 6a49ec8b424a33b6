"""The Celery application (``celery -A saddlescope_worker.app worker`` or ``saddlescope worker``).

Long, CPU-heavy jobs: late acknowledgement and rejection on a lost worker (a crashed job is run
again, stages are idempotent), prefetch 1 (a busy worker never hoards jobs), JSON only, and a
broker visibility timeout longer than the longest job. One task runs one whole job; a task never
waits on another task.
"""

from __future__ import annotations

from celery import Celery

from saddlescope.jobs import QUEUE_NAME, celery_config
from saddlescope.settings import ConfigurationError, Settings, get_settings


def create_celery(settings: Settings) -> Celery:
    """A Celery app configured from `settings` (the broker URL must be set)."""
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


def run_worker(argv: list[str] | None = None) -> int:
    """Run a worker in this process until it is stopped; returns the exit status."""
    _settings_for_worker()
    args = ["worker", "--loglevel=INFO", "-Q", QUEUE_NAME, *(argv or [])]
    try:
        app.worker_main(args)
    except SystemExit as exc:
        return int(exc.code or 0) if isinstance(exc.code, int | None) else 1
    return 0

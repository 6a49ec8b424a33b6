"""The Celery app's configuration and `saddlescope worker`'s refusals (no broker or services needed)."""

from __future__ import annotations

import subprocess

import integration_services
import pytest

from conftest import PROJECT_ROOT
from saddlescope.services.jobs.queue import QUEUE_NAME, RUN_JOB_TASK
from saddlescope.settings import load_settings
from saddlescope_worker.app import app, create_celery


def test_long_task_settings():
    settings = load_settings(
        broker_url="redis://broker:6379/0", secret_key="a-test-secret-of-enough-length", job_time_limit_s=7200
    )
    conf = create_celery(settings).conf
    assert conf.task_acks_late and conf.task_reject_on_worker_lost
    assert conf.worker_prefetch_multiplier == 1
    assert conf.task_serializer == "json" and conf.accept_content == ["json"]
    assert settings.stale_after_s < conf.broker_transport_options["visibility_timeout"] <= 600 < conf.task_time_limit
    assert conf.task_default_queue == QUEUE_NAME


def test_the_task_is_registered_by_the_name_the_api_sends():
    app.loader.import_default_modules()
    assert RUN_JOB_TASK in app.tasks


@pytest.mark.parametrize(
    ("env", "message"),
    [
        ({}, "a Celery worker needs SADDLESCOPE_BROKER_URL"),
        ({"SADDLESCOPE_BROKER_URL": "redis://127.0.0.1:1/0"}, "SADDLESCOPE_SECRET_KEY must be set"),
    ],
)
def test_worker_command_refuses_to_start_with_one_clear_sentence(tmp_path, env, message):
    base = integration_services.service_env(
        database_url=f"sqlite:///{tmp_path / 'db.sqlite'}", storage_dir=tmp_path / "storage"
    )
    base.pop("SADDLESCOPE_SECRET_KEY")
    out = subprocess.run(
        [str(integration_services.VENV_BIN / "saddlescope"), "worker"],
        env=base | env,
        capture_output=True,
        text=True,
        timeout=60,
        cwd=PROJECT_ROOT,
    )
    assert out.returncode == 2
    assert message in out.stderr and "Traceback" not in out.stderr

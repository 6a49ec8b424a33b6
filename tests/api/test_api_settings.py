"""The one settings object: environment variables, defaults, and refusing unsafe deployments."""

from __future__ import annotations

from pathlib import Path

import pytest

from saddlescope.settings import DEFAULT_SECRET_KEY, ConfigurationError, load_settings


@pytest.fixture(autouse=True)
def clean_env(monkeypatch):
    import os

    for name in list(os.environ):
        if name.startswith("SADDLESCOPE_"):
            monkeypatch.delenv(name)


def test_defaults_are_the_embedded_laptop_setup():
    s = load_settings()
    assert s.embedded and s.broker_url is None and s.migrate_on_start
    assert s.database_url == "sqlite:///./var/saddlescope.db"
    assert s.storage_dir == Path("var/storage")
    assert s.max_upload_bytes == 4 * 1024**3
    assert s.secret_key.get_secret_value() == DEFAULT_SECRET_KEY
    assert s.token_lifetime_s > 0


def test_environment_variables_are_read(monkeypatch, tmp_path):
    monkeypatch.setenv("SADDLESCOPE_DATABASE_URL", "postgresql+psycopg://u@db/saddlescope")
    monkeypatch.setenv("SADDLESCOPE_BROKER_URL", "redis://redis:6379/0")
    monkeypatch.setenv("SADDLESCOPE_STORAGE_DIR", str(tmp_path))
    monkeypatch.setenv("SADDLESCOPE_MAX_UPLOAD_BYTES", "1000")
    monkeypatch.setenv("SADDLESCOPE_SECRET_KEY", "a-long-random-production-secret")
    monkeypatch.setenv("SADDLESCOPE_TOKEN_LIFETIME_S", "600")
    s = load_settings()
    assert not s.embedded and not s.migrate_on_start
    assert (s.database_url, s.broker_url, s.storage_dir) == (
        "postgresql+psycopg://u@db/saddlescope",
        "redis://redis:6379/0",
        tmp_path,
    )
    assert (s.max_upload_bytes, s.token_lifetime_s) == (1000, 600)


def test_the_default_secret_is_refused_with_a_broker(monkeypatch):
    monkeypatch.setenv("SADDLESCOPE_BROKER_URL", "redis://redis:6379/0")
    with pytest.raises(
        ConfigurationError, match="SADDLESCOPE_SECRET_KEY must be set to your own random value"
    ):
        load_settings()


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"broker_url": "  "}, "SADDLESCOPE_BROKER_URL is set but empty"),
        ({"secret_key": "short"}, "too short"),
        ({"max_upload_bytes": 0}, "max_upload_bytes"),
    ],
)
def test_invalid_settings_name_the_problem(overrides, message):
    with pytest.raises(ConfigurationError, match=message):
        load_settings(**overrides)


def test_visibility_timeout_outlasts_the_longest_job():
    s = load_settings(job_time_limit_s=3600)
    assert s.visibility_timeout_s > 3600

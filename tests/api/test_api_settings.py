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


def test_visibility_timeout_is_minutes_past_the_stale_time():
    # Issue 39 item 11: it was longer than the longest job (over 6 h): a killed worker's task waited that long.
    s = load_settings(job_time_limit_s=6 * 3600)
    assert s.stale_after_s < s.visibility_timeout_s <= 600
    assert load_settings(stale_after_s=600).visibility_timeout_s == 1200
    assert load_settings(broker_visibility_timeout_s=30).visibility_timeout_s == 30


@pytest.mark.parametrize("secret", ["a" * 16, "abababababababababab", "0123456"])
def test_weak_secrets_are_refused_at_start_up(secret):
    with pytest.raises(ConfigurationError, match="SADDLESCOPE_SECRET_KEY is too (weak|short)"):
        load_settings(broker_url="redis://redis:6379/0", secret_key=secret)


def test_embedded_mode_generates_and_keeps_its_own_secret(tmp_path):
    import stat

    from saddlescope.settings import with_embedded_secret

    settings = load_settings(storage_dir=str(tmp_path / "var" / "storage"))
    first = with_embedded_secret(settings)
    secret = first.secret_key.get_secret_value()
    assert secret != DEFAULT_SECRET_KEY and len(secret) >= 32
    path = tmp_path / "var" / "secret_key"
    assert path.read_text().strip() == secret
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert with_embedded_secret(settings).secret_key.get_secret_value() == secret  # reused on restart
    other = with_embedded_secret(load_settings(storage_dir=str(tmp_path / "other" / "storage")))
    assert other.secret_key.get_secret_value() != secret


def test_the_app_never_signs_with_the_public_default_secret(tmp_path):
    from saddlescope.api import create_app

    app = create_app(load_settings(storage_dir=str(tmp_path / "storage"),
                                   database_url=f"sqlite:///{tmp_path / 'db.sqlite'}"))
    assert app.state.settings.secret_key.get_secret_value() != DEFAULT_SECRET_KEY


@pytest.mark.parametrize(("choice", "scheme", "secure"),
                         [("auto", "http", False), ("auto", "https", True), ("true", "http", True),
                          ("false", "https", False)])
def test_the_cookie_secure_flag_follows_the_setting_not_the_proxy_address(choice, scheme, secure):
    from types import SimpleNamespace

    from saddlescope.api.routers.auth import cookie_secure

    request = SimpleNamespace(url=SimpleNamespace(scheme=scheme))
    assert cookie_secure(request, load_settings(cookie_secure=choice)) is secure

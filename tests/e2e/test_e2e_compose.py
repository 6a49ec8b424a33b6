"""docker-compose.yml: api, scalable worker, redis, postgres and a one-shot migrate service.

With the compose plugin, `docker compose config` must accept the file. Without it (this machine
has the docker client but no compose plugin) the YAML is parsed and its structure checked.
"""

from __future__ import annotations

import shutil
import subprocess

import integration_services
import yaml

from conftest import PROJECT_ROOT

COMPOSE = PROJECT_ROOT / "docker-compose.yml"
ENV = {"SADDLESCOPE_SECRET_KEY": "compose-config-test-secret", "PATH": "/usr/local/bin:/usr/bin:/bin"}


def compose_plugin_available() -> bool:
    if shutil.which("docker") is None:
        return False
    probe = subprocess.run(["docker", "compose", "version"], capture_output=True, text=True, timeout=30)
    return probe.returncode == 0


def load_compose() -> dict:
    """The compose model: from `docker compose config` when possible, else the parsed YAML."""
    if compose_plugin_available():
        out = subprocess.run(
            ["docker", "compose", "-f", str(COMPOSE), "config", "--format", "json"],
            capture_output=True,
            text=True,
            timeout=60,
            env=ENV,
            cwd=PROJECT_ROOT,
        )
        assert out.returncode == 0, f"docker compose config rejected the file:\n{out.stderr}"
        import json

        return json.loads(out.stdout)
    return yaml.safe_load(COMPOSE.read_text())


def test_compose_file_has_its_services_wired_together(request):
    model = load_compose()
    how = (
        "`docker compose config`"
        if compose_plugin_available()
        else "a YAML structure check (no compose plugin)"
    )
    integration_services.report_service(request.config, f"docker-compose.yml validated by {how}")
    services = model["services"]
    assert set(services) == {"proxy", "api", "worker", "redis", "postgres", "seaweedfs", "migrate"}
    assert services["migrate"]["command"][-1].startswith("alembic upgrade head")
    for name in ("api", "worker"):
        depends = services[name]["depends_on"]
        assert depends["migrate"]["condition"] == "service_completed_successfully"
        assert depends["redis"]["condition"] == "service_healthy"
        assert not _volumes(services[name]), name  # no shared folder: clips and results live in the bucket
    assert services["migrate"]["depends_on"]["postgres"]["condition"] == "service_healthy"
    assert services["migrate"]["depends_on"]["seaweedfs"]["condition"] == "service_healthy"
    # scalable API replicas and workers: no fixed name, no published port (the proxy publishes one)
    for name in ("api", "worker"):
        assert "container_name" not in services[name] and "ports" not in services[name], name
    assert services["proxy"].get("ports")
    assert services["worker"]["command"] == ["saddlescope", "worker"]
    for name in ("api", "worker", "migrate"):
        env = services[name]["environment"]
        assert env["SADDLESCOPE_DATABASE_URL"].startswith("postgresql+psycopg://")
        assert env["SADDLESCOPE_BROKER_URL"].startswith("redis://redis:6379")
        assert env["SADDLESCOPE_STORAGE_URL"].startswith("s3://")
        assert "SADDLESCOPE_SECRET_KEY" in env


def _volumes(service: dict) -> list[str]:
    out = []
    for v in service.get("volumes", []):
        out.append(v if isinstance(v, str) else v.get("target", ""))
    return out


def test_the_secret_is_required_not_defaulted():
    assert "${SADDLESCOPE_SECRET_KEY:?" in COMPOSE.read_text()
    if compose_plugin_available():
        out = subprocess.run(
            ["docker", "compose", "-f", str(COMPOSE), "config"],
            capture_output=True,
            text=True,
            timeout=60,
            env={"PATH": ENV["PATH"]},
            cwd=PROJECT_ROOT,
        )
        assert out.returncode != 0 and "SADDLESCOPE_SECRET_KEY" in out.stderr


def test_dockerfile_installs_the_package_and_serves():
    dockerfile = (PROJECT_ROOT / "Dockerfile").read_text()
    assert dockerfile.startswith("#") and "FROM python:3.11" in dockerfile
    assert "pip install" in dockerfile and '"saddlescope", "serve"' in dockerfile

"""The production compose file and the proxy config (issue 26 part 4).

`docker-compose config` (the compose CLI from PyPI, 1.29.2, which needs no Docker daemon for `config`)
validates the file and resolves it: variables, anchors, merge keys. `make install` puts it in a venv
of its own, `.cache/compose-venv` (it pins PyYAML<6 and jsonschema<4, which the project's venv must not
take). Then the resolved file's production shape is checked.
"""

from __future__ import annotations

import ipaddress
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
import s3_server as s3_server_module
import yaml

ROOT = Path(__file__).resolve().parents[2]
COMPOSE = ROOT / "docker-compose.yml"
COMPOSE_CLI = ROOT / ".cache" / "compose-venv" / "bin" / "docker-compose"
HAPROXY_CFG = ROOT / "deploy" / "haproxy.cfg"
IN_CI = os.environ.get("CI", "").lower() in {"1", "true", "yes"}
REQUIRED = {"SADDLESCOPE_SECRET_KEY": "s" * 64, "AWS_SECRET_ACCESS_KEY": "a" * 48}


def _require(tool: Path | None, message: str) -> None:
    if tool is None or not Path(tool).exists():
        if IN_CI:
            pytest.fail(f"{message}; CI=true requires this check to run")
        pytest.skip(message)


def compose_config(file: Path = COMPOSE, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """`docker-compose -f FILE config` in the project's folder, with only `env` set besides PATH/HOME."""
    _require(COMPOSE_CLI, f"the compose CLI is not installed at {COMPOSE_CLI}: run `make install`")
    environ = {"PATH": os.environ.get("PATH", ""), "HOME": os.environ.get("HOME", "/root"),
               **(REQUIRED if env is None else env)}
    return subprocess.run([str(COMPOSE_CLI), "-f", str(file), "--project-directory", str(ROOT), "config"],
                          capture_output=True, text=True, env=environ, timeout=120)


@pytest.fixture(scope="module")
def compose() -> dict:
    """The file as `docker-compose config` resolves it (it refuses an invalid file)."""
    resolved = compose_config()
    assert resolved.returncode == 0, resolved.stderr
    return yaml.safe_load(resolved.stdout)


def test_compose_config_validates_the_file(compose):
    assert {"proxy", "api", "worker", "postgres", "redis", "seaweedfs"} <= set(compose["services"])


def test_compose_config_refuses_an_invalid_file(tmp_path):
    broken = yaml.safe_load(COMPOSE.read_text())
    broken["services"]["api"]["healthcheck"]["intervall"] = "5s"  # a misspelt key
    file = tmp_path / "docker-compose.yml"
    file.write_text(yaml.safe_dump(broken))
    resolved = compose_config(file)
    assert resolved.returncode != 0 and "intervall" in resolved.stderr, resolved.stderr


def test_secrets_are_required_not_defaulted():
    for name in REQUIRED:
        resolved = compose_config(env={k: v for k, v in REQUIRED.items() if k != name})
        assert resolved.returncode != 0 and name in resolved.stderr, resolved.stderr


def _named_volumes(service: dict) -> set[str]:
    out = set()
    for volume in service.get("volumes", []):
        source = volume.split(":", 1)[0] if isinstance(volume, str) else volume.get("source", "")
        out.add(source)
    return out


def shape_problems(compose: dict) -> list[str]:
    """What the production shape forbids, each as a sentence (empty: the file has the shape)."""
    services, problems = compose["services"], []
    if not services["proxy"].get("ports"):
        problems.append("the proxy publishes no port")
    for name in ("api", "worker", "postgres", "redis"):
        if services[name].get("ports"):
            problems.append(f"{name} has a host port (the API's would forbid --scale api=N)")
    for name in ("api", "worker"):
        if "container_name" in services[name]:
            problems.append(f"{name} has a container_name (forbids --scale)")
    api, worker = services["api"], services["worker"]
    if _named_volumes(api) or _named_volumes(worker):
        problems.append(f"API or worker volumes: {_named_volumes(api) | _named_volumes(worker)} "
                        "(clips travel through the bucket only)")
    for name, service in (("api", api), ("worker", worker)):
        env = service.get("environment", {})
        if not str(env.get("SADDLESCOPE_STORAGE_URL", "")).startswith("s3://"):
            problems.append(f"{name} does not store in the bucket (SADDLESCOPE_STORAGE_URL)")
    command = services["redis"].get("command", [])
    if "--appendonly" not in command or command[command.index("--appendonly") + 1] != "yes":
        problems.append("redis is not append-only")
    problems += [f"{name} has no healthcheck" for name, service in services.items() if not service.get("healthcheck")]
    return problems


def test_the_file_has_the_production_shape(compose):
    assert shape_problems(compose) == []


@pytest.mark.parametrize("breakage, expected", [
    (lambda c: c["services"]["api"].update(ports=["8000:8000"]), "api has a host port"),
    (lambda c: c["services"]["worker"].update(volumes=["storage:/data"]), "API or worker volumes"),
    (lambda c: c["services"]["redis"].update(command=["redis-server"]), "redis is not append-only"),
    (lambda c: c["services"]["seaweedfs"].pop("healthcheck"), "seaweedfs has no healthcheck"),
    (lambda c: c["services"]["api"]["environment"].update(SADDLESCOPE_STORAGE_URL="/data"), "api does not store"),
])
def test_the_shape_check_catches_each_breakage(compose, breakage, expected):
    broken = json.loads(json.dumps(compose))
    breakage(broken)
    assert any(p.startswith(expected) for p in shape_problems(broken)), shape_problems(broken)


def test_the_api_reaches_the_store_by_its_service_name(compose):
    for name in ("api", "worker"):
        assert compose["services"][name]["environment"]["SADDLESCOPE_S3_ENDPOINT_URL"] == "http://seaweedfs:8333"


def test_workers_have_pinned_threads_and_a_cpu_limit(compose):
    worker = compose["services"]["worker"]
    threads = int(worker["environment"]["SADDLESCOPE_WORKER_THREADS"])
    assert threads >= 1 and float(worker["cpus"]) >= threads


def test_forwarded_headers_are_trusted_from_the_proxy_only(compose):
    proxy_ip = compose["services"]["proxy"]["networks"]["front"]["ipv4_address"]
    assert compose["services"]["api"]["environment"]["SADDLESCOPE_FORWARDED_ALLOW_IPS"] == proxy_ip
    subnet = compose["networks"]["front"]["ipam"]["config"][0]["subnet"]
    assert ipaddress.ip_address(proxy_ip) in ipaddress.ip_network(subnet)


def test_seaweedfs_names_every_port(compose):
    command = " ".join(compose["services"]["seaweedfs"]["command"])
    assert command.split()[0] == "mini"
    for flag in s3_server_module.PORT_FLAGS:  # the flags the tests' own `weed mini` names
        assert f"-{flag}=" in command, f"weed mini's {flag} is left to its default"


def test_the_proxy_checks_api_health_without_sticky_sessions():
    text = HAPROXY_CFG.read_text()
    assert "option httpchk GET /api/health" in text
    assert "cookie " not in text and "stick " not in text, "uploads resume on any replica: no stickiness"
    assert "X-Forwarded-Proto" in text


def test_haproxy_accepts_its_config():
    haproxy = shutil.which("haproxy")
    _require(haproxy and Path(haproxy), "haproxy is not installed (apt-get install haproxy)")
    out = subprocess.run([haproxy, "-c", "-f", str(HAPROXY_CFG)], capture_output=True, text=True, timeout=30)
    assert out.returncode == 0, out.stdout + out.stderr

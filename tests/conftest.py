"""Shared test helpers: where ../shared/data/real is, and how services are required under CI."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
REAL_DATA = PROJECT_ROOT.parent / "shared" / "data" / "real"
IN_CI = os.environ.get("CI", "").lower() in {"1", "true", "yes"}


def real_data_path(*parts: str) -> Path:
    """Path into ../shared/data/real; skips the test with a reason where it is absent."""
    path = REAL_DATA.joinpath(*parts)
    if not path.exists():
        if IN_CI:
            pytest.fail(f"real data {path} is missing under CI")
        pytest.skip(f"real data not available: {path} (../shared is absent in a user's own clone)")
    return path


@pytest.fixture
def real_data():
    return real_data_path


# --- pytest-xdist (`make test` runs the suite on two workers, --dist loadfile) ------------------------
# Each worker collects the services its tests used (integration_services.report_service); they are
# handed to the controller, whose terminal summary names them as a single-process run does.

_SERVICES_KEY = "saddlescope_services"


def pytest_sessionfinish(session):
    config = session.config
    if hasattr(config, "workeroutput"):  # an xdist worker
        plugin = config.pluginmanager.get_plugin("saddlescope-service-report")
        config.workeroutput[_SERVICES_KEY] = list(plugin.lines) if plugin is not None else []


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    from integration_services import report_service

    for line in getattr(node, "workeroutput", {}).get(_SERVICES_KEY, []):
        report_service(node.config, line)

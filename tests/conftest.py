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


# --- the order of test files (`make test`: --dist loadfile --no-loadscope-reorder) ---------------------
# Each worker takes the next whole file as it finishes one; pytest-xdist's own order (most tests first)
# left the heaviest files, which hold few tests, to the end, with one worker idle meanwhile. The files
# measured heaviest go first (heaviest first; CPU seconds on a quiet run), then the files with the most
# slow, browser or integration tests, then the rest in their usual order: the light files fill the end.
HEAVY_FIRST = (
    "tests/multihost/test_multihost.py",  # ~240 s
    "tests/core/test_sync_motion.py",  # ~230 s
    "tests/core/pipeline/test_wide_rig.py",  # ~220 s
    "tests/bench/test_dashboard_bench.py",  # ~200 s
    "tests/core/pipeline/test_pipeline.py",
    "tests/api/test_api_flow.py",
    "tests/e2e/dashboard_helpers.py",
    "tests/e2e/test_page_audit.py",
    "tests/io/test_synth_writer.py",
    # few tests each but long ones (CI's durations, 2026-11-29): first, so none is left running alone at the end
    "tests/e2e/test_club_journey.py",  # ~150 s
    "tests/api/test_api_real_pipeline.py",  # ~145 s
    "tests/core/pipeline/test_wand_ride.py",  # ~125 s
    "tests/core/pipeline/test_partial_views.py",  # ~100 s
    "tests/core/pipeline/test_passes_rendered.py",  # ~85 s
    "tests/core/pipeline/test_rolling_shutter_ride.py",  # ~85 s
    "tests/services/test_calibration_check.py",  # ~80 s
)
_HEAVY_MARKS = ("slow", "browser", "integration")


def pytest_collection_modifyitems(config, items):
    """Heavy files first (see HEAVY_FIRST); each file's own tests keep their order."""
    files: dict[str, list] = {}
    for item in items:
        files.setdefault(item.nodeid.split("::", 1)[0], []).append(item)
    rank = {path: i for i, path in enumerate(HEAVY_FIRST)}

    def weight(entry):
        position, (path, its_items) = entry
        heavy = sum(any(item.get_closest_marker(m) for m in _HEAVY_MARKS) for item in its_items)
        return (rank.get(path, len(rank)), -heavy, position)

    ordered = sorted(enumerate(files.items()), key=weight)
    items[:] = [item for _, (_, its_items) in ordered for item in its_items]

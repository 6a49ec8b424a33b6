"""Shared test helpers: where ../shared/data/real is, and how services are required under CI."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Argon2's cheapest parameters for every server the tests start (Settings.password_hashing): the suite signs in
# thousands of times, each 0.15 s of a core with a club server's parameters; test_api_accounts checks those.
os.environ.setdefault("SADDLESCOPE_PASSWORD_HASHING", "cheapest-for-tests")

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
# measured heaviest go first (heaviest first), then the files with the most
# slow, browser or integration tests, then the rest in their usual order: the light files fill the end.
HEAVY_FIRST = (
    # test seconds on a full run, setup included (pytest's junit report, 2026-11-29 evening)
    "tests/multihost/test_multihost.py",  # ~300 s
    "tests/api/test_api_flow.py",  # ~255 s
    "tests/core/pipeline/test_wide_rig.py",  # ~225 s
    "tests/core/test_sync_motion.py",  # ~130 s
    "tests/core/pipeline/test_pipeline.py",  # ~120 s
    "tests/core/pipeline/test_wand_ride.py",  # ~105 s
    "tests/e2e/test_page_audit.py",  # ~105 s
    "tests/core/calibration/test_wand.py",  # ~90 s
    "tests/api/test_api_real_pipeline.py",  # ~90 s
    "tests/core/kinematics/test_kinematics_floor.py",  # ~85 s
    "tests/e2e/test_club_journey.py",  # ~75 s
    "tests/core/pipeline/test_board_wand_ride.py",  # ~75 s
    "tests/core/pipeline/test_passes_rendered.py",  # ~70 s
    "tests/e2e/test_dashboard.py",  # ~70 s
    "tests/core/pipeline/test_partial_views.py",  # ~65 s
    "tests/services/test_calibration_check.py",  # ~60 s
    "tests/bench/test_service_bench.py",  # ~60 s
    "tests/api/test_api_schemathesis.py",  # ~55 s
    "tests/e2e/test_failed_ride_page.py",  # ~55 s
    "tests/io/test_calibration_files.py",  # ~50 s
    "tests/io/test_synth_writer.py",  # ~45 s
    "tests/api/test_api_worker_fault.py",  # ~45 s
    "tests/core/pipeline/test_rolling_shutter_ride.py",  # ~45 s
    "tests/api/test_api_sessions.py",  # ~45 s
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

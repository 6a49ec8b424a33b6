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

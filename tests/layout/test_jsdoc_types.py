"""The dashboard's JSDoc types are checked (issue 34 part 6): `tsc -p frontend/tsconfig.json` passes on the
modules that start with `// @ts-check`, as `make lint` runs it.

TypeScript comes from npm into .cache/npm-tsc (the Makefile's `$(TSC_STAMP)`); without it the check
skips with the reason, and fails under CI=true, where the Makefile installs it.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TSC = ROOT / ".cache" / "npm-tsc" / "node_modules" / ".bin" / "tsc"
CHECKED = ("js/api.js", "js/format.js", "js/options.js")


def test_the_typed_modules_ask_to_be_checked():
    for name in CHECKED:
        first = (ROOT / "frontend" / name).read_text(encoding="utf-8").splitlines()[0]
        assert first == "// @ts-check", name


def test_the_jsdoc_types_check():
    if not TSC.exists():
        reason = f"typescript is not installed ({TSC}); `make lint` installs it with npm"
        if os.environ.get("CI") == "true":
            pytest.fail(reason)
        pytest.skip(reason)
    done = subprocess.run([str(TSC), "-p", "frontend/tsconfig.json"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300, check=False)
    assert done.returncode == 0, done.stdout + done.stderr

"""The dashboard's JSDoc types are checked (issue 34 part 6): `tsc -p frontend/tsconfig.json` passes, strict,
on every module of frontend/ (app.js, js/, js/views/), as `make lint` runs it; the API's answers are typed
by js/api-types.d.ts, which tests/api/test_api_frontend_types.py keeps equal to the API's OpenAPI schema.

TypeScript comes from npm into .cache/npm-tsc (the Makefile's `$(TSC_STAMP)`); without it the checks that
run tsc skip with the reason, and fail under CI=true, where the Makefile installs it.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FRONTEND = ROOT / "frontend"
TSC = ROOT / ".cache" / "npm-tsc" / "node_modules" / ".bin" / "tsc"
# What switches the checker off for a line or a file: none is used (a module that needs one says why in
# plain JSDoc instead, with a cast).
OPT_OUTS = re.compile(r"@ts-(ignore|nocheck|expect-error)")


def _modules() -> list[Path]:
    return sorted(p for p in FRONTEND.rglob("*.js") if "vendor" not in p.relative_to(FRONTEND).parts)


def _tsc(*args: str) -> subprocess.CompletedProcess[str]:
    if not TSC.exists():
        reason = f"typescript is not installed ({TSC}); `make lint` installs it with npm"
        if os.environ.get("CI") == "true":
            pytest.fail(reason)
        pytest.skip(reason)
    return subprocess.run([str(TSC), "-p", "frontend/tsconfig.json", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, check=False)


def test_the_check_is_strict_and_reads_plain_javascript():
    options = json.loads((FRONTEND / "tsconfig.json").read_text(encoding="utf-8"))["compilerOptions"]
    assert options["strict"] is True
    assert options["checkJs"] is True and options["allowJs"] is True


def test_no_module_switches_the_checker_off():
    found = [f"{p.relative_to(ROOT)}:{n}" for p in _modules()
             for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if OPT_OUTS.search(line)]
    assert not found, "modules that switch tsc off: " + ", ".join(found)


def test_every_dashboard_module_is_checked():
    done = _tsc("--listFilesOnly")
    assert done.returncode == 0, done.stdout + done.stderr
    checked = {Path(line.strip()).resolve() for line in done.stdout.splitlines() if line.strip()}
    unchecked = [str(p.relative_to(ROOT)) for p in _modules() if p.resolve() not in checked]
    assert not unchecked, f"modules tsc does not check: {unchecked}"
    assert (FRONTEND / "js" / "api-types.d.ts").resolve() in checked


def test_the_jsdoc_types_check():
    done = _tsc()
    assert done.returncode == 0, done.stdout + done.stderr


PROBE = """\
import {{ get }} from "{api}";

/** @typedef {{import("{types}").RideDetail}} RideDetail */

/** @param {{number}} id */
export async function named(id) {{
  /** @type {{RideDetail}} */
  const ride = await get(`/api/rides/${{id}}`);
  return ride.horse_name;
}}

/** @param {{number}} id */
export async function misspelt(id) {{
  /** @type {{RideDetail}} */
  const ride = await get(`/api/rides/${{id}}`);
  return ride.horse_nam;
}}

/** @param {{number}} id */
export async function unnamed(id) {{
  const ride = await get(`/api/rides/${{id}}`);
  return ride.horse_name;
}}
"""


def test_a_page_reading_the_api_must_name_the_schema_and_its_fields(tmp_path):
    """What the check holds a page to: an answer read through api.js's `get` has the type the page names
    from api-types.d.ts (a field the API does not send fails), and no type at all (`unknown`) unnamed."""
    probe = tmp_path / "probe.js"
    probe.write_text(PROBE.format(api=FRONTEND / "js" / "api.js", types=FRONTEND / "js" / "api-types"),
                     encoding="utf-8")
    if not TSC.exists():
        _tsc()  # skips (fails under CI) with the reason
    done = subprocess.run([str(TSC), "--noEmit", "--allowJs", "--checkJs", "--strict", "--target", "ES2022",
                           "--module", "ES2022", "--moduleResolution", "bundler", "--skipLibCheck", str(probe)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False)
    errors = [line for line in done.stdout.splitlines() if "probe.js(" in line]
    lines = {int(re.search(r"probe\.js\((\d+),", line).group(1)) for line in errors}
    source = PROBE.splitlines()
    assert lines == {source.index("  return ride.horse_nam;") + 1, len(source) - 1}, done.stdout
    assert "horse_nam" in errors[0] and "unknown" in errors[1], errors

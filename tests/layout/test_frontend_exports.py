"""A dashboard module exports only what another module (or a browser test) uses (issue 34).

An export nothing imports is either dead (a chart no page draws any more: `spreadBarChart` and `gradeScatter`
were) or a name the module keeps to itself, which should not widen its interface. A use is the name as a
whole word in another module, `app.js` or a test (the router's dynamic `import()` calls are read the same way).
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FRONTEND = ROOT / "frontend"
EXPORT = re.compile(r"^export (?:async )?(?:function\*?|const|let|class) ([A-Za-z_$][\w$]*)", re.M)


def _sources() -> dict[Path, str]:
    files = [FRONTEND / "app.js", *sorted((FRONTEND / "js").rglob("*.js"))]
    return {path: path.read_text(encoding="utf-8") for path in files}


def _exports_nobody_uses(sources: dict[Path, str], tests_text: str) -> list[str]:
    unused = []
    for path, text in sources.items():
        for name in EXPORT.findall(text):
            word = re.compile(rf"(?<![\w$]){re.escape(name)}(?![\w$])")
            if not any(word.search(other) for p, other in sources.items() if p != path) and not word.search(tests_text):
                unused.append(f"{path.relative_to(ROOT)}: {name}")
    return unused


def test_every_export_of_a_dashboard_module_is_used_elsewhere():
    tests_text = "\n".join(p.read_text(encoding="utf-8") for p in (ROOT / "tests").rglob("*.py"))
    unused = _exports_nobody_uses(_sources(), tests_text)
    assert not unused, ("exported but used by no other module or test (delete it, or drop `export` if the module "
                        "uses it itself):\n  " + "\n  ".join(unused))


def test_the_check_sees_an_export_nobody_imports():
    sources = {FRONTEND / "js" / "a.js": "export function drawn() {}\nexport const kept = 1;\n"
                                         "export function dead() {}\n",
               FRONTEND / "js" / "b.js": 'import { drawn } from "./a.js";\ndrawn();\n'}
    assert _exports_nobody_uses(sources, "page.evaluate('kept')") == ["frontend/js/a.js: dead"]

"""The layout stays easy to read: small modules, short functions, no import cycles (issue 22).

Migrations are exempt: each is one long, generated-looking upgrade.
"""

from __future__ import annotations

import ast
from pathlib import Path

import grimp

PACKAGE = Path(__file__).resolve().parents[2] / "backend" / "saddlescope"
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 80


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py"))


def test_no_module_over_800_lines():
    long = {str(p.relative_to(PACKAGE)): n for p in _modules()
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_no_function_over_80_lines():
    long = []
    for path in _modules():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, "functions over 80 lines (def to last line, docstring included):\n" + "\n".join(long)


def _cycle(graph: grimp.ImportGraph, modules: set[str]) -> list[str] | None:
    """One import cycle among ``modules`` (a list of modules, first = last), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(module: str, path: list[str]) -> list[str] | None:
        state[module] = 1
        # a module importing its own package's __init__ (which imports the module back) is no cycle of
        # design: the package only re-exports its modules' names
        for imported in sorted(m for m in graph.find_modules_directly_imported_by(module) & modules
                               if not module.startswith(m + ".")):
            if state.get(imported) == 1:
                return path[path.index(imported):] + [imported]
            if imported not in state and (found := visit(imported, path + [imported])):
                return found
        state[module] = 2
        return None

    for module in sorted(modules):
        if module not in state and (found := visit(module, [module])):
            return found
    return None


def test_no_import_cycle_between_modules():
    graph = grimp.build_graph("saddlescope", cache_dir=None)
    cycle = _cycle(graph, set(graph.modules))
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def _stage(module: str) -> str:
    """The package a module's private names belong to: its parent, at most three deep ("saddlescope.api",
    "saddlescope.core.calibration", "saddlescope.services.rigs")."""
    return ".".join(module.split(".")[:-1][:3])


def test_private_names_are_imported_only_inside_their_package():
    """Issue 34: 90 imports of `_private` names crossed modules; a name with a leading underscore is a
    package's own, so another package reaches it through a public one instead."""
    crossings = []
    for path in _modules():
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        importer = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        for node in ast.walk(ast.parse(path.read_text())):
            if not (isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("saddlescope")):
                continue
            for alias in node.names:
                private = alias.name.startswith("_") and not alias.name.startswith("__")
                if private and not importer.startswith(_stage(node.module)):
                    crossings.append(f"{importer} imports {node.module}.{alias.name}")
    assert not crossings, crossings

"""Each dashboard page's markup lives beside its module (issue 34 part 6): `js/views/ride.html` holds the
`<template id="page-ride">` that `ride.js` fills, a part shared by several pages lives beside the module
that fills it (`js/ride-edit.html`), and index.html keeps only the shell.

A route in app.js names the files its page needs (`markup: [...]`), fetched before the page mounts; the
browser cannot know a module's imports before loading them, so this test checks the list against them:
the route's own module's file, and the file of every module it imports (transitively) that holds parts
only. A page's file of another route is not fetched (ride.js imports similar.js for a helper, not for
the pair page's markup).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import cache
from html.parser import HTMLParser
from pathlib import Path

FRONTEND = Path(__file__).resolve().parents[2] / "frontend"
# The shell's own templates: the router's fallback, and the page shown when the server does not answer
# (when nothing more can be fetched).
SHELL_TEMPLATES = {"page-unreachable", "page-not-found"}


@dataclass
class Markup:
    """One HTML file's top-level templates, what lies beside them, and the parts its templates ask for."""

    templates: list[str] = field(default_factory=list)
    stray: list[str] = field(default_factory=list)  # elements or text outside the templates
    parts_asked: set[str] = field(default_factory=set)  # data-part="NAME" placeholders


class _TopLevel(HTMLParser):
    """Reads a markup file's templates (only template nesting is counted: what they hold is the page's)."""

    def __init__(self) -> None:
        super().__init__()
        self.markup, self.depth = Markup(), 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        if values.get("data-part"):
            self.markup.parts_asked.add(values["data-part"] or "")
        if tag == "template":
            if self.depth == 0:
                self.markup.templates.append(values.get("id") or "")
            self.depth += 1
        elif self.depth == 0:
            self.markup.stray.append(f"<{tag}>")

    def handle_endtag(self, tag: str) -> None:
        if tag == "template":
            self.depth -= 1

    def handle_data(self, data: str) -> None:
        if self.depth == 0 and data.strip():
            self.markup.stray.append(data.strip()[:40])


@cache
def read_markup(path: Path) -> Markup:
    parser = _TopLevel()
    parser.feed(path.read_text(encoding="utf-8"))
    parser.close()
    return parser.markup


def markup_files() -> list[Path]:
    return sorted((FRONTEND / "js").rglob("*.html"))


IMPORT = re.compile(r"""(?:\bfrom\s*|\bimport\s*\(?\s*)["'](\.{1,2}/[^"']+\.js)["']""")
ROUTE = re.compile(r"""\broute\(\s*["']([^"']+)["']\s*,\s*lazy\(\s*\(\)\s*=>\s*import\(\s*["']\./([^"']+)["']\s*\)"""
                   r"""(.*?)\)\s*;""", re.S)
MARKUP_OPTION = re.compile(r"markup\s*:\s*\[([^\]]*)\]")


def imports_of(module: Path) -> set[Path]:
    """The dashboard modules `module` imports (static and dynamic), transitively, itself included."""
    seen, todo = set(), [module.resolve()]
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        code = re.sub(r"^\s*(//|\*).*$", "", current.read_text(encoding="utf-8"), flags=re.M)  # not comments
        todo += [(current.parent / target).resolve() for target in IMPORT.findall(code)]
    return seen


def routes() -> list[tuple[str, Path, list[str]]]:
    """Each `route(...)` of app.js: its pattern, its page's module and the markup files it names."""
    found = []
    for pattern, module, options in ROUTE.findall((FRONTEND / "app.js").read_text(encoding="utf-8")):
        named = MARKUP_OPTION.search(options)
        files = re.findall(r"""["']([^"']+)["']""", named.group(1)) if named else []
        found.append((pattern, FRONTEND / module, files))
    return found


def test_index_html_holds_only_the_shell():
    shell = read_markup(FRONTEND / "index.html")
    assert set(shell.templates) == SHELL_TEMPLATES, (
        "index.html keeps the shell's templates only; a page's markup goes beside its module (js/views/NAME.html)")


def test_each_markup_file_sits_beside_its_module_and_holds_templates_only():
    assert len(markup_files()) >= 15, markup_files()  # the pages' files were found at all
    for path in markup_files():
        markup = read_markup(path)
        where = path.relative_to(FRONTEND)
        assert path.with_suffix(".js").exists(), f"{where} has no module beside it ({path.stem}.js)"
        assert markup.templates and not markup.stray, f"{where}: only <template>s at the top, found {markup.stray}"
        assert all(re.fullmatch(r"(page|part)-[a-z0-9-]+", t) for t in markup.templates), (where, markup.templates)


def test_template_ids_are_unique_across_the_files():
    owners: dict[str, list[str]] = {}
    for path in [FRONTEND / "index.html", *markup_files()]:
        for template in read_markup(path).templates:
            owners.setdefault(template, []).append(str(path.relative_to(FRONTEND)))
    assert {t: files for t, files in owners.items() if len(files) > 1} == {}


def test_a_module_finds_its_templates_in_the_file_beside_it():
    """`page("ride")` in ride.js is `page-ride` in ride.html; `part("ride-edit")` in ride-edit.js likewise."""
    uses = re.compile(r"""\b(page|part)\(\s*["']([\w-]+)["']\s*\)""")
    checked = 0
    for module in [FRONTEND / "app.js", *sorted((FRONTEND / "js").rglob("*.js"))]:
        beside = FRONTEND / "index.html" if module.name == "app.js" else module.with_suffix(".html")
        defined = set(read_markup(beside).templates) if beside.exists() else set()
        for kind, name in uses.findall(module.read_text(encoding="utf-8")):
            checked += 1
            assert f"{kind}-{name}" in defined, f"{module.relative_to(FRONTEND)}: {kind}-{name} is not in {beside.name}"
    assert checked >= 15


def test_each_route_names_the_markup_its_modules_need():
    table = routes()
    assert len(table) >= 15 and all(files for _, _, files in table), table
    for pattern, module, files in table:
        named = {FRONTEND / f for f in files}
        assert all(p.exists() for p in named), (pattern, files)
        need = {module.with_suffix(".html")}  # its own page(s)
        for imported in imports_of(module) - {module.resolve()}:
            beside = imported.with_suffix(".html")
            if beside.exists() and all(t.startswith("part-") for t in read_markup(beside).templates):
                need.add(beside)  # a shared part comes with the module that fills it
        assert named == need, (f"route {pattern}: markup {sorted(files)}, its modules need "
                               f"{sorted(str(p.relative_to(FRONTEND)) for p in need)}")
        defined = {t for p in named for t in read_markup(p).templates}
        asked = {f"part-{name}" for p in named for name in read_markup(p).parts_asked}
        assert asked <= defined, f"route {pattern}: data-part placeholders without their part: {asked - defined}"

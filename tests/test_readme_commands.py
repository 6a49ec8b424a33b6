"""README's table of commands and `saddlescope --help` agree: every command listed, every option named exists.

The table is what a new club reads first; a command or option added to the parser and not to the table (or
the other way round) fails here, naming it.
"""

from __future__ import annotations

import argparse
import re

from conftest import PROJECT_ROOT
from saddlescope.cli import build_parser

README = PROJECT_ROOT / "README.md"


def _readme_rows() -> dict[str, str]:
    """Command -> its row in README's "Commands" table (its usage, and usages quoted in its description)."""
    text = README.read_text(encoding="utf-8")
    section = text.split("## Commands", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        if m := re.match(r"\| `saddlescope ([a-z-]+)([^`]*)` \|", line):
            rows.setdefault(m.group(1), line)
    return rows


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_every_command_is_in_the_readme_and_every_readme_command_exists():
    rows, commands = _readme_rows(), _subparsers()
    assert sorted(set(commands) - set(rows)) == [], "commands missing from README's table"
    assert sorted(set(rows) - set(commands)) == [], "README lists commands saddlescope does not have"


def test_the_readme_names_each_option_of_each_command_and_no_other():
    rows = _readme_rows()
    for name, sub in _subparsers().items():
        options = {o for a in sub._actions for o in a.option_strings if o.startswith("--") and o != "--help"}
        named = set(re.findall(r"--[a-z][a-z-]*", rows[name]))
        assert sorted(options - named) == [], f"saddlescope {name}: options missing from README"
        assert sorted(named - options) == [], f"saddlescope {name}: README names options it does not have"

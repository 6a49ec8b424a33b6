"""Every flag sentence the pipeline can raise has a plain-language note (services/quality_notes.py).

The flags are free sentences with numbers in them, made in many places (core, io). This test reads the
source: every string or f-string appended to, assigned to or returned as a flag, warning or note is
rendered with placeholder numbers and must match an entry of the table (not the catch-all). A new flag
without a note fails here, naming the file and line.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from saddlescope.services.quality_notes import NOTES, SEVERITIES, note_for, quality_notes, quality_summary

PACKAGE = Path(__file__).resolve().parents[2] / "backend" / "saddlescope"
# where flags are made; arena/ (the synthetic arena's own checks) and the API are not the pipeline
SOURCES = ("core", "io", "services/mocap.py", "services/analysis.py")
# files whose "notes" and "problems" are not flags: a spreadsheet's notes sheet, a document's refusals
NOT_FLAGS = {"io/export.py", "io/result_schema.py"}
WORDS = ("flag", "warning", "notes", "problem", "rejected")


def _render(node: ast.AST, filler: str) -> str | None:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else filler for v in node.values)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        left, right = _render(node.left, filler), _render(node.right, filler)
        return None if left is None or right is None else left + right
    return None


def _named(node: ast.AST) -> str:
    name = node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else ""
    return name.lower()


def _strings(node: ast.AST):
    """String-like nodes inside a flag's expression (lists, tuples, conditionals, comprehensions)."""
    if isinstance(node, ast.Constant | ast.JoinedStr | ast.BinOp):
        yield node
    elif isinstance(node, ast.List | ast.Tuple):
        for elt in node.elts:
            yield from _strings(elt)
    elif isinstance(node, ast.IfExp):
        yield from _strings(node.body)
        yield from _strings(node.orelse)
    elif isinstance(node, ast.ListComp):
        yield from _strings(node.elt)


def _flag_nodes(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "append":
            if any(w in _named(node.func.value) for w in WORDS):
                yield from _strings(node.args[0])
        elif isinstance(node, ast.Assign | ast.AugAssign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if node.value is not None and any(any(w in _named(t) for w in WORDS) for t in targets):
                yield from _strings(node.value)
        elif isinstance(node, ast.FunctionDef):
            doc = (ast.get_docstring(node) or "").lower()
            if any(w in node.name.lower() or w in doc for w in ("flag", "notes")):  # returns its flag or notes
                for ret in ast.walk(node):
                    if isinstance(ret, ast.Return) and ret.value is not None:
                        yield from _strings(ret.value)


def pipeline_flags() -> list[tuple[str, str]]:
    """(file:line, the flag rendered with numbers for its placeholders) for every flag in the source."""
    found = []
    for source in SOURCES:
        path = PACKAGE / source
        for file in sorted([path] if path.is_file() else path.rglob("*.py")):
            if str(file.relative_to(PACKAGE)) in NOT_FLAGS:
                continue
            for node in _flag_nodes(ast.parse(file.read_text())):
                text = _render(node, "12")
                # short strings (dictionary keys, unit names) are not sentences a user reads
                if text and len(text) > 12 and " " in text:
                    found.append((f"{file.relative_to(PACKAGE)}:{node.lineno}", text))
    return found


def test_the_source_scan_finds_the_flags_of_every_stage():
    texts = " | ".join(text for _, text in pipeline_flags())
    for known in ("eigenvalue ratio", "stride orders", "principal point", "wild samples", "no plumb clips",
                  "cameras disagree", "no fit determined the fundamental", "states no units"):
        assert known in texts, f"the scan missed the flag about {known!r}"


@pytest.mark.parametrize(("where", "flag"), pipeline_flags(), ids=lambda v: v if ":" in v else None)
def test_every_pipeline_flag_has_a_plain_language_note(where, flag):
    note = note_for(flag)
    assert note.code != "other", f"{where}: no entry in services/quality_notes.py for the flag {flag!r}"


def test_every_note_has_a_severity_and_one_actionable_sentence():
    for note in NOTES.values():
        assert note.severity in SEVERITIES
        assert note.message.endswith(".") and note.message.count(". ") == 0, note.message
        assert len(note.message) <= 140, note.code


def test_the_issues_jargon_reads_as_advice_with_the_expert_detail_kept():
    weak = ("rotation about the markers' weakest axis (eigenvalue ratio 0.026) kept at 0% in ω and 0% in α: "
            "the rest is what skin motion predicts")
    depth = ("the rig fixes depth 9 times worse than image position: each marker's depth was fitted with a "
             "straight path across the view (stride orders [0, 0, 0]); lateral sway ...")
    notes = quality_notes([weak, depth, "markers lost from 0.40 s to 0.47 s", "no board was seen by two "
                           "cameras at once: the rig's metric accuracy is unchecked"])
    assert [n["severity"] for n in notes] == ["problem", "check", "check", "check"]  # most serious first
    by_code = {n["code"]: n for n in notes}
    assert "10 cm below" in by_code["rotation.weak_axis"]["message"]
    assert by_code["rotation.weak_axis"]["detail"] == weak
    assert "eigenvalue" not in by_code["rotation.weak_axis"]["message"]
    assert by_code["tracking.lost"]["severity"] == "check"


def test_an_unknown_flag_still_gets_a_note_and_the_summary_names_the_worst():
    assert note_for("something new happened").code == "other"
    assert quality_summary({"flags": []})[0] == "ok"
    assert quality_summary({"flags": ["markers lost from 1.00 s to 1.10 s"]})[0] == "check"
    assert quality_summary(None)[0] == "ok"
    assert quality_summary({"flags": ["the markers kept the static shot's layout only to 30 mm"]})[0] == "problem"


def test_the_guessed_depth_flags_built_from_a_variable_have_their_notes():
    """core/saddle.py builds these two from one sentence held in a variable, which the source scan above
    does not read: a partial view whose ends were left out (check) or could not be (problem)."""
    what = ("markers seen by two cameras only, one of them outside the region its calibration board covered, in "
            "51 frames from 1.14 s to 2.86 s: their depth rests on the lens model extrapolated there")
    left_out = note_for(f"{what}; the analysis used the 0.72 s from 1.66 s to 2.36 s where three cameras or the "
                        "board's region fix them")
    broken = note_for(f"{what}, and the run holds less than a stride without them: the saddle point's motion may be "
                      "broken (move the board to the edges of every camera's view)")
    assert (left_out.code, left_out.severity) == ("calibration.guessed_depth", "check")
    assert (broken.code, broken.severity) == ("calibration.guessed_depth_broken", "problem")

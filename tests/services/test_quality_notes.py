"""Findings as data (issue 34): one table of kinds, every code raised somewhere, old sentences still read.

The analysis raises :class:`~saddlescope.core.findings.Finding` values by code; the plain-language note
is the table's entry for that code (services/results/quality_notes.py). Results stored before findings were data
hold sentences only: ``legacy_flags.json`` lists sentences of every kind the analysis wrote then (the
old source's flags rendered with placeholder numbers, scanned at commit 4dc2726) with the code the old
regular expressions gave each; the legacy reader must keep giving those codes.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

from saddlescope.core.findings import FINDING_KINDS, SEVERITIES, Finding
from saddlescope.io.legacy_flags import finding_from_sentence
from saddlescope.services.results.quality_notes import NOTES, document_findings, quality_notes, quality_summary

PACKAGE = Path(__file__).resolve().parents[2] / "backend" / "saddlescope"
LEGACY = json.loads((Path(__file__).with_name("legacy_flags.json")).read_text(encoding="utf-8"))
# the readers of stored findings build them from a code held in a variable
READERS = {"io/legacy_flags.py", "io/findings_document.py"}


def _finding_calls() -> list[tuple[str, ast.Call]]:
    """(file:line, call) of every ``Finding(...)`` in the package's source."""
    calls = []
    for file in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(file.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "Finding":
                calls.append((f"{file.relative_to(PACKAGE)}:{node.lineno}", node))
    return calls


def _literals(node: ast.AST | None) -> list[str]:
    """The codes a code argument names: a string, or both branches of a conditional."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node.value]
    if isinstance(node, ast.IfExp):
        return _literals(node.body) + _literals(node.orelse)
    return []


def _codes_named(call: ast.Call) -> list[str]:
    return _literals(call.args[0] if call.args else next((k.value for k in call.keywords if k.arg == "code"), None))


def test_every_kind_has_a_severity_a_stage_and_one_actionable_sentence():
    for code, kind in FINDING_KINDS.items():
        finding = Finding(code, f"an expert's sentence about {code}", {"share_pct": 12.0})
        assert (finding.severity, finding.stage, str(finding)) == (kind.severity, kind.stage, finding.detail)
        assert finding.severity in SEVERITIES and finding.stage
        assert kind.advice.endswith(".") and kind.advice.count(". ") == 0, kind.advice
        assert len(kind.advice) <= 140, code
        assert NOTES[code].message == kind.advice and NOTES[code].severity == kind.severity


def test_an_unknown_code_or_an_empty_detail_is_a_programming_error():
    with pytest.raises(ValueError, match="unknown finding code 'tracking.lots'"):
        Finding("tracking.lots", "markers lost")
    with pytest.raises(ValueError, match="needs its detail"):
        Finding("tracking.lost", " ")
    nan = Finding("tracking.lost", "markers lost from 1.00 s to 1.20 s",
                  {"gap_start_s": 1.0, "gap_end_s": float("nan")})
    assert dict(nan.values) == {"gap_start_s": 1.0}  # a number not determined is left out, not stored as NaN


def test_every_finding_in_the_source_names_a_code_of_the_table_and_every_code_is_raised():
    raised: dict[str, list[str]] = {}
    for where, call in _finding_calls():
        codes = _codes_named(call)
        if not codes:
            assert any(where.startswith(reader + ":") for reader in READERS), f"{where}: Finding without a literal code"
        for code in codes:
            assert code in FINDING_KINDS, f"{where}: Finding({code!r}) is not in saddlescope.core.findings' table"
            raised.setdefault(code, []).append(where)
    assert set(raised) >= {"sync.motion", "sync.motion_uncertain", "calibration.units_guessed", "mocap.extra_cells"}
    assert set(FINDING_KINDS) == set(raised), set(FINDING_KINDS) ^ set(raised)
    # "other" only where a stored document is read: a sentence no old pattern knows, a code from a later version
    assert {w.split(":")[0] for w in raised["other"]} <= READERS
    assert finding_from_sentence("something new happened").code == "other"


@pytest.mark.parametrize(("sentence", "code"), LEGACY, ids=[code for _, code in LEGACY])
def test_an_old_sentence_gets_the_code_it_was_shown_with(sentence, code):
    assert finding_from_sentence(sentence).code == code


def test_an_old_document_with_sentences_only_gives_the_notes_it_gave_before():
    old = {"quality": {"flags": [s for s, _ in LEGACY]}, "calibration": {"flags": [LEGACY[0][0]]}}
    notes = quality_notes(document_findings(old))
    assert sorted((n["code"], n["detail"]) for n in notes) == sorted((c, s) for s, c in LEGACY)
    rank = {s: i for i, s in enumerate(reversed(SEVERITIES))}
    assert [rank[n["severity"]] for n in notes] == sorted(rank[n["severity"]] for n in notes)  # most serious first
    assert all(n["message"] == NOTES[n["code"]].message for n in notes)


def test_a_new_document_is_read_by_its_codes_not_its_sentences():
    """A stored finding's code decides its note even where its sentence would match another pattern."""
    doc = {"quality": {"flags": ["markers lost from 0.40 s to 0.47 s"],
                       "findings": [{"code": "tracking.lost_all_along", "severity": "problem", "stage": "kinematics",
                                     "detail": "markers lost from 0.40 s to 0.47 s", "values": {"gap_start_s": 0.4}}]}}
    [note] = quality_notes(document_findings(doc))
    assert (note["code"], note["severity"]) == ("tracking.lost_all_along", "problem")
    assert quality_summary(document_findings(doc))[0] == "problem"


def test_the_issues_jargon_reads_as_advice_with_the_expert_detail_kept():
    weak = Finding("rotation.weak_axis", "rotation about the markers' weakest axis (eigenvalue ratio 0.026) kept at "
                   "0% in ω and 0% in α: the rest is what skin motion predicts", {"eigenvalue_ratio": 0.026})
    notes = quality_notes([weak, Finding("rig.weak_depth", "the rig fixes depth 9 times worse"),
                           Finding("tracking.lost", "markers lost from 0.40 s to 0.47 s"),
                           Finding("calibration.no_shared_view", "no board was seen by two cameras at once")])
    assert [n["severity"] for n in notes] == ["problem", "check", "check", "check"]  # most serious first
    by_code = {n["code"]: n for n in notes}
    assert "10 cm below" in by_code["rotation.weak_axis"]["message"]
    assert by_code["rotation.weak_axis"]["detail"] == weak.detail
    assert "eigenvalue" not in by_code["rotation.weak_axis"]["message"]


def test_the_summary_names_the_worst():
    assert quality_summary([])[0] == "ok"
    assert quality_summary([Finding("tracking.gaps_bridged", "3 frames with a short marker gap bridged")])[0] == "ok"
    assert quality_summary([Finding("tracking.lost", "markers lost from 1.00 s to 1.10 s")])[0] == "check"
    assert quality_summary([Finding("tracking.lost", "markers lost"),
                            Finding("markers.rigidity", "the markers kept the static shot's layout only to 30 mm")]
                           )[0] == "problem"

"""Plain-language notes on a result's findings: one source for the API, the ride page and the report.

The analysis raises typed findings (:mod:`saddlescope.core.findings`): a code, the expert's sentence
("eigenvalue ratio 0.026 kept at 0 % in ω") and the numbers behind it. A note is the finding's kind
looked up by code in ONE table: a severity a club can read at a glance (``ok``: nothing to do;
``check``: worth a look or a change next time; ``problem``: the numbers concerned are not to be
trusted) and ONE sentence saying what to do. The finding's sentence stays as the expert detail.

Results stored before findings were data hold the sentences only; the document reader
(:func:`saddlescope.io.findings_document.findings_of`) turns those into findings by the old patterns.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from saddlescope.core.findings import FINDING_KINDS, SEVERITIES, Finding, Severity
from saddlescope.io.findings_document import findings_of

__all__ = ["NOTES", "SEVERITIES", "QualityNote", "document_findings", "quality_notes", "quality_summary"]


@dataclass(frozen=True)
class QualityNote:
    """One kind of finding: its code, how serious it is and what a club should do about it."""

    code: str
    severity: Severity
    message: str


NOTES: dict[str, QualityNote] = {code: QualityNote(code, kind.severity, kind.advice)
                                 for code, kind in FINDING_KINDS.items()}


def document_findings(doc: Mapping[str, Any]) -> list[Finding]:
    """A result document's findings with its calibration's, each once (the rig's are usually among them)."""
    found = [*findings_of(doc.get("quality")), *findings_of(doc.get("calibration"))]
    return list(dict.fromkeys(found))


def quality_notes(findings: Iterable[Finding]) -> list[dict[str, str]]:
    """``[{code, severity, message, detail}]`` for ``findings``, most serious first.

    ``detail`` is the finding's sentence with its numbers; findings of one code keep their own detail
    each, in the pipeline's order.
    """
    rank: dict[str, int] = {s: i for i, s in enumerate(reversed(SEVERITIES))}
    notes = [{"code": n.code, "severity": n.severity, "message": n.message, "detail": f.detail}
             for f in findings for n in (NOTES[f.code],)]
    return sorted(notes, key=lambda n: rank[n["severity"]])


def quality_summary(findings: Iterable[Finding]) -> tuple[Severity, str]:
    """The overall severity of ``findings`` and one line saying it.

    The points are counted as the ride page and the report list them: one per piece of advice (findings
    that ask for the same thing are one line there), so "6 points to check" sits over six lines.
    """
    lines = {NOTES[f.code].message: f.severity for f in findings}
    counts = {s: list(lines.values()).count(s) for s in SEVERITIES}
    if counts["problem"]:
        found = _counted(counts["problem"], "problem", "problems")
        return "problem", f"{found} found: the numbers they concern are not to be trusted."
    if counts["check"]:
        return "check", f"{_counted(counts['check'], 'point', 'points')} to check; the main results stand."
    return "ok", "The recording and the analysis look good."


def _counted(n: int, one: str, many: str) -> str:
    return f"{n} {one if n == 1 else many}"

"""The quality summary counts the lines the ride page and the report show (issue #37: "7 point(s) to check"
over 6 notes): findings that ask for the same thing are one line, and the count reads in plain English."""

from __future__ import annotations

from saddlescope.core.findings import FINDING_KINDS, Finding
from saddlescope.services.results.quality_notes import quality_notes, quality_summary


def _checks(n: int) -> list[str]:
    return [code for code, kind in FINDING_KINDS.items() if kind.severity == "check"][:n]


def test_two_findings_of_one_kind_are_one_point_as_on_the_page():
    one, other = _checks(2)
    findings = [Finding(one, "first detail"), Finding(one, "second detail"), Finding(other, "detail")]
    lines = {note["message"] for note in quality_notes(findings)}  # the page's lines (grouped by message)
    assert quality_summary(findings) == ("check", f"{len(lines)} points to check; the main results stand.")
    assert len(lines) == 2


def test_one_point_is_singular():
    (one,) = _checks(1)
    assert quality_summary([Finding(one, "detail")])[1] == "1 point to check; the main results stand."

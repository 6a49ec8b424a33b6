"""Findings (:mod:`saddlescope.core.findings`) as stored in result and calibration documents, and read back.

A document section (``quality`` of a result, a ``calibration``) stores its findings as data,
``findings: [{code, severity, stage, detail, values}]``, beside ``flags`` (the same details as sentences,
for readers of the first format). :func:`findings_of` reads them back; a section written before findings
were data has ``flags`` only, and only then are the sentences read, by :mod:`saddlescope.io.legacy_flags`.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable, Mapping
from typing import Any

from saddlescope.core.findings import FINDING_KINDS, Finding
from saddlescope.io.legacy_flags import findings_from_sentences

__all__ = ["finding_to_dict", "findings_of", "findings_to_list"]


def finding_to_dict(finding: Finding) -> dict[str, Any]:
    """``{code, severity, stage, detail, values}`` of one finding (severity and stage from its kind)."""
    return {"code": finding.code, "severity": finding.severity, "stage": finding.stage, "detail": finding.detail,
            "values": dict(finding.values)}


def findings_to_list(findings: Iterable[Finding]) -> list[dict[str, Any]]:
    """The stored form of ``findings``, in their order."""
    return [finding_to_dict(f) for f in findings]


def _stored_finding(entry: Mapping[str, Any]) -> Finding | None:
    detail = str(entry.get("detail") or "").strip()
    if not detail:
        return None
    code = str(entry.get("code") or "")
    stored = entry.get("values")
    values: Mapping[str, Any] = stored if isinstance(stored, Mapping) else {}
    numbers_only = {str(k): float(v) for k, v in values.items()
                    if isinstance(v, numbers.Real) and not isinstance(v, bool)}
    # a code this version does not know (a document from a later one) keeps its detail under "other"
    return Finding(code if code in FINDING_KINDS else "other", detail, numbers_only)


def findings_of(section: Mapping[str, Any] | None) -> list[Finding]:
    """The findings a document section stores; from its ``flags`` sentences only when it has no ``findings``."""
    section = section or {}
    stored = section.get("findings")
    if isinstance(stored, list):
        return [f for entry in stored if isinstance(entry, Mapping) and (f := _stored_finding(entry)) is not None]
    return findings_from_sentences(section.get("flags") or [])

"""A ride of several passes in front of the cameras as the ride page and the report show it (issue 38).

The result document's ``passes`` (``docs/result-document.md``) and ``quality.pass_pooling`` become one
line a club reads ("3 passes: 2, 2 and 3 strides") and the pass-to-pass spread of the W_b r.m.s.
"""

from __future__ import annotations

from typing import Any

__all__ = ["passes_view"]


def _strides_words(strides: list[int]) -> str:
    """"2, 2 and 3 strides"."""
    s = [str(n) for n in strides]
    listed = s[0] if len(s) == 1 else f"{', '.join(s[:-1])} and {s[-1]}"
    return f"{listed} stride{'' if s == ['1'] else 's'}"


def passes_view(doc: dict[str, Any]) -> dict[str, Any] | None:
    """The passes of result document ``doc``, or None for a ride of one pass.

    Returns ``count`` (passes used), ``strides`` (per used pass), ``line`` ("3 passes: 2, 2 and 3 strides",
    with the passes left out), ``wb_rms_spread_percent`` (the passes' standard deviation over their mean, %,
    or None) and ``passes`` (each used or left-out pass: start and end s, strides, speed, W_b r.m.s.).
    """
    passes = doc.get("passes")
    if not isinstance(passes, list) or not passes:
        return None
    used = [p for p in passes if isinstance(p, dict) and p.get("used", True)]
    strides = [int(p.get("strides") or 0) for p in used]
    line = f"{len(used)} pass{'' if len(used) == 1 else 'es'}: {_strides_words(strides)}" if used else "no pass used"
    left_out = len(passes) - len(used)
    if left_out:
        line += f" ({left_out} more left out: too short)"
    spread = ((doc.get("quality") or {}).get("pass_pooling") or {}).get("spread_fraction") or {}
    wb_spread = spread.get("acc_y_wb_rms")
    rows = [{"start_s": p.get("start_s"), "end_s": p.get("end_s"), "strides": p.get("strides"),
             "speed_m_s": p.get("speed_m_s"), "used": bool(p.get("used", True)), "reason": p.get("reason"),
             "acc_y_wb_rms": (p.get("indicators") or {}).get("acc_y_wb_rms")} for p in passes if isinstance(p, dict)]
    return {"count": len(used), "strides": strides, "line": line,
            "wb_rms_spread_percent": None if wb_spread is None else 100.0 * float(wb_spread), "passes": rows}

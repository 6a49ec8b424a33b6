"""`saddlescope bench`'s field-nuisance coverage table (issue 38).

The rides of :data:`~saddlescope.bench.coverage.FIELD_RIDES` (seeds no test uses): the rider's boot over the
rear marker on or off, a rolling shutter's readout of 0, 15 or 33 ms, x264 CRF 18 or 28, across the four gaits
and two rigs (a fraction of the full design in which every level of every factor meets every gait and both
rigs). Per indicator: the share of intervals holding the truth (goal 90-98 %) and the rides whose value is
further from the truth than twice its interval's half-width without the ride being marked too uncertain (goal
none); the worst W_b r.m.s. error among the rides not marked (goal within 10 %); the share marked (goal at most
1 in 10 outside the walk); the refusals, each with its reason; and per level of each nuisance the median
error of each indicator.

``python -m saddlescope.bench.coverage --rides field --out DIR`` runs the rides alone (a stopped run resumes);
:func:`field_table` tabulates them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["FIELD_FACTORS", "FIELD_KEYS", "MISS_KEYS", "field_table", "misses_unmarked"]

# the indicators the table reports on
FIELD_KEYS: tuple[str, ...] = ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vdv_y_wk", "amplitude_y_m",
                               "crest_factor_y", "vel_x_avg_kmh", "stride_frequency_hz")
# the indicators whose miss by more than twice the interval's half-width must mark the ride (issue 38 item 6)
MISS_KEYS: tuple[str, ...] = ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "amplitude_y_m")
# the ride set-up's fields the errors are broken down by (CoverageRide's names)
FIELD_FACTORS: tuple[str, ...] = ("boot_share", "readout_s", "crf", "passes", "gait", "rig")


_NOT_RUN = "not run"  # coverage_rows' error for a ride folder without a result nor an error (yet)


def _error_pct(row: dict, key: str) -> float | None:
    """The value's error against the truth (% of the truth), None where either is missing."""
    value, true = row["values"].get(key), row["truth"].get(key)
    if value is None or not true:
        return None
    return 100.0 * (float(value) / float(true) - 1)


def misses_unmarked(row: dict, keys: Sequence[str] = MISS_KEYS) -> list[dict]:
    """The indicators of one analysed ride further from the truth than twice their interval's half-width.

    Only on a ride not marked too uncertain (a marked ride has said its numbers are not to be used). Each miss
    gives the indicator, its error and its interval's half-width (% of the value) and how many half-widths off.
    """
    if row.get("uncertain"):
        return []
    out = []
    for key in keys:
        if key not in row["intervals"] or key not in row["truth"] or key not in row["values"]:
            continue
        lo, hi = row["intervals"][key]
        value, true = float(row["values"][key]), float(row["truth"][key])
        half = 0.5 * (hi - lo)
        if abs(value - true) > 2 * half:
            out.append({"indicator": key, "error_pct": round(100 * (value / true - 1), 2) if true else None,
                        "half_width_pct": round(100 * half / abs(value), 2) if value else None,
                        "half_widths_off": round(abs(value - true) / half, 1) if half > 0 else None})
    return out


def _coverage_per_key(ok: Sequence[dict], keys: Sequence[str]) -> dict:
    """Per indicator: the share of intervals holding the truth, the median and worst error, the unmarked misses."""
    table = {}
    for key in keys:
        rows = [r for r in ok if key in r["intervals"] and key in r["truth"] and key in r["values"]]
        if not rows:
            continue
        hits = [r["intervals"][key][0] <= r["truth"][key] <= r["intervals"][key][1] for r in rows]
        errors = [abs(e) for r in rows if (e := _error_pct(r, key)) is not None]
        table[key] = {"rides": len(rows), "coverage_pct": round(100.0 * float(np.mean(hits)), 1),
                      "median_abs_error_pct": round(float(np.median(errors)), 2) if errors else None,
                      "max_abs_error_pct": round(float(max(errors)), 2) if errors else None,
                      "misses_beyond_twice_half_width_unmarked": sum(
                          bool(misses_unmarked(r, (key,))) for r in rows)}
    return table


def _level(value) -> str:
    return f"{value:g}" if isinstance(value, int | float) else str(value)


def _per_level(ok: Sequence[dict], keys: Sequence[str]) -> dict:
    """Per factor and level: how many rides, how many marked, and each indicator's median absolute error (%)."""
    out: dict = {}
    for factor in FIELD_FACTORS:
        levels: dict[str, list[dict]] = {}
        for r in ok:
            if factor in (r.get("setup") or {}):
                levels.setdefault(_level(r["setup"][factor]), []).append(r)
        out[factor] = {}
        for level, rows in sorted(levels.items()):
            medians = {}
            for key in keys:
                errors = [abs(e) for r in rows if (e := _error_pct(r, key)) is not None]
                if errors:
                    medians[key] = round(float(np.median(errors)), 2)
            out[factor][level] = {"rides": len(rows), "marked_too_uncertain": sum(bool(r["uncertain"]) for r in rows),
                                  "median_abs_error_pct": medians}
    return out


def field_table(rows: Sequence[dict], keys: Sequence[str] = FIELD_KEYS) -> dict:
    """The field-nuisance table from :func:`~saddlescope.bench.coverage.coverage_rows` (each with its ``setup``).

    Parameters
    ----------
    rows : sequence of dict
        Per ride: ``values``, ``truth``, ``intervals``, ``uncertain`` (the too-uncertain reason or None) and
        ``setup`` (the CoverageRide's fields); a refused ride holds ``error`` instead.
    keys : sequence of str
        The indicators tabulated.

    Returns
    -------
    dict
        ``indicators`` (per key: coverage, median and worst error, misses beyond twice the half-width
        unmarked), ``misses_beyond_twice_half_width_unmarked`` (count and each ride's), the worst W_b r.m.s.
        error among the rides not marked, the rides marked (share overall and outside the walk, each with
        its reason), the refusals with their reasons (``not_run``: the rides without a result yet), and
        ``per_level`` (:func:`_per_level`).
    """
    ok = [r for r in rows if "error" not in r]
    kept = [abs(e) for r in ok if not r["uncertain"] and (e := _error_pct(r, "acc_y_wb_rms")) is not None]
    not_walk = [r for r in ok if (r.get("setup") or {}).get("gait") != "walk"]
    misses = [{"ride": r["ride"], "misses": m} for r in ok if (m := misses_unmarked(r))]
    return {
        "rides": len(rows), "analysed": len(ok),
        "refused": [{"ride": r["ride"], "reason": r["error"]} for r in rows if r.get("error", _NOT_RUN) != _NOT_RUN],
        "not_run": [r["ride"] for r in rows if r.get("error") == _NOT_RUN],  # a run stopped early, or under way
        "indicators": _coverage_per_key(ok, keys),
        "misses_beyond_twice_half_width_unmarked": sum(len(m["misses"]) for m in misses),
        "misses_unmarked": misses,
        "acc_y_wb_rms_max_abs_error_pct_not_marked": round(float(max(kept)), 2) if kept else None,
        "marked_too_uncertain": [{"ride": r["ride"], "reason": r["uncertain"]} for r in ok if r["uncertain"]],
        "marked_too_uncertain_pct": round(100.0 * float(np.mean([bool(r["uncertain"]) for r in ok])), 1)
        if ok else None,
        "marked_too_uncertain_pct_outside_walk": round(100.0 * float(np.mean(
            [bool(r["uncertain"]) for r in not_walk])), 1) if not_walk else None,
        "per_level": _per_level(ok, keys),
    }

"""The one-page ride report for a vet or a trainer: HTML that prints to one A4 sheet, and its PDF.

Horse, rider, date and gait; the main indicators with units against the horse's own normal band
(`services.horses.normal_band`); one chart drawn here as inline SVG (the W_b-weighted vertical acceleration
over one stride, so it prints sharp without JavaScript); the quality in plain words
(`services.results.quality_notes`); the analysis version. The PDF is the same HTML laid out by WeasyPrint.
"""

from __future__ import annotations

import datetime as dt
import html
import math
from pathlib import Path
from string import Template
from typing import Any

import numpy as np
from sqlalchemy.orm import Session

from saddlescope.core.vibration import INDICATORS, PASSIVE_SEATED_CAVEAT
from saddlescope.db.repositories import RideRepository
from saddlescope.io.findings_document import findings_of
from saddlescope.services.horses.normal_band import MIN_RIDES_FOR_BAND, horse_history, normal_bands_before
from saddlescope.services.results.documents import analysed_result, result_document
from saddlescope.services.results.passes_view import passes_view
from saddlescope.services.results.quality_notes import quality_notes, quality_summary
from saddlescope.services.results.series import strides_analysed, vertical_harmonics_of, weighted_series
from saddlescope.storage import Storage

__all__ = [
    "GAIT_WORDS", "MAX_DIGITS", "REPORT_INDICATORS", "distance_text", "duration_text", "member_links",
    "range_text", "ride_report_html", "ride_report_pdf", "stride_chart_svg", "value_text",
]

TEMPLATE = Template((Path(__file__).parents[1] / "templates" / "ride_report.html").read_text(encoding="utf-8"))
# The indicators a vet or trainer reads first (the thesis's comfort indicators and the W_k twins).
REPORT_INDICATORS = (
    ("acc_y_wb_rms", "Vertical acceleration, W_b r.m.s."),
    ("acc_y_wk_rms", "Vertical acceleration, W_k r.m.s."),
    ("vdv_y_wb", "Vibration dose value, W_b"),
    ("acc_y_max", "Peak vertical acceleration (unweighted)"),
    ("crest_factor_y", "Crest factor (W_b peak / r.m.s.)"),
    ("t_a8_limit_wb_h", "Riding time to the A(8) limit value (W_b)"),
    ("t_vdv_limit_wb_h", "Riding time to the VDV limit value (W_b)"),
    ("vel_x_avg_kmh", "Average speed"),
    ("amplitude_y_m", "Vertical movement of the saddle (peak to peak)"),
    ("stride_frequency_hz", "Stride frequency"),
)
_UNITS = {"m/s^2": "m/s²", "m/s^1.75": "m/s¹·⁷⁵"}
# No number on the report has more significant digits than this (the dashboard's MAX_DIGITS, issue 37).
MAX_DIGITS = 4
GAIT_WORDS = {"walk": "walk", "sitting_trot": "sitting trot", "rising_trot": "rising trot", "canter": "canter"}


def duration_text(hours: float | None) -> str:
    """A time in hours as a rider says it: "2 h 05 min", "12 min", "under a minute" ("–" when unknown).

    Seconds are not given: the exposure times are estimates, so "55 s" would claim a precision they lack.
    The dashboard's `durationText` (frontend/js/format.js) says the same words.
    """
    if hours is None or not isinstance(hours, int | float) or math.isnan(hours) or hours < 0:
        return "–"
    if math.isinf(hours):
        return "no limit"
    minutes = round(hours * 60)
    if hours * 60 < 1:
        return "under a minute"
    if minutes < 60:
        return f"{minutes} min"
    if hours >= 100:
        return f"{hours:,.0f} h"
    return f"{minutes // 60} h {minutes % 60:02d} min"


def distance_text(km: float | None) -> str:
    """A riding distance as a rider says it: "about 4 m", "about 420 m", "about 1.2 km" ("–" when unknown).

    Two significant digits: the distances are estimates, so "0.00416 km" would claim a precision they lack.
    The dashboard's `distanceText` (frontend/js/format.js) says the same words.
    """
    if km is None or not isinstance(km, int | float) or math.isnan(km) or km < 0:
        return "–"
    if math.isinf(km):
        return "no limit"
    metres = km * 1000
    if metres < 1:
        return "under a metre"
    if metres < 10:
        return f"about {round(metres)} m"
    if metres < 1000:
        return f"about {_two_digits(metres)} m"
    return f"about {_two_digits(km)} km"


def _two_digits(value: float) -> str:
    """`value` (>= 1) to two significant digits without trailing zeros: 4.16 -> "4.2", 416 -> "420"."""
    rounded = float(f"{value:.2g}")
    return f"{rounded:,.0f}" if rounded >= 10 else f"{rounded:g}"


def _number(value: Any, digits: int = 3) -> str:
    """`digits` significant digits, as the dashboard's `fmt`."""
    if not isinstance(value, int | float) or not math.isfinite(value):
        return "–"
    if value == 0:
        return "0"
    magnitude = math.floor(math.log10(abs(value)))
    if magnitude >= digits - 1:  # 12345.6 -> "12300": no more digits than asked for
        return f"{float(f'{value:.{digits}g}'):.0f}"
    return f"{value:.{digits - 1 - magnitude}f}"


def range_text(low: float | None, high: float | None, digits: int = 3) -> str:
    """A 95 % interval "low–high" (no unit) that never reads as one value, as the dashboard's `rangeText`.

    Ends that show alike at `digits` significant digits get one more digit (up to `MAX_DIGITS`); ends
    alike even then read "± under 0.01" (the interval is narrower than the last digit shown). An open
    end (None) is "–∞" or "∞".
    """
    if low is None or high is None:
        return f"{'−∞' if low is None else _number(low, digits)}–{'∞' if high is None else _number(high, digits)}"
    widest = max(digits, MAX_DIGITS)
    for d in range(digits, widest + 1):
        a, b = _number(low, d), _number(high, d)
        if a != b:
            return f"{a}–{b}"
    size = max(abs(low), abs(high))
    if not size > 0:
        return "± 0"
    return f"± under {_number(10.0 ** (math.floor(math.log10(size)) - (widest - 1)), 1)}"


def _scale_and_unit(key: str) -> tuple[float, str]:
    """What an indicator's value is multiplied by for the report, and the unit it then reads in."""
    if key == "amplitude_y_m":
        return 100.0, "cm"
    return 1.0, _UNITS.get(INDICATORS[key].unit, INDICATORS[key].unit) if key in INDICATORS else ""


def value_text(key: str, value: Any) -> str:
    """An indicator's value in the report's words and units ("1.23 m/s²", "12 min", "4.2 cm")."""
    if key.endswith("_h"):
        return duration_text(value)
    scale, unit = _scale_and_unit(key)
    return f"{_number(value * scale if isinstance(value, int | float) else value)} {unit}".strip()


def _label_html(label: str) -> str:
    return html.escape(label).replace("W_b", "W<sub>b</sub>").replace("W_k", "W<sub>k</sub>")


def _band_cell(key: str, value: Any, band: dict[str, Any] | None) -> str:
    if band is None:
        return '<span class="hint">not enough earlier rides</span>'
    span = f"{value_text(key, band['low'])} – {value_text(key, band['high'])} (n = {band['n']})"
    if not isinstance(value, int | float):
        return html.escape(span)
    where = "within" if band["low"] <= value <= band["high"] else "above" if value > band["high"] else "below"
    css = "band-in" if where == "within" else "band-out"
    return f'{html.escape(span)} <span class="{css}">{where}</span>'


def stride_chart_svg(doc: dict[str, Any], *, width: int = 680, height: int = 210) -> tuple[str, str]:
    """Inline SVG of S's vertical acceleration over one stride, unweighted and W_b-weighted; and a caption."""
    harm = vertical_harmonics_of(doc)
    if harm is None or not harm["f0_hz"] > 0:
        return "<p class=\"hint\">This result has no vertical track to draw.</p>", ""
    period = 1.0 / harm["f0_hz"]
    t = np.linspace(0.0, period, 241)
    amps, phases = np.asarray(harm["amplitudes_m_s2"]), np.asarray(harm["phases_rad"])
    k = np.arange(1, len(amps) + 1)[:, None]
    raw = (amps[:, None] * np.cos(2 * np.pi * k * harm["f0_hz"] * t + phases[:, None])).sum(axis=0)
    weighted = np.asarray(weighted_series(doc, t.tolist())[0]["acc_y_wb_m_s2"], dtype=float)
    top = float(max(np.abs(raw).max(), np.abs(weighted).max(), 0.1)) * 1.1
    left, right, upper, lower = 48, 12, 12, 30
    sx = (width - left - right) / period
    sy = (height - upper - lower) / (2 * top)

    def path(y: np.ndarray) -> str:
        return " ".join(f"{'M' if i == 0 else 'L'}{left + ti * sx:.1f},{upper + (top - yi) * sy:.1f}"
                        for i, (ti, yi) in enumerate(zip(t, y, strict=True)))

    step = 10 ** math.floor(math.log10(top))
    step = step * 2 if top / step > 4 else step
    grid = []
    for v in np.arange(-math.floor(top / step) * step, top, step):
        y = upper + (top - v) * sy
        grid.append(f'<line x1="{left}" x2="{width - right}" y1="{y:.1f}" y2="{y:.1f}" stroke="#e6e9ee"/>'
                    f'<text x="{left - 4}" y="{y + 3:.1f}" text-anchor="end">{v:g}</text>')
    for frac in (0, 0.25, 0.5, 0.75, 1.0):
        x = left + frac * period * sx
        grid.append(f'<text x="{x:.1f}" y="{height - lower + 13}" text-anchor="middle">{frac * period:.2f}</text>')
    svg = (
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width} {height}" role="img" '
        f'aria-label="Vertical acceleration at the saddle over one stride" font-size="10" '
        f'font-family="DejaVu Sans, Arial, sans-serif" fill="#4a5563">'
        + "".join(grid)
        + f'<line x1="{left}" x2="{width - right}" y1="{upper + top * sy:.1f}" y2="{upper + top * sy:.1f}" '
        f'stroke="#9aa3ae"/>'
        f'<path d="{path(raw)}" fill="none" stroke="#9aa3ae" stroke-width="1.4" stroke-dasharray="4 3"/>'
        f'<path d="{path(weighted)}" fill="none" stroke="#1f5fa8" stroke-width="2.2"/>'
        f'<text x="{(left + width - right) / 2}" y="{height - 3}" text-anchor="middle">time in the stride (s)</text>'
        f'<text x="11" y="{upper + (height - upper - lower) / 2}" text-anchor="middle" '
        f'transform="rotate(-90 11 {upper + (height - upper - lower) / 2})">m/s²</text>'
        f'<text x="{width - right}" y="{upper + 8}" text-anchor="end" fill="#1f5fa8">— Wb-weighted</text>'
        f'<text x="{width - right}" y="{upper + 20}" text-anchor="end">- - unweighted</text>'
        "</svg>")
    caption = (f"One stride of {period:.2f} s ({harm['f0_hz']:.2f} strides per second), from the ride's "
               f"{len(amps)} harmonics; weighted with BS 6841 Wb as the comfort indicators are.")
    return svg, caption


def _indicator_rows(session: Session, ride, doc: dict[str, Any], club_id: int) -> tuple[str, int]:
    """The indicator table's rows, and how many analysed rides of the horse in this gait came before."""
    history = horse_history(session, club_id=club_id, horse_id=ride.horse_id, gait=ride.gait)
    keys = [key for key, _ in REPORT_INDICATORS]
    bands = normal_bands_before(history, ride.id, keys)
    earlier = next((i for i, row in enumerate(history) if row["ride_id"] == ride.id), len(history))
    indicators = doc.get("indicators") or {}
    intervals = doc.get("indicators_interval_95") or {}
    rows = []
    for key, label in REPORT_INDICATORS:
        value = indicators.get(key)
        ci = _interval_html(key, intervals.get(key))
        rows.append(f'      <tr data-indicator="{key}"><td>{_label_html(label)}</td>'
                    f'<td class="num">{html.escape(value_text(key, value))}{ci}</td>'
                    f'<td class="band">{_band_cell(key, value, bands.get(key))}</td></tr>')
    return "\n".join(rows), earlier


def _interval_html(key: str, pair: Any) -> str:
    """The indicator's 95 % interval under its value ("95 %: 1.10–1.41 m/s²"), or nothing without one.

    Numbers as the dashboard shows them (`range_text`: never "18.0–18.0"); times in words, left out
    when both ends read alike ("under a minute").
    """
    if not isinstance(pair, list | tuple) or len(pair) != 2:
        return ""
    if key.endswith("_h"):
        lo, hi = ("–∞" if pair[0] is None else value_text(key, pair[0]), "∞" if pair[1] is None else
                  value_text(key, pair[1]))
        if lo == hi:  # an interval that reads as one value says nothing the value does not
            return ""
        text = f"{lo} – {hi}"
    else:
        scale, unit = _scale_and_unit(key)
        ends = [v * scale if isinstance(v, int | float) else None for v in pair]
        text = f"{range_text(ends[0], ends[1])} {unit}".strip()
    return f'<span class="ci" data-ci="{key}">95 %: {html.escape(text)}</span>'


def _decision_html(doc: dict[str, Any]) -> str:
    """A ride too uncertain for a decision says so above its numbers (docs/accuracy.md)."""
    decision = (doc.get("quality") or {}).get("decision") or {}
    if not decision.get("too_uncertain"):
        return ""
    return (f'  <p class="decision" data-decision="too-uncertain"><strong>Too uncertain for a decision:</strong> '
            f"{html.escape(str(decision.get('reason')))}. Do not compare or rank this ride; leaderboards leave it "
            "out.</p>")


def _quality_rows(doc: dict[str, Any]) -> tuple[str, str]:
    findings = list(dict.fromkeys(findings_of(doc.get("quality"))))
    notes = quality_notes(findings)
    _, summary = quality_summary(findings)
    if not notes:
        return '    <li><span class="sev sev-ok">OK</span>Nothing to report.</li>', summary
    # one line per piece of advice keeps the page to one sheet however many flags a ride has
    seen: dict[str, dict[str, Any]] = {}
    for note in notes:
        seen.setdefault(note["message"], {**note, "count": 0})["count"] += 1
    # the most serious first; five lines leave room for the intervals and the verdict on the one sheet
    rank = {"problem": 0, "check": 1, "ok": 2}
    shown = sorted(seen.values(), key=lambda n: rank.get(n["severity"], 1))[:5]
    rows = []
    for n in shown:
        times = f" ({n['count']} times)" if n["count"] > 1 else ""
        badge = f'<span class="sev sev-{n["severity"]}">{n["severity"].upper()}</span>'
        rows.append(f'    <li data-note="{n["code"]}">{badge}{html.escape(n["message"])}{times}</li>')
    if len(seen) > len(shown):
        more = len(seen) - len(shown)
        rows.append(f'    <li class="hint">{more} more note{"s" if more != 1 else ""}: the club sees every note on '
                    "the ride page.</li>")
    return "\n".join(rows), summary


def _strides_text(doc: dict[str, Any], strides: int | None) -> str:
    """The "Analysed" cell: the window's whole strides, or a ride of several passes' strides per pass and spread."""
    passes = passes_view(doc)
    if passes is not None:
        spread = passes["wb_rms_spread_percent"]
        return html.escape(passes["line"]) + (f" (W<sub>b</sub> spread ±{spread:.1f} %)" if spread is not None else "")
    return f"{strides} whole stride{'s' if strides != 1 else ''}" if strides else "–"


def member_links(ride_id: int) -> str:
    """The report's links above the sheet for a signed-in member: back to the ride page, the PDF."""
    return (f'<a href="/#/rides/{ride_id}">&larr; Back to the ride</a> &middot; '
            f'<a href="/api/rides/{ride_id}/report.pdf">Download as PDF</a>')


def ride_report_html(session: Session, storage: Storage, ride_id: int, *, club_id: int,
                     screen_links: str | None = None) -> str:
    """The report of an analysed ride of the club as one HTML page (404 until it is analysed).

    `screen_links`: the links shown above the sheet on screen (HTML; default `member_links`; a shared
    report links only to what its share link opens).
    """
    ride = RideRepository(session, club_id=club_id).get(ride_id)
    result = analysed_result(session, storage, ride_id, club_id=club_id)
    doc = result_document(session, storage, ride_id, club_id=club_id)
    horse = ride.horse
    details = ", ".join(str(p) for p in (horse.breed, f"born {horse.birth_year}" if horse.birth_year else None) if p)
    gait = GAIT_WORDS.get(ride.gait, ride.gait)
    strides = strides_analysed(doc)
    period = doc.get("period_s")
    chart, caption = stride_chart_svg(doc, width=340, height=150)  # half the sheet: beside the quality notes
    quality_rows, summary = _quality_rows(doc)
    indicator_rows, earlier = _indicator_rows(session, ride, doc, club_id)
    esc = html.escape
    return TEMPLATE.substitute(
        ride_id=ride.id, screen_links=member_links(ride.id) if screen_links is None else screen_links,
        horse=esc(horse.name), horse_details=esc(f"{horse.name}{f' ({details})' if details else ''}"),
        rider=esc(ride.rider.name), gait=esc(gait),
        direction="clockwise" if ride.direction == "CW" else "counter-clockwise",
        date=esc(ride.ridden_on.isoformat() if ride.ridden_on else "date not given"),
        strides=_strides_text(doc, strides),
        stride_text=f"{_number(period)} s" if isinstance(period, int | float) else "–",
        indicator_rows=indicator_rows, decision=_decision_html(doc), chart=chart, chart_caption=esc(caption),
        earlier=f"{earlier} earlier analysed ride{'' if earlier == 1 else 's'}",
        min_rides=MIN_RIDES_FOR_BAND,
        quality_summary=esc(summary.rstrip(".").lower() if summary.startswith("The") else summary.rstrip(".")),
        quality_rows=quality_rows, caveat=esc(PASSIVE_SEATED_CAVEAT.split(":")[0] + "."),
        version=esc(result.code_version or "unknown"),
        result_time=esc(result.created_at.strftime("%Y-%m-%d %H:%M") if result.created_at else "–"),
        now=dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"))


def ride_report_pdf(session: Session, storage: Storage, ride_id: int, *, club_id: int) -> bytes:
    """The report as an A4 PDF, laid out by WeasyPrint from the same HTML."""
    from weasyprint import HTML  # imported here: it loads pango, which only the PDF needs

    return HTML(string=ride_report_html(session, storage, ride_id, club_id=club_id)).write_pdf()

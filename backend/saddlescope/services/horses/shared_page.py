"""A horse's page as a share link shows it: one self-contained, read-only HTML page without the app.

For a vet without an account: the horse, and per gait its analysed rides oldest first with the main
comfort numbers, each against the horse's own normal band of the rides before it (`services.horses.normal_band`),
a small trend of the W_b r.m.s. drawn as inline SVG, and a link to each ride's one-page report (which the
same share link opens, and nothing else). No script: the page runs under the report's strict policy.
"""

from __future__ import annotations

import datetime as dt
import html
import math
from pathlib import Path
from string import Template
from typing import Any

from sqlalchemy.orm import Session

from saddlescope.core.vibration import GAITS, PASSIVE_SEATED_CAVEAT
from saddlescope.db.models import ShareLink
from saddlescope.db.repositories import HorseRepository, NotFound
from saddlescope.services.horses.normal_band import MIN_RIDES_FOR_BAND, band_of, horse_history
from saddlescope.services.results.report import GAIT_WORDS, value_text

__all__ = ["HORSE_COLUMNS", "shared_horse_html", "trend_svg"]

TEMPLATE = Template((Path(__file__).parents[1] / "templates" / "shared_horse.html").read_text(encoding="utf-8"))
# The columns a vet reads first, in the report's words; the band is the first one's (W_b r.m.s.).
HORSE_COLUMNS = (
    ("acc_y_wb_rms", "W<sub>b</sub> r.m.s."),
    ("vdv_y_wb", "VDV (W<sub>b</sub>)"),
    ("vel_x_avg_kmh", "Speed"),
    ("stride_frequency_hz", "Stride frequency"),
    ("amplitude_y_m", "Saddle movement"),
)
BAND_KEY = "acc_y_wb_rms"


def _finite(value: Any) -> float | None:
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else None


def trend_svg(values: list[float | None], band: dict[str, Any] | None, *, width: int = 520, height: int = 110) -> str:
    """Inline SVG of the W_b r.m.s. ride by ride (oldest left), with the band of all rides shaded."""
    points = [(i, v) for i, v in enumerate(values) if v is not None]
    if len(points) < 2:
        return ""
    top = max([v for _, v in points] + ([band["high"]] if band else [])) * 1.1
    low = min([v for _, v in points] + ([band["low"]] if band else [])) * 0.9
    left, right, upper, lower = 44, 10, 8, 18
    span = max(top - low, 1e-9)

    def y(v: float) -> float:
        return upper + (top - v) / span * (height - upper - lower)

    def x(i: int) -> float:
        return left + i / max(len(values) - 1, 1) * (width - left - right)

    parts = []
    if band is not None:
        parts.append(f'<rect x="{left}" y="{y(band["high"]):.1f}" width="{width - left - right}" '
                     f'height="{max(y(band["low"]) - y(band["high"]), 0.5):.1f}" fill="#dff3e6"/>')
    for v in (low, (low + top) / 2, top):
        parts.append(f'<text x="{left - 4}" y="{y(v) + 3:.1f}" text-anchor="end">{v:.2g}</text>')
    path = " ".join(f"{'M' if n == 0 else 'L'}{x(i):.1f},{y(v):.1f}" for n, (i, v) in enumerate(points))
    parts.append(f'<path d="{path}" fill="none" stroke="#1f5fa8" stroke-width="1.8"/>')
    parts += [f'<circle cx="{x(i):.1f}" cy="{y(v):.1f}" r="2.6" fill="#1f5fa8"/>' for i, v in points]
    parts.append(f'<text x="{(left + width - right) / 2}" y="{height - 3}" text-anchor="middle">'
                 "rides, oldest left; m/s²; shaded: the horse's normal band</text>")
    return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width} {height}" role="img" '
            'aria-label="W_b r.m.s. acceleration ride by ride" font-size="9" '
            'font-family="DejaVu Sans, Arial, sans-serif" fill="#4a5563">' + "".join(parts) + "</svg>")


def _gait_section(rows: list[dict[str, Any]], gait: str, ride_href) -> str:
    """One gait's rides: the trend and a table, each ride against the band of the rides before it."""
    esc = html.escape
    values = [_finite((row.get("indicators") or {}).get(BAND_KEY)) for row in rows]
    lines: list[str] = []
    earlier: list[float | None] = []
    for row, value in zip(rows, values, strict=True):
        band = band_of(earlier)
        verdict = "–"
        if band is not None and value is not None:
            verdict = "within" if band["low"] <= value <= band["high"] else (
                "above" if value > band["high"] else "below")
        earlier.append(value)
        cells = "".join(f'<td class="num">{esc(value_text(key, (row.get("indicators") or {}).get(key)))}</td>'
                        for key, _ in HORSE_COLUMNS)
        css = "band-in" if verdict == "within" else "band-out" if verdict != "–" else "hint"
        date = row["date"].isoformat() if row.get("date") else "date not given"
        lines.append(f'<tr data-ride="{row["ride_id"]}"><td class="date">{esc(date)}</td>'
                     f'<td>{esc(str(row["rider"]))}</td>{cells}'
                     f'<td class="{css}">{verdict}</td>'
                     f'<td><a href="{esc(ride_href(row["ride_id"]))}">Report</a></td></tr>')
    head = "".join(f'<th scope="col" class="num">{label}</th>' for _, label in HORSE_COLUMNS)
    n = len(rows)
    return (f'<section data-gait="{gait}"><h2>{esc(GAIT_WORDS.get(gait, gait).capitalize())}: {n} analysed '
            f"ride{'' if n == 1 else 's'}</h2>\n<figure>{trend_svg(values, band_of(values))}</figure>\n"
            f'<div class="scroll" tabindex="0" role="region" aria-label="Rides in {esc(GAIT_WORDS.get(gait, gait))}">'
            '<table class="ind"><thead><tr><th scope="col">Ridden on</th><th scope="col">Rider'
            f'</th>{head}<th scope="col">W<sub>b</sub> against its band</th><th scope="col">'
            '<span class="visually-hidden">One-page report</span></th></tr></thead>\n<tbody>\n'
            + "\n".join(lines) + "\n</tbody></table></div></section>")


def shared_horse_html(session: Session, link: ShareLink, *, ride_href) -> str:
    """The horse page a share link shows; `ride_href(ride_id)`: the link's address of a ride's report."""
    if link.horse_id is None:
        raise NotFound("this link shows one ride, not a horse's page")
    horse = HorseRepository(session, club_id=link.club_id).get(link.horse_id)
    history = horse_history(session, club_id=link.club_id, horse_id=horse.id)
    sections = []
    for gait in GAITS:
        rows = [row for row in history if row["gait"] == gait]
        if rows:
            sections.append(_gait_section(rows, gait, ride_href))
    details = ", ".join(str(p) for p in (horse.breed, f"born {horse.birth_year}" if horse.birth_year else None) if p)
    esc = html.escape
    return TEMPLATE.substitute(
        horse=esc(horse.name), details=esc(details or "no breed or year of birth recorded"),
        expires=esc(f"{link.expires_at:%Y-%m-%d}"), min_rides=MIN_RIDES_FOR_BAND,
        sections="\n".join(sections) or '<p class="hint">This horse has no analysed rides yet.</p>',
        caveat=esc(PASSIVE_SEATED_CAVEAT.split(":")[0] + "."),
        now=dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"))

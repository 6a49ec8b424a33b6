"""CSV and Excel (xlsx) export of comfort indicators: one ride, a horse's rides, a club's rides.

The thesis saved its Table 8.7 "in a format which is compatible with EXCEL"; here a table has one row
per ride: the ride's metadata (Ride, Horse, Rider, Gait, Ridden on, Saddle, Rider's weight (kg), why it is
too uncertain for a decision, then any other text fields) followed
by its indicators. Columns are named in the field's words with the unit in the header ("W_b r.m.s.
(m/s²)", "Speed (km/h)"), never a code; values are rounded to three significant digits (what the
measurement supports), times to the exposure values are in minutes and distances in metres (not
fractions of hours and km), the saddle's movement in cm. Indicator columns come in the order of thesis
Table 8.7 (CONTRACTS section 2), then the other known indicators, then unknown numeric keys sorted.
The xlsx's "Units" sheet names each column's key and meaning, for scripts that read the file.

A row is a dict; the indicators may sit at its top level or under ``"indicators"`` (as in the
result document).  Empty and NaN values become empty cells; an infinite time or distance reads "no limit".
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import math
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import IO

import numpy as np
from openpyxl import Workbook
from openpyxl.cell.cell import ILLEGAL_CHARACTERS_RE
from openpyxl.styles import Font
from openpyxl.utils import get_column_letter

from saddlescope.core.errors import InputError
from saddlescope.core.vibration import (
    COMFORT_INDICATORS,
    CONTRACT_KEYS,
    INDICATORS,
    PASSIVE_SEATED_CAVEAT,
    indicator_unit,
)

__all__ = [
    "METADATA_COLUMNS", "OPTIONAL_METADATA", "SIGNIFICANT_DIGITS",
    "column_header", "column_value", "indicator_table", "indicators_to_csv",
    "indicators_to_xlsx",
]

METADATA_COLUMNS = ("ride_id", "horse", "rider", "gait", "date")
# Then these, in this order, when the rows carry them (the club's exports do; empty where a ride has none):
# which saddle and how heavy the rider was are the first questions asked of a comfort number (issue 37).
OPTIONAL_METADATA = ("saddle", "rider_weight_kg", "uncertain_reason")
METADATA_HEADERS = {"ride_id": "Ride", "horse": "Horse", "rider": "Rider", "gait": "Gait", "date": "Ridden on",
                    "saddle": "Saddle", "rider_weight_kg": "Rider's weight (kg)",
                    "uncertain_reason": "Too uncertain for a decision because"}
GAIT_WORDS = {"walk": "walk", "sitting_trot": "sitting trot", "rising_trot": "rising trot", "canter": "canter"}
SIGNIFICANT_DIGITS = 3  # what a ride's numbers support (their 95 % intervals are a few % wide at best)
# The names a rider or vet uses for the indicators they read first; the others are named from their label.
SHORT_NAMES = {
    "acc_y_wb_rms": "W_b r.m.s.", "acc_y_wk_rms": "W_k r.m.s.", "vdv_y_wb": "VDV W_b", "vdv_y_wk": "VDV W_k",
    "acc_y_max": "Peak vertical acceleration", "crest_factor_y": "Crest factor, W_b",
    "crest_factor_y_wk": "Crest factor, W_k", "vel_x_avg_kmh": "Speed",
    "amplitude_y_m": "Saddle movement up and down", "stride_frequency_hz": "Stride frequency",
    "duration_s": "Analysed duration",
}
# unit as stored -> (unit in the header, factor to it)
_SHOWN_UNITS = {"h": ("min", 60.0), "km": ("m", 1000.0), "m/s^2": ("m/s²", 1.0), "m/s^1.75": ("m/s¹·⁷⁵", 1.0)}
_NO_LIMIT = "no limit"
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def _is_number(value) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def _flatten(row: Mapping, index: int) -> tuple[dict, dict]:
    """Split a row into metadata (text, dates, ids) and indicators (numbers)."""
    if not isinstance(row, Mapping):
        raise InputError(f"export row {index} must be a dict, got {type(row).__name__}")
    nested = row.get("indicators", {})
    if not isinstance(nested, Mapping):
        raise InputError(f"export row {index}: 'indicators' must be a dict")
    meta, values = {}, {}
    for key, value in row.items():
        if key == "indicators":
            continue
        if key in METADATA_COLUMNS or key in OPTIONAL_METADATA or not (_is_number(value) or value is None):
            meta[str(key)] = value
        else:
            values[str(key)] = value
    for key, value in nested.items():
        if value is not None and not _is_number(value):
            raise InputError(f"export row {index}: indicator {key} = {value!r} is not a number")
        values[str(key)] = value
    return meta, values


def _shown_unit(key: str) -> tuple[str, float]:
    """The unit a column shows and the factor from the stored value (cm for the saddle's movement)."""
    if key == "amplitude_y_m":
        return "cm", 100.0
    unit = indicator_unit(key)
    return _SHOWN_UNITS.get(unit, (unit, 1.0))


def column_header(key: str) -> str:
    """A column's header in words with its unit: "W_b r.m.s. (m/s²)", "Time to the ... (min)"."""
    if key in METADATA_HEADERS:
        return METADATA_HEADERS[key]
    info = INDICATORS.get(key)
    if key in SHORT_NAMES:
        name = SHORT_NAMES[key]
    elif info is not None:
        name = info.label.replace(" (W_b)", ", W_b").replace(" (W_k)", ", W_k")
        name = name[:1].upper() + name[1:]
    else:
        name = key.replace("_", " ").capitalize()
    unit, _ = _shown_unit(key)
    return f"{name} ({unit})" if unit else name


def _round(value: float, digits: int = SIGNIFICANT_DIGITS) -> float | int:
    """`value` to `digits` significant digits (an int when it has no fraction left: 1230, not 1230.0)."""
    if value == 0 or not math.isfinite(value):
        return value
    rounded = round(value, digits - 1 - math.floor(math.log10(abs(value))))
    return int(rounded) if rounded == int(rounded) and abs(rounded) >= 10 ** (digits - 1) else rounded


def column_value(key: str, value):
    """A cell's value as the column shows it: in its header's unit, rounded; words for the gait."""
    if key == "gait" and isinstance(value, str):
        return GAIT_WORDS.get(value, value)
    if key == "rider_weight_kg" and _is_number(value):
        return round(float(value), 1)  # as weighed: to 100 g
    if key in METADATA_COLUMNS or key in OPTIONAL_METADATA or not _is_number(value):
        return value
    number = float(value)
    if math.isnan(number):
        return None
    if math.isinf(number):
        return _NO_LIMIT if number > 0 else None
    _, factor = _shown_unit(key)
    return _round(number * factor)


def _table(rows: Iterable[Mapping]) -> tuple[list[str], list[str], list[list]]:
    """Metadata keys, indicator keys and the aligned cells."""
    flat = [_flatten(row, i) for i, row in enumerate(rows)]
    if not flat:
        raise InputError("nothing to export: no rides given")
    extra_meta: list[str] = []
    indicator_keys: set[str] = set()
    for meta, values in flat:
        extra_meta += [k for k in meta if k not in METADATA_COLUMNS + OPTIONAL_METADATA and k not in extra_meta]
        indicator_keys.update(values)
    known_order = list(CONTRACT_KEYS) + [k for k in INDICATORS if k not in CONTRACT_KEYS]
    ordered = [k for k in known_order if k in indicator_keys]
    ordered += sorted(indicator_keys - set(ordered))
    carried = [k for k in OPTIONAL_METADATA if any(k in meta for meta, _ in flat)]
    meta_keys = list(METADATA_COLUMNS) + carried + extra_meta
    cells = [[column_value(k, meta.get(k)) for k in meta_keys] + [column_value(k, values.get(k)) for k in ordered]
             for meta, values in flat]
    return meta_keys, ordered, cells


def indicator_table(rows: Iterable[Mapping]) -> tuple[list[str], list[str], list[list]]:
    """Column keys, column headers (with units) and cell values of the export table.

    Parameters
    ----------
    rows : iterable of dict
        One dict per ride (metadata and indicators, see the module docstring).

    Returns
    -------
    keys : list of str
        Column keys: metadata first, then indicators.
    headers : list of str
        Column headers in words, indicators' with their unit in brackets (`column_header`).
    cells : list of list
        One list per ride, aligned with ``keys``, as the columns show them (`column_value`); None where a
        ride lacks a value.
    """
    meta_keys, indicator_keys, cells = _table(rows)
    keys = meta_keys + indicator_keys
    return keys, [column_header(k) for k in keys], cells


def _csv_text(value) -> str:
    if value is None:
        return ""
    if _is_number(value):
        number = float(value)
        if math.isnan(number):
            return ""
        if math.isinf(number):
            return _NO_LIMIT if number > 0 else ""
        if isinstance(value, int | np.integer) or (number.is_integer() and abs(number) < 1e15):
            return str(int(number))
        return repr(number)  # already rounded (`column_value`): the shortest form, "0.123"
    if isinstance(value, dt.date | dt.datetime):
        return value.isoformat()
    text = str(value)
    # A spreadsheet would run a cell starting with "=" etc. as a formula (CSV injection).
    return "'" + text if text.startswith(_FORMULA_START) else text


def indicators_to_csv(rows: Iterable[Mapping], path_or_buffer: str | os.PathLike | IO) -> None:
    """Write the indicators of one or more rides as CSV (UTF-8, comma-separated).

    Parameters
    ----------
    rows : iterable of dict
        One dict per ride.
    path_or_buffer : path or file object
        A path (written as UTF-8 with a byte-order mark, so that Excel reads accents and units
        correctly), a text buffer (``io.StringIO``) or a binary buffer (``io.BytesIO``).
    """
    _, headers, cells = indicator_table(rows)

    def write(handle) -> None:
        writer = csv.writer(handle, lineterminator="\r\n")
        writer.writerow(headers)
        for line in cells:
            writer.writerow([_csv_text(v) for v in line])

    if isinstance(path_or_buffer, str | os.PathLike):
        with open(Path(path_or_buffer), "w", encoding="utf-8-sig", newline="") as handle:
            write(handle)
    elif isinstance(path_or_buffer, io.TextIOBase):
        write(path_or_buffer)
    elif hasattr(path_or_buffer, "write"):
        wrapper = io.TextIOWrapper(path_or_buffer, encoding="utf-8-sig", newline="")
        try:
            write(wrapper)
            wrapper.flush()
        finally:
            wrapper.detach()  # leave the caller's buffer open
    else:
        raise InputError(f"cannot write CSV to {type(path_or_buffer).__name__}; give a path or a buffer")


def _xlsx_value(value):
    if value is None:
        return None
    if _is_number(value):
        number = float(value)
        if math.isnan(number):
            return None
        if math.isinf(number):
            return _NO_LIMIT if number > 0 else None  # Excel has no infinity
        return int(value) if isinstance(value, int | np.integer) else number
    if isinstance(value, dt.date | dt.datetime):
        return value
    return ILLEGAL_CHARACTERS_RE.sub("", str(value))


def _write_sheet(sheet, headers: list[str], lines: list[list], *, n_text_columns: int) -> None:
    sheet.append(headers)
    for cell in sheet[1]:
        cell.font = Font(bold=True)
    for line in lines:
        sheet.append([_xlsx_value(v) for v in line])
    for row in sheet.iter_rows(min_row=2):
        for cell in row:
            if isinstance(cell.value, str) and cell.value.startswith("="):
                cell.data_type = "s"  # text, never a formula
            elif isinstance(cell.value, dt.date | dt.datetime):
                cell.number_format = "yyyy-mm-dd"
    sheet.freeze_panes = sheet.cell(row=2, column=n_text_columns + 1)
    for i, header in enumerate(headers, start=1):
        sheet.column_dimensions[get_column_letter(i)].width = max(10, min(len(header) + 2, 40))


def _summary_lines(keys: list[str], cells: list[list]) -> tuple[list[str], list[list]]:
    """Mean and number of rides per horse and gait for the comfort indicators present."""
    col = {k: i for i, k in enumerate(keys)}
    indicators = [k for k in COMFORT_INDICATORS if k in col]
    groups: dict[tuple[str, str], list[list]] = {}
    for line in cells:
        groups.setdefault((str(line[col["horse"]]), str(line[col["gait"]])), []).append(line)
    headers = ["Horse", "Gait", "Rides"] + [column_header(k) + ", mean" for k in indicators]
    lines = []
    for (horse, gait), members in sorted(groups.items()):
        means = []
        for k in indicators:
            values = [float(m[col[k]]) for m in members if _is_number(m[col[k]])]
            values = [v for v in values if not math.isnan(v)]
            means.append(_round(float(np.mean(values))) if values else None)
        lines.append([horse, gait, len(members)] + means)
    return headers, lines


def indicators_to_xlsx(rows: Iterable[Mapping], path_or_buffer: str | os.PathLike | IO) -> None:
    """Write the indicators of one or more rides as an Excel workbook.

    Sheets: "Indicators" (one row per ride, named columns with units in the headers, values as
    `column_value` gives them), "Summary" (per horse and gait: number of rides and mean of the
    eight comfort indicators; only when the rides cover more than one horse or gait), "Units"
    (column, key, unit, meaning, name in thesis Table 8.7) and "Notes" (the caveat that the
    directive's limits assume a passive, seated person).

    Parameters
    ----------
    rows : iterable of dict
        One dict per ride.
    path_or_buffer : path or binary file object
        Where to save the workbook.
    """
    meta_keys, indicator_keys, cells = _table(rows)
    keys = meta_keys + indicator_keys
    headers = [column_header(k) for k in keys]
    book = Workbook()
    sheet = book.active
    sheet.title = "Indicators"
    _write_sheet(sheet, headers, cells, n_text_columns=len(meta_keys))

    col = {k: i for i, k in enumerate(keys)}
    combos = {(line[col["horse"]], line[col["gait"]]) for line in cells}
    if len(combos) > 1:
        summary_headers, summary = _summary_lines(keys, cells)
        _write_sheet(book.create_sheet("Summary"), summary_headers, summary, n_text_columns=2)

    units = book.create_sheet("Units")
    unit_lines = [[column_header("rider_weight_kg"), "rider_weight_kg", "kg", "the rider's weight on the ride", ""]
                  ] if "rider_weight_kg" in meta_keys else []
    for key in indicator_keys:
        info = INDICATORS.get(key)
        unit_lines.append([column_header(key), key, _shown_unit(key)[0], info.label if info else "",
                           info.thesis_name if info and info.thesis_name else ""])
    _write_sheet(units, ["Column", "Key", "Unit", "Meaning", "Name in thesis Table 8.7"], unit_lines,
                 n_text_columns=1)
    notes = book.create_sheet("Notes")
    notes.append(["SaddleScope comfort indicators"])
    notes["A1"].font = Font(bold=True)
    notes.append([PASSIVE_SEATED_CAVEAT])
    notes.append(["W_b = BS 6841, W_k = ISO 2631-1, vertical = y axis of the motion frame; "
                  "times in minutes, distances in metres, values to three significant digits "
                  "(EU 2002/44/EC action 0.5 m/s^2 and "
                  "9.1 m/s^1.75, limit 1.15 m/s^2 and 21 m/s^1.75)."])
    notes.column_dimensions["A"].width = 120

    if isinstance(path_or_buffer, str | os.PathLike):
        book.save(Path(path_or_buffer))
    elif hasattr(path_or_buffer, "write"):
        book.save(path_or_buffer)
    else:
        raise InputError(f"cannot write xlsx to {type(path_or_buffer).__name__}; give a path or a buffer")

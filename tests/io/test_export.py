"""CSV and xlsx export of comfort indicators (io.export)."""

from __future__ import annotations

import csv
import datetime as dt
import io
import math

import pytest
from openpyxl import load_workbook

from saddlescope.core.errors import InputError
from saddlescope.core.vibration import CONTRACT_KEYS, ride_indicators
from saddlescope.io import export


def _ride(ride_id, horse, gait, rider="Rider A", scale=1.0):
    f0 = 1.65 if gait == "canter" else 2.8
    ind = ride_indicators(f0_hz=f0, acc_y_amplitudes_m_s2=[6.0 * scale, 2.0], acc_y_phases_rad=[0.0, 1.0],
                          duration_s=2 / f0, speed_kmh=17.6, amplitude_y_m=0.3, stride_frequency_hz=f0)
    return {"ride_id": ride_id, "horse": horse, "rider": rider, "gait": gait,
            "date": dt.date(2024, 5, ride_id), "indicators": ind}


def test_csv_of_one_ride_has_units_in_headers_and_full_precision():
    ride = _ride(1, "Horse 2", "canter")
    buffer = io.StringIO()
    export.indicators_to_csv([ride], buffer)
    table = list(csv.reader(io.StringIO(buffer.getvalue())))
    header, line = table
    assert header[:5] == ["ride_id", "horse", "rider", "gait", "date"]
    assert header[5:8] == ["acc_y_wb_rms [m/s^2]", "acc_y_wk_rms [m/s^2]", "vdv_y_wb [m/s^1.75]"]
    for column in ("crest_factor_y", "t_a8_limit_wb_h [h]", "d_vdv_limit_wk_km [km]"):
        assert column in header
    # Every contract key is a column, in Table 8.7 order.
    keys = [h.split(" [")[0] for h in header[5:]]
    assert keys[: len(CONTRACT_KEYS)] == list(CONTRACT_KEYS)
    assert line[:5] == ["1", "Horse 2", "Rider A", "canter", "2024-05-01"]
    value = float(line[header.index("t_a8_limit_wb_h [h]")])
    assert value == ride["indicators"]["t_a8_limit_wb_h"]  # round-trips exactly


def test_csv_to_path_is_utf8_with_bom_and_to_bytes_buffer(tmp_path):
    rows = [_ride(1, "Hörse", "walk", rider="=HYPERLINK(\"x\")")]
    path = tmp_path / "ride.csv"
    export.indicators_to_csv(rows, path)
    raw = path.read_bytes()
    assert raw.startswith(b"\xef\xbb\xbf")
    text = raw.decode("utf-8-sig")
    assert "Hörse" in text
    assert "'=HYPERLINK" in text  # never a live formula in a spreadsheet
    binary = io.BytesIO()
    export.indicators_to_csv(rows, binary)
    assert not binary.closed
    assert binary.getvalue() == raw


def test_club_export_merges_columns_and_leaves_missing_values_empty():
    rows = [_ride(1, "Horse 1", "walk"), _ride(2, "Horse 2", "canter", scale=1.3),
            {"ride_id": 3, "horse": "Horse 3", "rider": "Rider B", "gait": "walk", "date": "2024-05-03",
             "arena": "indoor", "acc_y_wb_rms": 1.5, "t_a8_limit_wb_h": math.nan, "my_score": 2.0}]
    keys, headers, cells = export.indicator_table(rows)
    assert keys[5] == "arena" and keys[-1] == "my_score"
    assert cells[2][keys.index("acc_y_wb_rms")] == 1.5
    assert cells[2][keys.index("vdv_y_wb")] is None
    buffer = io.StringIO()
    export.indicators_to_csv(rows, buffer)
    table = list(csv.reader(io.StringIO(buffer.getvalue())))
    assert len(table) == 4
    assert table[3][keys.index("t_a8_limit_wb_h")] == ""  # NaN -> empty
    assert table[1][keys.index("arena")] == ""


def test_xlsx_has_indicator_summary_units_and_notes_sheets(tmp_path):
    rows = [_ride(1, "Horse 1", "canter"), _ride(2, "Horse 1", "canter", scale=1.2),
            _ride(3, "Horse 2", "canter", scale=0.8), _ride(4, "Horse 2", "walk", rider="=1+1")]
    path = tmp_path / "club.xlsx"
    export.indicators_to_xlsx(rows, path)
    book = load_workbook(path)
    assert book.sheetnames == ["Indicators", "Summary", "Units", "Notes"]
    sheet = book["Indicators"]
    header = [c.value for c in sheet[1]]
    assert header[:5] == ["ride_id", "horse", "rider", "gait", "date"]
    col = header.index("acc_y_wb_rms [m/s^2]") + 1
    expected = rows[1]["indicators"]["acc_y_wb_rms"]
    assert sheet.cell(row=3, column=col).value == pytest.approx(expected, rel=1e-15)  # Excel keeps ~16 digits
    assert sheet.cell(row=5, column=3).value == "=1+1" and sheet.cell(row=5, column=3).data_type == "s"
    assert sheet.cell(row=2, column=5).value.date() == dt.date(2024, 5, 1)
    summary = book["Summary"]
    lines = {(r[0], r[1]): r for r in summary.iter_rows(min_row=2, values_only=True)}
    assert lines[("Horse 1", "canter")][2] == 2
    mean_col = [c.value for c in summary[1]].index("acc_y_wb_rms [m/s^2] mean")
    expected = (rows[0]["indicators"]["acc_y_wb_rms"] + rows[1]["indicators"]["acc_y_wb_rms"]) / 2
    assert lines[("Horse 1", "canter")][mean_col] == pytest.approx(expected)
    units = {r[0]: r[1] for r in book["Units"].iter_rows(min_row=2, values_only=True)}
    assert units["vdv_y_wb"] == "m/s^1.75" and units["t_vdv_limit_wk_h"] == "h"
    assert "passive, seated" in book["Notes"]["A2"].value


def test_xlsx_of_one_ride_to_buffer_has_no_summary():
    buffer = io.BytesIO()
    export.indicators_to_xlsx([_ride(1, "Horse 2", "canter")], buffer)
    book = load_workbook(io.BytesIO(buffer.getvalue()))
    assert "Summary" not in book.sheetnames


def test_bad_rows_are_refused():
    with pytest.raises(InputError, match="no rides"):
        export.indicators_to_csv([], io.StringIO())
    with pytest.raises(InputError, match="not a number"):
        export.indicators_to_csv([{"horse": "H", "indicators": {"acc_y_max": "high"}}], io.StringIO())
    with pytest.raises(InputError, match="must be a dict"):
        export.indicators_to_xlsx(["ride"], io.BytesIO())

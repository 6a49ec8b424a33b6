"""CSV and xlsx export of comfort indicators (io.export)."""

from __future__ import annotations

import csv
import datetime as dt
import io
import math
import re

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


def test_csv_of_one_ride_has_named_columns_with_units_and_rounded_values():
    ride = _ride(1, "Horse 2", "canter")
    buffer = io.StringIO()
    export.indicators_to_csv([ride], buffer)
    table = list(csv.reader(io.StringIO(buffer.getvalue())))
    header, line = table
    assert header[:5] == ["Ride", "Horse", "Rider", "Gait", "Ridden on"]
    assert header[5:8] == ["W_b r.m.s. (m/s²)", "W_k r.m.s. (m/s²)", "VDV W_b (m/s¹·⁷⁵)"]
    for column in ("Crest factor, W_b", "Time to the A(8) exposure limit value, W_b (min)", "Speed (km/h)",
                   "Distance to the VDV exposure limit value, W_k (m)", "Saddle movement up and down (cm)"):
        assert column in header
    assert len(set(header)) == len(header)
    # no code as a header: every header is words (a capital first), no snake_case key
    assert all(h[0].isupper() and not re.search(r"[a-z]_[a-z]", h) for h in header), header
    # Every contract key is a column, in Table 8.7 order.
    keys, headers, _ = export.indicator_table([ride])
    assert keys[5: 5 + len(CONTRACT_KEYS)] == list(CONTRACT_KEYS) and headers == header
    assert line[:5] == ["1", "Horse 2", "Rider A", "canter", "2024-05-01"]
    hours = ride["indicators"]["t_a8_limit_wb_h"]
    minutes = float(line[header.index("Time to the A(8) exposure limit value, W_b (min)")])
    assert minutes == pytest.approx(hours * 60, rel=5e-3)  # minutes, three significant digits
    assert line[header.index("Saddle movement up and down (cm)")] == "30"  # 0.3 m
    for cell in line[5:]:
        digits = cell.replace("-", "").replace(".", "").lstrip("0")
        assert len(digits.rstrip("0")) <= 3, cell  # no 16-digit numbers


@pytest.mark.parametrize(("key", "value", "shown"), [
    ("acc_y_wb_rms", 1.23456789, 1.23), ("acc_y_wb_rms", 0.0123456, 0.0123), ("vdv_y_wb", 12.3456, 12.3),
    ("t_a8_limit_wb_h", 2 + 5 / 60, 125), ("t_a8_limit_wb_h", 0.00025, 0.015), ("d_a8_limit_wb_km", 0.00416, 4.16),
    ("d_a8_limit_wb_km", 15.63, 15600), ("vel_x_avg_kmh", 17.6499, 17.6), ("amplitude_y_m", 0.07346, 7.35),
    ("t_a8_limit_wb_h", math.inf, "no limit"), ("acc_y_wb_rms", math.nan, None),
    ("gait", "sitting_trot", "sitting trot"),
    ("ride_id", 12345678, 12345678),
])
def test_a_cell_is_in_its_headers_unit_rounded_to_three_significant_digits(key, value, shown):
    assert export.column_value(key, value) == (pytest.approx(shown) if isinstance(shown, float) else shown)


def test_infinite_times_read_no_limit_in_both_formats(tmp_path):
    ride = _ride(1, "Horse 1", "walk")
    ride["indicators"]["t_a8_limit_wb_h"] = math.inf
    buffer = io.StringIO()
    export.indicators_to_csv([ride], buffer)
    header, line = list(csv.reader(io.StringIO(buffer.getvalue())))
    assert line[header.index("Time to the A(8) exposure limit value, W_b (min)")] == "no limit"
    export.indicators_to_xlsx([ride], tmp_path / "one.xlsx")
    sheet = load_workbook(tmp_path / "one.xlsx")["Indicators"]
    header = [c.value for c in sheet[1]]
    column = header.index("Time to the A(8) exposure limit value, W_b (min)") + 1
    assert sheet.cell(row=2, column=column).value == "no limit"


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
    assert headers[5] == "Arena" and headers[-1] == "My score"
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
    assert header[:5] == ["Ride", "Horse", "Rider", "Gait", "Ridden on"]
    col = header.index("W_b r.m.s. (m/s²)") + 1
    expected = rows[1]["indicators"]["acc_y_wb_rms"]
    assert sheet.cell(row=3, column=col).value == pytest.approx(expected, rel=5e-3)
    assert sheet.cell(row=3, column=col).value == float(f"{expected:.3g}")  # three significant digits
    assert sheet.cell(row=5, column=3).value == "=1+1" and sheet.cell(row=5, column=3).data_type == "s"
    assert sheet.cell(row=2, column=5).value.date() == dt.date(2024, 5, 1)
    summary = book["Summary"]
    assert [c.value for c in summary[1]][:3] == ["Horse", "Gait", "Rides"]
    lines = {(r[0], r[1]): r for r in summary.iter_rows(min_row=2, values_only=True)}
    assert lines[("Horse 1", "canter")][2] == 2
    mean_col = [c.value for c in summary[1]].index("W_b r.m.s. (m/s²), mean")
    expected = (rows[0]["indicators"]["acc_y_wb_rms"] + rows[1]["indicators"]["acc_y_wb_rms"]) / 2
    assert lines[("Horse 1", "canter")][mean_col] == pytest.approx(expected, rel=1e-2)
    units = {r[1]: r for r in book["Units"].iter_rows(min_row=2, values_only=True)}
    assert units["vdv_y_wb"][2] == "m/s¹·⁷⁵" and units["t_vdv_limit_wk_h"][2] == "min"
    assert units["d_a8_limit_wb_km"][:3] == (
        "Distance to the A(8) exposure limit value, W_b (m)", "d_a8_limit_wb_km", "m")
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

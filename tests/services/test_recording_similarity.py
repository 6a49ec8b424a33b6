"""`saddlescope similar` on recordings: labels matched, aligned in time, where they differ, many at once."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest

from conftest import real_data_path
from saddlescope.cli import main
from saddlescope.core.errors import InputError
from saddlescope.io.mocap import read_mocap, write_c3d, write_trc
from saddlescope.services.similarity.compare import compare_files, compare_recordings


def _walk(n: int, t0: float = 0.0, *, shape: float = 0.0) -> np.ndarray:
    """Three markers (n, 3, 3) mm at 100 Hz: a periodic motion with travel along x."""
    t = t0 + np.arange(n) / 100.0
    p = 2 * np.pi * 1.1 * t
    out = [np.column_stack([40 * np.cos(p + m) + 1300 * t, 25 * np.sin(2 * p + m) + shape * np.sin(3 * p) + 900,
                            15 * np.sin(p + m) + 100 * m]) for m in range(3)]
    return np.stack(out, axis=1)


@pytest.mark.realdata
def test_gait_c3d_against_gait_trc_is_almost_identical():
    res = compare_files(real_data_path("c3d", "Gait.c3d"), real_data_path("c3d", "Gait.trc"))
    assert res["similarity"] >= 0.99
    assert len(res["markers"]) == 33
    assert any(n.startswith("matched by marker-set aliases: RSHO=R.Shoulder") for n in res["notes"])
    # the TRC's markers are seen from frame 160 on, the C3D's from 138: the same stretch was found
    assert res["alignment"]["method"] == "subsequence_dtw"
    assert res["alignment"]["span_a_s"][0] == pytest.approx(0.22, abs=0.02)


@pytest.mark.realdata
def test_a_walk_started_0_4_s_later_is_above_another_persons_walk(tmp_path):
    gait = read_mocap(real_data_path("c3d", "Gait.c3d"))
    first = int(np.flatnonzero(np.isfinite(gait.points).all(axis=(1, 2)))[0])
    later = write_c3d(tmp_path / "later.c3d", list(gait.labels), gait.points[first + 40:], gait.rate_hz)
    other = real_data_path("c3d", "PiG_Motion3_FF.c3d")
    for original in (real_data_path("c3d", "Gait.c3d"), real_data_path("c3d", "Gait.trc")):
        same = compare_files(original, later)["similarity"]
        assert same > compare_files(original, other)["similarity"]
        assert same > compare_files(later, other)["similarity"]


def test_a_marker_empty_in_one_file_is_left_out_with_a_note(tmp_path):
    a, b = _walk(330), _walk(400, 0.3)
    b[:, 1] = np.nan
    b[::50, 1] = 5.0  # seen now and then: 2 % of the frames
    pa = write_trc(tmp_path / "a.trc", ["RASI", "LASI", "SACR"], a, 100.0)
    pb = write_trc(tmp_path / "b.trc", ["R.ASIS", "L.ASIS", "V.Sacral"], b, 100.0)
    res = compare_files(pa, pb)
    assert res["markers"] == ["RASI", "SACR"]
    assert any(n.startswith("LASI left out: seen in 2 % of b.trc") for n in res["notes"])
    assert res["similarity"] > 0.99


def test_user_map_and_missing_partner(tmp_path, capsys):
    a, b = _walk(330), _walk(400, 0.3)
    pa = write_trc(tmp_path / "a.trc", ["P1", "P2", "P3"], a, 100.0)
    pb = write_trc(tmp_path / "b.trc", ["Q1", "Q2", "Q3"], b, 100.0)
    with pytest.raises(InputError, match="share no marker"):
        compare_files(pa, pb)
    out = tmp_path / "ab.json"
    assert main(["similar", str(pa), str(pb), "--map", "P1=Q1", "--map", "P2=Q2", "--map", "P3=Q3",
                 "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["markers"] == ["P1", "P2", "P3"] and res["similarity"] > 0.99
    capsys.readouterr()
    assert main(["similar", str(pa), str(pb), "--map", "P1Q1"]) == 2
    err = capsys.readouterr().err
    assert "LABEL_IN_A=LABEL_IN_B" in err and len(err.strip().splitlines()) == 1


def test_the_answer_says_the_alignment_and_where_the_motions_differ():
    a = _walk(330)
    b = _walk(420, 0.25)
    t = 0.25 + np.arange(420) / 100.0
    b[:, 2, 1] += np.where(((1.1 * t) % 1.0 > 0.3) & ((1.1 * t) % 1.0 < 0.4), 20.0, 0.0)
    res = compare_recordings(a, b, labels=["A", "B", "C"], up=1)
    assert res["frame"] == "cycle_phase+kabsch" and res["alignment"]["method"] == "cycle_phase"
    assert res["alignment"]["cycles"] == [3, 4]
    diff = res["differences"]
    assert diff["time_base"] == "cycle phase" and diff["stretches"] == 10
    assert diff["most_different_marker"] == "C" and diff["most_different_stretch"] == 3
    assert [m["marker"] for m in diff["per_marker"]] == ["A", "B", "C"]
    assert len(diff["per_marker"][2]["per_stretch_mm"]) == 10 and len(diff["per_stretch_mm"]) == 10
    json.dumps(res, allow_nan=False)


def test_many_recordings_give_the_matrix_csv_and_heat_map(tmp_path, capsys):
    folder = tmp_path / "recs"
    folder.mkdir()
    write_trc(folder / "h1_a.trc", ["A", "B", "C"], _walk(330), 100.0)
    write_trc(folder / "h1_b.trc", ["A", "B", "C"], _walk(450, 0.4), 100.0)
    write_trc(folder / "h2_a.trc", ["A", "B", "C"], _walk(380, 0.1, shape=15.0), 100.0)
    (folder / "broken.c3d").write_bytes(b"")
    csv_path, png_path = tmp_path / "m.csv", tmp_path / "m.png"
    assert main(["similar", str(folder), "--csv", str(csv_path), "--png", str(png_path)]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["files"] == ["broken.c3d", "h1_a.trc", "h1_b.trc", "h2_a.trc"]
    sim = res["similarity"]
    assert sim[0] == [None] * 4 and any(n.startswith("broken.c3d: the file is empty") for n in res["notes"])
    assert sim[1][1] == 1.0 and sim[1][2] == sim[2][1] and sim[1][2] > sim[1][3]
    rows = list(csv.reader(csv_path.open()))
    assert rows[0] == ["file", "broken.c3d", "h1_a.trc", "h1_b.trc", "h2_a.trc"]
    assert rows[2][0] == "h1_a.trc" and float(rows[2][3]) == pytest.approx(sim[1][2], abs=1e-4)
    image = cv2.imread(str(png_path))
    assert image is not None and image.shape[0] > 4 * 40
    # a list of files works as a folder does
    assert main(["similar", str(folder / "h1_a.trc"), str(folder / "h1_b.trc"), str(folder / "h2_a.trc")]) == 0
    assert json.loads(capsys.readouterr().out)["files"] == ["h1_a.trc", "h1_b.trc", "h2_a.trc"]


def test_rides_differences_find_the_marker_and_stretch_that_differ():
    from saddlescope.bench.similarity import synthetic_ride
    from saddlescope.services.similarity.compare import compare_ride_documents

    doc = synthetic_ride(0, "sitting_trot", 0, strides=10.0)
    other = {**doc, "markers": {**doc["markers"], "position_m": np.array(doc["markers"]["position_m"], copy=True)}}
    n = len(other["markers"]["position_m"])
    phase = (np.arange(n) / (doc["period_s"] * doc["fps"])) % 1.0
    other["markers"]["position_m"][:, 1, 1] += np.where((phase > 0.5) & (phase < 0.6), 0.02, 0.0)  # M2, 20 mm
    diff = compare_ride_documents(doc, other, markers="all")["differences"]
    assert diff["most_different_marker"] == "M2" and diff["most_different_stretch"] == 5
    same = compare_ride_documents(doc, doc, markers="all")["differences"]
    assert max(m["rms_mm"] for m in same["per_marker"]) < 1e-6

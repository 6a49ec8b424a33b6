"""C3D / TRC reading and writing: real BTK sample files, round trips, and bad files."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from conftest import real_data_path
from saddlescope.core.errors import InputError, MocapFileError
from saddlescope.io.mocap import MocapData, read_mocap, write_c3d, write_trc

EB015 = ("Eb015pi.c3d", "Eb015pr.c3d", "Eb015sr.c3d")
BAD_FILES = ("Empty.c3d", "Empty.trc", "Truncated.trc", "badParameterOffset.c3d", "bad_parameter_section.c3d")


def _tracks(rng, n_frames=12, n_markers=3):
    points = rng.normal(0.0, 800.0, (n_frames, n_markers, 3))
    points[2, 1] = np.nan
    points[5, 0] = np.nan
    return [f"M{j + 1}" for j in range(n_markers)], points


# ------------------------------------------------------------------------------------ real files


@pytest.mark.realdata
@pytest.mark.parametrize("name", EB015)
def test_eb015_header_and_first_point(name):
    data = read_mocap(real_data_path("c3d", name))
    assert data.source_format == "c3d"
    assert (data.n_frames, data.n_markers) == (450, 26)
    assert data.rate_hz == 50.0
    assert data.units == "mm"
    assert data.first_frame == 1
    assert data.labels[0] == "RFT1"
    np.testing.assert_allclose(data.points[0, 0], [248.5834, 226.8334, 37.4167], atol=1e-3)


@pytest.mark.realdata
def test_eb015_integer_real_and_sgi_give_the_same_trajectories():
    pi, pr, sr = (read_mocap(real_data_path("c3d", n)) for n in EB015)
    assert pi.labels == pr.labels == sr.labels
    for other in (pr, sr):
        np.testing.assert_array_equal(np.isnan(pi.points), np.isnan(other.points))
    present = ~np.isnan(pi.points)
    assert present.mean() > 0.9
    # Integer storage rounds to the POINT:SCALE step (0.0833 mm): at most half a step apart.
    assert np.max(np.abs(pi.points[present] - pr.points[present])) <= 0.0834 / 2
    # PC-real and SGI-real hold the same float32 numbers, only the byte order differs.
    np.testing.assert_array_equal(pr.points[present], sr.points[present])


@pytest.mark.realdata
def test_gait_c3d_and_trc():
    c3d = read_mocap(real_data_path("c3d", "Gait.c3d"))
    assert (c3d.n_frames, c3d.n_markers, c3d.rate_hz, c3d.units) == (487, 33, 100.0, "mm")
    # Frames without a marker are gaps (residual -1), not zeros.
    assert np.isnan(c3d.points[0]).all()
    assert np.isfinite(c3d.points[293]).all()

    trc = read_mocap(real_data_path("c3d", "Gait.trc"))
    assert (trc.n_frames, trc.n_markers, trc.rate_hz, trc.units) == (487, 66, 100.0, "mm")
    assert trc.labels[0] == "R.Shoulder" and trc.labels[32] == "PX" and trc.labels[33] == "M034"
    assert [w.values["markers_named"] for w in trc.warnings if w.code == "mocap.marker_names"] == [33]
    # The 33 named TRC markers are the C3D trial's markers (processed separately: within a few mm).
    dist = np.linalg.norm(trc.points[:, :33] - c3d.points, axis=2)
    both = np.isfinite(dist)
    assert both.sum() > 5000
    assert np.median(dist[both]) < 2.0


# What the ``c3d`` package reads (BTK samples with faulty headers included), with the repairs noted:
# name -> (frames, markers, rate Hz, a note that must be there or None).
READ_BY_LIBRARIES = {
    "dynamic.C3D": (296, 34, 100.0, "POINT:DATA_START is missing"),
    "standing.C3D": (200, 38, 100.0, "POINT:RATE is missing"),
    "Dance.c3d": (499, 40, 65.053, "POINT:FRAMES says 500 frames"),
    "golfswing.c3d": (514, 29, 107.527, "POINT:DATA_START is 0"),
    "Gait.c3d": (487, 33, 100.0, None),
    "PiG_Motion3_FF.c3d": (293, 97, 100.0, None),
    "PiG_Calibration3_FF.c3d": (95, 66, 100.0, None),
}


@pytest.mark.realdata
@pytest.mark.parametrize("name", sorted(READ_BY_LIBRARIES))
def test_every_file_a_well_kept_reader_reads_is_read(name):
    frames, markers, rate, note = READ_BY_LIBRARIES[name]
    data = read_mocap(real_data_path("c3d", name))
    assert (data.n_frames, data.n_markers) == (frames, markers)
    assert data.rate_hz == pytest.approx(rate, abs=1e-3)
    assert len(set(data.labels)) == markers
    seen = np.isfinite(data.points).all(axis=2)
    assert seen.mean() > 0.3
    assert np.nanmax(np.abs(data.points)) < 1e5  # millimetres of a lab, not garbage
    if note:
        repaired = [w.detail for w in data.warnings if w.code == "mocap.header_repaired"]
        assert any(detail.startswith(note) for detail in repaired), data.warnings


@pytest.mark.realdata
@pytest.mark.parametrize("name", ["dynamic.C3D", "standing.C3D", "Dance.c3d", "golfswing.c3d"])
def test_repaired_files_give_smooth_trajectories(name):
    # A wrong layout (data start, word size, scale) reads noise: ezc3d 1.5 gives dynamic.C3D a median
    # |second difference| of ~1 m per frame. A body marker at 65-108 Hz moves a few mm per frame.
    points = read_mocap(real_data_path("c3d", name)).points
    assert np.nanmedian(np.abs(np.diff(points, 2, axis=0))) < 3.0


@pytest.mark.realdata
@pytest.mark.parametrize("name", BAD_FILES)
def test_bad_real_files_raise_a_clear_error(name):
    with pytest.raises(MocapFileError) as info:
        read_mocap(real_data_path("c3d", name))
    assert str(info.value).startswith(name + ":")


@pytest.mark.realdata
def test_summary_is_json():
    summary = read_mocap(real_data_path("c3d", "Eb015pi.c3d")).summary()
    text = json.dumps(summary, allow_nan=False)
    back = json.loads(text)
    assert back["format"] == "c3d" and back["n_markers"] == 26 and back["n_frames"] == 450
    assert back["duration_s"] == pytest.approx(9.0)
    np.testing.assert_allclose(back["first_frame_points"]["RFT1"], [248.5834, 226.8334, 37.4167], atol=1e-3)
    assert back["first_frame_points"]["LFT1"] is None  # missing in frame 1


# ------------------------------------------------------------------------------------ round trips


def test_c3d_round_trip(tmp_path):
    labels, points = _tracks(np.random.default_rng(1))
    path = write_c3d(tmp_path / "tracks.c3d", labels, points, 30.0)
    data = read_mocap(path)
    assert data.labels == tuple(labels)
    assert data.rate_hz == 30.0 and data.units == "mm" and data.first_frame == 1
    np.testing.assert_array_equal(np.isnan(data.points), np.isnan(points))
    np.testing.assert_allclose(data.points, points, atol=1e-3, equal_nan=True)  # float32 storage


@pytest.mark.parametrize("units, atol", [("mm", 1e-6), ("m", 1e-9)])
def test_trc_round_trip(tmp_path, units, atol):
    labels, points = _tracks(np.random.default_rng(2))
    if units == "m":
        points = points / 1000.0
    path = write_trc(tmp_path / "tracks.trc", labels, points, 29.97, units=units, first_frame=7)
    data = read_mocap(path)
    assert data.labels == tuple(labels) and data.units == units and data.first_frame == 7
    assert data.rate_hz == 29.97 and data.warnings == ()
    np.testing.assert_allclose(data.points, points, atol=atol, equal_nan=True)
    np.testing.assert_array_equal(np.isnan(data.points), np.isnan(points))


def test_writers_reject_bad_arguments(tmp_path):
    labels, points = _tracks(np.random.default_rng(3))
    with pytest.raises(InputError, match="labels for 3 markers"):
        write_trc(tmp_path / "a.trc", labels[:2], points, 30.0)
    with pytest.raises(InputError, match=r"shape \(F, M, 3\)"):
        write_c3d(tmp_path / "a.c3d", labels, points[..., :2], 30.0)
    with pytest.raises(InputError, match="distinct"):
        write_trc(tmp_path / "a.trc", ["A", "A", "B"], points, 30.0)
    with pytest.raises(InputError, match="rate_hz"):
        write_trc(tmp_path / "a.trc", labels, points, 0.0)
    with pytest.raises(InputError, match="units"):
        write_trc(tmp_path / "a.trc", labels, points, 30.0, units="in")


# ------------------------------------------------------------------------------- broken files


def test_unknown_extension_and_missing_file(tmp_path):
    odd = tmp_path / "tracks.csv"
    odd.write_text("1,2,3\n")
    with pytest.raises(MocapFileError, match="tracks.csv: unknown motion-capture file type"):
        read_mocap(odd)
    with pytest.raises(MocapFileError, match="not found"):
        read_mocap(tmp_path / "nothing.c3d")


def _small_c3d(tmp_path) -> bytes:
    labels, points = _tracks(np.random.default_rng(4))
    return write_c3d(tmp_path / "ok.c3d", labels, points, 30.0).read_bytes()


def test_c3d_bad_key_truncated_data_and_bad_offset(tmp_path):
    raw = _small_c3d(tmp_path)
    bad = tmp_path / "bad.c3d"

    bad.write_bytes(b"\x02\x51" + raw[2:])
    with pytest.raises(MocapFileError, match="not a C3D file"):
        read_mocap(bad)

    data_start = (struct.unpack_from("<H", raw, 16)[0] - 1) * 512
    bad.write_bytes(raw[:data_start + 300])  # 12 frames of 3 points need 576 bytes
    with pytest.raises(MocapFileError, match="truncated"):
        read_mocap(bad)

    # First parameter record: point its "offset to next" far past the parameter section.
    p0 = (raw[0] - 1) * 512
    name_len = abs(struct.unpack_from("b", raw, p0 + 4)[0])
    corrupt = bytearray(raw)
    struct.pack_into("<h", corrupt, p0 + 4 + 2 + name_len, 30000)
    bad.write_bytes(bytes(corrupt))
    with pytest.raises(MocapFileError, match="parameter section is corrupt"):
        read_mocap(bad)


@pytest.mark.realdata
def test_file_that_crashes_ezc3d_does_not_crash_us(tmp_path):
    # One byte turns the DESCRIPTIONS parameter into a group record; ezc3d 1.5 segfaults on it.
    raw = bytearray(real_data_path("c3d", "Eb015pi.c3d").read_bytes())
    raw[1561] = 240
    path = tmp_path / "mutated.c3d"
    path.write_bytes(bytes(raw))
    try:
        data = read_mocap(path)
    except MocapFileError as exc:
        assert "mutated.c3d" in str(exc)
    else:
        assert data.n_markers == 26


def test_random_corruption_gives_data_or_a_mocap_error(tmp_path):
    raw = _small_c3d(tmp_path)
    rng = np.random.default_rng(5)
    path = tmp_path / "fuzz.c3d"
    outcomes = []
    for _ in range(12):
        buf = bytearray(raw)
        for i in rng.integers(512, 1024, size=3):  # the parameter section
            buf[int(i)] = int(rng.integers(0, 256))
        path.write_bytes(bytes(buf))
        try:
            outcomes.append(isinstance(read_mocap(path), MocapData))
        except MocapFileError:
            outcomes.append(False)
    assert len(outcomes) == 12


TRC_HEAD = ("PathFileType\t4\t(X/Y/Z)\tx.trc\n"
            "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n"
            "100\t100\t{frames}\t2\tmm\n"
            "Frame#\tTime\tA\t\t\tB\t\t\n"
            "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\n")


@pytest.mark.parametrize("rows, frames, message", [
    (["1\t0.00\t1\t2\t3\t4\t5\t6"], 2, "declares 2 frames but the file holds 1"),
    (["1\t0.00\t1\t2\t3\t4\t5"], 1, "ends inside a marker"),
    (["1\t0.00\t1\t2\t3\t4\tx\t6"], 1, "not a number"),
    (["1\t0.00\t1\t2\t3\t4\t5\t6", "2\t0.01\t1\t2\t3\t4\t5\t6"], 1, "more data rows"),
])
def test_trc_truncated_or_garbled(tmp_path, rows, frames, message):
    path = tmp_path / "x.trc"
    path.write_text(TRC_HEAD.format(frames=frames) + "\n".join(rows) + "\n")
    with pytest.raises(MocapFileError, match=message):
        read_mocap(path)


def test_trc_last_row_cut_off_and_partial_marker(tmp_path):
    path = tmp_path / "x.trc"
    path.write_text(TRC_HEAD.format(frames=2) + "1\t0.00\t1\t2\t3\t4\t5\t6\n2\t0.01\t1\t2\t3")
    with pytest.raises(MocapFileError, match="cut off"):
        read_mocap(path)
    # An empty coordinate makes the whole marker missing; a short row with a line end is tolerated.
    path.write_text(TRC_HEAD.format(frames=2) + "1\t0.00\t1\t\t3\t4\t5\t6\n2\t0.01\t1\t2\t3\n")
    data = read_mocap(path)
    assert np.isnan(data.points[0, 0]).all() and np.isfinite(data.points[0, 1]).all()
    assert np.isnan(data.points[1, 1]).all()
    assert [(w.code, w.values["rows"]) for w in data.warnings] == [("mocap.short_rows", 1)]

"""Round trips read back by other readers with every frame and column: ezc3d, the ``c3d`` package
(past 65,535 frames too) and a strict OpenSim-style TRC parser; repeated C3D labels told apart."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import real_data_path
from saddlescope.io.mocap import read_mocap, write_c3d, write_trc
from saddlescope.io.mocap.c3d import distinct_labels


def _tracks(n_frames, n_markers=3, seed=0):
    points = np.random.default_rng(seed).normal(0.0, 500.0, (n_frames, n_markers, 3))
    points[2, 1] = np.nan
    points[-1, -1] = np.nan  # the last marker of the last row: the case OpenSim refused
    points[:, -1][5::7] = np.nan
    return [f"M{j + 1}" for j in range(n_markers)], points


def opensim_trc(path):
    """A strict TRC reader as OpenSim's TRCFileAdapter: each data row, trimmed, must hold Frame#, Time
    and 3 x NumMarkers cells (RowLengthMismatch otherwise); cells are numbers or NaN."""
    lines = path.read_text().splitlines()
    header = dict(zip(lines[1].split("\t"), lines[2].split("\t"), strict=True))
    n_frames, n_markers = int(header["NumFrames"]), int(header["NumMarkers"])
    names = [s for s in lines[3].strip().split("\t")[2:] if s]
    assert len(names) == n_markers
    rows = [ln.strip() for ln in lines[5:] if ln.strip()]
    assert len(rows) == n_frames
    out = np.empty((n_frames, n_markers, 3))
    for i, row in enumerate(rows):
        cells = row.split("\t")
        if len(cells) != 2 + 3 * n_markers:
            raise ValueError(f"RowLengthMismatch: row {i + 1} has {len(cells)} columns, expected {2 + 3 * n_markers}")
        out[i] = np.array([float(c) for c in cells[2:]]).reshape(n_markers, 3)  # float('') raises
    return names, out


def test_trc_rows_carry_every_column_for_opensim(tmp_path):
    labels, points = _tracks(40)
    path = write_trc(tmp_path / "t.trc", labels, points, 100.0)
    names, back = opensim_trc(path)
    assert names == labels
    np.testing.assert_array_equal(np.isnan(back), np.isnan(points))
    np.testing.assert_allclose(back, points, atol=1e-6, equal_nan=True)
    ours = read_mocap(path)
    np.testing.assert_allclose(ours.points, points, atol=1e-6, equal_nan=True)


def test_c3d_round_trip_read_by_ezc3d_and_the_c3d_package(tmp_path):
    ezc3d = pytest.importorskip("ezc3d")
    c3d = pytest.importorskip("c3d", reason="the c3d package (pip install c3d; in the test extras)")
    labels, points = _tracks(50)
    path = write_c3d(tmp_path / "t.c3d", labels, points, 120.0, descriptions=["a", "b", "c"])
    e = ezc3d.c3d(str(path))
    xyz = np.transpose(e["data"]["points"][:3], (2, 1, 0))
    invalid = e["data"]["meta_points"]["residuals"][0].T < 0
    np.testing.assert_array_equal(invalid, np.isnan(points).any(axis=2))
    np.testing.assert_allclose(xyz[~invalid], points[~invalid], atol=1e-3)
    assert list(e["parameters"]["POINT"]["LABELS"]["value"]) == labels
    with path.open("rb") as fh:
        reader = c3d.Reader(fh)
        frames = [pts for _, pts, _ in reader.read_frames()]
        assert [s.strip() for s in reader.point_labels] == labels
    got = np.stack(frames)  # (F, M, 5): x, y, z, residual, cameras
    assert got.shape[0] == 50
    np.testing.assert_array_equal(got[..., 3] < 0, np.isnan(points).any(axis=2))
    np.testing.assert_allclose(got[..., :3][~invalid], points[~invalid], atol=1e-3)
    assert read_mocap(path).descriptions == ("a", "b", "c")


@pytest.mark.slow
def test_c3d_past_65535_frames_every_reader_gets_every_frame(tmp_path):
    ezc3d = pytest.importorskip("ezc3d")
    c3d = pytest.importorskip("c3d", reason="the c3d package (pip install c3d; in the test extras)")
    n = 70_001
    labels, points = _tracks(n, n_markers=2)
    path = write_c3d(tmp_path / "long.c3d", labels, points, 200.0)
    e = ezc3d.c3d(str(path))
    assert e["data"]["points"].shape[2] == n
    assert e["data"]["points"][0, 0, -1] == pytest.approx(points[-1, 0, 0], abs=1e-3)
    with path.open("rb") as fh:
        reader = c3d.Reader(fh)
        assert reader.frame_count == n
        count, last = 0, None
        for frame in reader.read_frames():
            count, last = count + 1, frame
    assert count == n and last[1][0, 0] == pytest.approx(points[-1, 0, 0], abs=1e-3)
    ours = read_mocap(path)
    assert ours.n_frames == n
    np.testing.assert_array_equal(np.isnan(ours.points), np.isnan(points))


def test_repeated_labels_get_their_descriptions_or_rank():
    labels, warnings = distinct_labels(["A", "K", "K", "B"], ["x", "Knee", "Knee medial", "y"])
    assert labels == ("A", "K (Knee)", "K (Knee medial)", "B")
    assert [w.code for w in warnings] == ["mocap.repeated_labels"] and "K" in warnings[0].detail
    labels, _ = distinct_labels(["K", "K"], ["", ""])
    assert labels == ("K#1", "K#2")
    assert distinct_labels(["A", "B"]) == (("A", "B"), ())


@pytest.mark.realdata
def test_gait_c3d_repeated_labels_warned_and_told_apart():
    data = read_mocap(real_data_path("c3d", "Gait.c3d"))
    assert any("RKNE, RANK, LKNE, LANK, RFOO, LFOO" in w.detail for w in data.warnings)
    assert "RKNE (R.Knee)" in data.labels and "RKNE (R.Knee.Medial)" in data.labels
    assert len(set(data.labels)) == data.n_markers == 33
    assert data.up_axis == "+z"
    with pytest.raises(Exception, match=r"used by 2 markers; choose one of 'RKNE \(R.Knee\)'"):
        data.marker("RKNE")
    medial = data.marker("RKNE (R.Knee.Medial)")
    assert math.isfinite(float(np.nanmedian(medial[:, 2])))

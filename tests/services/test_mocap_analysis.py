"""A motion-capture file analysed as a ride: a synthetic triad in a TRC in metres, y up (OpenSim's
convention), its point given by offsets: the stride and the speed come back."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.io.mocap import write_trc
from saddlescope.services.analysis.mocap import analyze_mocap_file, parse_up_axis


def _walking_triad_m(tmp_path, *, speed_m_s=1.6, stride_s=0.9, rate_hz=100.0, seconds=5.0):
    t = np.arange(int(seconds * rate_hz)) / rate_hz
    w = 2 * np.pi / stride_s
    body = np.array([[0.25, 0.0, 0.1], [-0.25, 0.02, 0.1], [0.0, -0.08, -0.12]])  # x forward, y up, z side
    centre = np.stack([speed_m_s * t + 0.01 * np.sin(2 * w * t), 1.2 + 0.02 * np.cos(2 * w * t) + 0.005 * np.cos(w * t),
                       0.01 * np.sin(w * t)], axis=1)
    points = centre[:, None, :] + body[None]
    points += np.random.default_rng(3).normal(0, 0.0003, points.shape)
    return write_trc(tmp_path / "triad.trc", ["A", "B", "C"], points, rate_hz, units="m")


def test_a_trc_in_metres_with_y_up_gives_its_stride_and_speed(tmp_path):
    path = _walking_triad_m(tmp_path)
    doc = analyze_mocap_file(path, ["A", "B", "C"], offset_mm=(0.0, 50.0, 0.0), gait="walk")
    assert doc["source"]["up"] == "+y" and "OpenSim" in doc["source"]["up_reason"]
    assert doc["source"]["units"] == "m"
    assert doc["period_s"] == pytest.approx(0.9, rel=0.02)
    assert doc["indicators"]["vel_x_avg_kmh"] / 3.6 == pytest.approx(1.6, rel=0.02)
    assert doc["motion_frame"]["gravity_source"] == "lab_vertical"
    codes = [f["code"] for f in doc["quality"]["findings"]]
    assert "gravity.from_hint" not in codes and "gravity.lab_vertical" in codes
    assert not any("no plumb line" in f for f in doc["quality"]["flags"])


def test_bad_choices_are_refused_with_the_reason(tmp_path):
    path = _walking_triad_m(tmp_path, seconds=3.0)
    with pytest.raises(InputError, match="three different markers"):
        analyze_mocap_file(path, ["A", "A", "C"])
    with pytest.raises(InputError, match="no marker labelled 'D'"):
        analyze_mocap_file(path, ["A", "B", "D"])
    with pytest.raises(InputError, match="one of the three markers"):
        analyze_mocap_file(path, ["A", "B", "C"], point="A")
    with pytest.raises(InputError, match="vertical axis"):
        parse_up_axis("up")
    assert parse_up_axis("-Y") == (1, -1.0)

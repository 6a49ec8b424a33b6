"""The synthetic arena's truth.json against its own exact geometry: result structure, saddle, extras."""

from __future__ import annotations

import json

import numpy as np
import pytest

from saddlescope.arena import (
    build_scene,
    build_truth,
    check_result_structure,
    saddle_truth_at,
)
from saddlescope.core.errors import InputError


@pytest.fixture(scope="module")
def scene():
    return build_scene(gait="canter", seed=7, calibration_poses=8)


@pytest.fixture(scope="module")
def truth(scene):
    return json.loads(json.dumps(build_truth(scene)))  # exactly what truth.json holds


def test_truth_has_the_result_structure(truth):
    assert check_result_structure(truth) == []
    broken = json.loads(json.dumps(truth))
    del broken["indicators"]["vdv_y_wb"]
    broken["saddle"]["position_m"] = broken["saddle"]["position_m"][:-1]
    assert len(check_result_structure(broken)) == 2
    tr = truth["truth"]
    for key in (
        "markers_3d_mm",
        "marker_names",
        "motion_frame",
        "model",
        "saddle_acc_y_harmonics",
        "speed_kmh",
        "amplitude_y_m",
    ):
        assert key in tr
    assert truth["sync"]["motion"]["left"] == 0.0
    assert set(truth["sync"]) >= {"calibration", "plumb", "static", "motion", "freefall", "board_distance"}
    # window: two periods starting at a left frame
    assert truth["window"]["duration_s"] == pytest.approx(2 * truth["period_s"])
    assert truth["window"]["start_s"] * truth["fps"] == pytest.approx(round(truth["window"]["start_s"] * truth["fps"]))
    t = np.array(truth["saddle"]["t_s"])
    np.testing.assert_allclose(np.diff(t), 1 / truth["fps"])
    assert t[0] == pytest.approx(truth["window"]["start_s"])
    assert t[-1] < truth["window"]["start_s"] + truth["window"]["duration_s"]
    assert truth["indicators"]["stride_frequency_hz"] == pytest.approx(1 / truth["period_s"])


def test_truth_saddle_matches_markers_and_saddle_truth_at(scene, truth):
    tr = truth["truth"]
    mf = tr["motion_frame"]
    r_rm, origin = np.array(mf["R_rig_to_motion"]), np.array(mf["origin_mm"])
    np.testing.assert_allclose(r_rm @ r_rm.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r_rm), 1.0)
    np.testing.assert_allclose(r_rm[1], tr["gravity_rig"], atol=1e-12)  # motion y = gravity (down)
    names = tr["marker_names"]["motion"]
    s_idx = names.index("saddle")
    s_rig = np.array(tr["markers_3d_mm"]["motion"], dtype=float)[:, s_idx]
    t = np.array(truth["saddle"]["t_s"])
    k = np.round(t * truth["fps"]).astype(int)
    s_motion = (s_rig[k] - origin) @ r_rm.T / 1000.0
    np.testing.assert_allclose(s_motion, truth["saddle"]["position_m"], atol=1e-9)
    again = saddle_truth_at(truth, t)
    for key in ("position_m", "velocity_m_s", "acceleration_m_s2"):
        np.testing.assert_allclose(again[key], truth["saddle"][key], atol=1e-12)
    np.testing.assert_allclose(again["omega_rad_s"], truth["angular"]["omega_rad_s"], atol=1e-12)
    # origin is marker 1 at the first sample; x is the travel direction (net displacement per period)
    one = saddle_truth_at(truth, np.array([t[0], t[0] + truth["period_s"]]))
    d = one["position_m"][1] - one["position_m"][0]
    assert d[0] == pytest.approx(truth["truth"]["speed_m_s"] * truth["period_s"], rel=1e-9)
    np.testing.assert_allclose(d[1:], 0.0, atol=1e-12)
    # harmonics in truth reproduce the exact vertical acceleration at the window samples
    h = tr["saddle_acc_y_harmonics"]
    kk = np.arange(1, len(h["amplitudes_m_s2"]) + 1)
    ay = np.cos(np.multiply.outer(t, 2 * np.pi * h["f0_hz"] * kk) + h["phases_rad"]) @ np.array(h["amplitudes_m_s2"])
    np.testing.assert_allclose(ay, np.array(truth["saddle"]["acceleration_m_s2"])[:, 1], atol=1e-9)
    # amplitude_y = peak-to-peak of S's vertical displacement
    dense = saddle_truth_at(truth, t[0] + np.linspace(0, truth["period_s"], 2001))["position_m"][:, 1]
    assert np.ptp(dense) == pytest.approx(tr["amplitude_y_m"], abs=1e-6)


def test_saddle_truth_at_rejects_bad_input(truth):
    with pytest.raises(InputError):
        saddle_truth_at({"format": "x"}, np.array([0.0]))
    with pytest.raises(InputError):
        saddle_truth_at(truth, np.array([]))


def test_skin_motion_is_small_but_present(scene, truth):
    names = truth["truth"]["marker_names"]["motion"]
    m = np.array(truth["truth"]["markers_3d_mm"]["motion"], dtype=float)
    t = np.arange(m.shape[0]) / truth["fps"]
    rigid = scene.model.marker_positions(t, skin=False) @ scene.m_dir.T
    rigid_rig = scene.rig.world_to_rig_mm(rigid)
    dev = np.linalg.norm(m[:, :3] - rigid_rig[:, :3], axis=2)
    assert 0.3 < dev.max() < 8.0  # millimetres of skin motion on markers 1-3
    np.testing.assert_allclose(m[:, names.index("saddle")], rigid_rig[:, 3], atol=1e-9)  # S is rigid


def test_freefall_truth_is_free_fall(scene, truth):
    ff = truth["truth"]["freefall"]
    a, b = ff["flight_left_frames"]
    assert b - a + 1 >= 21
    p = np.array(truth["truth"]["markers_3d_mm"]["freefall"], dtype=float)[a : b + 1, 0]
    g = np.array(truth["truth"]["gravity_rig"])
    along = p @ g / 1000.0
    acc = np.diff(along, 2) * truth["fps"] ** 2
    np.testing.assert_allclose(acc, 9.81, rtol=1e-9)
    assert np.ptp(along) > 0.5  # thrown from the lower edge to the upper edge of the volume


def test_board_distance_truth(truth):
    bd = truth["truth"]["board_distance"]
    assert bd["distances_mm"]["AB"] == 500 and bd["distances_mm"]["AC"] == 500
    assert bd["distances_mm"]["AD"] == pytest.approx(707.107, abs=1e-3)
    assert len(bd["poses"]) == 3
    for pose in bd["poses"]:
        pts = {k: np.array(v) for k, v in pose["points_mm"].items()}
        assert np.linalg.norm(pts["A"] - pts["B"]) == pytest.approx(500, abs=1e-9)
        assert np.linalg.norm(pts["A"] - pts["D"]) == pytest.approx(707.1068, abs=1e-3)
        a, b = pose["still_left_frames"]
        assert b - a >= 10

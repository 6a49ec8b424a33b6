"""Motion reference frame (eq. 5.6-5.12) against a known rig-to-world pose."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.kinematics.frames import motion_frame, plumb_gravity, to_motion_frame, vectors_to_motion_frame


def _rotation(rx, ry, rz):
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


# World (= true motion frame): x travel, y down, z = x cross y. Rig = R_RW @ world + t_RW (mm).
R_RW = _rotation(0.15, -0.4, 0.05)
T_RW = np.array([300.0, -150.0, 7500.0])
PERIOD_S = 0.6
T = np.arange(0, 2 * PERIOD_S + 1e-9, 1 / 30)  # 37 samples: x(0) .. x(2T)


def _to_rig(world_mm):
    return world_mm @ R_RW.T + T_RW


def _marker_world_mm():
    w = 2 * np.pi / PERIOD_S
    return np.stack([4000 * T + 100, 800 + 120 * np.cos(w * T), 50 + 20 * np.sin(w * T)], axis=1)


def _plumb(n=20, swing_deg=0.5, seed=0):
    rng = np.random.default_rng(seed)
    top = np.tile([2000.0, -500.0, 1000.0], (n, 1))
    swing = np.deg2rad(swing_deg) * np.sin(np.linspace(0, 2 * np.pi, n, endpoint=False))
    bottom = top + 1000 * np.stack([np.sin(swing), np.cos(swing), np.zeros(n)], axis=1)
    return _to_rig(top) + rng.normal(0, 0.2, top.shape), _to_rig(bottom) + rng.normal(0, 0.2, top.shape)


def test_plumb_frame_recovers_the_world_axes():
    marker_rig = _to_rig(_marker_world_mm())
    top, bottom = _plumb()
    frame = motion_frame(marker_rig, plumb_top_mm=top, plumb_bottom_mm=bottom)
    assert frame.gravity_source == "plumb" and frame.warnings == ()
    # The rows of R are the world axes expressed in rig coordinates: R = R_RW^T.
    np.testing.assert_allclose(frame.R, R_RW.T, atol=2e-4)
    np.testing.assert_allclose(frame.R @ frame.R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(frame.R) == pytest.approx(1.0)
    motion_m = to_motion_frame(marker_rig, frame)
    expected_m = (_marker_world_mm() - _marker_world_mm()[0]) / 1000.0
    np.testing.assert_allclose(motion_m, expected_m, atol=2e-3)
    np.testing.assert_allclose(motion_m[0], 0.0, atol=1e-12)  # origin: the first marker position
    assert frame.angle_travel_gravity_deg == pytest.approx(90.0, abs=0.1)
    assert frame.diagnostics["plumb_length_mm"] == pytest.approx(1000.0, abs=1.0)


def test_gravity_is_orthogonalised_against_travel():
    # A plumb tilted 3 degrees towards the travel: x stays exactly the travel (eq. 5.8-5.9).
    marker_rig = _to_rig(_marker_world_mm())
    tilt = np.deg2rad(3.0)
    top = _to_rig(np.zeros(3))
    bottom = _to_rig(np.array([np.sin(tilt), np.cos(tilt), 0.0]) * 1000)
    frame = motion_frame(marker_rig, plumb_top_mm=top, plumb_bottom_mm=bottom)
    np.testing.assert_allclose(frame.R[0], R_RW[:, 0], atol=1e-12)
    np.testing.assert_allclose(frame.R[1], R_RW[:, 1], atol=1e-12)
    assert frame.angle_travel_gravity_deg == pytest.approx(87.0, abs=1e-9)
    assert frame.warnings == ()


def test_steep_ground_warns():
    marker_rig = _to_rig(_marker_world_mm())
    tilt = np.deg2rad(15.0)
    frame = motion_frame(marker_rig, plumb_top_mm=_to_rig(np.zeros(3)),
                         plumb_bottom_mm=_to_rig(np.array([np.sin(tilt), np.cos(tilt), 0.0]) * 1000))
    assert [w.code for w in frame.warnings] == ["gravity.tilted"]
    assert frame.warnings[0].values["off_perpendicular_deg"] == pytest.approx(15.0, abs=0.5)


def test_without_plumb_uses_hint_or_camera_down_with_a_warning():
    marker_rig = _to_rig(_marker_world_mm())
    frame = motion_frame(marker_rig, rig_down_hint=R_RW[:, 1] + np.array([0.01, 0.0, 0.0]))
    assert frame.gravity_source == "hint" and [w.code for w in frame.warnings] == ["gravity.from_hint"]
    np.testing.assert_allclose(frame.R[1], R_RW[:, 1], atol=0.02)
    frame = motion_frame(marker_rig)
    assert frame.gravity_source == "camera_down"
    assert [w.code for w in frame.warnings] == ["gravity.from_camera"]


def test_vectors_rotate_without_origin():
    marker_rig = _to_rig(_marker_world_mm())
    top, bottom = _plumb()
    frame = motion_frame(marker_rig, plumb_top_mm=top, plumb_bottom_mm=bottom)
    v = vectors_to_motion_frame(R_RW @ np.array([1000.0, 0.0, 0.0]), frame)
    np.testing.assert_allclose(v, [1.0, 0.0, 0.0], atol=1e-3)


def test_bad_inputs():
    still = np.tile([1.0, 2.0, 3.0], (10, 1))
    with pytest.raises(KinematicsError, match="travel"):
        motion_frame(still)
    with pytest.raises(KinematicsError, match="plumb"):
        plumb_gravity(np.full((5, 3), np.nan), np.zeros((5, 3)))
    marker_rig = _to_rig(_marker_world_mm())
    along = marker_rig[-1] - marker_rig[0]
    with pytest.raises(KinematicsError, match="travel direction"):
        motion_frame(marker_rig, plumb_top_mm=np.zeros(3), plumb_bottom_mm=along)
    with pytest.raises(InputError, match="shape"):
        motion_frame(np.zeros((4, 2)))


def test_travel_velocity_is_exact_for_a_window_that_is_not_whole_periods():
    from saddlescope.core.kinematics.frames import travel_velocity

    marker_rig = _to_rig(_marker_world_mm())
    window = marker_rig[:-3]  # 34 samples: not a whole number of periods
    naive = motion_frame(window)
    fitted = motion_frame(window, t_s=T[:-3], period_s=PERIOD_S)
    assert fitted.diagnostics["travel_method"] == "line_plus_series"
    np.testing.assert_allclose(fitted.travel_raw, R_RW[:, 0], atol=1e-9)
    assert np.degrees(np.arccos(naive.travel_raw @ R_RW[:, 0])) > 0.5  # eq. 5.7 tilts here
    velocity = travel_velocity(T, marker_rig, period_s=PERIOD_S)
    np.testing.assert_allclose(velocity, 4000 * R_RW[:, 0], atol=1e-6)


def test_travel_velocity_leaves_out_a_look_alike_followed_for_a_few_frames():
    from saddlescope.core.kinematics.frames import travel_velocity

    marker_rig = _to_rig(_marker_world_mm()).copy()
    marker_rig[1:4] += [400.0, -300.0, 250.0]  # a look-alike near the start, as on a wide-rig trot
    velocity = travel_velocity(T, marker_rig, period_s=PERIOD_S)
    np.testing.assert_allclose(velocity, 4000 * R_RW[:, 0], atol=1e-6)
    kept = travel_velocity(T, marker_rig, period_s=PERIOD_S, reject_sigma=None)
    assert np.degrees(np.arccos(kept @ R_RW[:, 0] / np.linalg.norm(kept))) > 0.5

"""Angular kinematics and the invisible saddle point against an analytic rigid motion."""

from __future__ import annotations

import re

import numpy as np
import pytest

from saddlescope.core.errors import KinematicsError
from saddlescope.core.kinematics import (
    VERSION_NAMES,
    alpha_versions,
    angular_kinematics,
    body_frame,
    omega_versions,
    saddle_body_coordinates,
    saddle_point_kinematics,
    singularity_index,
)

F0_HZ = 1.6


def _skew(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def _elementary(axis: int, angle, rate, accel):
    """R, R', R'' of a rotation about a fixed axis with angle(t): R' = θ' [e]x R etc."""
    e = np.zeros(3)
    e[axis] = 1.0
    K = _skew(e)
    n = angle.shape[0]
    R = np.eye(3) + np.sin(angle)[:, None, None] * K + (1 - np.cos(angle))[:, None, None] * (K @ K)
    dR = rate[:, None, None] * np.einsum("ij,fjk->fik", K, R)
    ddR = (accel[:, None, None] * np.einsum("ij,fjk->fik", K, R)
           + (rate**2)[:, None, None] * np.einsum("ij,fjk->fik", K @ K, R))
    assert R.shape == (n, 3, 3)
    return R, dR, ddR


def _angle(t, amp, phase, harmonic=1):
    w = 2 * np.pi * F0_HZ * harmonic
    return (amp * np.sin(w * t + phase), amp * w * np.cos(w * t + phase), -amp * w**2 * np.sin(w * t + phase))


def rigid_motion(t, *, roll=0.03, pitch=0.05, yaw=0.02, body=None, extra=None):
    """Analytic rigid motion: R = Rz(yaw) Ry(roll-ish) Rx(...) from Fourier angles, Fourier translation.

    Returns positions, velocities, accelerations of the body points (F, P, 3), omega, alpha (F, 3).
    """
    mul = np.matmul
    A, dA, ddA = _elementary(2, *_angle(t, pitch, 0.4))          # about z (lateral): pitch
    B, dB, ddB = _elementary(1, *_angle(t, yaw, 1.1, 2))        # about y (vertical): yaw
    C, dC, ddC = _elementary(0, *_angle(t, roll, -0.7))          # about x (travel): roll
    R = mul(mul(A, B), C)
    dR = mul(mul(dA, B), C) + mul(mul(A, dB), C) + mul(mul(A, B), dC)
    ddR = (mul(mul(ddA, B), C) + mul(mul(A, ddB), C) + mul(mul(A, B), ddC)
           + 2 * (mul(mul(dA, dB), C) + mul(mul(dA, B), dC) + mul(mul(A, dB), dC)))
    w = 2 * np.pi * F0_HZ
    p = np.stack([4.0 * t + 0.02 * np.sin(w * t), 0.9 + 0.12 * np.cos(w * t) + 0.03 * np.sin(2 * w * t),
                  0.02 * np.sin(w * t + 0.3)], axis=1)
    dp = np.stack([4.0 + 0.02 * w * np.cos(w * t), -0.12 * w * np.sin(w * t) + 0.06 * w * np.cos(2 * w * t),
                   0.02 * w * np.cos(w * t + 0.3)], axis=1)
    ddp = np.stack([-0.02 * w**2 * np.sin(w * t),
                    -0.12 * w**2 * np.cos(w * t) - 0.12 * w**2 * np.sin(2 * w * t),
                    -0.02 * w**2 * np.sin(w * t + 0.3)], axis=1)
    Wx = np.einsum("fij,fkj->fik", dR, R)  # [ω]x = R' R^T
    omega = np.stack([Wx[:, 2, 1], Wx[:, 0, 2], Wx[:, 1, 0]], axis=1)
    Ax = np.einsum("fij,fkj->fik", ddR, R) + np.einsum("fij,fkj->fik", dR, dR)  # d/dt(R' R^T)
    alpha = np.stack([Ax[:, 2, 1], Ax[:, 0, 2], Ax[:, 1, 0]], axis=1)
    pts = body if body is not None else THESIS_LAYOUT
    pos = np.einsum("fij,pj->fpi", R, pts) + p[:, None]
    vel = np.einsum("fij,pj->fpi", dR, pts) + dp[:, None]
    acc = np.einsum("fij,pj->fpi", ddR, pts) + ddp[:, None]
    return pos, vel, acc, omega, alpha


# Markers in a near-horizontal row on the horse's left side (x travel, y down, z lateral), with
# the saddle point S above and inside; the markers' plane normal is close to z.
THESIS_LAYOUT = np.array([[-0.25, 0.00, 0.30], [0.02, -0.06, 0.31], [0.28, 0.03, 0.29]])
SADDLE = np.array([0.0, -0.25, 0.0])
T = np.arange(0, 1.25, 1 / 30)


def test_rigid_motion_helper_is_consistent():
    # The analytic ω must reproduce the point velocities: v_P - v_O = ω x (r_P - r_O).
    pos, vel, acc, omega, alpha = rigid_motion(T)
    d = pos[:, 1] - pos[:, 0]
    np.testing.assert_allclose(vel[:, 1] - vel[:, 0], np.cross(omega, d), atol=1e-12)
    np.testing.assert_allclose(acc[:, 1] - acc[:, 0],
                               np.cross(alpha, d) + np.cross(omega, np.cross(omega, d)), atol=1e-12)


def test_six_versions_agree_with_known_omega_away_from_singularity():
    # A layout whose plane normal is along the travel axis while ω is mostly roll: well conditioned.
    layout = np.array([[0.0, -0.2, -0.2], [0.0, 0.25, -0.1], [0.05, 0.0, 0.3]])
    pos, vel, acc, omega, alpha = rigid_motion(T, roll=0.08, pitch=0.01, yaw=0.01, body=layout)
    sing = singularity_index(pos, omega)
    # ω's direction swings as the roll rate passes zero; most of the time it is near n.
    assert np.mean(sing > 0.5) > 0.8
    away = sing > 0.3
    w_ver, cond = omega_versions(pos, vel)
    assert w_ver.shape == (T.size, 6, 3) and len(VERSION_NAMES) == 6
    np.testing.assert_allclose(w_ver[away], np.broadcast_to(omega[away, None], w_ver[away].shape),
                               atol=1e-9, rtol=1e-8)
    a_ver, _ = alpha_versions(pos, acc, omega)
    np.testing.assert_allclose(a_ver[away], np.broadcast_to(alpha[away, None], a_ver[away].shape),
                               atol=1e-7, rtol=1e-8)
    ang = angular_kinematics(pos, vel, acc)
    np.testing.assert_allclose(ang.omega_rad_s, omega, atol=1e-10)
    np.testing.assert_allclose(ang.alpha_rad_s2, alpha, atol=1e-8)
    np.testing.assert_allclose(ang.omega_versions_mean, omega, atol=1e-9)
    assert np.nanmax(ang.omega_spread) < 1e-8
    assert "rotation.near_singularity" not in [f.code for f in ang.flags]


def test_singularity_index_flags_the_thesis_layout_for_roll_not_for_pitch():
    # Thesis 8.4.1: ω roughly along x (roll) and n roughly along z -> |n . ω̂| near 0.
    pos, vel, acc, omega_roll, _ = rigid_motion(T, roll=0.08, pitch=0.005, yaw=0.005)
    roll_index = singularity_index(pos, omega_roll)
    n = np.median(np.abs(np.cross(pos[:, 0] - pos[:, 1], pos[:, 0] - pos[:, 2])), axis=0)
    assert np.argmax(n) == 2  # the thesis layout's normal is lateral (z)
    ang = angular_kinematics(pos, vel, acc)
    assert np.median(roll_index) < 0.2
    assert "rotation.near_singularity" in [f.code for f in ang.flags]
    assert ang.excluded.any()
    said = [f.detail for f in ang.flags if f.code == "rotation.versions_excluded"]
    assert [f[0] for f in said] == ["ω", "α"]  # one line each, listing the share per version
    assert re.search(r"ω\^\d,ver\d \d+%", said[0])
    # Least squares over the pairs is unaffected by the singularity.
    np.testing.assert_allclose(ang.omega_lsq, omega_roll, atol=1e-10)
    # Pitch (about the lateral axis, along n) is far from the singularity for the same layout.
    pos_p, vel_p, acc_p, omega_pitch, _ = rigid_motion(T, roll=0.003, pitch=0.08, yaw=0.003)
    assert np.median(singularity_index(pos_p, omega_pitch)) > 0.8


def test_versions_are_fragile_near_singularity_but_least_squares_is_not():
    rng = np.random.default_rng(3)
    pos, vel, acc, omega, _ = rigid_motion(T, roll=0.08, pitch=0.005, yaw=0.005)
    noisy_v = vel + rng.normal(0, 0.002, vel.shape)  # 2 mm/s velocity noise
    ang = angular_kinematics(pos, noisy_v, acc)
    err_lsq = np.median(np.linalg.norm(ang.omega_lsq - omega, axis=1))
    w_ver, _ = omega_versions(pos, noisy_v)
    err_ver = np.median(np.linalg.norm(w_ver - omega[:, None], axis=2))
    assert err_lsq < 0.05
    assert err_ver > 3 * err_lsq


def test_saddle_point_kinematics_match_known_rigid_motion():
    body = np.vstack([THESIS_LAYOUT, SADDLE])
    pos, vel, acc, omega, alpha = rigid_motion(T, roll=0.04, pitch=0.06, yaw=0.02, body=body)
    markers = pos[:, :3]
    # Static shot: the body at another pose (frame 7) with S visible.
    r_bs = saddle_body_coordinates(markers[7], pos[7, 3])
    ang = angular_kinematics(markers, vel[:, :3], acc[:, :3])
    s = saddle_point_kinematics(markers, vel[:, :3], acc[:, :3], ang, r_bs)
    np.testing.assert_allclose(s.position_m, pos[:, 3], atol=1e-9)
    np.testing.assert_allclose(s.velocity_m_s, vel[:, 3], atol=1e-6)
    np.testing.assert_allclose(s.acceleration_m_s2, acc[:, 3], atol=1e-6)
    assert np.max(s.velocity_spread) < 1e-9 and np.max(s.acceleration_spread) < 1e-6
    assert s.velocity_per_marker.shape == (T.size, 3, 3)


def test_body_frame_is_a_rotation():
    pos, *_ = rigid_motion(T)
    R = body_frame(pos)
    identity = np.broadcast_to(np.eye(3), R.shape)
    np.testing.assert_allclose(np.einsum("fji,fjk->fik", R, R), identity, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)


def test_collinear_markers_raise():
    line = np.array([[0.0, 0.0, 0.3], [0.25, 0.001, 0.3], [0.5, 0.0, 0.3]])
    pos, vel, acc, *_ = rigid_motion(T, body=line)
    with pytest.raises(KinematicsError, match="collinear"):
        angular_kinematics(pos, vel, acc)
    with pytest.raises(KinematicsError, match="collinear"):
        saddle_body_coordinates(line, SADDLE)


def test_missing_static_saddle_raises():
    with pytest.raises(KinematicsError, match="saddle marker"):
        saddle_body_coordinates(THESIS_LAYOUT, np.array([np.nan, 0.0, 0.0]))


def test_stages_chain_recovers_saddle_acceleration():
    """Rig tracks -> period -> window -> motion frame -> registration -> fits -> angular -> S."""
    from saddlescope.core.kinematics.fitting import fit_marker_kinematics
    from saddlescope.core.kinematics.frames import motion_frame, to_motion_frame
    from saddlescope.core.kinematics.period import analysis_window, estimate_period
    from saddlescope.core.kinematics.registration import marker_model, register_rigid

    c, s = np.cos(0.5), np.sin(0.5)
    R_rw = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])  # rig <- world (world = true motion frame)

    def to_rig_mm(p_m):
        return (p_m * 1000.0) @ R_rw.T + np.array([-2000.0, 300.0, 8000.0])

    t = np.arange(0, 3.0, 1 / 30)
    body = np.vstack([THESIS_LAYOUT, SADDLE])
    pos, vel, acc, omega, _ = rigid_motion(t, roll=0.04, pitch=0.06, yaw=0.02, body=body)
    rig = to_rig_mm(pos[:, :3])
    static = to_rig_mm(rigid_motion(np.array([0.3]), roll=0.0, pitch=0.0, yaw=0.0, body=body)[0][0])
    period, _ = estimate_period(t, rig)
    assert period == pytest.approx(1 / F0_HZ, rel=1e-3)
    start, stop = analysis_window(t, np.ones(t.size, bool), period)
    frame = motion_frame(rig[start:stop + 1, 0], plumb_top_mm=to_rig_mm(np.zeros(3)),
                         plumb_bottom_mm=to_rig_mm(np.array([0.0, 1.0, 0.0])), t_s=t[start:stop + 1],
                         period_s=period)
    np.testing.assert_allclose(frame.R @ R_rw, np.eye(3), atol=1e-5)
    model = to_motion_frame(marker_model(static[:3]), frame)
    reg = register_rigid(to_motion_frame(rig[start:stop], frame), model)
    kin = fit_marker_kinematics(t[start:stop], reg.registered, period_s=period, extra_orders=3,
                                x_model="fourier")
    ang = angular_kinematics(reg.registered, kin.velocity_m_s, kin.acceleration_m_s2)
    r_bs = saddle_body_coordinates(model, to_motion_frame(static[3], frame))
    sk = saddle_point_kinematics(reg.registered, kin.velocity_m_s, kin.acceleration_m_s2, ang, r_bs)
    true_acc = acc[start:stop, 3]  # world axes = motion axes
    rms_err = np.sqrt(np.mean((sk.acceleration_m_s2 - true_acc) ** 2, axis=0))
    assert np.all(rms_err < 0.02), rms_err  # against ~12 m/s² r.m.s. vertical acceleration
    np.testing.assert_allclose(ang.omega_rad_s, omega[start:stop], atol=1e-3)

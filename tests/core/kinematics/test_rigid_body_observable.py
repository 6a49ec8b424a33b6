"""Angular velocity over the observable axes only: markers near a line leave rotation about it unseen."""

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.core.kinematics.rigid_body import angular_kinematics, unobservable_axis, weak_axis_gain


def _row_motion(roll_amp: float, skin_mm: float, rng):
    """Three markers in a near-horizontal row along x (heights differ by 4 cm), pitching and rolling."""
    t = np.linspace(0, 1.2, 60)
    f = 1.6
    model = np.array([[0.0, 0.0, 0.0], [0.2, 0.04, 0.0], [0.4, 0.01, 0.0]])
    pitch = 0.05 * np.sin(2 * np.pi * f * t)
    roll = roll_amp * np.sin(2 * np.pi * f * t + 0.4)
    dp = 0.05 * 2 * np.pi * f * np.cos(2 * np.pi * f * t)
    dr = roll_amp * 2 * np.pi * f * np.cos(2 * np.pi * f * t + 0.4)
    omega = np.stack([dr, np.zeros_like(t), dp], axis=1)  # small angles: roll about x, pitch about z
    r = np.empty((len(t), 3, 3))
    v = np.empty_like(r)
    for k in range(len(t)):
        cz, sz, cx, sx = np.cos(pitch[k]), np.sin(pitch[k]), np.cos(roll[k]), np.sin(roll[k])
        R = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        r[k] = model @ R.T
        v[k] = np.cross(omega[k], r[k])
    v += rng.normal(0, skin_mm * 1e-3 * 2 * np.pi * f, v.shape)  # skin motion seen as velocity noise
    return r, v, np.zeros_like(v), omega


def test_row_of_markers_has_an_unobservable_axis_along_it():
    r, _, _, _ = _row_motion(0.0, 0.0, np.random.default_rng(0))
    axis, ratio = unobservable_axis(r, min_eig_ratio=0.05)
    assert ratio < 0.05
    assert abs(abs(axis[0]) - 1) < 0.05  # the row runs along x


def test_leaving_out_the_unobservable_axis_beats_full_least_squares_under_skin_motion():
    rng = np.random.default_rng(1)
    r, v, a, omega = _row_motion(0.02, 3.0, rng)
    full = angular_kinematics(r, v, a, method="lsq")
    obs = angular_kinematics(r, v, a, method="lsq_observable")
    err_full = np.sqrt(np.mean((full.omega_rad_s - omega) ** 2))
    err_obs = np.sqrt(np.mean((obs.omega_rad_s - omega) ** 2))
    assert err_obs < 0.5 * err_full
    assert "rotation.markers_in_line" in [f.code for f in obs.flags]
    # pitch, about a well-observed axis, is estimated as well as by full least squares
    pitch_obs = np.sqrt(np.mean((obs.omega_rad_s[:, 2] - omega[:, 2]) ** 2))
    pitch_full = np.sqrt(np.mean((full.omega_rad_s[:, 2] - omega[:, 2]) ** 2))
    assert pitch_obs <= 1.1 * pitch_full


def test_well_spread_markers_keep_every_axis():
    rng = np.random.default_rng(2)
    r, v, a, omega = _row_motion(0.02, 0.0, rng)
    r = r.copy()
    r[:, 1, 1] += 0.25  # a triangle, not a row: nothing to leave out
    res = angular_kinematics(r, np.cross(omega[:, None, :], r), a, method="lsq_observable")
    assert "rotation.markers_in_line" not in [f.code for f in res.flags]
    assert np.allclose(res.omega_rad_s, omega, atol=1e-9)


# --- lsq_wiener: the weak axis kept as far as the skin motion measured on the raw markers allows ---


def test_wiener_keeps_the_weak_axis_when_the_markers_move_rigidly():
    # No skin motion: roll about the row is small but exact, so nothing is shrunk (lsq_observable
    # would drop it).
    r, v, a, omega = _row_motion(0.02, 0.0, np.random.default_rng(4))
    res = angular_kinematics(r, v, a, method="lsq_wiener", raw=(r, v, a))
    assert np.allclose(res.omega_rad_s, omega, atol=1e-9)
    assert [f.values["omega_kept_pct"] for f in res.flags if f.code == "rotation.weak_axis"] == [pytest.approx(100)]
    dropped = angular_kinematics(r, v, a, method="lsq_observable")
    assert np.sqrt(np.mean((dropped.omega_rad_s[:, 0] - omega[:, 0]) ** 2)) > 0.1 * np.std(omega[:, 0])


def test_wiener_shrinks_a_weak_axis_that_skin_motion_swamps():
    errs = {"lsq": [], "lsq_observable": [], "lsq_wiener": []}
    for seed in range(8):
        r, v, a, omega = _row_motion(0.02, 3.0, np.random.default_rng(10 + seed))
        for method in errs:
            res = angular_kinematics(r, v, a, method=method, raw=(r, v, a))
            errs[method].append(np.sqrt(np.mean((res.omega_rad_s - omega) ** 2)))
    mean = {k: float(np.mean(e)) for k, e in errs.items()}
    # roll 100 times below its noise: Wiener keeps what a chance excess of noise power lets through
    # (the powers come from 60 frames), so it lands near dropping the axis, far below keeping it
    assert mean["lsq_wiener"] < 0.35 * mean["lsq"]
    assert mean["lsq_wiener"] < 1.6 * mean["lsq_observable"]


def test_wiener_gain_follows_the_roll_against_its_noise():
    # Large roll against little skin motion: kept nearly whole; no roll at all: shrunk away.
    r, v, a, _ = _row_motion(0.15, 0.3, np.random.default_rng(5))
    gain_w, _ = weak_axis_gain(r, v, a)
    assert gain_w > 0.9
    r, v, a, _ = _row_motion(0.0, 3.0, np.random.default_rng(6))
    gain_w, _ = weak_axis_gain(r, v, a)
    assert gain_w < 0.3


def test_wiener_needs_the_raw_markers():
    r, v, a, _ = _row_motion(0.02, 0.0, np.random.default_rng(7))
    with pytest.raises(InputError, match="raw"):
        angular_kinematics(r, v, a, method="lsq_wiener")


def test_wiener_gain_survives_degenerate_raw_frames():
    # Raw (unregistered) markers may coincide or line up in a few frames (a look-alike taken for two
    # markers): those frames are left out of the gain, never a crash (LinAlgError before).
    r, v, a, _ = _row_motion(0.05, 0.5, np.random.default_rng(8))
    r, v, a = r.copy(), v.copy(), a.copy()
    r[:5] = r[:5, :1]  # three markers on one point
    r[5:10, 2] = 2 * r[5:10, 1] - r[5:10, 0]  # exactly on a line
    gain_w, gain_a = weak_axis_gain(r, v, a)
    assert 0.0 <= gain_w <= 1.0 and 0.0 <= gain_a <= 1.0
    r[:] = r[:, :1]  # every frame degenerate: nothing to keep
    assert weak_axis_gain(r, v, a) == (0.0, 0.0)


def test_a_wandering_roll_about_the_row_stays_out_of_the_saddle_position():
    """With the roll about the marker row dropped from ω and α (gain 0), S's position keeps the
    row's mean roll too: on the thesis rig each marker's straight depth path has its own slope, the
    registered markers rolled 0.2 rad in two strides and S, 0.3 m above the row, drifted 6 cm. With
    gain 1 the position is eq. 6.48 unchanged."""
    from dataclasses import replace

    from saddlescope.core.kinematics.saddle_point import saddle_point_kinematics

    rng = np.random.default_rng(3)
    r, v, a, _ = _row_motion(0.0, 0.0, rng)
    t = np.linspace(0, 1.2, 60)
    centroid = r.mean(axis=1, keepdims=True)
    drift = 0.2 * t / t[-1]  # spurious roll about the row (x), rad
    c, s = np.cos(drift), np.sin(drift)
    roll = np.zeros((len(t), 3, 3))
    roll[:, 0, 0], roll[:, 1, 1], roll[:, 1, 2], roll[:, 2, 1], roll[:, 2, 2] = 1, c, -s, s, c
    rolled = np.einsum("fij,fmj->fmi", roll, r - centroid) + centroid
    r_bs = np.array([0.1, -0.3, -0.07])
    ang = angular_kinematics(rolled, v, a, method="lsq")
    true_path = saddle_point_kinematics(r, v, a, ang, r_bs).position_m
    drifting = saddle_point_kinematics(rolled, v, a, ang, r_bs).position_m
    kept = saddle_point_kinematics(rolled, v, a, replace(ang, weak_axis_gain=(0.0, 0.0)), r_bs).position_m
    whole = saddle_point_kinematics(rolled, v, a, replace(ang, weak_axis_gain=(1.0, 1.0)), r_bs).position_m
    assert np.max(np.linalg.norm(drifting - true_path, axis=1)) > 0.03  # what eq. 6.48 alone gives
    steady = kept - true_path
    assert np.max(np.linalg.norm(steady - steady.mean(axis=0), axis=1)) < 0.002
    np.testing.assert_allclose(whole, drifting, atol=1e-12)

"""Rigid registration (Horn quaternion) against known rotations."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.kinematics.registration import layout_ratio, marker_model, register_rigid

MODEL_MM = np.array([[0.0, 0.0, 0.0], [500.0, 20.0, 0.0], [250.0, -150.0, 30.0]])


def _random_rotations(n, rng):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def test_recovers_known_rotations_exactly():
    rng = np.random.default_rng(0)
    R = _random_rotations(40, rng)
    t = rng.normal(0, 2000, (40, 3))
    measured = np.einsum("fij,mj->fmi", R, MODEL_MM) + t[:, None]
    reg = register_rigid(measured, MODEL_MM)
    np.testing.assert_allclose(reg.R, R, atol=1e-9)
    np.testing.assert_allclose(reg.t, t, atol=1e-6)
    np.testing.assert_allclose(reg.registered, measured, atol=1e-6)
    assert reg.valid.all() and np.max(reg.rms_residual) < 1e-9


def test_noise_is_made_rigid():
    rng = np.random.default_rng(1)
    R = _random_rotations(200, rng)
    measured = np.einsum("fij,mj->fmi", R, MODEL_MM) + rng.normal(0, 2.0, (200, 3, 3))
    reg = register_rigid(measured, MODEL_MM)
    # Registered markers keep the model's distances exactly.
    d_model = np.linalg.norm(MODEL_MM[1] - MODEL_MM[0])
    np.testing.assert_allclose(np.linalg.norm(reg.registered[:, 1] - reg.registered[:, 0], axis=1), d_model)
    # 9 coordinates, 6 pose parameters: expected squared residual per marker 2^2 * 3 * (9-6)/9.
    assert np.sqrt(np.mean(reg.rms_residual**2)) == pytest.approx(2.0, rel=0.15)
    angle = np.degrees(np.arccos(np.clip((np.einsum("fij,fij->f", reg.R, R) - 1) / 2, -1, 1)))
    # The roll about the long side is fixed by marker 3, ~150 mm off it: about 2 / 150 rad.
    assert np.median(angle) < 1.2


def test_missing_marker_makes_a_gap_with_three_markers():
    rng = np.random.default_rng(2)
    measured = np.einsum("fij,mj->fmi", _random_rotations(5, rng), MODEL_MM)
    measured[2, 1] = np.nan
    reg = register_rigid(measured, MODEL_MM)
    assert reg.valid.tolist() == [True, True, False, True, True]
    assert np.isnan(reg.R[2]).all() and np.isnan(reg.registered[2]).all() and np.isnan(reg.rms_residual[2])
    assert reg.n_markers.tolist() == [3, 3, 2, 3, 3]


def test_four_markers_register_with_one_missing():
    rng = np.random.default_rng(3)
    model = np.vstack([MODEL_MM, [[100.0, 300.0, -40.0]]])
    R = _random_rotations(3, rng)
    measured = np.einsum("fij,mj->fmi", R, model) + 10.0
    measured[1, 3] = np.nan
    reg = register_rigid(measured, model)
    assert reg.valid.all()
    np.testing.assert_allclose(reg.R, R, atol=1e-9)
    np.testing.assert_allclose(reg.registered[1, 3], R[1] @ model[3] + 10.0, atol=1e-6)  # filled in


def test_marker_model_median_and_errors():
    rng = np.random.default_rng(4)
    static = MODEL_MM + rng.normal(0, 0.5, (15, 3, 3))
    static[3, 0] = np.nan
    np.testing.assert_allclose(marker_model(static), MODEL_MM, atol=0.5)
    static[:, 2] = np.nan
    with pytest.raises(KinematicsError, match="marker 3 is not found"):
        marker_model(static)
    line = np.array([[0.0, 0.0, 0.0], [250.0, 1.0, 0.0], [500.0, 0.0, 0.0]])
    with pytest.raises(KinematicsError, match="collinear"):
        marker_model(line)


def test_layout_ratio_and_shapes():
    equilateral = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, np.sqrt(3) / 2, 0.0]])
    assert layout_ratio(equilateral) == pytest.approx(np.sqrt(3) / 2)
    with pytest.raises(InputError, match="markers"):
        register_rigid(np.zeros((4, 3, 3)), np.zeros((4, 3)))


def test_look_alikes_that_break_the_marker_distances_are_found():
    from saddlescope.core.kinematics.registration import broken_distance_samples

    rng = np.random.default_rng(5)
    n = 120
    body = np.array([[0.0, 0.0, 0.0], [200.0, 40.0, 10.0], [400.0, -5.0, 0.0]])
    t = np.arange(n) / 60
    xyz = body[None] + np.stack([3000 * t, 30 * np.sin(2 * np.pi * 2.8 * t), 0 * t], axis=1)[:, None, :]
    xyz += rng.normal(0.0, 1.0, xyz.shape)  # camera noise and skin: a few millimetres at most
    assert not broken_distance_samples(xyz).any()
    xyz[10:14, 1] += [900.0, -300.0, 50.0]  # one marker taken for a glint: that marker only
    xyz[40:43, 0] += [-1400.0, 200.0, 0.0]  # two wrong at once: the whole frame
    xyz[40:43, 2] += [800.0, 100.0, 20.0]
    xyz[70, 2] = np.nan  # a missing sample stays missing, and never counts as broken
    xyz[71, 2] = np.nan
    xyz[71, 0] += [0.0, 0.0, 600.0]  # with a marker missing, the one broken pair marks both of its markers
    drop = broken_distance_samples(xyz)
    expected = np.zeros((n, 3), dtype=bool)
    expected[10:14, 1] = True
    expected[40:43] = True
    expected[71, :2] = True
    np.testing.assert_array_equal(drop, expected)

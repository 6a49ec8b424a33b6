"""Invariance of the chain codes (issue 24): grid rotations, ties, the anchored walk's hysteresis."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from saddlescope.core.similarity import (
    chain_code_3d,
    closed_loop_chain,
    grid_walk,
    kabsch_align,
    noise_step,
    ride_strides,
)


def _rotations() -> list[np.ndarray]:
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            r = np.zeros((3, 3))
            r[range(3), perm] = signs
            if np.isclose(np.linalg.det(r), 1.0):
                out.append(r)
    return out


def test_corner_ties_give_the_same_chain_for_a_quarter_turn():
    # The example: fixed x, y, z order gave [2, 2] and, rotated 90 degrees about z, [2, 0].
    path = np.array([[0, 0, 0], [1, 1, 0], [2, 1, 0]], dtype=float)
    quarter = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    for walk in ("anchored", "nearest"):
        ref = chain_code_3d(path, step=1.0, walk=walk)
        assert np.array_equal(chain_code_3d(path @ quarter.T, step=1.0, walk=walk), ref)


@pytest.mark.slow
def test_lattice_walk_with_many_ties_is_the_same_under_the_24_grid_rotations():
    rng = np.random.default_rng(4)
    path = np.cumsum(rng.integers(-1, 2, size=(300, 3)), axis=0).astype(float)  # diagonal moves: ties
    for walk in ("anchored", "nearest"):
        ref = chain_code_3d(path, step=1.0, walk=walk)
        assert ref.size > 100
        for r in _rotations():
            assert np.array_equal(chain_code_3d(path @ r.T + 7.0, step=1.0, walk=walk), ref)


def test_anchored_walk_ignores_noise_below_a_step():
    rng = np.random.default_rng(0)
    still = rng.uniform(-0.24, 0.24, size=(5000, 3))  # two samples are never a full step apart
    dirs, _ = grid_walk(still, step=0.5)
    assert dirs.size == 0
    nearest, _ = grid_walk(still, step=0.5, walk="nearest")
    assert nearest.size > 1000  # snapping turns the same noise into thousands of steps


def test_still_marker_with_half_a_millimetre_of_noise_is_no_motion():
    rng = np.random.default_rng(1)
    still = rng.normal(0.0, 0.5, size=(3000, 3))  # mm, 30 strides of 100 samples
    strides = ride_strides(still, period_samples=100.0)
    assert not strides.moves
    step = noise_step([strides.mean], [strides.sigma_m])
    assert step >= 4 * 0.3  # the step follows the measured noise (resampling averages some away)
    assert closed_loop_chain(strides.mean, step=step).size == 0


def test_closed_loop_chain_does_not_depend_on_where_the_loop_starts():
    t = np.linspace(0.0, 2 * np.pi, 129)[:-1]
    loop = np.column_stack([np.cos(t), 0.52 * np.sin(2 * t + 0.2), 0.31 * np.sin(t)])
    step = 1 / 25
    ref = closed_loop_chain(loop, step=step)
    for start in (1, 45, 100):
        codes = closed_loop_chain(np.roll(loop, -start, axis=0), step=step)
        assert codes.size == ref.size
        # the same cyclic chain, read from another element
        doubled = np.r_[ref, ref]
        assert any(np.array_equal(doubled[k: k + ref.size], codes) for k in range(ref.size))


def test_kabsch_undoes_an_arbitrary_rotation():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(200, 3))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    aligned, rot, residual = kabsch_align(a, a @ q.T + 5.0)
    assert residual < 1e-9 and np.allclose(aligned, a)
    assert np.isclose(np.linalg.det(rot), 1.0)

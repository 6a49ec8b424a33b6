"""Tests of saddlescope.core.similarity: chain codes, Needleman-Wunsch, shape dissimilarity, DTW."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.core.similarity import (
    CODE_STILL,
    GAP,
    alignment_similarity,
    chain_code_3d,
    chain_to_path,
    codes_from_steps,
    default_step,
    dtw_distance_reference,
    grid_walk,
    maximal_matches,
    needleman_wunsch,
    nw_similarity,
    shape_dissimilarity,
    trajectory_similarity,
)


def _rotations() -> list[np.ndarray]:
    """The 24 proper rotations of the cube (signed permutation matrices with det +1)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            r = np.zeros((3, 3))
            r[range(3), perm] = signs
            if np.isclose(np.linalg.det(r), 1.0):
                out.append(r)
    return out


def _helix(n: int = 400) -> np.ndarray:
    t = np.linspace(0.0, 4 * np.pi, n)
    return np.column_stack([10 * np.cos(t), 10 * np.sin(t), 3 * t])


def _nw_brute(a, b, match, mismatch, gap) -> float:
    """Plain full-matrix Needleman-Wunsch score."""
    n, m = len(a), len(b)
    h = np.zeros((n + 1, m + 1))
    h[:, 0] = gap * np.arange(n + 1)
    h[0, :] = gap * np.arange(m + 1)
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            s = match if a[i - 1] == b[j - 1] else mismatch
            h[i, j] = max(h[i - 1, j - 1] + s, h[i - 1, j] + gap, h[i, j - 1] + gap)
    return float(h[n, m])


# ---------------------------------------------------------------------------------------- chain code


def test_square_loop_chain_code():
    # Steps +x x4, +y x4, -x x4, -y x4. First turn defines u (code 2); then -x = -u and -y = -u (4).
    square = np.array([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0], [0, 0, 0]], dtype=float)
    codes = chain_code_3d(square, step=1.0)
    assert codes.tolist() == [0, 0, 0, 2, 0, 0, 0, 4, 0, 0, 0, 4, 0, 0, 0]


def test_hand_made_3d_curve_and_reversal():
    # +x, +y, +z, +x: first turn 2; z = x cross y (1); x = y cross z (1).
    path = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 1, 1], [2, 1, 1]], dtype=float)
    assert chain_code_3d(path, step=1.0).tolist() == [2, 1, 1]
    # +x, +y, -x (= -u, 4), -x (0), +x (reversal, 5).
    path = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [-1, 1, 0], [0, 1, 0]], dtype=float)
    assert chain_code_3d(path, step=1.0).tolist() == [2, 4, 0, 5]
    # u survives a straight run and a reversal: +x, +y, +y, -y, +z gives 2, 0, 5 and then, with
    # u = +x and v = -y, u x v = -z, so +z = -(u x v): code 3.
    assert codes_from_steps([0, 2, 2, 3, 4]).tolist() == [2, 0, 5, 3]


def test_diagonal_moves_are_filled_in_the_order_the_line_crosses_the_planes():
    # From (0,0,0) to (3,1,0): the line crosses x = 0.5, x = 1.5, y = 0.5 (at t = 0.5), x = 2.5.
    dirs, seg = grid_walk(np.array([[0.0, 0, 0], [3.0, 1.0, 0.0]]), step=1.0, walk="nearest")
    assert dirs.tolist() == [0, 0, 2, 0]
    assert seg.tolist() == [0, 0, 0, 0]
    # The anchored walk steps at full steps: x = 1, 2, 3 and y = 1, the last two at once (t = 1);
    # the tie is ordered by the smallest chain, straight on first.
    dirs, seg = grid_walk(np.array([[0.0, 0, 0], [3.0, 1.0, 0.0]]), step=1.0)
    assert dirs.tolist() == [0, 0, 0, 2]


def test_helix_invariant_under_grid_rotations_and_translation():
    helix = _helix()
    ref = chain_code_3d(helix)
    assert ref.size > 100
    for r in _rotations():
        moved = helix @ r.T + np.array([5.3, -7.1, 100.25])
        assert np.array_equal(chain_code_3d(moved), ref)


def test_mirror_swaps_codes_1_and_3():
    # (Away from exact ties, whose order is chosen by a rule that mirrors do not keep.)
    helix = _helix()[:-1]
    ref = chain_code_3d(helix)
    assert np.any(ref == 1) or np.any(ref == 3)
    mirrored = chain_code_3d(helix * np.array([1.0, 1.0, -1.0]))
    swap = ref.copy()
    swap[ref == 1], swap[ref == 3] = 3, 1
    assert np.array_equal(mirrored, swap)


def test_chain_to_path_round_trip():
    codes = chain_code_3d(_helix())
    path = chain_to_path(codes)
    assert np.all(np.abs(np.diff(path, axis=0)).sum(axis=1) == 1)  # 6-connected unit steps
    assert np.array_equal(chain_code_3d(path.astype(float), step=1.0), codes)


def test_centred_grid_makes_a_closed_loop_independent_of_its_start():
    t = np.linspace(0.0, 2 * np.pi, 338)[:-1] + 0.1
    loop = np.column_stack([np.cos(t), 0.52 * np.sin(2 * t + 0.2), 0.31 * np.sin(t)])
    step = default_step(loop)
    centre = loop.mean(axis=0)  # of the open loop: the closing sample would weigh one point twice
    # The nearest-vertex walk has no memory: one lap is the same lattice loop from any start (the
    # anchored walk needs a lap to forget its start, see tests of closed_loop_chain).
    ref = chain_code_3d(np.vstack([loop, loop[:1]]), step=step, origin=centre, walk="nearest")
    ref_dirs, _ = grid_walk(np.vstack([loop, loop[:1]]), step=step, origin=centre, walk="nearest")
    for start in (45, 100, 250):
        rolled = np.roll(loop, -start, axis=0)
        closed = np.vstack([rolled, rolled[:1]])
        # The same closed lattice path, read from another vertex: a cyclic rotation of the steps.
        dirs, _ = grid_walk(closed, step=step, origin=centre, walk="nearest")
        shifts = [k for k in range(ref_dirs.size) if np.array_equal(np.roll(ref_dirs, -k), dirs)]
        assert len(shifts) == 1
        # Its chain code is the cyclic chain read from there, except before the first turn, where
        # u is still imaginary.
        k = shifts[0]
        cyclic = codes_from_steps(np.r_[ref_dirs, ref_dirs])[k: k + ref.size]
        codes = chain_code_3d(closed, step=step, origin=centre, walk="nearest")
        assert codes.size == ref.size
        assert np.count_nonzero(codes != cyclic) <= 1
        assert nw_similarity(codes, cyclic) > 0.99
    assert np.array_equal(chain_code_3d(loop, origin="mean", walk="nearest"),
                          chain_code_3d(loop, origin=centre, walk="nearest"))
    with pytest.raises(InputError, match="origin"):
        chain_code_3d(loop, origin="median")


def test_default_step_is_a_fiftieth_of_the_largest_extent():
    line = np.column_stack([np.linspace(0.0, 1.0, 200), np.zeros(200), np.zeros(200)])
    assert default_step(line) == pytest.approx(0.02)
    codes = chain_code_3d(line)
    assert codes.tolist() == [0] * 49  # 50 unit steps


def test_keep_still_marks_intervals_without_a_step():
    xyz = np.array([[0, 0, 0], [0.1, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [2.1, 0, 0], [3.0, 0, 0]])
    codes = chain_code_3d(xyz, step=1.0, keep_still=True)
    assert codes.tolist() == [CODE_STILL, 0, CODE_STILL, 0]
    assert chain_code_3d(xyz, step=1.0).tolist() == [0, 0]


@pytest.mark.parametrize("bad, fragment", [
    (np.zeros((1, 3)), "at least 2"),
    (np.array([[0.0, 0, 0], [np.nan, 1, 0], [1, 1, 1]]), "NaN"),
    (np.zeros((5, 2)), "(N, 3)"),
    (np.ones((5, 3)), "does not move"),
])
def test_chain_code_bad_input(bad, fragment):
    with pytest.raises(InputError, match=fragment.replace("(", r"\(").replace(")", r"\)")):
        chain_code_3d(bad)


def test_chain_code_bad_step():
    with pytest.raises(InputError, match="positive"):
        chain_code_3d(_helix(), step=0.0)


# ---------------------------------------------------------------------------------------- Needleman-Wunsch


def test_nw_dissertation_example():
    # Dissertation 3.2: match 1, mismatch 0, gap 0 gives 6, e.g. GAATTCAGTTA / GGA_TC_G__A.
    score, al_a, al_b = needleman_wunsch("GAATTCAGTTA", "GGATCGA", match=1, mismatch=0, gap=0)
    assert score == 6
    assert al_a == "GAATTCAGTTA"
    assert al_b == "GGA-TC-G--A"


def test_nw_hand_computed():
    # A/A (+1), C/- (-1), G/G (+1) = 1; any other alignment scores less.
    score, al_a, al_b = needleman_wunsch("ACG", "AG", match=1, mismatch=-1, gap=-1)
    assert score == 1
    assert (al_a, al_b) == ("ACG", "A-G")
    score, al_a, al_b = needleman_wunsch(np.array([0, 1, 2]), np.array([0, 2]))
    assert al_b.tolist() == [0, GAP, 2]


def test_nw_matches_brute_force_on_random_sequences():
    rng = np.random.default_rng(7)
    for _ in range(60):
        n, m = rng.integers(1, 25, size=2)
        a, b = rng.integers(0, 4, n), rng.integers(0, 4, m)
        match, mismatch, gap = int(rng.integers(0, 3)), -int(rng.integers(0, 3)), -int(rng.integers(0, 3))
        score, al_a, al_b = needleman_wunsch(a, b, match=match, mismatch=mismatch, gap=gap)
        assert score == _nw_brute(a, b, match, mismatch, gap)
        # The alignment spells the inputs and adds up to the score.
        assert np.array_equal(al_a[al_a != GAP], a) and np.array_equal(al_b[al_b != GAP], b)
        total = sum(gap if GAP in (x, y) else (match if x == y else mismatch)
                    for x, y in zip(al_a, al_b, strict=True))
        assert total == score
        # A band can only lose score.
        assert needleman_wunsch(a, b, match=match, mismatch=mismatch, gap=gap, band=1)[0] <= score


def test_nw_float_scores_and_default_band_on_long_similar_chains():
    rng = np.random.default_rng(3)
    a = rng.integers(0, 5, 300)
    b = np.delete(a, rng.choice(300, 20, replace=False))
    b[rng.random(b.size) < 0.1] = 0
    full = needleman_wunsch(a, b, match=1.5, mismatch=-0.25, gap=-0.75, band=400)[0]
    assert needleman_wunsch(a, b, match=1.5, mismatch=-0.25, gap=-0.75)[0] == pytest.approx(full)


def test_nw_similarity_identical_and_bad_input():
    a = np.array([0, 1, 2, 0, 0, 4])
    assert nw_similarity(a, a) == 1.0
    assert alignment_similarity("AC-", "A-G") == pytest.approx(1 / 3)
    with pytest.raises(InputError, match="empty"):
        needleman_wunsch(np.array([], dtype=int), a)
    with pytest.raises(InputError, match="negative"):
        needleman_wunsch(np.array([0, -1]), a)
    with pytest.raises(InputError, match="integer"):
        needleman_wunsch(np.array([0.5, 1.0]), a)


# ---------------------------------------------------------------------------------------- shape dissimilarity


def test_dissertation_worked_example_of_common_couples():
    a = np.array([int(c) for c in "41434"])
    b = np.array([int(c) for c in "222221432222214322222100200000400003100003000400031003004031034"])
    i, j, length, _ = maximal_matches(a, b, min_length=2)
    # (S, T) = (4143, 22222143), (4143, 2222214322222143), (41434, B): P = 143, 143, 34.
    found = list(zip(i.tolist(), j.tolist(), length.tolist(), strict=True))
    assert found == [(1, 5, 3), (1, 13, 3), (3, 61, 2)]
    d, couples = shape_dissimilarity(a, b, return_couples=True)
    # The second couple is dropped: its P lies inside the first one's (dissertation's chosen list).
    assert [(c["i"], c["j"]) for c in couples] == [(1, 5), (3, 61)]
    assert [c["nes"] for c in couples] == [2, 2] and [c["net"] for c in couples] == [2, 3]
    # eq. 1 for the first couple: |4 - 8| / 7 + (5 - 3) + Delta + 0, over m + n = 68 (eq. 2).
    assert couples[0]["d_prime"] == pytest.approx((4 / 7 + 2 + couples[0]["delta"]) / 68)
    assert 0 < d < 1


def test_shape_dissimilarity_orders_similar_before_different():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 6 * np.pi, 600)
    helix = np.column_stack([np.cos(t), np.sin(t), 0.1 * t])
    noisy = helix + rng.normal(0, 0.003, helix.shape)
    walk = np.cumsum(rng.normal(0, 0.03, (600, 3)), axis=0)
    step = default_step(helix, noisy, walk)
    ch, cn, cw = (chain_code_3d(x, step=step) for x in (helix, noisy, walk))
    assert shape_dissimilarity(ch, ch) == 0.0
    assert shape_dissimilarity(ch, cn) < shape_dissimilarity(ch, cw)
    assert nw_similarity(ch, cn) > nw_similarity(ch, cw)


def test_shape_dissimilarity_bad_input():
    with pytest.raises(InputError, match="empty"):
        shape_dissimilarity(np.array([CODE_STILL, CODE_STILL]), np.array([0, 1, 2]))
    with pytest.raises(InputError, match="outside"):
        shape_dissimilarity(np.array([0, 9]), np.array([0, 1, 2]))


# ---------------------------------------------------------------------------------------- DTW reference


def test_dtw_reference_hand_computed():
    # Squared costs [[0, 4], [1, 1], [4, 0]]; best path (0,0) (1,0)|(1,1) (2,1): 0 + 1 + 0 = 1.
    assert dtw_distance_reference([0.0, 1.0, 2.0], [0.0, 2.0]) == pytest.approx(1.0)
    x = np.random.default_rng(1).normal(size=(20, 3))
    assert dtw_distance_reference(x, x) == 0.0
    # window = 1 on equal lengths: only the diagonal, i.e. the Euclidean distance.
    y = x[::-1].copy()
    assert dtw_distance_reference(x, y, window=1) == pytest.approx(np.linalg.norm(x - y))
    assert dtw_distance_reference(x, y, window=3) <= dtw_distance_reference(x, y, window=1)


def test_dtw_reference_matches_full_matrix():
    rng = np.random.default_rng(5)
    for _ in range(20):
        n, m = rng.integers(1, 15, size=2)
        a, b = rng.normal(size=(n, 2)), rng.normal(size=(m, 2))
        cost = ((a[:, None, :] - b[None, :, :]) ** 2).sum(axis=2)
        acc = np.full((n + 1, m + 1), np.inf)
        acc[0, 0] = 0.0
        for i in range(1, n + 1):
            for j in range(1, m + 1):
                acc[i, j] = cost[i - 1, j - 1] + min(acc[i - 1, j - 1], acc[i - 1, j], acc[i, j - 1])
        assert dtw_distance_reference(a, b) == pytest.approx(np.sqrt(acc[n, m]))


def test_dtw_reference_bad_input():
    with pytest.raises(InputError, match="NaN"):
        dtw_distance_reference([0.0, np.nan], [0.0, 1.0])
    with pytest.raises(InputError, match="dimensions"):
        dtw_distance_reference(np.zeros((4, 3)), np.zeros((4, 2)))


# ---------------------------------------------------------------------------------------- combination


def test_trajectory_similarity_per_subset_and_window():
    rng = np.random.default_rng(2)
    t = np.linspace(0, 4 * np.pi, 400)
    m0 = np.column_stack([np.cos(t), np.sin(t), 0.1 * t])
    m1 = np.column_stack([np.cos(2 * t), 0.5 * np.sin(t), 0.2 * np.cos(t)])
    a = np.stack([m0, m1], axis=1)
    b = a.copy()
    b[:, 1] = np.cumsum(rng.normal(0, 0.05, (400, 3)), axis=0)  # marker 1 moves differently in B
    res = trajectory_similarity(a, b, markers={"same": [0], "other": [1], "both": [0, 1]}, window=200)
    assert [(w["start"], w["stop"]) for w in res["windows"]] == [(0, 200), (200, 400)]
    same, other, both = (res["subsets"][k] for k in ("same", "other", "both"))
    assert same["nw_similarity"] == 1.0 and same["shape_dissimilarity"] == 0.0 and same["dtw"] == 0.0
    assert other["nw_similarity"] < 0.9 and other["dtw"] > 1.0
    assert both["nw_similarity"] == pytest.approx((same["nw_similarity"] + other["nw_similarity"]) / 2)
    one = trajectory_similarity(m0, m0 + 5.0, window=(10, 300))
    assert one["subsets"]["all"]["nw_similarity"] == 1.0
    assert one["windows"][0]["markers"][0]["chain_length_a"] > 0


@pytest.mark.parametrize("kwargs, fragment", [
    ({"markers": [2]}, "names marker 2"),
    ({"window": 1}, "at least 2 samples"),
    ({"window": (50, 20)}, "not a range"),
    ({"step": -1.0}, "positive"),
])
def test_trajectory_similarity_bad_options(kwargs, fragment):
    xyz = np.stack([_helix(100), _helix(100) * 2], axis=1)
    with pytest.raises(InputError, match=fragment):
        trajectory_similarity(xyz, xyz, **kwargs)


def test_trajectory_similarity_bad_recordings():
    xyz = _helix(100)
    bad = xyz.copy()
    bad[10, 1] = np.nan
    with pytest.raises(InputError, match="recording B contains NaN"):
        trajectory_similarity(xyz, bad)
    with pytest.raises(InputError, match="at least 2"):
        trajectory_similarity(xyz[:1], xyz)
    with pytest.raises(InputError, match="markers"):
        trajectory_similarity(np.stack([xyz, xyz], axis=1), xyz)

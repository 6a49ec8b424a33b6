"""`saddlescope bench`: motion similarity, retrieval on synthetic rides and speed.

Rides are drawn from the synthetic arena's exact gait models (``arena.sample_gait``: one horse =
one seed, with its own stride shape, marker layout and skin sliding), *not rendered*: rendering and
analysing dozens of videos is far too slow for a benchmark, so the exact saddle-point and marker
tracks are sampled and realistic tracking noise is added (white, ``NOISE_MM`` per axis, as the
pipeline's triangulated markers show). Each horse and gait is recorded twice: a new noise seed, a
new start (any phase), another length and another speed (travel and stride rate, +-8 %).
"""

from __future__ import annotations

import time
from collections.abc import Hashable
from typing import TYPE_CHECKING

import numpy as np

from saddlescope.arena.gait import sample_gait
from saddlescope.core.similarity import chain_code_3d, default_step, dtw_distance, nw_similarity, shape_dissimilarity

if TYPE_CHECKING:
    from saddlescope.services.similarity.compare import RideSignature

__all__ = ["NOISE_MM", "synthetic_ride", "retrieval", "ranking_speed", "synthetic_recording", "recording_retrieval",
           "run_similarity_benchmarks"]

NOISE_MM = 1.0
FPS = 60.0
GAITS = ("walk", "sitting_trot", "canter")
# The motion frame of a result (x travel, y down, z = x cross y) from the arena's (x travel, y up).
_TO_MOTION = np.diag([1.0, -1.0, -1.0])


def synthetic_ride(horse: int, gait: str, recording: int, *, strides: float | None = None,
                   noise_mm: float = NOISE_MM) -> dict:
    """A result-like document of one recording of one horse's gait.

    It holds ``fps``, ``period_s``, ``saddle.position_m`` (N, 3) and ``markers.position_m`` (N, 3, 3), in m,
    motion frame.
    """
    model = sample_gait(gait, np.random.default_rng(1000 + horse), camera_side=1.0)
    rng = np.random.default_rng([horse, GAITS.index(gait) if gait in GAITS else 9, recording])
    pace = float(rng.uniform(0.92, 1.08))
    stride_hz = model.stride_hz * pace
    model = type(model)(**{**model.__dict__, "stride_hz": stride_hz, "speed_m_s": model.speed_m_s * pace})
    n_strides = float(rng.uniform(8.0, 14.0)) if strides is None else float(strides)
    t0 = float(rng.uniform(0.0, 5.0))
    t = t0 + np.arange(int(round(n_strides / stride_hz * FPS))) / FPS
    pts = model.marker_positions(t) @ _TO_MOTION.T
    pts = pts - pts[0, 0]
    pts = pts + rng.normal(0.0, noise_mm / 1e3, pts.shape)
    return {"fps": FPS, "period_s": 1.0 / stride_hz, "saddle": {"position_m": pts[:, 3]},
            "markers": {"names": ["M1", "M2", "M3"], "position_m": pts[:, :3]}}


def _auc(pos: np.ndarray, neg: np.ndarray) -> float:
    """Area under the ROC curve: P(a positive scores above a negative), ties counted half."""
    allv = np.concatenate([pos, neg])
    order = np.argsort(allv, kind="mergesort")
    ranks = np.empty(allv.size)
    ranks[order] = np.arange(1, allv.size + 1)
    for v in np.unique(allv):  # average ranks of ties
        hit = allv == v
        if hit.sum() > 1:
            ranks[hit] = ranks[hit].mean()
    return float((ranks[: pos.size].sum() - pos.size * (pos.size + 1) / 2) / (pos.size * neg.size))


def retrieval(*, horses: int = 6, gaits: tuple[str, ...] = GAITS, markers: str = "saddle") -> dict:
    """Every ride queried against all others: top-1 and ROC AUC per measure, side by side.

    Top-1: the most alike other ride is the other recording of the same horse and gait. AUC:
    similarity of the pairs of recordings of the same horse and gait against all pairs of different
    horses.
    """
    from saddlescope.services.similarity.compare import MEASURES, RANKING_MEASURE, compare_signatures, ride_signature

    keys = [(h, g, r) for h in range(horses) for g in gaits for r in (0, 1)]
    t0 = time.perf_counter()
    sigs = [ride_signature(synthetic_ride(h, g, r), markers=markers) for h, g, r in keys]
    n = len(keys)
    measures = [m for m in MEASURES if m != "shape_dissimilarity"]  # = 1 - shape_similarity
    sims = {m: np.full((n, n), np.nan) for m in measures}
    for i in range(n):  # every measure is symmetric (either ride's strides against the other's mean)
        for j in range(i + 1, n):
            res = compare_signatures(sigs[i], sigs[j])
            for m in measures:
                sims[m][i, j] = sims[m][j, i] = res["measures"][m]
    seconds = time.perf_counter() - t0
    partner = [keys.index((h, g, 1 - r)) for h, g, r in keys]
    iu, ju = np.triu_indices(n, 1)
    same = np.array([keys[i][:2] == keys[j][:2] for i, j in zip(iu, ju, strict=True)])
    other = np.array([keys[i][0] != keys[j][0] for i, j in zip(iu, ju, strict=True)])
    out: dict = {"rides": n, "horses": horses, "gaits": list(gaits), "markers": markers,
                 "noise_mm": NOISE_MM, "ranking_measure": RANKING_MEASURE, "seconds": seconds, "measures": {}}
    for m in measures:
        s = np.where(np.isnan(sims[m]), -np.inf, sims[m])
        top1 = float(np.mean([int(np.argmax(s[i])) == partner[i] for i in range(n)]))
        out["measures"][m] = {"top1": top1, "auc": _auc(sims[m][iu, ju][same], sims[m][iu, ju][other])}
    return out


def ranking_speed(n_rides: int = 1000) -> dict:
    """Seconds to put ``n_rides`` stored rides into stride phase once, and to rank them for one query."""
    from saddlescope.services.similarity.compare import rank_signatures, ride_signature

    docs = [synthetic_ride(k % 50, GAITS[k % 3], k // 50, strides=10.0) for k in range(n_rides + 1)]
    t0 = time.perf_counter()
    sigs: dict[Hashable, RideSignature] = {k: ride_signature(d) for k, d in enumerate(docs)}
    t1 = time.perf_counter()
    query = sigs.pop(0)
    rows = rank_signatures(query, sigs, top=10)
    t2 = time.perf_counter()
    return {"rides": n_rides, "precompute_s": t1 - t0, "query_s": t2 - t1, "total_s": t2 - t0,
            "top": [r["ride"] for r in rows[:3]]}


RECORDING_RATE_HZ = 100.0
RECORDING_NOISE_MM = 0.5


def _random_turn(rng: np.random.Generator) -> np.ndarray:
    """A random proper rotation (3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q * np.sign(np.linalg.det(q))


def synthetic_recording(subject: int, recording: int, *, gait: str = "sitting_trot") -> np.ndarray:
    """One motion-capture recording (N, 4, 3) mm at 100 Hz of one horse (the three markers and the saddle point).

    Another start, 2-6 cycles, speed +-5 %, 0.5 mm noise, a random rotation and a translation of the lab frame for
    every recording.
    """
    model = sample_gait(gait, np.random.default_rng(1000 + subject), camera_side=1.0)
    rng = np.random.default_rng([subject, 77, recording])
    pace = float(rng.uniform(0.95, 1.05))
    stride_hz = model.stride_hz * pace
    model = type(model)(**{**model.__dict__, "stride_hz": stride_hz, "speed_m_s": model.speed_m_s * pace})
    cycles = float(rng.uniform(2.0, 6.0))
    t = float(rng.uniform(0.0, 5.0)) + np.arange(int(round(cycles / stride_hz * RECORDING_RATE_HZ))) / RECORDING_RATE_HZ
    pts = model.marker_positions(t) * 1e3
    pts = pts @ _random_turn(rng).T + rng.uniform(-3000.0, 3000.0, 3)
    return pts + rng.normal(0.0, RECORDING_NOISE_MM, pts.shape)


def _pair_cost(sig_a, sig_b) -> tuple[float, float]:
    """Seconds of one ranking comparison of two recordings' signatures, and of one DTW of their arrays.

    The DTW is dtaidistance's over the two recordings' arrays (N, 3M); both times are the best of 5.
    """
    from dtaidistance import dtw_ndim

    from saddlescope.services.similarity.compare import RANKING_MEASURE, compare_recording_signatures

    flat_a = np.ascontiguousarray(sig_a.x.reshape(sig_a.x.shape[0], -1))
    flat_b = np.ascontiguousarray(sig_b.x.reshape(sig_b.x.shape[0], -1))
    ours, theirs = [], []
    for _ in range(5):
        t0 = time.perf_counter()
        compare_recording_signatures(sig_a, sig_b, only=RANKING_MEASURE)
        t1 = time.perf_counter()
        dtw_ndim.distance_fast(flat_a, flat_b)
        ours.append(t1 - t0)
        theirs.append(time.perf_counter() - t1)
    return min(ours), min(theirs)


def recording_retrieval(*, subjects: int = 8) -> dict:
    """Recordings (not ride documents) queried against each other, aligned in time and space.

    Every horse is recorded twice (:func:`synthetic_recording`); each recording is queried against
    all others: top-1 is the other recording of the same horse. A copy of the first recording
    cropped by a third of a cycle at the start and a fifth of the recording at the end is compared
    with its original: it must score above every other horse's recordings. Each recording's
    signature (progression removed, period, cycles) is computed once (``signatures_s``); a pair then
    costs ``pair_s``, against dtaidistance's DTW of the same two arrays (``pair_vs_dtw_ratio``,
    median over the pairs).
    """
    from saddlescope.core.similarity import recording_signature
    from saddlescope.io.threads import single_threaded_numerics
    from saddlescope.services.similarity.compare import RANKING_MEASURE, compare_recording_signatures

    recs = [synthetic_recording(h, r) for h in range(subjects) for r in (0, 1)]
    n = len(recs)
    sims = np.full((n, n), -np.inf)
    methods: dict[str, int] = {}
    with single_threaded_numerics():
        t0 = time.perf_counter()
        sigs = [recording_signature(x, RECORDING_RATE_HZ) for x in recs]
        t1 = time.perf_counter()
        for i in range(n):
            for j in range(i + 1, n):
                res = compare_recording_signatures(sigs[i], sigs[j], only=RANKING_MEASURE)
                sims[i, j] = sims[j, i] = res["similarity"]
                methods[res["alignment"]["method"]] = methods.get(res["alignment"]["method"], 0) + 1
        t2 = time.perf_counter()
        cropped_ok, margins = [], []
        for h in range(subjects):
            a = recs[2 * h]
            period = RECORDING_RATE_HZ / _stride_hz(h)
            crop = recording_signature(a[int(period / 3): a.shape[0] - int(0.2 * a.shape[0])], RECORDING_RATE_HZ)
            own = compare_recording_signatures(sigs[2 * h], crop, only=RANKING_MEASURE)["similarity"]
            others = [sims[2 * h, k] for k in range(n) if k // 2 != h]
            cropped_ok.append(own > max(others))
            margins.append(own - max(others))
        costs = [_pair_cost(sigs[i], sigs[(i + 1 + i // 2) % n]) for i in range(0, n, max(1, n // 5))]
    top1 = float(np.mean([int(np.argmax(sims[i])) == (i ^ 1) for i in range(n)]))
    return {"subjects": subjects, "recordings": n, "rate_hz": RECORDING_RATE_HZ, "noise_mm": RECORDING_NOISE_MM,
            "measure": RANKING_MEASURE, "top1": top1, "cropped_above_others": float(np.mean(cropped_ok)),
            "cropped_margin_min": float(min(margins)), "alignments": methods,
            "signatures_s": t1 - t0, "pairs_s": t2 - t1,
            "pair_s": float(np.median([c[0] for c in costs])),
            "dtw_same_arrays_s": float(np.median([c[1] for c in costs])),
            "pair_vs_dtw_ratio": float(np.median([c[0] / c[1] for c in costs]))}


def _stride_hz(subject: int, gait: str = "sitting_trot") -> float:
    return sample_gait(gait, np.random.default_rng(1000 + subject), camera_side=1.0).stride_hz


def run_similarity_benchmarks(*, quick: bool = False) -> dict:
    """The keys `saddlescope bench` reports for similarity."""
    out: dict = {"chaincode_10k_s": bench_chaincode_10k(), "dtw_10k_s": bench_dtw_10k()}
    ret = retrieval(horses=6)
    out["similarity_retrieval"] = ret
    rank = ret["measures"][ret["ranking_measure"]]
    out["similarity_top1"] = rank["top1"]
    out["similarity_auc"] = rank["auc"]
    rec = recording_retrieval(subjects=8)
    out["recording_retrieval"] = rec
    out["recording_top1"] = rec["top1"]
    out["recording_cropped_above_others"] = rec["cropped_above_others"]
    out["recording_pair_vs_dtw_ratio"] = rec["pair_vs_dtw_ratio"]
    speed = ranking_speed(200 if quick else 1000)
    out["most_similar_1000_s"] = speed["total_s"] if not quick else None
    out["similarity_ranking_speed"] = speed
    return out


# ----------------------------------------------------------------------------------------------
# DTW and chain codes of 10,000-sample trajectories, timed (moved here from the similarity service)


def bench_trajectories(n: int = 10_000, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two seeded, ride-like 3-D trajectories of ``n`` samples (30 closed strides each, m).

    The second has another start phase, a slowly varying stride rate and its own measurement noise.
    """
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 30 * 2 * np.pi, n)
    warp = u + 0.3 * np.sin(u / 7.0)

    def loop(p: np.ndarray) -> np.ndarray:
        return np.column_stack([0.02 * np.cos(p) + 0.005 * np.cos(2 * p), 0.05 * np.sin(2 * p + 0.3),
                                0.015 * np.sin(p)])

    a = loop(u) + rng.normal(0.0, 2e-4, (n, 3))
    b = loop(warp + 0.4) + rng.normal(0.0, 2e-4, (n, 3))
    return a, b


def bench_chaincode_10k() -> float:
    """Seconds for one chain-code similarity of two 10,000-sample trajectories.

    Both chain codes (common default grid, 50 cells over the extent) plus the banded
    Needleman-Wunsch similarity of the two chains.
    """
    a, b = bench_trajectories()
    t0 = time.perf_counter()
    step = default_step(a, b)
    nw_similarity(chain_code_3d(a, step=step), chain_code_3d(b, step=step))
    return time.perf_counter() - t0


def bench_shape_10k() -> float:
    """Seconds for the chain codes plus Bribiesca & Aguilar's shape dissimilarity (10,000 samples)."""
    a, b = bench_trajectories()
    t0 = time.perf_counter()
    step = default_step(a, b)
    shape_dissimilarity(chain_code_3d(a, step=step), chain_code_3d(b, step=step))
    return time.perf_counter() - t0


def bench_dtw_10k() -> float:
    """Seconds for one 3-D DTW distance of two 10,000-sample trajectories (C, window 10 %)."""
    a, b = bench_trajectories()
    t0 = time.perf_counter()
    dtw_distance(a, b, window=1000)
    return time.perf_counter() - t0

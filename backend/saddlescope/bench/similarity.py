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

import numpy as np

from saddlescope.arena.gait import sample_gait

__all__ = ["NOISE_MM", "synthetic_ride", "retrieval", "ranking_speed", "run_similarity_benchmarks"]

NOISE_MM = 1.0
FPS = 60.0
GAITS = ("walk", "sitting_trot", "canter")
# The motion frame of a result (x travel, y down, z = x cross y) from the arena's (x travel, y up).
_TO_MOTION = np.diag([1.0, -1.0, -1.0])


def synthetic_ride(horse: int, gait: str, recording: int, *, strides: float | None = None,
                   noise_mm: float = NOISE_MM) -> dict:
    """A result-like document of one recording of one horse's gait (``fps``, ``period_s``,
    ``saddle.position_m`` (N, 3) and ``markers.position_m`` (N, 3, 3), m, motion frame)."""
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
    from saddlescope.services.similarity import MEASURES, RANKING_MEASURE, compare_signatures, ride_signature

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
    from saddlescope.services.similarity import rank_signatures, ride_signature

    docs = [synthetic_ride(k % 50, GAITS[k % 3], k // 50, strides=10.0) for k in range(n_rides + 1)]
    t0 = time.perf_counter()
    sigs = {k: ride_signature(d) for k, d in enumerate(docs)}
    t1 = time.perf_counter()
    query = sigs.pop(0)
    rows = rank_signatures(query, sigs, top=10)
    t2 = time.perf_counter()
    return {"rides": n_rides, "precompute_s": t1 - t0, "query_s": t2 - t1, "total_s": t2 - t0,
            "top": [r["ride"] for r in rows[:3]]}


def run_similarity_benchmarks(*, quick: bool = False) -> dict:
    """The keys `saddlescope bench` reports for similarity."""
    from saddlescope.services.similarity import bench_chaincode_10k, bench_dtw_10k

    out: dict = {"chaincode_10k_s": bench_chaincode_10k(), "dtw_10k_s": bench_dtw_10k()}
    ret = retrieval(horses=6)
    out["similarity_retrieval"] = ret
    rank = ret["measures"][ret["ranking_measure"]]
    out["similarity_top1"] = rank["top1"]
    out["similarity_auc"] = rank["auc"]
    speed = ranking_speed(200 if quick else 1000)
    out["most_similar_1000_s"] = speed["total_s"] if not quick else None
    out["similarity_ranking_speed"] = speed
    return out

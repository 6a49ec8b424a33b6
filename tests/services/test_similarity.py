"""Tests of the ride similarity: dtaidistance DTW and the ranking of ride pairs (core.similarity.stride_ranking),
the comparison of result documents and files (services.similarity.compare)."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.bench.similarity import bench_chaincode_10k, bench_dtw_10k
from saddlescope.core.errors import InputError
from saddlescope.core.similarity import (
    dtw_distance,
    dtw_distance_reference,
    most_similar_rides,
    normalise_stride,
    stride_distance_dtw,
)

FPS = 30.0


def _ride(rng, f_hz: float, speed_m_s: float, phase: float, gait: str, *, n: int = 240,
          noise_m: float = 5e-4, amp: float = 1.0) -> np.ndarray:
    """A saddle-like track: a closed stride loop (vertical amplitude scaled by ``amp``) plus travel
    along x, sampled at 30 fps (m)."""
    t = np.arange(n) / FPS
    p = 2 * np.pi * f_hz * t + phase
    if gait == "trot":  # vertical at twice the stride frequency
        loop = np.column_stack([0.01 * np.cos(2 * p), 0.05 * amp * np.sin(2 * p + 0.3), 0.02 * np.sin(p)])
    else:
        loop = np.column_stack([0.03 * np.cos(p), 0.10 * amp * np.sin(p + 0.3), 0.01 * np.sin(2 * p)])
    travel = np.column_stack([speed_m_s * t, np.zeros(n), np.zeros(n)])
    return loop + travel + rng.normal(0.0, noise_m, (n, 3))


def test_dtaidistance_matches_numpy_reference():
    rng = np.random.default_rng(11)
    for k in range(40):
        n, m = (int(v) for v in rng.integers(2, 30, size=2))
        window = None if k % 3 == 0 else int(rng.integers(1, 8))
        a, b = rng.normal(size=(n, 3)), rng.normal(size=(m, 3))
        assert dtw_distance(a, b, window=window) == pytest.approx(dtw_distance_reference(a, b, window=window))
        a1, b1 = a[:, 0], b[:, 0]
        assert dtw_distance(a1, b1, window=window) == pytest.approx(
            dtw_distance_reference(a1, b1, window=window))


def test_dtw_distance_bad_input():
    with pytest.raises(InputError, match="NaN"):
        dtw_distance(np.array([0.0, np.nan]), np.array([0.0, 1.0]))
    with pytest.raises(InputError, match="dimensions"):
        dtw_distance(np.zeros((5, 3)), np.zeros(5))


def test_normalise_stride_removes_travel_and_mean():
    rng = np.random.default_rng(0)
    track = _ride(rng, 1.5, 3.0, 0.0, "canter", noise_m=0.0)
    stride = normalise_stride(track, period_samples=FPS / 1.5, n_samples=64)
    assert stride.shape == (64, 3)
    assert np.allclose(stride.mean(axis=0), 0.0)
    # What is left is the loop: x within its +-3 cm, not metres of travel.
    assert np.ptp(stride[:, 0]) < 0.07
    # The estimated period gives the same stride (up to interpolation).
    est = normalise_stride(track, fps=FPS, n_samples=64)
    assert np.allclose(est, stride, atol=3e-3)


def test_identical_rides_rank_first_and_gaits_group():
    rng = np.random.default_rng(3)
    trot = _ride(rng, 1.4, 3.0, 0.0, "trot")
    tracks = {
        "trot1": trot,
        # The same ride recorded from another start and at another travel speed: same motion.
        "trot1_again": trot[17:] + np.column_stack([0.4 * np.arange(223) / FPS, np.zeros((223, 2))]),
        "trot2": _ride(rng, 1.45, 3.3, 1.0, "trot", amp=1.4),
        "canter1": _ride(rng, 1.65, 4.0, 0.5, "canter"),
        "canter2": _ride(rng, 1.6, 4.2, 2.0, "canter", amp=0.8),
    }
    same_gait = {frozenset(p) for p in (("trot1", "trot1_again"), ("trot1", "trot2"),
                                        ("trot1_again", "trot2"), ("canter1", "canter2"))}
    ranked = most_similar_rides(tracks, method="dtw", top=10)
    assert len(ranked) == 10 and [d["rank"] for d in ranked] == list(range(1, 11))
    assert ranked[0]["rides"] == ["trot1", "trot1_again"]
    assert ranked[0]["distance"] < 0.3 * ranked[1]["distance"]
    assert {frozenset(d["rides"]) for d in ranked[:4]} == same_gait
    assert all(d["distance"] <= e["distance"] for d, e in zip(ranked, ranked[1:], strict=False))

    ranked = most_similar_rides(tracks, method="chaincode", top=5)
    assert ranked[0]["rides"] == ["trot1", "trot1_again"]
    assert {frozenset(d["rides"]) for d in ranked[:4]} == same_gait
    assert ranked[0]["similarity"] > ranked[-1]["similarity"]
    assert ranked[0]["shape_dissimilarity"] < ranked[-1]["shape_dissimilarity"]


def test_dtw_shift_search_undoes_the_start_phase():
    rng = np.random.default_rng(4)
    stride = normalise_stride(_ride(rng, 1.5, 3.0, 0.0, "canter", noise_m=0.0), period_samples=20.0,
                              n_samples=40)
    dist, shift = stride_distance_dtw(stride, np.roll(stride, 7, axis=0))
    assert dist == pytest.approx(0.0, abs=1e-12) and shift == 7


def test_most_similar_rides_bad_input():
    rng = np.random.default_rng(5)
    good = _ride(rng, 1.5, 3.0, 0.0, "canter")
    bad = good.copy()
    bad[30, 2] = np.nan
    with pytest.raises(InputError, match="ride 'b'.*NaN"):
        most_similar_rides({"a": good, "b": bad})
    with pytest.raises(InputError, match="at least two rides"):
        most_similar_rides({"a": good})
    with pytest.raises(InputError, match="unknown similarity method"):
        most_similar_rides({"a": good, "b": good}, method="euclid")
    with pytest.raises(InputError, match="at least 8"):
        most_similar_rides({"a": good, "b": good[:5]})
    with pytest.raises(InputError, match="shorter than one stride"):
        most_similar_rides({"a": good, "b": good[:20]}, periods={"b": 30.0})


def test_benchmarks_return_seconds():
    # Timing is never asserted (shared machine); only that the benchmarks run and report a duration.
    for bench in (bench_chaincode_10k, bench_dtw_10k):
        seconds = bench()
        assert np.isfinite(seconds) and seconds > 0


# ---------------------------------------------------------------------------------------- the product's interface

def _doc_with(doc: dict, saddle: np.ndarray, **extra) -> dict:
    return {**doc, **extra, "saddle": {"position_m": saddle}}


@pytest.fixture(scope="module")
def trot():
    from saddlescope.bench.similarity import synthetic_ride

    return synthetic_ride(0, "sitting_trot", 0)


def test_compare_reports_every_measure_with_frame_and_step(trot):
    from saddlescope.services.similarity.compare import MEASURES, RANKING_MEASURE, compare_ride_documents

    res = compare_ride_documents(trot, trot)
    assert res["measure"] == RANKING_MEASURE and res["similarity"] == res["measures"][RANKING_MEASURE]
    assert res["similarity"] == pytest.approx(1.0)
    assert set(res["measures"]) == set(MEASURES)
    assert res["frame"] == "motion+stride_phase" and res["step_mm"] > 0
    assert res["details"]["chain_code_nw"]["step_mm"] == res["step_mm"]
    assert res["details"]["dtw"]["frame"] == res["frame"]
    assert res["markers"] == "saddle" and res["span"] == "stride"
    assert compare_ride_documents(trot, trot, span="window")["span"] == "window"


def test_translated_later_started_and_time_stretched_copies_score_as_identical(trot):
    from saddlescope.services.similarity.compare import compare_ride_documents

    x = np.asarray(trot["saddle"]["position_m"])
    ident = compare_ride_documents(trot, trot)["measures"]
    n, f = x.shape[0], 1.15
    tq = np.arange(int((n - 1) * f)) / f
    stretched = np.stack([np.interp(tq, np.arange(n), x[:, k]) for k in range(3)], axis=-1)
    copies = {"translated": _doc_with(trot, x + np.array([5.0, -2.0, 3.0])),
              "later": _doc_with(trot, x[17:]),
              "stretched": _doc_with(trot, stretched, period_s=trot["period_s"] * f)}
    for name, doc in copies.items():
        got = compare_ride_documents(trot, doc)["measures"]
        for m in ("dtw", "chain_code_nw", "shape_similarity"):
            assert got[m] >= 0.95 * ident[m], (name, m, got[m], ident[m])


def test_still_marker_is_no_motion(trot):
    from saddlescope.services.similarity.compare import compare_ride_documents

    rng = np.random.default_rng(0)

    def still_m1():
        m = np.array(trot["markers"]["position_m"], dtype=float)
        m[:, 0] = rng.normal(0.0, 5e-4, (m.shape[0], 3))  # 0.5 mm noise, no motion
        return {**trot, "markers": {"names": ["M1", "M2", "M3"], "position_m": m}}

    both = compare_ride_documents(still_m1(), still_m1(), markers="M1")
    assert both["moves"] == {"a": False, "b": False} and both["similarity"] == 1.0
    assert both["step_mm"] >= 1.0  # four noise deviations, not 1/50 of the noise's extent
    one = compare_ride_documents(still_m1(), trot, markers="M1")
    assert one["moves"] == {"a": False, "b": True} and one["similarity"] == 0.0


def test_shape_dissimilarity_does_not_depend_on_the_recording_length():
    from saddlescope.bench.similarity import synthetic_ride
    from saddlescope.services.similarity.compare import compare_ride_documents

    d = [compare_ride_documents(synthetic_ride(3, "sitting_trot", 0, strides=k),
                                synthetic_ride(3, "sitting_trot", 1, strides=k))["measures"]["shape_dissimilarity"]
         for k in (5, 10, 20, 40)]
    assert max(d) - min(d) < 0.02, d


def test_rank_rides_finds_the_other_recording(trot):
    from saddlescope.bench.similarity import synthetic_ride
    from saddlescope.services.similarity.compare import rank_rides

    cands = {f"h{h}-{g}-{r}": synthetic_ride(h, g, r) for h in range(3) for g in ("walk", "sitting_trot")
             for r in (0, 1)}
    del cands["h0-sitting_trot-0"]
    cands["broken"] = {"fps": 60.0}
    rows = rank_rides(trot, cands, top=3)
    assert [r["rank"] for r in rows] == [1, 2, 3]
    assert rows[0]["ride"] == "h0-sitting_trot-1"
    assert rows[0]["similarity"] >= rows[1]["similarity"] >= rows[2]["similarity"]
    assert {"frame", "step_mm", "measures", "details"} <= set(rows[0])


def test_generic_recordings_are_compared_in_cycle_phase_and_a_kabsch_frame(trot):
    from saddlescope.services.similarity.compare import compare_recordings

    a = np.asarray(trot["markers"]["position_m"]) * 1e3  # mm
    q, _ = np.linalg.qr(np.random.default_rng(3).normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    res = compare_recordings(a, a @ q.T + np.array([100.0, -50.0, 2000.0]), rate_a_hz=float(trot["fps"]))
    assert res["frame"] == "cycle_phase+kabsch" and res["kabsch_residual_mm"] < 1e-6
    assert res["alignment"]["method"] == "cycle_phase" and res["alignment"]["phase_shift"] == 0.0
    assert res["similarity"] > 0.999 and res["measures"]["chain_code_nw"] > 0.95
    with pytest.raises(InputError, match="markers"):
        compare_recordings(a, a[:, :2])


def test_cli_similar_on_results_and_on_bad_input(trot, tmp_path, capsys):
    import json

    from saddlescope.bench.similarity import synthetic_ride
    from saddlescope.cli import main

    def dump(name, doc):
        path = tmp_path / name
        path.write_text(json.dumps({k: (v if not isinstance(v, dict) else
                                        {kk: np.asarray(vv).tolist() for kk, vv in v.items()})
                                    for k, v in doc.items()}))
        return str(path)

    a, b = dump("a.json", trot), dump("b.json", synthetic_ride(0, "sitting_trot", 1))
    out = tmp_path / "out.json"
    assert main(["similar", a, b, "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["similarity"] > 0.95 and res["frame"] == "motion+stride_phase"
    assert all(d["frame"] for d in res["details"].values()) and res["step_mm"] > 0
    capsys.readouterr()
    assert main(["similar", a, str(tmp_path / "missing.c3d")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("saddlescope similar:") and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_cli_similar_on_motion_capture(real_data, capsys):
    from saddlescope.cli import main

    gait = real_data("c3d", "Gait.c3d")
    assert main(["similar", str(gait), str(gait), "--markers", "LASI,RASI,VSAC", "--up", "z"]) == 0
    import json

    res = json.loads(capsys.readouterr().out)
    assert res["frame"].endswith("+kabsch") and res["kabsch_residual_mm"] < 1e-6
    assert res["similarity"] == pytest.approx(1.0, abs=1e-9)
    assert res["markers"] == ["LASI", "RASI", "VSAC"] and res["up"] == "z"

"""The retrieval benchmark's bookkeeping on a small set (the full run is `saddlescope bench`)."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.bench.similarity import _auc, retrieval, synthetic_ride


def test_auc_counts_pairs_and_ties():
    assert _auc(np.array([3.0, 4.0]), np.array([1.0, 2.0])) == 1.0
    assert _auc(np.array([1.0]), np.array([1.0])) == 0.5
    assert _auc(np.array([1.0, 3.0]), np.array([2.0])) == 0.5


def test_recordings_differ_in_start_length_and_pace_but_not_in_horse():
    a, b = synthetic_ride(0, "canter", 0), synthetic_ride(0, "canter", 1)
    assert a["period_s"] != b["period_s"] and len(a["saddle"]["position_m"]) != len(b["saddle"]["position_m"])
    assert abs(a["period_s"] / b["period_s"] - 1) < 0.2


@pytest.mark.slow
def test_small_retrieval_reports_every_measure_side_by_side():
    res = retrieval(horses=2, gaits=("walk", "canter"))
    assert res["rides"] == 8 and res["ranking_measure"] == "dtw"
    assert set(res["measures"]) == {"dtw", "chain_code_nw", "shape_similarity"}
    assert res["measures"]["dtw"]["top1"] == 1.0


def test_synthetic_recordings_differ_in_frame_start_length_and_pace():
    from saddlescope.bench.similarity import RECORDING_RATE_HZ, _stride_hz, synthetic_recording

    a, b = synthetic_recording(0, 0), synthetic_recording(0, 1)
    assert a.shape[1:] == (4, 3) and a.shape[0] != b.shape[0]
    cycles = [x.shape[0] / RECORDING_RATE_HZ * _stride_hz(0) for x in (a, b)]
    assert all(1.9 <= c <= 6.4 for c in cycles)
    assert np.linalg.norm(a.mean(axis=(0, 1)) - b.mean(axis=(0, 1))) > 100.0  # another lab frame


@pytest.mark.slow
def test_small_recording_retrieval_finds_the_twin_and_the_cropped_copy():
    from saddlescope.bench.similarity import recording_retrieval

    res = recording_retrieval(subjects=3)
    assert res["recordings"] == 6 and res["measure"] == "dtw"
    assert res["top1"] == 1.0 and res["cropped_above_others"] == 1.0 and res["cropped_margin_min"] > 0
    assert res["pair_vs_dtw_ratio"] > 0 and set(res["alignments"]) <= {"cycle_phase", "subsequence_dtw"}

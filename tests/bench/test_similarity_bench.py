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

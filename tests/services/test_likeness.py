"""The similarity use cases' own pieces: the pair view's alignment and the job's payload check."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.services.similarity.club import similarity_payload
from saddlescope.services.similarity.pair_view import STRIDE_SAMPLES, pair_paths


def _doc(start_rad: float, *, strides: int = 6, fps: float = 50.0, f0: float = 1.5) -> dict:
    t = np.arange(int(strides / f0 * fps)) / fps
    arg = 2 * np.pi * f0 * t + start_rad
    loop = np.column_stack([0.02 * np.cos(arg), 0.03 * np.sin(2 * arg + 0.4), 0.01 * np.sin(arg)])
    return {"fps": fps, "period_s": 1 / f0, "saddle": {"position_m": (loop + [[4.0, 0, 0]] * t[:, None]).tolist()}}


def test_the_pair_view_lines_up_a_later_started_stride():
    view = pair_paths(_doc(0.0), _doc(np.pi / 2))  # the second starts a quarter stride later
    strides = view["strides"]
    assert view["reason"] is None and len(strides["phase"]) == STRIDE_SAMPLES
    assert strides["shift_phase"] == pytest.approx(0.75, abs=1.5 / STRIDE_SAMPLES)
    np.testing.assert_allclose(strides["second_mm"], strides["first_mm"], atol=1.0)  # mm
    assert np.abs(np.subtract(strides["second_unaligned_mm"], strides["first_mm"])).max() > 10
    # the travel is removed: both paths stay within the stride's few centimetres
    assert all(np.abs(np.asarray(p)).max() < 50 for p in view["paths_mm"])


def test_the_pair_view_says_why_when_a_ride_is_shorter_than_a_stride():
    short = _doc(0.0, strides=1)
    short["saddle"]["position_m"] = short["saddle"]["position_m"][:20]
    assert pair_paths(_doc(0.0), short)["reason"] == "a ride is shorter than one whole stride"
    assert pair_paths({"fps": 50}, _doc(0.0))["reason"] == "a result has no saddle-point track"


def test_the_similarity_job_payload_is_checked_and_ordered():
    clean = similarity_payload({"markers": "M1", "pairs": [[5, 2], [2, 5], [3, 9]]})
    assert clean == {"markers": "M1", "span": "stride", "pairs": [[2, 5], [3, 9]]}
    for bad, words in (({"pairs": []}, "pairs must be a list"), ({"pairs": [[1, True]]}, "two different"),
                       ({"pairs": [[1, 2]], "span": "lap"}, "span: unknown span")):
        with pytest.raises(InputError, match=words):
            similarity_payload(bad)

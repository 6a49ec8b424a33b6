"""Rigs nobody tuned for (issue 27): side cameras that see part of the crossing, a board carried only
through the middle of the volume, markers reaching the image corners, a canter at 4-6 m/s.

The arena's ``wide_partial`` rig at 640x360 (1280x720 halved). Seed 2 is the ride that came out
W_b r.m.s. +86 % before the lens model was limited to the board's reach; seed 1 the one refused because
the markers were tracked together for 1.16 s, just under two strides (docs/accuracy.md).
"""

from __future__ import annotations

import json

import pytest

from saddlescope.core import pipeline as P
from saddlescope.io.result_document import result_to_document

pytestmark = pytest.mark.slow

RIDE = {"gait": "canter", "rig": "wide_partial", "size": (640, 360), "calibration_poses": 40, "extras": False,
        "board_band": 0.6, "speed_range_m_s": (4.0, 6.0)}


def _analysed(tmp_path_factory, seed: int, **changes):
    from rendered_rides import cached_ride_bundle

    from saddlescope.io.bundle import open_bundle
    from saddlescope.io.clip_source import BundleClips

    out = cached_ride_bundle(tmp_path_factory.mktemp(f"partial{seed}") / "canter", seed=seed, **{**RIDE, **changes})
    with open_bundle(out) as bundle:
        result = result_to_document(P.analyze_ride(BundleClips(bundle.clip_paths), bundle.meta))
    return result, json.loads((out / "truth.json").read_text())


def _errors_pct(result: dict, truth: dict) -> dict[str, float]:
    ind, ref = result["indicators"], truth["indicators"]
    return {k: 100 * (ind[k] / ref[k] - 1) for k in ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vel_x_avg_kmh",
                                                     "stride_frequency_hz")}


@pytest.fixture(scope="module")
def extrapolated(tmp_path_factory):
    return _analysed(tmp_path_factory, 2)


@pytest.fixture(scope="module")
def short_common_view(tmp_path_factory):
    return _analysed(tmp_path_factory, 1)


@pytest.fixture(scope="module")
def guessed_ends(tmp_path_factory):
    # at 1280x720 this ride's saddle point broke (W_b r.m.s. +176 %; 640x360: +8.0 %): its ends were
    # triangulated by two cameras, the middle one beyond its board's reach, 0.1-0.8 m off in depth
    return _analysed(tmp_path_factory, 5, board_band=0.8)


def test_partial_view_canter_with_the_lens_extrapolated_is_within_ten_percent(extrapolated):
    result, truth = extrapolated
    err = _errors_pct(result, truth)
    print("wide_partial seed 2:", {k: round(v, 1) for k, v in err.items()})
    assert "calibration.coverage" in [f["code"] for f in result["quality"]["findings"]]  # the user is told
    assert abs(err["acc_y_wb_rms"]) < 10.0 and abs(err["acc_y_wk_rms"]) < 10.0
    # stride frequency 0.78 % off: the fundamental pooled from the vertical fits at the extrema rule's order
    # (1.38 % when pooled from the higher-order fits of every harmonic the frame rate resolves, issue 38)
    assert abs(err["vel_x_avg_kmh"]) < 1.0 and abs(err["stride_frequency_hz"]) < 1.0


def test_a_canter_tracked_for_less_than_two_strides_is_analysed_not_refused(short_common_view):
    result, truth = short_common_view
    err = _errors_pct(result, truth)
    print("wide_partial seed 1:", {k: round(v, 1) for k, v in err.items()}, result["window"])
    assert abs(err["acc_y_wb_rms"]) < 10.0
    assert abs(err["vel_x_avg_kmh"]) < 1.0


def test_a_canter_whose_ends_rest_on_a_guessed_lens_is_analysed_where_they_do_not(guessed_ends):
    result, truth = guessed_ends
    err = _errors_pct(result, truth)
    print("wide_partial seed 5, band 0.8:", {k: round(v, 1) for k, v in err.items()}, result["window"])
    assert "calibration.guessed_depth" in [f["code"] for f in result["quality"]["findings"]]
    assert abs(err["acc_y_wb_rms"]) < 5.0 and abs(err["acc_y_wk_rms"]) < 5.0
    assert abs(err["vel_x_avg_kmh"]) < 1.0 and abs(err["stride_frequency_hz"]) < 1.0

"""The passes line the ride page, the report and the API show for a ride of several passes (issue 38)."""

from __future__ import annotations

from saddlescope.api.schemas import PassesOut
from saddlescope.services.results.passes_view import passes_view


def _doc(strides, used=None, spread=0.021):
    used = used or [True] * len(strides)
    return {"passes": [{"start_s": 8.0 * i, "end_s": 8.0 * i + 1.3, "start_frame": 240 * i, "frames": 39,
                        "strides": n, "speed_m_s": 4.0 if u else None, "used": u, "reason": None if u else "too short",
                        "indicators": {"acc_y_wb_rms": 4.0} if u else {}}
                       for i, (n, u) in enumerate(zip(strides, used, strict=True))],
            "quality": {"pass_pooling": {"spread_fraction": {"acc_y_wb_rms": spread}}}}


def test_one_pass_has_no_passes_line():
    assert passes_view({"quality": {}}) is None
    assert passes_view({"passes": []}) is None


def test_strides_per_pass_and_the_spread():
    view = passes_view(_doc([2, 2, 3]))
    assert view["line"] == "3 passes: 2, 2 and 3 strides"
    assert view["strides"] == [2, 2, 3] and view["count"] == 3
    assert abs(view["wb_rms_spread_percent"] - 2.1) < 1e-9
    PassesOut(**view)  # what the API serves


def test_a_pass_left_out_is_said():
    view = passes_view(_doc([2, 0, 1], used=[True, False, True], spread=None))
    assert view["line"] == "2 passes: 2 and 1 strides (1 more left out: too short)"
    assert view["wb_rms_spread_percent"] is None
    assert [p["used"] for p in view["passes"]] == [True, False, True]

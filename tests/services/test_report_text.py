"""The words for riding times and distances and their intervals (issue #37: "1 s (95 %: 1 s–1 s)", "0.00416 km")."""

from __future__ import annotations

from saddlescope.services.report import _interval_html, distance_text, duration_text


def test_times_under_a_minute_are_not_given_in_seconds():
    assert duration_text(0.00025) == "under a minute"
    assert duration_text(55 / 3600) == "under a minute"
    assert duration_text(90 / 3600) == "2 min"


def test_an_interval_whose_ends_read_alike_is_left_out():
    assert _interval_html("t_a8_limit_wb_h", [0.0002, 0.0003]) == ""
    shown = _interval_html("t_a8_limit_wb_h", [0.1, 0.5])
    assert "95 %: 6 min – 30 min" in shown
    assert "∞" in _interval_html("t_a8_limit_wb_h", [0.1, None])


def test_distances_read_in_metres_or_km_to_two_digits():
    assert [distance_text(km) for km in (0.00416, 0.0004, 0.416, 0.04, 1.234, 15.6, 1234.0, None, float("inf"))] == [
        "about 4 m", "under a metre", "about 420 m", "about 40 m", "about 1.2 km", "about 16 km", "about 1,200 km",
        "–", "no limit"]

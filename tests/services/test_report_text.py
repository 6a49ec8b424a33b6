"""The words for riding times and distances and their intervals (issue #37: "1 s (95 %: 1 s–1 s)", "0.00416 km")."""

from __future__ import annotations

from saddlescope.services.results.report import _interval_html, _number, distance_text, duration_text, range_text


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


# (low, high, what the report and the ride page show): ends that round alike get one more digit, and
# past four digits the interval reads as narrower than the last digit shown (issue 37: "18.00–18.00 km/h")
RANGES = [
    (17.91, 18.12, "17.9–18.1"),
    (18.01, 18.04, "18.01–18.04"),
    (18.0001, 18.0004, "± under 0.01"),
    (0.0041611, 0.0041614, "± under 0.000001"),
    (1234.2, 1234.4, "± under 1"),
    (3.7, 4.52, "3.70–4.52"),
    (None, 4.52, "−∞–4.52"),
    (0.5, None, "0.500–∞"),
]


def test_an_interval_never_collapses_to_one_value():
    for low, high, shown in RANGES:
        assert range_text(low, high) == shown, (low, high)
    assert "95 %: ± under 0.01 km/h" in _interval_html("vel_x_avg_kmh", [18.0001, 18.0004])
    assert "95 %: 2.101–2.104 cm" in _interval_html("amplitude_y_m", [0.021011, 0.021044])


def test_large_numbers_keep_their_significant_digits_only():
    assert [_number(v) for v in (12345.6, 1234.5, 999.6, 18.04, 0.00416)] == ["12300", "1230", "1000", "18.0",
                                                                              "0.00416"]

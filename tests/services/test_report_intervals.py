"""The one-page report shows each indicator's 95 % interval under its value and says when a ride is too
uncertain for a decision (issue 27; services/results/report.py)."""

from __future__ import annotations

from saddlescope.services.results.report import _decision_html, _interval_html


def test_the_interval_reads_in_the_values_own_units():
    assert _interval_html("acc_y_wb_rms", [3.7, 4.52]) == ('<span class="ci" data-ci="acc_y_wb_rms">'
                                                          "95 %: 3.70–4.52 m/s²</span>")
    assert "95 %: 21.0–25.8 cm" in _interval_html("amplitude_y_m", [0.21, 0.258])
    assert "∞" in _interval_html("t_a8_action_wb_h", [0.5, None])  # an unbounded time
    assert _interval_html("acc_y_wb_rms", None) == ""  # a result made before intervals


def test_a_too_uncertain_ride_says_so_and_a_good_one_says_nothing():
    doc = {"quality": {"decision": {"too_uncertain": True, "reason": "the W_b r.m.s. is known only to ±19 % <b>"}}}
    text = _decision_html(doc)
    assert "Too uncertain for a decision" in text and "±19 %" in text and "&lt;b&gt;" in text
    assert _decision_html({"quality": {"decision": {"too_uncertain": False, "reason": None}}}) == ""
    assert _decision_html({}) == ""

"""The result document carries indicators_interval_95 beside the indicators (issue 27): written, read back,
and checked by the schema (an interval must hold its indicator's value)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
from factories import ride_result

from saddlescope.io.result_document import result_from_document, result_to_document
from saddlescope.io.result_schema import result_problems


def test_intervals_round_trip_with_an_unbounded_end():
    result = replace(ride_result(np.random.default_rng(5), calibrated=True),
                     indicators_interval_95={"acc_y_wb_rms": (4.1, 4.9), "t_a8_action_wb_h": (1.0, math.inf)})
    doc = json.loads(json.dumps(result_to_document(result), allow_nan=False))
    assert doc["indicators_interval_95"] == {"acc_y_wb_rms": [4.1, 4.9], "t_a8_action_wb_h": [1.0, None]}
    back = result_from_document(doc)
    assert back.indicators_interval_95 == {"acc_y_wb_rms": (4.1, 4.9), "t_a8_action_wb_h": (1.0, math.inf)}


def test_a_result_made_before_intervals_has_no_key_and_reads_back_as_none():
    doc = result_to_document(ride_result(np.random.default_rng(5), calibrated=False))
    assert "indicators_interval_95" not in doc
    assert result_from_document(doc).indicators_interval_95 is None


def test_the_schema_refuses_an_interval_that_misses_its_value_or_has_no_indicator():
    doc = {"indicators": {"acc_y_wb_rms": 4.5}, "indicators_interval_95": {"acc_y_wb_rms": [4.6, 5.0],
                                                                           "vdv_y_wb": [1.0, 2.0]}}
    problems = result_problems(doc)
    assert any("indicators_interval_95.acc_y_wb_rms [4.6, 5.0] does not hold" in p for p in problems), problems
    assert any("indicators_interval_95.vdv_y_wb has no indicator" in p for p in problems), problems
    doc["indicators_interval_95"] = {"acc_y_wb_rms": [4.0]}
    assert any("indicators_interval_95" in p for p in result_problems(doc))
    doc["indicators_interval_95"] = {"acc_y_wb_rms": [4.0, None]}
    assert not any("indicators_interval_95" in p for p in result_problems(doc))

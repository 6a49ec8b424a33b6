"""The phase-deletion factor's table (bench/hidden_phase.py): what it counts, on rows made by hand."""

from __future__ import annotations

from saddlescope.bench.hidden_phase import factor_table
from saddlescope.core.vibration.intervals import SKIN_FLOORS


def test_the_factor_table_counts_costs_inside_and_trots_and_canters_marked():
    trot_floor = SKIN_FLOORS["sitting_trot"][0]
    rows = [{"gait": "sitting_trot", "seed": 1, "cost": 0.01, "median_change": 0.005},   # inside at any factor
            {"gait": "canter", "seed": 2, "cost": 0.20, "median_change": 0.04},         # inside from factor 2.5
            {"gait": "walk", "seed": 3, "cost": 0.02, "median_change": 0.10},           # a walk is never counted marked
            {"gait": "canter", "seed": 4, "cost": 0.05, "median_change": None}]         # test not done: left out
    one, three = factor_table(rows, factors=(1.0, 3.0))
    assert (one["rides"], one["trots_and_canters"]) == (3, 2)
    assert (one["covered"], three["covered"]) == (2, 3)
    # the canter's half-width 1.96 * hypot(floor, 0.04) is under 10 % at 1.0 and over it at 3.0
    assert (one["marked"], three["marked"]) == (0, 1)
    assert 1.96 * trot_floor < 0.1

"""Whole-body vibration of the saddle and the rider comfort indicators (thesis chapters 7-8).

- :mod:`.weighting`: the ISO 2631-1 / BS 6841 frequency weightings and their digital filters;
- :mod:`.metrics`: r.m.s., peak, crest factor, VDV and MTVV of weighted accelerations;
- :mod:`.exposure`: A(8) and the EU 2002/44/EC action and limit values;
- :mod:`.indicator_keys`: the indicator keys, their units and meaning (:data:`INDICATORS`);
- :mod:`.indicators`: the comfort indicators of one ride;
- :mod:`.intervals`: their 95 % intervals and whether a ride is too uncertain for a decision;
- :mod:`.comparisons`: relative comfort, comparisons, leaderboards and riders' grades;
- :mod:`.group_difference`: a group's mean interval and whether two groups differ beyond it (Welch).

``weighting_response``, ``harmonic_metrics`` and ``exposure_limits`` are imported from here by
outside code: their path and signatures are fixed.
"""

from saddlescope.core.vibration.comparisons import (
    average_grades,
    compare_gaits,
    compare_horses,
    grade_correlation,
    grades_vs_indicators,
    leaderboard,
    relative_comfort,
    relative_comfort_table,
    summarize,
)
from saddlescope.core.vibration.exposure import (
    A8_ACTION_M_S2,
    A8_LIMIT_M_S2,
    HORIZONTAL_FACTOR,
    VDV_ACTION_M_S175,
    VDV_LIMIT_M_S175,
    a8,
    exposure_limits,
    per_axis_exposure,
)
from saddlescope.core.vibration.group_difference import (
    GroupDifference,
    MeanInterval,
    mean_interval,
    welch_difference,
)
from saddlescope.core.vibration.indicator_keys import (
    COMFORT_INDICATORS,
    CONTRACT_KEYS,
    GAITS,
    INDICATORS,
    PASSIVE_SEATED_CAVEAT,
    IndicatorInfo,
    indicator_unit,
)
from saddlescope.core.vibration.indicators import comfort_indicators, ride_indicators, ride_indicators_sampled
from saddlescope.core.vibration.intervals import (
    INTERVAL_KEYS,
    bootstrap_indicators,
    decision_uncertainty,
    interval_sources,
    ride_intervals,
)
from saddlescope.core.vibration.metrics import (
    crest_factor,
    harmonic_metrics,
    mtvv,
    peak,
    sampled_metrics,
    vdv,
    weighted_rms,
)
from saddlescope.core.vibration.weighting import (
    WEIGHTINGS,
    WeightingParameters,
    digital_band_hz,
    weight_signal,
    weighting_response,
    weighting_sos,
)

__all__ = [
    # weighting
    "WEIGHTINGS",
    "WeightingParameters",
    "weighting_response",
    "weighting_sos",
    "digital_band_hz",
    "weight_signal",
    # metrics
    "weighted_rms",
    "peak",
    "crest_factor",
    "vdv",
    "mtvv",
    "sampled_metrics",
    "harmonic_metrics",
    # exposure
    "A8_ACTION_M_S2",
    "A8_LIMIT_M_S2",
    "VDV_ACTION_M_S175",
    "VDV_LIMIT_M_S175",
    "HORIZONTAL_FACTOR",
    "a8",
    "exposure_limits",
    "per_axis_exposure",
    # indicator keys
    "GAITS",
    "CONTRACT_KEYS",
    "COMFORT_INDICATORS",
    "INDICATORS",
    "IndicatorInfo",
    "PASSIVE_SEATED_CAVEAT",
    "indicator_unit",
    # one ride
    "ride_indicators",
    "ride_indicators_sampled",
    "comfort_indicators",
    # 95 % intervals
    "INTERVAL_KEYS",
    "bootstrap_indicators",
    "decision_uncertainty",
    "interval_sources",
    "ride_intervals",
    # comparisons
    "relative_comfort",
    "relative_comfort_table",
    "summarize",
    "compare_gaits",
    "compare_horses",
    "leaderboard",
    "average_grades",
    "grade_correlation",
    "grades_vs_indicators",
    # two groups of rides
    "GroupDifference",
    "MeanInterval",
    "mean_interval",
    "welch_difference",
]

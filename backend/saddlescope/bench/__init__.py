"""`saddlescope bench`: speed and accuracy measured as ratios taken side by side in one run.

- :mod:`.analysis`: the analysis itself (detection against decoding, calibration, whole rides against
  their footage, accuracy against the synthetic arena's exact answers, the exact-marker floor);
- :mod:`.service`: the web service under load (uploads, leaderboards, concurrent readers);
- :mod:`.similarity`: motion similarity (retrieval on synthetic rides, ranking 1,000 rides, 10k-sample pairs).
"""

from saddlescope.bench.analysis import (
    accuracy,
    analysis_vs_footage,
    calibration_3cams,
    detection_vs_decode,
    exact_marker_floor,
    indicator_errors_pct,
    kinematics_floor,
    run_benchmarks,
)

__all__ = ["accuracy", "analysis_vs_footage", "calibration_3cams", "detection_vs_decode", "exact_marker_floor",
           "indicator_errors_pct", "kinematics_floor", "run_benchmarks"]

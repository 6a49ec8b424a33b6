"""`saddlescope bench`: speed and accuracy measured as ratios taken side by side in one run.

- :mod:`.analysis`: the analysis itself (detection against decoding, whole rides against decoding their
  clips once at 640x480 and 1080p60 with each stage's share, rides per core-hour, a 2160p30 ride's peak
  memory, calibration, whole rides against their footage, accuracy against the synthetic arena's exact
  answers, the exact-marker floor);
- :mod:`.service`: the web service under load (uploads, leaderboards, concurrent readers);
- :mod:`.similarity`: motion similarity (retrieval on synthetic rides, ranking 1,000 rides, 10k-sample pairs);
- :mod:`.dashboard`: the dashboard's time to interactive in Chromium with 10,000 rides (rides list,
  leaderboard, a ride page with 10,000 samples per curve).
"""

from saddlescope.bench import analysis as _analysis
from saddlescope.bench.analysis import (
    accuracy,
    analysis_vs_decode,
    analysis_vs_footage,
    calibration_3cams,
    decode_once,
    detection_vs_decode,
    exact_marker_floor,
    indicator_errors_pct,
    kinematics_floor,
    peak_rss_analysis,
    speed_keys,
    speed_rides,
)
from saddlescope.bench.coverage import run_coverage
from saddlescope.bench.dashboard import dashboard_tti, run_dashboard_benchmarks

TTI_KEYS = ("tti_rides_list_s", "tti_leaderboard_s", "tti_ride_page_s")


def run_benchmarks(*, quick: bool = False) -> dict:
    """Every benchmark (`analysis.run_benchmarks`), then the dashboard's: its three times to interactive
    as top-level keys (None where Chromium is absent, with the reason in ``dashboard["skipped"]``)."""
    out = _analysis.run_benchmarks(quick=quick)
    out["coverage"] = run_coverage(quick=quick)  # issue 27: do the 95 % intervals hold the truth?
    dashboard = run_dashboard_benchmarks(quick=quick)
    out.update({key: dashboard[key] for key in TTI_KEYS})
    out["dashboard"] = {k: v for k, v in dashboard.items() if k not in TTI_KEYS}
    return out


__all__ = ["TTI_KEYS", "accuracy", "analysis_vs_decode", "analysis_vs_footage", "calibration_3cams", "dashboard_tti",
           "decode_once", "detection_vs_decode", "exact_marker_floor", "indicator_errors_pct", "kinematics_floor",
           "peak_rss_analysis", "run_benchmarks", "run_dashboard_benchmarks", "speed_keys", "speed_rides"]

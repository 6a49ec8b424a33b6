"""`saddlescope bench`: speed and accuracy measured as ratios taken side by side in one run.

- :mod:`.analysis`: the analysis itself (detection against decoding, whole rides against decoding their
  clips once at 640x480 and 1080p60 with each stage's share, rides per core-hour, a 2160p30 ride's peak
  memory quiet and beside busy loops, calibration, whole rides against their footage, accuracy against the
  synthetic arena's exact answers, the exact-marker floor);
- :mod:`.service`: the web service under load (uploads, leaderboards, concurrent readers);
- :mod:`.similarity`: motion similarity (retrieval on synthetic rides, ranking 1,000 rides, 10k-sample pairs);
- :mod:`.dashboard`: the dashboard's time to interactive in Chromium with 10,000 rides (rides list,
  leaderboard, a ride page with 10,000 samples per curve).

Each part is a :class:`BenchSection`; ``saddlescope bench --only speed,accuracy`` measures those alone, with
the same JSON keys as a whole run (which takes about half an hour on two cores).
"""

from __future__ import annotations

import os
import platform
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

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
    peak_rss_loaded_vs_quiet,
    speed_keys,
    speed_rides,
)
from saddlescope.bench.coverage import run_coverage
from saddlescope.bench.dashboard import TTI_PAGE_KEYS, dashboard_tti, run_dashboard_benchmarks

TTI_KEYS = TTI_PAGE_KEYS  # rides list, leaderboard, ride page, horse page, compare


@dataclass(frozen=True)
class BenchSection:
    """A part of `saddlescope bench` that can be measured alone (``--only NAME``) with the keys of a whole run."""

    name: str
    summary: str
    run: Callable[[Path, bool], dict]  # (scratch folder, quick) -> the run's top-level keys


def _calibration_check(tmp: Path, quick: bool) -> dict:
    from saddlescope.bench.calibration import calibration_check_clips_s

    return calibration_check_clips_s(tmp, quick=quick)  # issue 35: the rig page's check within 2 minutes


def _similarity(tmp: Path, quick: bool) -> dict:
    from saddlescope.bench.similarity import run_similarity_benchmarks

    return run_similarity_benchmarks(quick=quick)


def _service(tmp: Path, quick: bool) -> dict:
    from saddlescope.bench import load as service_bench

    return {"service": service_bench.run_all(quick=quick)}


def _coverage(tmp: Path, quick: bool) -> dict:
    """Issue 27: do the 95 % intervals hold the truth? Issue 38: and on rides with the field's nuisances."""
    from saddlescope.bench.coverage import run_field_nuisances

    return {"coverage": run_coverage(quick=quick), "field_nuisances": run_field_nuisances(quick=quick)}


def _rolling_shutter(tmp: Path, quick: bool) -> dict:
    """Rides filmed with a phone's 25 ms readout: sync and speed against the truth (issue 38, item 3)."""
    from saddlescope.bench.rolling import rolling_shutter_section

    return rolling_shutter_section(tmp, quick)


def _wand(tmp: Path, quick: bool) -> dict:
    """A wide rig from a wand and close-up boards against the full board walk; a middle band refined by a wand.

    Issue 35: ``wand_vs_board``, ``wand_refines_band`` and (not ``quick``) ``wand_refines_band_rendered`` of
    :mod:`saddlescope.bench.calibration`.
    """
    from saddlescope.bench.calibration import wand_refines_band, wand_refines_band_rendered, wand_vs_board

    band = wand_refines_band(seeds=(1013,)) if quick else wand_refines_band()
    # the same refinement as a pipeline step on a rendered partial-view canter (about 15 min): the full run only
    rendered = {} if quick else wand_refines_band_rendered(tmp)
    return {**wand_vs_board(tmp, quick=quick), **band, **rendered}


def _dashboard(tmp: Path, quick: bool) -> dict:
    """The dashboard's five times to interactive as top-level keys, the rest under ``dashboard``.

    The times are None where Chromium is absent, with the reason in ``dashboard["skipped"]``.
    """
    dashboard = run_dashboard_benchmarks(quick=quick)
    return {**{key: dashboard[key] for key in TTI_KEYS},
            "dashboard": {k: v for k, v in dashboard.items() if k not in TTI_KEYS}}


# In the order of a whole run (CONTRACTS section 3's keys first).
SECTIONS: tuple[BenchSection, ...] = (
    BenchSection("detection", "marker detection against decoding, 640x480 and 1080p", _analysis.detection_section),
    BenchSection("calibration", "three cameras calibrated from their board clips", _analysis.calibration_section),
    BenchSection("calibration_check", "calibration clips checked before riding: three 30 s 1080p clips",
                 _calibration_check),
    BenchSection("wand", "a wide rig from a wand and close-up boards against the full board calibration; a "
                 "middle-band rig refined by a wand", _wand),
    BenchSection("speed", "whole rides against decoding their clips once, stages, memory", _analysis.speed_section),
    BenchSection("footage", "whole rides against the length of their footage", _analysis.footage_section),
    BenchSection("floor", "the kinematics' exact-marker floor", _analysis.floor_section),
    BenchSection("accuracy", "rendered rides against the arena's exact answers", _analysis.accuracy_section),
    BenchSection("rolling_shutter", "rides filmed with a 25 ms rolling-shutter readout: sync and speed errors",
                 _rolling_shutter),
    BenchSection("similarity", "motion similarity: retrieval, ranking, long pairs", _similarity),
    BenchSection("service", "the web service under load", _service),
    BenchSection("coverage", "do the 95 % intervals hold the truth, also with the field's nuisances", _coverage),
    BenchSection("dashboard", "the dashboard's time to interactive in Chromium", _dashboard),
)
SECTION_NAMES = tuple(section.name for section in SECTIONS)


def sections_named(only: str | Sequence[str] | None) -> tuple[BenchSection, ...]:
    """The sections ``only`` names ("speed,accuracy" or a list; None: every one), in a whole run's order.

    Raises ValueError naming the sections that exist when a name is not one of them.
    """
    if only is None:
        return SECTIONS
    names = [n.strip() for n in (only.split(",") if isinstance(only, str) else only) if n.strip()]
    unknown = [n for n in names if n not in SECTION_NAMES]
    if unknown or not names:
        raise ValueError(f"no benchmark section {', '.join(map(repr, unknown)) or 'named'}: choose from "
                         f"{', '.join(SECTION_NAMES)}")
    return tuple(section for section in SECTIONS if section.name in names)


def run_benchmarks(*, quick: bool = False, only: str | Sequence[str] | None = None) -> dict:
    """The benchmarks of the sections ``only`` names (every one by default), with the machine they ran on.

    A section measured alone gives the same JSON keys as in a whole run.
    """
    from saddlescope.settings import get_settings

    chosen = sections_named(only)
    out: dict = {"machine": {"cpus": os.cpu_count(), "worker_threads": get_settings().resolved_worker_threads,
                             "python": platform.python_version(), "load_avg_start": list(os.getloadavg()),
                             "sections": [section.name for section in chosen]}}
    tmp = Path(tempfile.mkdtemp(prefix="saddlescope-bench-"))
    try:
        for section in chosen:
            out.update(section.run(tmp, quick))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    out["machine"]["load_avg_end"] = list(os.getloadavg())
    return out


__all__ = ["SECTIONS", "SECTION_NAMES", "TTI_KEYS", "BenchSection", "accuracy", "analysis_vs_decode",
           "analysis_vs_footage", "calibration_3cams", "dashboard_tti", "decode_once", "detection_vs_decode",
           "exact_marker_floor", "indicator_errors_pct", "kinematics_floor", "peak_rss_analysis",
           "peak_rss_loaded_vs_quiet", "run_benchmarks", "run_dashboard_benchmarks", "sections_named", "speed_keys",
           "speed_rides"]

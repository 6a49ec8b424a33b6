"""`saddlescope bench --only rolling_shutter`: phones' rolling shutters against the arena's truth (issue 38, item 3).

Rides filmed with a 25 ms readout (rows exposed top to bottom over 25 ms): the thesis rig at 640x480@30,
the wide rig at 1280x720@30 (CRF 28, a phone's compression) and a phone-like 1920x1080@60 canter. Per
ride: each camera's sync error against truth.json's offsets (frames), the readouts measured (ms), the
speed error (%), and whether each indicator's 95 % interval holds the truth; beside each 30 fps ride the
same horse, rig and seed with a global shutter (readout 0). Seeds 5101-5103: used by no test.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ROLLING_RIDES", "RollingRide", "rolling_ride_row", "rolling_shutter_section"]


@dataclass(frozen=True)
class RollingRide:
    """One ride of the section: rig, gait, seed, frame size and rate, readout (s), compression."""

    name: str
    rig: str
    gait: str
    seed: int
    size: tuple[int, int] | None = None
    fps: float | None = None
    readout_s: float = 0.025
    crf: int = 20


ROLLING_RIDES = (
    RollingRide("thesis_rising_trot", "thesis", "rising_trot", 5101),
    RollingRide("wide720p30_canter_crf28", "wide", "canter", 5102, size=(1280, 720), fps=30.0, crf=28),
    RollingRide("wide1080p60_canter_crf28", "wide", "canter", 5103, size=(1920, 1080), fps=60.0, crf=28),
)


def rolling_ride_row(ride: Path, result: dict) -> dict:
    """A ride's sync errors (frames), readouts (ms), speed error (%) and intervals against its truth.json."""
    from saddlescope.bench.coverage import truth_indicators

    truth = json.loads((ride / "truth.json").read_text())
    sync_err = {kind: {cam: round(result["sync"][kind][cam] - truth["sync"][kind][cam], 4)
                       for cam in result["sync"][kind]} for kind in result["sync"] if kind in truth["sync"]}
    ref = truth_indicators(result, truth)
    held = {}
    for key, (lo, hi) in result.get("indicators_interval_95", {}).items():
        if key in ref:
            held[key] = bool(lo <= ref[key] <= hi)
    return {
        "sync_error_frames": sync_err,
        "worst_sync_error_frames": max(abs(e) for per in sync_err.values() for e in per.values()),
        "readout_ms": {kind: q.get("readout_ms") for kind, q in result["quality"]["sync"].items()},
        "speed_error_pct": 100 * (result["indicators"]["vel_x_avg_kmh"] / truth["truth"]["speed_kmh"] - 1),
        "interval_holds_truth": held,
    }


def _analysed(tmp: Path, spec: RollingRide, readout_s: float) -> dict:
    from saddlescope.arena import RenderOptions
    from saddlescope.io.synth_writer import write_ride_bundle
    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    ride = tmp / f"rolling_{spec.name}_ro{1000 * readout_s:g}ms"
    if not (ride / "truth.json").exists():
        write_ride_bundle(ride, gait=spec.gait, seed=spec.seed, rig=spec.rig, size=spec.size, fps=spec.fps,
                          calibration_poses=60, extras=False,
                          options=RenderOptions(readout_s=readout_s, crf=spec.crf))
    try:
        result = analyze_bundle(ride)
    except Exception as exc:  # noqa: BLE001 - a benchmark reports every failure and goes on
        return {"error": f"{type(exc).__name__}: {exc}"}
    return rolling_ride_row(ride, result)


def rolling_shutter_section(tmp: Path, quick: bool) -> dict:
    """``rolling_shutter``: per ride the 25 ms readout's row and, at 30 fps, the global shutter's beside it.

    Quick mode: the thesis ride alone, without its twin.
    """
    rides = ROLLING_RIDES[:1] if quick else ROLLING_RIDES
    out: dict = {}
    for spec in rides:
        entry = {"rolling": _analysed(tmp, spec, spec.readout_s)}
        if not quick and (spec.fps or 30.0) <= 30.0:
            entry["global"] = _analysed(tmp, spec, 0.0)
        out[spec.name] = entry
    return {"rolling_shutter": out}

"""`saddlescope bench`'s coverage table: do the 95 % intervals contain the truth (issue 27)?

Synthetic rides from the arena (a table easy to extend: one :class:`CoverageRide` a row, rigs,
gaits, resolutions, frame rates, calibration poses; partial views and rides without a flash join
as the arena learns them) are analysed like any ride; each result's ``indicators_interval_95`` is
checked against the ride's ``truth.json``. Per indicator: the share of rides whose interval holds
the truth (goal 90-98 %) and the median interval width (% of the value). Beside it: the W_b r.m.s.
error on every ride not marked too uncertain (goal within 10 %), the share so marked (goal <= 1 in
10) and the speed error (goal within 1 %).

The rides' seeds (2001-2099) are used by no test and not by the rides the interval's noise floors
were set on (seeds 1001-1099, :data:`BUILD_RIDES`).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

__all__ = ["BUILD_RIDES", "COVERAGE_RIDES", "CoverageRide", "coverage_rows", "coverage_table", "run_coverage",
           "run_rides", "truth_indicators"]


@dataclass(frozen=True)
class CoverageRide:
    """One synthetic ride of the coverage table (arguments of ``write_ride_bundle``)."""

    rig: str
    gait: str
    seed: int
    size: tuple[int, int] | None = None
    fps: float | None = None
    calibration_poses: int = 30
    duration_s: float | None = None

    @property
    def name(self) -> str:
        """A folder name that says what the ride is."""
        size = "x".join(map(str, self.size)) if self.size else "default"
        fps = f"{self.fps:g}" if self.fps else "default"
        return f"{self.rig}_{self.gait}_{size}_{fps}fps_{self.calibration_poses}poses_s{self.seed}"


_GAITS = ("walk", "sitting_trot", "rising_trot", "canter")
# (rig, size, fps, calibration poses): the thesis's 640x480 at 30 fps and variations, the wide rig at
# lower resolutions and rates than its 1920x1080 at 60 fps (the 2 shared cores of the bench machine)
_SETUPS = (("thesis", None, None, 30), ("thesis", (800, 600), 30.0, 24), ("thesis", (640, 480), 60.0, 40),
           ("wide", (1280, 720), 30.0, 30), ("wide", (960, 540), 60.0, 24))


def _rides(first_seed: int, n: int) -> tuple[CoverageRide, ...]:
    """``n`` rides cycling through gaits and set-ups (4 and 5 are coprime: 20 rides meet every pair)."""
    out = []
    for i in range(n):
        rig, size, fps, poses = _SETUPS[i % len(_SETUPS)]
        out.append(CoverageRide(rig=rig, gait=_GAITS[i % len(_GAITS)], seed=first_seed + i, size=size, fps=fps,
                                calibration_poses=poses))
    return tuple(out)


# the rides the interval's floors were set on, and the rides the coverage is checked on
BUILD_RIDES: tuple[CoverageRide, ...] = _rides(1001, 12)
COVERAGE_RIDES: tuple[CoverageRide, ...] = _rides(2001, 40)


def run_rides(rides: Iterable[CoverageRide], out_dir: Path, *, keep_clips: bool = False, log=None) -> list[Path]:
    """Render and analyse each ride; keep ``ride.json``, ``truth.json`` and ``result.json`` (or ``error.txt``).

    A ride whose folder already holds a result or an error is not run again (a long run can resume).
    """
    from saddlescope.io.synth_writer import write_ride_bundle
    from saddlescope.services.analysis import analyze_bundle

    done = []
    for ride in rides:
        folder = Path(out_dir) / ride.name
        if not ((folder / "result.json").exists() or (folder / "error.txt").exists()):
            work = folder / "bundle"
            write_ride_bundle(work, gait=ride.gait, seed=ride.seed, rig=ride.rig, size=ride.size, fps=ride.fps,
                              duration_s=ride.duration_s, calibration_poses=ride.calibration_poses, extras=False)
            shutil.copy(work / "truth.json", folder / "truth.json")
            (folder / "ride.txt").write_text(json.dumps(asdict(ride)))
            try:
                result = analyze_bundle(work)
            except Exception as exc:  # noqa: BLE001 - a benchmark reports every failure and goes on
                (folder / "error.txt").write_text(f"{type(exc).__name__}: {exc}")
            else:
                (folder / "result.json").write_text(json.dumps(result))
            if not keep_clips:
                shutil.rmtree(work, ignore_errors=True)
        if log:
            log(ride.name)
        done.append(folder)
    return done


def truth_indicators(result: dict, truth: dict) -> dict:
    """truth.json's indicators on the result's analysed duration (the VDV scales with it)."""
    ref = dict(truth.get("indicators", {}))
    analysed_s = result["period_s"] * round(result["window"]["duration_s"] / result["period_s"])
    ratio = analysed_s / float(truth["window"]["duration_s"])
    out = {}
    for key, value in ref.items():
        if not isinstance(value, int | float):
            continue
        if key.startswith("vdv_"):
            value = value * ratio ** 0.25  # VDV^4 grows with the duration of a periodic signal
        # (T_VDV = τ (VDV_threshold / VDV)^4 = VDV_threshold^4 / (VDV^4 / τ): the same for any whole
        # number of periods, as are the r.m.s., peaks and the A(8) times)
        out[key] = float(value)
    return out


def coverage_rows(folders: Iterable[Path], *, recompute: bool = True) -> list[dict]:
    """Per ride: the truth, the values, the intervals and the too-uncertain verdict.

    With ``recompute`` the intervals are computed again from the stored result document (the
    current interval model on results analysed earlier); otherwise the document's own are read.
    """
    from saddlescope.core.vibration.intervals import decision_uncertainty, ride_intervals
    from saddlescope.io.result_document import result_from_document

    rows = []
    for folder in folders:
        folder = Path(folder)
        row: dict = {"ride": folder.name}
        if (folder / "error.txt").exists() or not (folder / "result.json").exists():
            row["error"] = (folder / "error.txt").read_text() if (folder / "error.txt").exists() else "not run"
            rows.append(row)
            continue
        doc = json.loads((folder / "result.json").read_text())
        truth = json.loads((folder / "truth.json").read_text())
        if recompute or "indicators_interval_95" not in doc:
            intervals = ride_intervals(result_from_document(doc))
        else:
            intervals = {k: tuple(v) for k, v in doc["indicators_interval_95"].items()}
        row.update({"values": doc["indicators"], "intervals": intervals,
                    "truth": truth_indicators(doc, truth),
                    "uncertain": decision_uncertainty(doc["indicators"], intervals)})
        rows.append(row)
    return rows


def coverage_table(rows: Sequence[dict], keys: Sequence[str] | None = None) -> dict:
    """The coverage table: per indicator the share of rides whose interval holds the truth and the
    median width; the W_b r.m.s. error on rides not marked too uncertain, the share marked, speed."""
    from saddlescope.core.vibration.intervals import INTERVAL_KEYS

    ok = [r for r in rows if "error" not in r]
    table: dict = {}
    for key in keys or INTERVAL_KEYS:
        hits, widths = [], []
        for r in ok:
            if key not in r["truth"] or key not in r["intervals"]:
                continue
            lo, hi = r["intervals"][key]
            true = r["truth"][key]
            hits.append(bool(lo <= true <= hi))
            value = r["values"][key]
            widths.append(100.0 * (hi - lo) / abs(value) if value else np.inf)
        if hits:
            table[key] = {"coverage_pct": 100.0 * float(np.mean(hits)), "median_width_pct": float(np.median(widths)),
                          "rides": len(hits)}
    wb = [(r, 100.0 * (r["values"]["acc_y_wb_rms"] / r["truth"]["acc_y_wb_rms"] - 1)) for r in ok]
    kept = [e for r, e in wb if not r["uncertain"]]
    speed = [100.0 * (r["values"]["vel_x_avg_kmh"] / r["truth"]["vel_x_avg_kmh"] - 1) for r in ok]
    return {
        "rides": len(rows), "analysed": len(ok),
        "failed": [r["ride"] + ": " + r["error"] for r in rows if "error" in r],
        "indicators": table,
        "marked_too_uncertain": [r["ride"] for r in ok if r["uncertain"]],
        "marked_too_uncertain_pct": 100.0 * float(np.mean([bool(r["uncertain"]) for r in ok])) if ok else None,
        "acc_y_wb_rms_max_abs_error_pct_not_marked": float(max(map(abs, kept))) if kept else None,
        # per ride: the W_b r.m.s. error and its interval's half-width (% of the value), and the verdict
        "per_ride": [{"ride": r["ride"], "acc_y_wb_rms_error_pct": round(e, 2),
                      "acc_y_wb_rms_half_width_pct": round(_half_width_pct(r, "acc_y_wb_rms"), 2),
                      "too_uncertain": r["uncertain"]} for r, e in wb],
        "speed_max_abs_error_pct": float(max(map(abs, speed))) if speed else None,
    }


def _half_width_pct(row: dict, key: str) -> float:
    lo, hi = row["intervals"][key]
    return 50.0 * (hi - lo) / abs(row["values"][key])


def run_coverage(tmp: Path | None = None, *, quick: bool = False, rides: Sequence[CoverageRide] | None = None
                 ) -> dict:
    """The coverage table over :data:`COVERAGE_RIDES` (``quick``: the first 4), analysed in ``tmp``.

    Without ``tmp`` a temporary folder is made and removed. 40 rides take about an hour on two cores.
    """
    import tempfile

    chosen = tuple(rides) if rides is not None else (COVERAGE_RIDES[:4] if quick else COVERAGE_RIDES)
    own = tmp is None
    work = Path(tempfile.mkdtemp(prefix="saddlescope-coverage-")) if own else Path(tmp) / "coverage"
    try:
        folders = run_rides(chosen, work)
        return coverage_table(coverage_rows(folders, recompute=False))
    finally:
        if own:
            shutil.rmtree(work, ignore_errors=True)

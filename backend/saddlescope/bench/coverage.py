"""`saddlescope bench`'s coverage table: whether the 95 % intervals contain the truth (issue 27).

Synthetic rides from the arena (a table easy to extend: one :class:`CoverageRide` a row: rigs, gaits,
resolutions, frame rates, calibration poses, partial views with the board through the middle only,
rides without a flash) are analysed like any ride; each result's ``indicators_interval_95`` is
checked against the ride's ``truth.json``. Per indicator: the share of rides whose interval holds
the truth (goal 90-98 %) and the median interval width (% of the value). Beside it: the W_b r.m.s.
error on every ride not marked too uncertain (goal within 10 %), the share so marked (goal <= 1 in
10), the speed error (goal within 1 %), the motion sync's offsets against the arena's on the rides
without a flash (goal within 0.1 frame) and, on rides analysed with both syncs, how far the motion
sync's indicators are from the flash's (goal within 2 %).

The rides' seeds (2001-2099) are used by no test and not by the rides the interval's noise floors
were set on (seeds 1001-1099, :data:`BUILD_RIDES` and :data:`BUILD_RIDES_PARTIAL_NO_FLASH`).
``python -m saddlescope.bench.coverage --out DIR`` runs the table alone and keeps every ride's
documents, so that the intervals can be recomputed later with another model (``--table-only``);
``--rides field`` the field-nuisance table of issue 38 (:data:`FIELD_RIDES`, :mod:`.nuisances`).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

__all__ = ["BUILD_RIDES", "BUILD_RIDES_PARTIAL_NO_FLASH", "COVERAGE_RIDES", "FIELD_BOOT_SHARES", "FIELD_CRFS",
           "FIELD_PASSES", "run_field_nuisances",
           "FIELD_READOUTS_S", "FIELD_RIDES", "NUISANCE_RIDES", "SYNC_COMPARED_KEYS",
           "CoverageRide", "coverage_rows", "coverage_table", "main", "motion_vs_flash", "run_coverage", "run_rides",
           "sync_check", "truth_indicators"]


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
    board_band: float | None = None  # the board carried only through this central share of the volume
    speed_range_m_s: tuple[float, float] | None = None  # e.g. a canter at 4-6 m/s
    flash: bool = True  # False: no sync lamp, the cameras synchronised from the markers' motion
    # also analysed synchronised from motion although it has a flash (``result_motion.json``): the two
    # syncs' results side by side
    motion_sync_too: bool = False
    # the field's nuisances (issue 38, arena.RenderOptions): the rider's boot over the rear marker for
    # this share of every stride, a rolling shutter's readout (s), the clips' compression, a 6th
    # stride harmonic carrying this share of the vertical acceleration
    boot_share: float = 0.0
    readout_s: float = 0.0
    crf: int = 20
    high_harmonic_share: float = 0.0
    # passes of the horse in front of the cameras in the one motion clip (issue 38 item 4: strides pooled)
    passes: int = 1

    def render_options(self):
        """The arena's render options for this ride."""
        from saddlescope.arena import RenderOptions

        return RenderOptions(flash=self.flash, boot_share=self.boot_share, readout_s=self.readout_s, crf=self.crf,
                             high_harmonic_share=self.high_harmonic_share, passes=self.passes)

    @property
    def nuisance_suffix(self) -> str:
        """The nuisances in a folder name ("" for none)."""
        return ((f"_boot{self.boot_share:g}" if self.boot_share else "")
                + (f"_ro{1000 * self.readout_s:g}ms" if self.readout_s else "")
                + (f"_crf{self.crf}" if self.crf != 20 else "")
                + (f"_h6x{self.high_harmonic_share:g}" if self.high_harmonic_share else "")
                + (f"_{self.passes}passes" if self.passes != 1 else ""))

    @property
    def name(self) -> str:
        """A folder name that says what the ride is."""
        size = "x".join(map(str, self.size)) if self.size else "default"
        fps = f"{self.fps:g}" if self.fps else "default"
        extra = (f"_band{self.board_band:g}" if self.board_band is not None else "") + (
            "_{:g}-{:g}ms".format(*self.speed_range_m_s) if self.speed_range_m_s else "") + (
            "" if self.flash else "_noflash") + ("_bothsyncs" if self.motion_sync_too else "") + self.nuisance_suffix
        return f"{self.rig}_{self.gait}_{size}_{fps}fps_{self.calibration_poses}poses{extra}_s{self.seed}"


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


def _partial_and_no_flash(first_seed: int) -> tuple[CoverageRide, ...]:
    """Rigs nobody tuned for.

    4 canters at 4-6 m/s on the wide rig with partial views and the board through its middle only (two bands), 4
    rides without a flash (thesis and wide rigs, two gaits each) and 2 rides with a flash also synchronised from
    motion (the two syncs side by side).
    """
    partial = tuple(CoverageRide(rig="wide_partial", gait="canter", seed=first_seed + i, board_band=band,
                                 speed_range_m_s=(4.0, 6.0), calibration_poses=30)
                    for i, band in enumerate((0.6, 0.8, 0.6, 0.8)))
    no_flash = tuple(CoverageRide(rig=rig, gait=gait, seed=first_seed + 4 + i, size=size, fps=fps, flash=False)
                     for i, (rig, gait, size, fps) in enumerate((
                         ("thesis", "sitting_trot", None, None), ("thesis", "canter", (640, 480), 60.0),
                         ("wide", "rising_trot", (1280, 720), 30.0), ("wide", "walk", (960, 540), 60.0))))
    both = (CoverageRide(rig="thesis", gait="rising_trot", seed=first_seed + 8, motion_sync_too=True),
            CoverageRide(rig="wide", gait="canter", seed=first_seed + 9, size=(1280, 720), fps=30.0,
                         motion_sync_too=True))
    return partial + no_flash + both


def _nuisance_rides(first_seed: int) -> tuple[CoverageRide, ...]:
    """The field's nuisances (issue 38), each ride beside the same horse, rig and seed without it.

    The rider's boot over the rear marker on canters and a sitting trot (thesis and wide rigs), a sitting
    trot whose saddle rings at its 6th stride harmonic, and a rising trot filmed by phones (25 ms readout,
    x264 CRF 28).
    """
    base = (CoverageRide(rig="thesis", gait="canter", seed=first_seed),
            CoverageRide(rig="wide", gait="canter", seed=first_seed + 1, size=(1280, 720), fps=30.0),
            CoverageRide(rig="thesis", gait="sitting_trot", seed=first_seed + 2))
    boot = tuple(CoverageRide(**{**asdict(r), "boot_share": 0.2}) for r in base)
    harmonic = (CoverageRide(rig="thesis", gait="sitting_trot", seed=first_seed + 3),
                CoverageRide(rig="thesis", gait="sitting_trot", seed=first_seed + 3, high_harmonic_share=0.15))
    phone = (CoverageRide(rig="thesis", gait="rising_trot", seed=first_seed + 4),
             CoverageRide(rig="thesis", gait="rising_trot", seed=first_seed + 4, readout_s=0.025, crf=28))
    return base + boot + harmonic + phone


# the field-nuisance table's factors (issue 38): the rider's boot over the rear marker for a fifth of
# every stride or none, a rolling shutter's readout (s), the clips' x264 CRF; rigs: the thesis's
# 640x480 at 30 fps and the wide rig at 1280x720 at 30 fps
FIELD_BOOT_SHARES = (0.0, 0.2)
FIELD_READOUTS_S = (0.0, 0.015, 0.033)
FIELD_CRFS = (18, 28)
FIELD_PASSES = (1, 3)  # one crossing of the cameras, or three (strides pooled)
_FIELD_RIGS = (("thesis", (640, 480), 30.0), ("wide", (1280, 720), 30.0))


def _field_rides(first_seed: int) -> tuple[CoverageRide, ...]:
    """The field-nuisance table: 24 rides, a fraction of the 4 x 2 x 2 x 3 x 2 x 2 full design.

    Every gait on both rigs at each readout (4 x 2 x 3); the boot, the CRF and the passes (1 or 3) alternate so
    that within each gait and rig (three readouts) both levels of each appear: every level of every factor meets
    every gait, both rigs and every level of the other factors. The order interleaves the readouts, so a run
    stopped early still holds each gait on both rigs.
    """
    out: list[CoverageRide] = []
    for k in range(len(FIELD_READOUTS_S)):
        for i, gait in enumerate(_GAITS):
            for j, (rig, size, fps) in enumerate(_FIELD_RIGS):
                boot = FIELD_BOOT_SHARES[(i + j + k) % 2]
                crf = FIELD_CRFS[(i // 2 + j + k) % 2]
                passes = FIELD_PASSES[(i // 2 + i + j + k) % 2]
                out.append(CoverageRide(rig=rig, gait=gait, seed=first_seed + len(out), size=size, fps=fps,
                                        boot_share=boot, readout_s=FIELD_READOUTS_S[k], crf=crf, passes=passes))
    return tuple(out)


# the rides the interval's floors were set on, and the rides the coverage is checked on
BUILD_RIDES: tuple[CoverageRide, ...] = _rides(1001, 12)
BUILD_RIDES_PARTIAL_NO_FLASH: tuple[CoverageRide, ...] = _partial_and_no_flash(1013)
COVERAGE_RIDES: tuple[CoverageRide, ...] = _rides(2001, 40) + _partial_and_no_flash(2041)
# the field's nuisances, seeds used by no test (issue 38)
NUISANCE_RIDES: tuple[CoverageRide, ...] = _nuisance_rides(3101)
# the field-nuisance coverage table (issue 38), seeds used by no test
FIELD_RIDES: tuple[CoverageRide, ...] = _field_rides(3201)


def run_rides(rides: Iterable[CoverageRide], out_dir: Path, *, keep_clips: bool = False, log=None) -> list[Path]:
    """Render and analyse each ride; keep ``ride.json``, ``truth.json`` and ``result.json`` (or ``error.txt``).

    A ride with ``motion_sync_too`` is analysed a second time synchronised from its markers' motion
    (``result_motion.json`` or ``error_motion.txt``). A ride whose folder already holds a result or an
    error is not run again (a long run can resume).
    """
    done = []
    for ride in rides:
        folder = Path(out_dir) / ride.name
        if not ((folder / "result.json").exists() or (folder / "error.txt").exists()):
            _run_ride(ride, folder, keep_clips=keep_clips)
        if log:
            log(ride.name)
        done.append(folder)
    return done


def _run_ride(ride: CoverageRide, folder: Path, *, keep_clips: bool) -> None:
    from saddlescope.io.synth_writer import write_ride_bundle

    work = folder / "bundle"
    write_ride_bundle(work, gait=ride.gait, seed=ride.seed, rig=ride.rig, size=ride.size, fps=ride.fps,
                      duration_s=ride.duration_s, calibration_poses=ride.calibration_poses, extras=False,
                      board_band=ride.board_band, speed_range_m_s=ride.speed_range_m_s,
                      options=ride.render_options())
    shutil.copy(work / "truth.json", folder / "truth.json")
    (folder / "ride.txt").write_text(json.dumps(asdict(ride)))
    if ride.motion_sync_too:  # first, so that a resumed run never lacks it beside a result
        _analyse(work, folder, "_motion", {"sync": {"method": "motion"}})
    _analyse(work, folder, "", None)
    if not keep_clips:
        shutil.rmtree(work, ignore_errors=True)


def _analyse(work: Path, folder: Path, suffix: str, overrides: dict | None) -> None:
    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    try:
        result = analyze_bundle(work, meta_overrides=overrides)
    except Exception as exc:  # noqa: BLE001 - a benchmark reports every failure and goes on
        (folder / f"error{suffix}.txt").write_text(f"{type(exc).__name__}: {exc}")
    else:
        (folder / f"result{suffix}.json").write_text(json.dumps(result))


def truth_indicators(result: dict, truth: dict) -> dict:
    """truth.json's indicators on the result's analysed duration (the VDV scales with it)."""
    ref = dict(truth.get("indicators", {}))
    # the indicators are those of the fitted periodic motion over n_periods strides, also where the
    # window held fewer (a partial-view canter analysed on one stride: 2^0.25 = +19 % on VDV otherwise)
    n_periods = (result.get("params") or {}).get("n_periods") or round(result["window"]["duration_s"]
                                                                       / result["period_s"])
    analysed_s = result["period_s"] * n_periods
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
    speed_ratio = _used_passes_speed_ratio(result, truth)
    if speed_ratio is not None:  # the speed (and the distances, speed x time) of the passes the analysis used
        for key in out:
            if key == "vel_x_avg_kmh" or (key.startswith("d_") and key.endswith("_km")):
                out[key] *= speed_ratio
    return out


def _used_passes_speed_ratio(result: dict, truth: dict) -> float | None:
    """The mean true speed of the passes the analysis used over that of every pass; None for one pass.

    The truth's speed is the mean of all the ride's passes (each counts once), the analysis's the mean of the
    passes it used: a pass left out ("no periodic motion found") changes what the speed is the mean of. Each
    used pass of the result is matched to the true pass whose span in view overlaps it most.
    """
    true_passes = (truth.get("truth") or {}).get("passes") or []
    found = [p for p in result.get("passes") or [] if p.get("used")]
    if len(true_passes) < 2 or not found:
        return None

    def overlap(found_pass: dict, true_pass: dict) -> float:
        start, end = true_pass["in_view_s"]
        return min(end, found_pass["end_s"]) - max(start, found_pass["start_s"])

    used = [max(true_passes, key=lambda t, f=f: overlap(f, t))["speed_m_s"] for f in found]
    return float(np.mean(used) / np.mean([t["speed_m_s"] for t in true_passes]))


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
            if (folder / "ride.txt").exists():
                row["setup"] = json.loads((folder / "ride.txt").read_text())
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
                    "uncertain": decision_uncertainty(doc["indicators"], intervals),
                    "sync": sync_check(doc, truth)})
        if (folder / "ride.txt").exists():  # the ride's set-up: its nuisances for the field table
            row["setup"] = json.loads((folder / "ride.txt").read_text())
        if (folder / "result_motion.json").exists():
            row["motion_sync"] = motion_vs_flash(json.loads((folder / "result_motion.json").read_text()), doc, truth)
        elif (folder / "error_motion.txt").exists():
            row["motion_sync"] = {"error": (folder / "error_motion.txt").read_text()}
        rows.append(row)
    return rows


# the indicators compared between the two syncs of one ride
SYNC_COMPARED_KEYS = ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "acc_y_max", "vel_x_avg_kmh", "stride_frequency_hz",
                      "amplitude_y_m")


def sync_check(doc: dict, truth: dict, kind: str = "motion") -> dict:
    """The motion clip's sync method and the largest error of its offsets against the arena's (frames).

    Offsets count how many frames later an instant appears in a camera; both sides are taken
    relative to the first camera (the result's reference).
    """
    found, true = doc.get("sync", {}).get(kind, {}), truth.get("sync", {}).get(kind, {})
    method = (doc.get("quality", {}).get("sync", {}).get(kind) or {}).get("method")
    cams = [c for c in found if c in true]
    if not cams:
        return {"method": method, "offset_error_frames": None}
    ref = cams[0]
    errors = [(found[c] - found[ref]) - (true[c] - true[ref]) for c in cams[1:]]
    return {"method": method, "offset_error_frames": float(max(map(abs, errors), default=0.0))}


def motion_vs_flash(motion_doc: dict, flash_doc: dict, truth: dict) -> dict:
    """One ride synchronised from its markers' motion against the same ride synchronised by its flash.

    The offsets' error of each against the arena and the indicators' differences (% of the flash's).
    """
    diffs = {k: 100.0 * (motion_doc["indicators"][k] / flash_doc["indicators"][k] - 1) for k in SYNC_COMPARED_KEYS
             if flash_doc["indicators"].get(k) and motion_doc["indicators"].get(k) is not None}
    return {"offset_error_frames": sync_check(motion_doc, truth)["offset_error_frames"],
            "flash_offset_error_frames": sync_check(flash_doc, truth)["offset_error_frames"],
            "method": sync_check(motion_doc, truth)["method"],
            "indicator_diff_pct": {k: round(v, 3) for k, v in diffs.items()},
            "max_abs_diff_pct": float(max(map(abs, diffs.values()), default=np.nan))}


def coverage_table(rows: Sequence[dict], keys: Sequence[str] | None = None) -> dict:
    """The coverage table.

    Per indicator the share of rides whose interval holds the truth and the median width; the W_b r.m.s. error on
    rides not marked too uncertain, the share marked, speed.
    """
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
        **_sync_summary(ok),
    }


def _sync_summary(ok: Sequence[dict]) -> dict:
    """The rides synchronised from motion (no flash).

    Their offsets' error; the rides analysed with both syncs: how far apart the results are.
    """
    moved = [(r["ride"], r["sync"]) for r in ok if (r.get("sync") or {}).get("method") == "motion"]
    errors = [s["offset_error_frames"] for _, s in moved if s["offset_error_frames"] is not None]
    both = [(r["ride"], r["motion_sync"]) for r in ok if "motion_sync" in r]
    return {
        "no_flash": [{"ride": name, **s} for name, s in moved],
        "no_flash_max_offset_error_frames": float(max(errors)) if errors else None,
        "motion_vs_flash": [{"ride": name, **m} for name, m in both],
        "motion_vs_flash_max_abs_diff_pct": float(max(m["max_abs_diff_pct"] for _, m in both if "error" not in m))
        if any("error" not in m for _, m in both) else None,
    }


def _half_width_pct(row: dict, key: str) -> float:
    lo, hi = row["intervals"][key]
    return 50.0 * (hi - lo) / abs(row["values"][key])


def run_coverage(tmp: Path | None = None, *, quick: bool = False, rides: Sequence[CoverageRide] | None = None
                 ) -> dict:
    """The coverage table over :data:`COVERAGE_RIDES` (``quick``: the first 4), analysed in ``tmp``.

    Without ``tmp`` a temporary folder is made and removed. The 50 rides take about 2.5 hours on two
    shared cores (1.5-3 minutes a ride; the wide_partial canters about 4).
    """
    import tempfile

    chosen = tuple(rides) if rides is not None else (COVERAGE_RIDES[:4] if quick else COVERAGE_RIDES)
    own = tmp is None
    work = Path(tempfile.mkdtemp(prefix="saddlescope-coverage-")) if tmp is None else Path(tmp) / "coverage"
    try:
        folders = run_rides(chosen, work)
        return coverage_table(coverage_rows(folders, recompute=False))
    finally:
        if own:
            shutil.rmtree(work, ignore_errors=True)


_RIDE_SETS = {"coverage": lambda: COVERAGE_RIDES, "build": lambda: BUILD_RIDES,
              "build-partial": lambda: BUILD_RIDES_PARTIAL_NO_FLASH, "nuisance": lambda: NUISANCE_RIDES,
              "field": lambda: FIELD_RIDES}


def run_field_nuisances(tmp: Path | None = None, *, quick: bool = False) -> dict:
    """The field-nuisance table over :data:`FIELD_RIDES` (``quick``: the first 8).

    Without ``tmp`` a temporary folder is made and removed. The 24 rides take about an hour on two quiet cores
    (the wide rig's 1280x720 rides about 3 minutes each).
    """
    import tempfile

    from saddlescope.bench.nuisances import field_table

    chosen = FIELD_RIDES[:8] if quick else FIELD_RIDES  # the first 8: every gait on both rigs
    own = tmp is None
    work = Path(tempfile.mkdtemp(prefix="saddlescope-field-")) if tmp is None else Path(tmp) / "field_nuisances"
    try:
        return field_table(coverage_rows(run_rides(chosen, work), recompute=False))
    finally:
        if own:
            shutil.rmtree(work, ignore_errors=True)


def _seed_list(text: str) -> list[int]:
    """``--seeds 3208,3214`` -> [3208, 3214]."""
    import argparse

    try:
        return [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of seeds") from None


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m saddlescope.bench.coverage --out DIR``.

    The coverage part of ``saddlescope bench`` alone, keeping every ride's documents in DIR (a stopped run resumes;
    ``--table-only`` recomputes the intervals of the rides done with the current model and writes the table).
    """
    import argparse
    import sys
    import time

    parser = argparse.ArgumentParser(prog="python -m saddlescope.bench.coverage", description=main.__doc__)
    parser.add_argument("--out", required=True, type=Path, help="folder for the rides' documents and table.json")
    parser.add_argument("--rides", choices=sorted(_RIDE_SETS), default="coverage")
    parser.add_argument("--table-only", action="store_true", help="do not run rides, tabulate those done")
    parser.add_argument("--stored-intervals", action="store_true",
                        help="read the documents' own intervals instead of recomputing them")
    parser.add_argument("--seeds", type=_seed_list, default=None,
                        help="only these rides of the set, in this order (comma-separated seeds, e.g. 3208,3214)")
    args = parser.parse_args(argv)
    # the rigs nobody tuned for first: a run stopped early still holds them
    rides = sorted(_RIDE_SETS[args.rides](), key=lambda r: r.flash and not r.board_band and not r.motion_sync_too)
    if args.seeds is not None:
        unknown = [s for s in args.seeds if all(r.seed != s for r in rides)]
        if unknown:
            parser.error(f"no ride of --rides {args.rides} has seed {', '.join(map(str, unknown))}")
        rides = [r for s in args.seeds for r in rides if r.seed == s]  # a seed may name two rides (a twin)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.table_only:
        folders = [args.out / r.name for r in rides if (args.out / r.name).exists()]
    else:
        t0 = time.monotonic()
        folders = run_rides(rides, args.out, log=lambda name: print(
            f"{time.monotonic() - t0:7.0f} s  done {name}", file=sys.stderr, flush=True))
    rows = coverage_rows(folders, recompute=not args.stored_intervals)
    if args.rides in ("field", "nuisance"):  # the field's nuisances: their own table (bench.nuisances)
        from saddlescope.bench.nuisances import field_table

        table = field_table(rows)
        (args.out / "field_table.json").write_text(json.dumps(table, indent=1))
        print(json.dumps(table, indent=1))
        return 0
    table = coverage_table(rows)
    (args.out / "table.json").write_text(json.dumps(table, indent=1))
    print(json.dumps({k: v for k, v in table.items() if k not in ("per_ride",)}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

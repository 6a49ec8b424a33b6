"""Use case: analyse one ride bundle end to end (what `saddlescope analyze` and the jobs run)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from saddlescope.core.findings import Finding
from saddlescope.core.pipeline import PipelineParams, analyze_ride
from saddlescope.core.types import Rig
from saddlescope.io.bundle import open_bundle
from saddlescope.io.clip_source import BundleClips
from saddlescope.io.result_document import result_to_document
from saddlescope.io.result_schema import validate_result
from saddlescope.io.threads import single_threaded_numerics


def load_calibration_file(path: Path) -> Rig:
    """A rig from a calibration TOML (anipose, Pose2Sim, FreeMoCap, caliscope; each in its unit) or our JSON."""
    from saddlescope.io.bundle import read_bundle_calibration

    return read_bundle_calibration(path)[0]


def analyze_bundle(path: Path | str, *, on_progress: Callable[[float, str], None] | None = None,
                   params: PipelineParams | None = None, rig: Rig | None = None,
                   meta_overrides: dict | None = None, rig_report: dict | None = None) -> dict:
    """Open a ride bundle (folder or zip), run the pipeline, return the validated result document.

    `rig_report`: a reused rig calibration's `n_views` and `board_coverage` (where its board has been), and for a
    board refined by a wand its `lens_coverage` (where the board and the wand have been).

    `meta_overrides` replace keys of the bundle's ride.json (a ride's gait edited after upload).
    """
    params = params or PipelineParams()
    if params.threads is None:  # the worker's budget (SADDLESCOPE_WORKER_THREADS, else its cgroup quota)
        from dataclasses import replace

        from saddlescope.settings import get_settings

        params = replace(params, threads=get_settings().resolved_worker_threads)
    with (open_bundle(Path(path)) as bundle, single_threaded_numerics(),
          BundleClips(bundle.clip_paths, threads=params.threads) as clips):
        notes: list[Finding] = []
        if rig is None and bundle.calibration_file is not None:
            from saddlescope.io.bundle import read_bundle_calibration

            rig, notes = read_bundle_calibration(bundle.calibration_file)
        meta = {**bundle.meta, **(meta_overrides or {})}
        result = analyze_ride(clips, meta, params=params, rig=rig, on_progress=on_progress,
                              input_flags=list(bundle.warnings) + notes, rig_report=rig_report)
    document = result_to_document(result)
    validate_result(document)
    return document

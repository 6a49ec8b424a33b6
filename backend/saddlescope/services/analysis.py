"""Use case: analyse one ride bundle end to end (what `saddlescope analyze` and the jobs run)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from saddlescope.core.pipeline import PipelineParams, analyze_ride
from saddlescope.core.types import Rig
from saddlescope.io.bundle import open_bundle
from saddlescope.io.clip_source import BundleClips
from saddlescope.io.result_document import result_to_document
from saddlescope.io.result_schema import validate_result


def load_calibration_file(path: Path) -> Rig:
    """A rig from an anipose-style TOML or our calibration JSON."""
    from saddlescope.io.calibration_files import read_anipose_toml
    from saddlescope.io.rig_document import rig_from_dict

    if path.suffix.lower() == ".toml":
        return read_anipose_toml(path)
    import json

    return rig_from_dict(json.loads(path.read_text()))


def analyze_bundle(path: Path | str, *, on_progress: Callable[[float, str], None] | None = None,
                   params: PipelineParams | None = None, rig: Rig | None = None) -> dict:
    """Open a ride bundle (folder or zip), run the pipeline, return the validated result document."""
    with open_bundle(Path(path)) as bundle:
        clips = BundleClips(bundle.clip_paths)
        if rig is None and bundle.calibration_file is not None:
            rig = load_calibration_file(bundle.calibration_file)
        result = analyze_ride(clips, bundle.meta, params=params, rig=rig, on_progress=on_progress,
                              input_flags=bundle.warnings)
    document = result_to_document(result)
    validate_result(document)
    return document

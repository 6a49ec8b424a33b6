"""A job's stage in plain words, and its progress as a whole percentage, for the dashboard.

A job's ``stage`` is the stage's name, optionally with the step inside it after ': ' (``"analyze:
detection"``, ``"probe: motion/left"``); this one table says each in words a club understands.
"""

from __future__ import annotations

from saddlescope.core.types import CAMERA_ROLES

__all__ = ["STAGE_LABELS", "STEP_LABELS", "progress_percent", "stage_label"]

# Stage names (services/jobs/stages.py) -> what the job is doing.
STAGE_LABELS: dict[str, str] = {
    "probe": "Checking the clips",
    "assemble": "Putting the clips together",
    "calibrate": "Calibrating the cameras",
    "calibrate_rig": "Calibrating the rig's cameras",
    "check_calibration": "Checking the calibration clips",
    "analyze": "Analysing the ride",
    "similarity": "Comparing rides",
    "selftest": "Testing the workers",
}

# Steps reported inside a stage (the pipeline's own stages) -> plain words.
STEP_LABELS: dict[str, str] = {
    "sync": "matching the cameras' clocks by the flash",
    "board views": "finding the calibration board",
    "calibration": "calibrating the cameras",
    "detection": "finding the markers",
    "triangulation": "locating the markers in 3-D",
    "kinematics": "fitting the saddle's motion",
    "indicators": "computing the comfort indicators",
}

_STATUS_LABELS = {
    "queued": "Waiting to start",
    "done": "Finished",
    "failed": "Stopped with an error",
    "cancelled": "Cancelled",
}


def stage_label(stage: str | None, status: str) -> str:
    """The job's stage in plain words ("Analysing the ride: finding the markers")."""
    if status in _STATUS_LABELS and (status != "queued" or not stage):
        return _STATUS_LABELS[status]
    if not stage:
        return "Starting"
    name, _, detail = stage.partition(":")
    name, detail = name.strip(), detail.strip()
    label = STAGE_LABELS.get(name, name.replace("_", " ").capitalize())
    if detail:
        step = STEP_LABELS.get(detail)
        kind, _, camera = detail.partition("/")
        if step is None and camera in CAMERA_ROLES:  # a clip: "motion/left"
            step = f"{kind} clip of the {camera} camera"
        label = f"{label}: {step or detail}"
    return label


def progress_percent(progress: float | None, status: str) -> int:
    """Progress 0-1 as a whole percentage (100 only when done; a running job shows at most 99)."""
    if status == "done":
        return 100
    value = int((progress or 0.0) * 100)
    return max(0, min(value, 99))

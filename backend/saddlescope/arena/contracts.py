"""The bundle contracts' documents of a synthetic ride: its ride.json, and a result structure check.

``ride_manifest`` writes the ride.json of a synthetic bundle (CONTRACTS section 1);
``check_result_structure`` lists what a result document (CONTRACTS section 2) lacks.
"""

from __future__ import annotations

import numpy as np

from saddlescope.arena.content import BOARD, EXTRA_CLIPS
from saddlescope.arena.scene import Scene
from saddlescope.core.types import CAMERA_ROLES, CLIP_KINDS
from saddlescope.core.vibration import CONTRACT_KEYS

__all__ = ["RESULT_KEYS", "check_result_structure", "ride_manifest"]


def ride_manifest(scene: Scene, *, suffix: str = ".mp4") -> dict:
    """The ride.json of the bundle (CONTRACTS section 1) with clip paths relative to the bundle."""
    clips = {kind: {role: f"{kind}/{role}{suffix}" for role in CAMERA_ROLES} for kind in CLIP_KINDS}
    extra = {
        kind: {role: f"{kind}/{role}{suffix}" for role in CAMERA_ROLES} for kind in EXTRA_CLIPS if kind in scene.timings
    }
    manifest = {
        "format": "saddlescope.ride/1",
        "cameras": list(CAMERA_ROLES),
        "board": {
            "kind": BOARD.kind,
            "inner_corners": list(BOARD.inner_corners),
            "square_mm": BOARD.square_mm,
        },
        "sync": {"method": "flash" if scene.options.flash else "motion"},
        "markers": {"horse": 3, "plumb": 2, "saddle": 1},
        "horse": scene.meta["horse"],
        "rider": scene.meta["rider"],
        "gait": scene.gait,
        "direction": scene.direction,
        "clips": clips,
        "fps": scene.fps,
        "frames": {kind: dict(tm.n_frames) for kind, tm in scene.timings.items()},
        "synthetic": {"seed": scene.seed, "rig": scene.rig.name, "truth": "truth.json"},
    }
    if extra:
        manifest["extra_clips"] = extra
    return manifest


RESULT_KEYS = (
    "format",
    "fps",
    "calibration",
    "sync",
    "period_s",
    "window",
    "saddle",
    "angular",
    "indicators",
    "quality",
    "timings_s",
)


def check_result_structure(result: dict, *, cameras=CAMERA_ROLES) -> list[str]:
    """Problems with a result document's structure (CONTRACTS section 2); empty when complete.

    A small structural check (keys, array shapes, indicator keys), not a JSON schema.
    """
    problems = [f"missing key {k!r}" for k in RESULT_KEYS if k not in result]
    if problems:
        return problems
    if result["format"] != "saddlescope.result/1":
        problems.append(f"format is {result['format']!r}")
    cams = result["calibration"].get("cameras", {})
    for role in cameras:
        cam = cams.get(role, {})
        if np.shape(cam.get("K")) != (3, 3) or np.shape(cam.get("dist")) != (5,):
            problems.append(f"calibration.cameras.{role} lacks K (3, 3) or dist (5,)")
        if len(cam.get("image_size", [])) != 2:
            problems.append(f"calibration.cameras.{role}.image_size")
    for role in cameras[1:]:
        ext = result["calibration"].get("extrinsics", {}).get(role, {})
        if np.shape(ext.get("R")) != (3, 3) or np.shape(ext.get("t_mm")) != (3,):
            problems.append(f"calibration.extrinsics.{role} lacks R (3, 3) or t_mm (3,)")
    n = len(result["saddle"].get("t_s", []))
    if n == 0:
        problems.append("saddle.t_s is empty")
    for key in ("position_m", "velocity_m_s", "acceleration_m_s2"):
        if np.shape(result["saddle"].get(key)) != (n, 3):
            problems.append(f"saddle.{key} is not ({n}, 3)")
    for key in ("omega_rad_s", "alpha_rad_s2"):
        if np.shape(result["angular"].get(key)) != (n, 3):
            problems.append(f"angular.{key} is not ({n}, 3)")
    if not {"start_s", "duration_s"} <= set(result["window"]):
        problems.append("window lacks start_s or duration_s")
    problems += [f"indicators.{k} missing" for k in CONTRACT_KEYS if k not in result["indicators"]]
    return problems

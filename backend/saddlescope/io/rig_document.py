"""A rig's calibration as the result document's ``calibration`` object (CONTRACTS section 2), and back.

The one serialiser of a :class:`~saddlescope.core.types.Rig`: the ride's result, a rig's stored
calibration and ``saddlescope calibrate --json`` all write it with :func:`rig_to_dict` and read it
with :func:`rig_from_dict`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.types import Camera, LensModel, Rig, WandCheck, WandRefinement
from saddlescope.io.findings_document import findings_of, findings_to_list

__all__ = ["checked_matrix", "distortion5", "lens_model_to_dict", "rig_from_dict", "rig_to_dict",
           "wand_refinement_of", "wand_refinement_to_dict"]


def _lst(a) -> list:
    """An array as nested lists of float."""
    return np.asarray(a, np.float64).tolist()


def rig_to_dict(rig: Rig) -> dict:
    """The result's ``calibration`` object (CONTRACTS section 2) for a rig.

    ``cameras``: K, dist (k1, k2, p1, p2, k3), image_size [w, h], rms_px, K_std, dist_std, lens_model
    (:func:`lens_model_to_dict`, where known);
    ``extrinsics`` of every camera but the first: R, t_mm (``x_cam = R @ x_first + t_mm``);
    ``checks``, ``findings`` (:mod:`saddlescope.io.findings_document`), ``flags`` (their details, for readers
    of the first format) and ``pairs`` {"a-b": {R, t_mm, rms_px, n_views, check_*}}; where a wand pass was
    offered to refine a board calibration, ``wand_refinement`` (:func:`wand_refinement_to_dict`).
    """
    names = rig.names
    cameras: dict[str, dict] = {}
    for name, cam in rig.cameras.items():
        entry: dict[str, object] = {"K": _lst(cam.K), "dist": _lst(distortion5(cam.dist, f"camera {name} dist")),
                 "image_size": [int(cam.image_size[0]), int(cam.image_size[1])], "rms_px": cam.rms_px}
        if cam.K_std is not None:
            entry["K_std"] = _lst(cam.K_std)
        if cam.dist_std is not None:
            entry["dist_std"] = _lst(cam.dist_std)
        if name in rig.lens_models:
            entry["lens_model"] = lens_model_to_dict(rig.lens_models[name])
        cameras[name] = entry
    extrinsics = {n: {"R": _lst(rig.cameras[n].R), "t_mm": _lst(rig.cameras[n].t_mm)} for n in names[1:]}
    pairs = {}
    for key, p in rig.pairs.items():
        pairs[key] = {k: (_lst(v) if isinstance(v, np.ndarray) else v) for k, v in p.items()}
    checks = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in rig.checks.items()}
    out = {"cameras": cameras, "extrinsics": extrinsics, "checks": checks, "flags": [f.detail for f in rig.flags],
           "findings": findings_to_list(rig.flags), "pairs": pairs}
    if rig.wand_refinement is not None:
        out["wand_refinement"] = wand_refinement_to_dict(rig.wand_refinement)
    return out


def _number(value: float) -> float | None:
    """A float for JSON: None where not finite (JSON has no NaN)."""
    return float(value) if np.isfinite(value) else None


def _check_to_dict(check: WandCheck) -> dict:
    return {"wand_length_rms_mm": _number(check.wand_length_rms_mm),
            "board_square_error_pct": _number(check.board_square_error_pct),
            "board_rms_px": _number(check.board_rms_px), "reach_px": {k: float(v) for k, v in check.reach_px.items()}}


def wand_refinement_to_dict(refinement: WandRefinement) -> dict:
    """A calibration's ``wand_refinement`` (issue 35): kept, why, the sentence, and both rigs' checks."""
    return {"kept": bool(refinement.kept), "reason": refinement.reason, "sentence": refinement.sentence,
            "wand_length_mm": float(refinement.wand_length_mm), "held_out_frames": int(refinement.held_out_frames),
            "board": _check_to_dict(refinement.board),
            "refined": _check_to_dict(refinement.refined) if refinement.refined is not None else None}


def _check_of(value: Mapping) -> WandCheck:
    def num(key: str) -> float:
        v = value.get(key)
        return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else float("nan")

    reach = value.get("reach_px") or {}
    return WandCheck(num("wand_length_rms_mm"), num("board_square_error_pct"), num("board_rms_px"),
                     {str(k): float(v) for k, v in reach.items() if isinstance(v, int | float)})


def wand_refinement_of(value) -> WandRefinement | None:
    """The WandRefinement of a stored ``wand_refinement`` (None where absent or not an object)."""
    if not isinstance(value, Mapping) or not isinstance(value.get("board"), Mapping):
        return None
    refined = value.get("refined")
    return WandRefinement(kept=bool(value.get("kept")), reason=str(value.get("reason", "")),
                          wand_length_mm=float(value.get("wand_length_mm") or 0.0),
                          held_out_frames=int(value.get("held_out_frames") or 0), board=_check_of(value["board"]),
                          refined=_check_of(refined) if isinstance(refined, Mapping) else None)


_LENS_FLAGS = ("equal_focal", "principal_point", "tangential", "k3", "given", "joint")


def lens_model_to_dict(model: LensModel) -> dict:
    """A camera's ``lens_model``: which parameters were fitted (booleans), ``label`` and ``reason`` in words."""
    return {**{k: bool(getattr(model, k)) for k in _LENS_FLAGS}, "label": model.label, "reason": model.reason}


def _lens_model_of(value) -> LensModel | None:
    """The LensModel of a stored ``lens_model`` (None where absent or not an object)."""
    if not isinstance(value, Mapping):
        return None
    defaults = LensModel()
    return LensModel(**{k: bool(value.get(k, getattr(defaults, k))) for k in _LENS_FLAGS},
                     reason=str(value.get("reason", "")))


def checked_matrix(value, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as a finite float array of ``shape``, or an InputError naming ``what``."""
    try:
        arr = np.asarray(value, np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not numeric") from None
    if arr.shape != shape or not np.all(np.isfinite(arr)):
        raise InputError(f"{what} must be finite numbers of shape {shape}, got {arr.shape}")
    return arr


def distortion5(value, what: str) -> np.ndarray:
    """OpenCV distortion coefficients as the 5-coefficient model (k1, k2, p1, p2, k3), shape (5,)."""
    d = np.asarray(value, np.float64).ravel()
    if d.size not in (4, 5, 8, 12, 14) and d.size > 5:
        raise InputError(f"{what} has {d.size} coefficients; expected 4 or 5 (k1, k2, p1, p2[, k3])")
    if d.size > 5 and np.any(d[5:] != 0):
        raise InputError(f"{what}: only the 5-coefficient model (k1, k2, p1, p2, k3) is supported")
    return np.pad(d[:5], (0, max(0, 5 - d.size)))


def rig_from_dict(d: Mapping) -> Rig:
    """Inverse of :func:`rig_to_dict` (also accepts the plain CONTRACTS ``calibration`` object)."""
    cams_in = d.get("cameras")
    if not isinstance(cams_in, Mapping) or not cams_in:
        raise InputError("calibration has no 'cameras'")
    extr = d.get("extrinsics", {}) or {}
    cameras = {}
    lens_models = {}
    for i, (name, c) in enumerate(cams_in.items()):
        K = checked_matrix(c.get("K"), (3, 3), f"camera {name} K")
        dist = distortion5(c.get("dist", [0, 0, 0, 0, 0]), f"camera {name} dist")
        size = c.get("image_size")
        if not isinstance(size, list | tuple) or len(size) != 2:
            raise InputError(f"camera {name} image_size must be [width, height]")
        e = extr.get(name)
        if e is None and i > 0:
            raise InputError(f"camera {name} has no extrinsics (only the first camera may omit them)")
        R = np.eye(3) if e is None else checked_matrix(e.get("R"), (3, 3), f"camera {name} R")
        t = np.zeros(3) if e is None else checked_matrix(e.get("t_mm"), (3,), f"camera {name} t_mm")
        opt = lambda key: None if c.get(key) is None else np.asarray(c[key], np.float64)  # noqa: B023
        cameras[name] = Camera(name, K, dist, (int(size[0]), int(size[1])), R=R, t_mm=t,
                               rms_px=c.get("rms_px"), K_std=opt("K_std"), dist_std=opt("dist_std"))
        model = _lens_model_of(c.get("lens_model"))
        if model is not None:
            lens_models[name] = model
    pairs = {}
    for key, p in (d.get("pairs") or {}).items():
        pairs[key] = {k: (np.asarray(v, np.float64) if k in ("R", "t_mm") else v) for k, v in p.items()}
    return Rig(cameras, checks=dict(d.get("checks") or {}), flags=tuple(findings_of(d)), pairs=pairs,
               lens_models=lens_models, wand_refinement=wand_refinement_of(d.get("wand_refinement")))

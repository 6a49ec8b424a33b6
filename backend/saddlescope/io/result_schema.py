"""JSON schemas of the result document (CONTRACTS section 2) and of a bundle's ``ride.json`` (section 1).

``validate_result(doc)`` and ``validate_ride_meta(meta)`` check a document against its schema plus the
few rules a schema cannot state (equal array lengths, finite numbers) and raise one typed error whose
message lists the first problems, each with where it is (``indicators.vdv_y_wb``) and what is wrong.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import jsonschema

from saddlescope.core.calibration.boards import BOARD_KINDS, board_meta_problems, board_type, options_schema
from saddlescope.core.calibration.wand import WAND_LENGTH_RANGE_M
from saddlescope.core.errors import BundleError, InputError
from saddlescope.core.findings import FINDING_KINDS, SEVERITIES
from saddlescope.core.pipeline.inputs import CALIBRATION_METHODS
from saddlescope.core.types import CAMERA_ROLES, CLIP_KINDS, DIRECTIONS, GAITS, WAND_CLIP_KINDS
from saddlescope.core.vibration import CONTRACT_KEYS

__all__ = ["RESULT_FORMAT", "RIDE_FORMAT", "result_schema", "ride_schema",
           "result_problems", "ride_problems", "validate_result", "validate_ride_meta"]

RESULT_FORMAT = "saddlescope.result/1"
RIDE_FORMAT = "saddlescope.ride/1"
MAX_LISTED_PROBLEMS = 5


_NUMBER = {"type": "number"}
_POSITIVE = {"type": "number", "exclusiveMinimum": 0}
_NON_NEGATIVE = {"type": "number", "minimum": 0}


def _vector(n: int, *, nullable: bool = False) -> dict:
    item = {"type": ["number", "null"]} if nullable else _NUMBER
    return {"type": "array", "items": item, "minItems": n, "maxItems": n}


def _matrix(rows: int, cols: int) -> dict:
    return {"type": "array", "items": _vector(cols), "minItems": rows, "maxItems": rows}


# A time series of 3-vectors; null marks a gap (JSON has no NaN).
_SERIES3 = {"type": "array", "items": _vector(3, nullable=True)}

_CAMERA = {
    "type": "object",
    "required": ["K", "dist", "image_size"],
    "properties": {
        "K": _matrix(3, 3),
        "dist": {"type": "array", "items": _NUMBER, "minItems": 4, "maxItems": 14},
        "image_size": {"type": "array", "items": {"type": "integer", "minimum": 1}, "minItems": 2,
                       "maxItems": 2},
        "rms_px": {"type": ["number", "null"], "minimum": 0},
        # which lens parameters the calibration fitted, and why (issue 35; absent in older results)
        "lens_model": {"type": "object", "properties": {
            **{k: {"type": "boolean"} for k in ("equal_focal", "principal_point", "tangential", "k3", "given",
                                                 "joint")},
            "label": {"type": "string"}, "reason": {"type": "string"}}},
    },
}
_POSE = {"type": "object", "required": ["R", "t_mm"],
         "properties": {"R": _matrix(3, 3), "t_mm": _vector(3)}}
# A finding as stored (saddlescope.io.findings_document): results made before findings were data have
# ``flags`` (sentences) only, so the key stays optional and the format's version is unchanged
_FINDINGS = {"type": "array", "items": {
    "type": "object", "required": ["code", "severity", "stage", "detail"],
    "properties": {"code": {"enum": list(FINDING_KINDS)}, "severity": {"enum": list(SEVERITIES)},
                   "stage": {"type": "string"}, "detail": {"type": "string", "minLength": 1},
                   "values": {"type": "object", "additionalProperties": _NUMBER}}}}
_FLAGS = {"type": "array", "items": {"type": "string"}}
# a board calibration offered a wand pass (issue 35): whether the refined rig was kept, and both rigs' checks
_WAND_CHECK = {"type": "object", "required": ["wand_length_rms_mm", "board_square_error_pct", "board_rms_px"],
               "properties": {"wand_length_rms_mm": {"type": ["number", "null"], "minimum": 0},
                              "board_square_error_pct": {"type": ["number", "null"], "minimum": 0},
                              "board_rms_px": {"type": ["number", "null"], "minimum": 0},
                              "reach_px": {"type": "object", "additionalProperties": _NON_NEGATIVE}}}
_WAND_REFINEMENT = {"type": "object", "required": ["kept", "reason", "board"],
                    "properties": {"kept": {"type": "boolean"}, "reason": {"type": "string"},
                                   "sentence": {"type": "string"}, "wand_length_mm": _POSITIVE,
                                   "held_out_frames": {"type": "integer", "minimum": 0}, "board": _WAND_CHECK,
                                   "refined": {"anyOf": [{"type": "null"}, _WAND_CHECK]}}}
_OFFSETS = {"type": "object", "required": list(CAMERA_ROLES),
            "properties": {role: _NUMBER for role in CAMERA_ROLES},
            "additionalProperties": False}
# a phone's rolling shutter: each camera's readout time in ms (0 a global shutter; a phone's 10-35 ms)
_READOUT_MS = {"type": "object", "properties": {role: {"type": "number", "minimum": 0, "maximum": 40}
                                                for role in CAMERA_ROLES},
               "additionalProperties": False}

_PASS = {"type": "object", "required": ["start_s", "end_s", "start_frame", "frames", "strides", "used"],
         "properties": {"start_s": _NUMBER, "end_s": _NUMBER, "start_frame": {"type": "integer", "minimum": 0},
                        "frames": {"type": "integer", "minimum": 1}, "strides": {"type": "integer", "minimum": 0},
                        "speed_m_s": {"type": ["number", "null"]}, "stride_frequency_hz": {"type": ["number", "null"]},
                        "indicators": {"type": "object", "additionalProperties": _NUMBER},
                        "indicators_interval_95": {"type": "object", "additionalProperties": _vector(2)},
                        "used": {"type": "boolean"}, "reason": {"type": ["string", "null"]}}}

RESULT_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": "https://saddlescope.example/schemas/result-1.json",
    "title": "SaddleScope ride result",
    "type": "object",
    "required": ["format", "fps", "calibration", "sync", "period_s", "window", "saddle", "angular",
                 "indicators", "quality", "timings_s"],
    "properties": {
        "format": {"const": RESULT_FORMAT},
        "fps": _POSITIVE,
        "calibration": {
            "type": "object",
            "required": ["cameras", "extrinsics"],
            "properties": {
                "cameras": {"type": "object", "required": list(CAMERA_ROLES),
                            "additionalProperties": _CAMERA},
                "extrinsics": {"type": "object", "required": [r for r in CAMERA_ROLES if r != "left"],
                               "additionalProperties": _POSE},
                "checks": {"type": "object", "additionalProperties": {"type": ["number", "null"]}},
                "flags": _FLAGS,
                "findings": _FINDINGS,
                "wand_refinement": _WAND_REFINEMENT,
            },
        },
        "sync": {"type": "object", "required": ["motion"],
                 "properties": {kind: _OFFSETS for kind in CLIP_KINDS}},
        "period_s": _POSITIVE,
        "window": {"type": "object", "required": ["start_s", "duration_s"],
                   "properties": {"start_s": _NON_NEGATIVE, "duration_s": _POSITIVE}},
        "saddle": {
            "type": "object",
            "required": ["t_s", "position_m", "velocity_m_s", "acceleration_m_s2"],
            "properties": {"t_s": {"type": "array", "items": _NUMBER, "minItems": 2},
                           "position_m": _SERIES3, "velocity_m_s": _SERIES3, "acceleration_m_s2": _SERIES3},
        },
        "angular": {
            "type": "object",
            "required": ["omega_rad_s", "alpha_rad_s2", "singularity_index"],
            "properties": {"omega_rad_s": _SERIES3, "alpha_rad_s2": _SERIES3,
                           "singularity_index": {"type": ["number", "null"], "minimum": 0, "maximum": 1}},
        },
        "indicators": {"type": "object", "required": list(CONTRACT_KEYS),
                       "properties": {key: _NUMBER for key in CONTRACT_KEYS}},
        # 95 % interval [low, high] beside each indicator (issue 27); null: unbounded (an infinite time)
        "indicators_interval_95": {"type": "object",
                                   "additionalProperties": {"type": "array", "items": {"type": ["number", "null"]},
                                                            "minItems": 2, "maxItems": 2}},
        "quality": {"type": "object", "properties": {"flags": _FLAGS, "findings": _FINDINGS}},
        # the passes in front of the cameras of a ride that held several (issue 38; absent for one pass)
        "passes": {"type": "array", "items": _PASS},
        "timings_s": {"type": "object", "required": ["total"],
                      "additionalProperties": _NON_NEGATIVE},
    },
}

_CLIP_SET = {"type": "object", "required": list(CAMERA_ROLES),
             "properties": {role: {"type": "string", "minLength": 1} for role in CAMERA_ROLES},
             "additionalProperties": False}

def _board_schema() -> dict[str, Any]:
    """ride.json's "board": a registered kind, the grid, and the fields each kind adds and needs."""
    schema: dict[str, Any] = {
        "type": "object",
        "required": ["kind", "inner_corners", "square_mm"],
        "properties": {
            "kind": {"enum": BOARD_KINDS},  # the live list: a kind registered later is accepted too
            "inner_corners": {"type": "array", "items": {"type": "integer", "minimum": 2},
                              "minItems": 2, "maxItems": 2},
            "square_mm": _POSITIVE,
        },
    }
    rules = []
    for kind in BOARD_KINDS:
        own = options_schema(board_type(kind).options)
        schema["properties"].update(own["properties"])
        if own.get("required"):
            rules.append({"if": {"properties": {"kind": {"const": kind}}},
                          "then": {"required": list(own["required"])}})
    if rules:
        schema["allOf"] = rules
    return schema


RIDE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": "https://saddlescope.example/schemas/ride-1.json",
    "title": "SaddleScope ride bundle (ride.json)",
    "type": "object",
    "required": ["format", "cameras", "board", "sync", "gait", "direction", "clips"],
    "properties": {
        "format": {"const": RIDE_FORMAT},
        "cameras": {"type": "array", "items": {"enum": list(CAMERA_ROLES)}, "uniqueItems": True,
                    "minItems": len(CAMERA_ROLES), "maxItems": len(CAMERA_ROLES)},
        "board": _board_schema(),
        "sync": {
            "type": "object",
            "required": ["method"],
            "properties": {
                "method": {"enum": ["flash", "offsets", "motion"]},
                "offsets": {"type": "object", "properties": {kind: _OFFSETS for kind in CLIP_KINDS},
                            "additionalProperties": _OFFSETS},
                "readout_ms": _READOUT_MS,
            },
            "if": {"properties": {"method": {"const": "offsets"}}},
            "then": {"required": ["offsets"]},
        },
        "markers": {"type": "object",
                    "properties": {"horse": {"type": "integer", "minimum": 3},
                                   "plumb": {"type": "integer", "minimum": 0},
                                   "saddle": {"type": "integer", "minimum": 0}},
                    "additionalProperties": {"type": "integer", "minimum": 0}},
        "horse": {"type": "object",
                  "properties": {"name": {"type": "string"}, "breed": {"type": ["string", "null"]},
                                 "birth_year": {"type": ["integer", "null"], "minimum": 1900},
                                 "height_m": {"type": ["number", "null"], "exclusiveMinimum": 0}}},
        # A rider's weight that day in kg (the range of db.enums.RIDER_WEIGHT_RANGE_KG: a typo or pounds outside).
        "rider": {"type": "object", "properties": {"name": {"type": "string"},
                                                    "weight_kg": {"type": ["number", "null"], "minimum": 20,
                                                                  "maximum": 200}}},
        # The saddle the horse wore (found by name among the club's saddles, added if new) and the pad.
        "saddle": {"type": "object", "required": ["name"],
                   "properties": {"name": {"type": "string", "minLength": 1, "maxLength": 200},
                                  "maker": {"type": ["string", "null"], "maxLength": 200},
                                  "type": {"type": ["string", "null"]},
                                  "tree_width": {"type": ["string", "null"], "maxLength": 40}}},
        "pad": {"type": ["string", "null"], "maxLength": 200},
        "gait": {"enum": list(GAITS)},
        "direction": {"enum": list(DIRECTIONS)},
        "clips": {
            "type": "object",
            "required": ["static", "motion"],
            "properties": {kind: _CLIP_SET for kind in CLIP_KINDS + WAND_CLIP_KINDS},
            "additionalProperties": False,
        },
        "extra_clips": {
            "type": "object",
            "additionalProperties": {
                "type": "object", "minProperties": 1,
                "properties": {role: {"type": "string", "minLength": 1} for role in CAMERA_ROLES},
                "additionalProperties": False},
        },
        "calibration_file": {"type": "string", "minLength": 1},
        # How the clips calibrate the rig (issue 35): the board walk (default), a wand of known length waved
        # through the volume (clips.wand) with the board filmed close to each camera (clips.close_up), or the
        # board walk refined by a wand walked along the track (clips.calibration and clips.wand: "board+wand").
        "calibration": {"type": "object", "required": ["method"],
                        "properties": {"method": {"enum": list(CALIBRATION_METHODS)},
                                       "wand_length_m": {"type": "number", "minimum": WAND_LENGTH_RANGE_M[0],
                                                         "maximum": WAND_LENGTH_RANGE_M[1]}},
                        "additionalProperties": False},
    },
    # A calibration clip set (or the wand's, checked in ride_problems) unless a calibration file replaces it.
    "anyOf": [{"required": ["calibration_file"]},
              {"properties": {"clips": {"required": ["calibration"]}}},
              {"required": ["calibration"],
               "properties": {"calibration": {"properties": {"method": {"const": "wand"}}}}}],
}


def result_schema() -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of the result document, a fresh copy."""
    import copy

    return copy.deepcopy(RESULT_SCHEMA)


def ride_schema() -> dict[str, Any]:
    """The JSON schema (draft 2020-12) of a ride bundle's ``ride.json``, a fresh copy."""
    import copy

    return copy.deepcopy(RIDE_SCHEMA)


def _where(path) -> str:
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _describe(error: jsonschema.ValidationError) -> str:
    """One readable sentence for a schema error, naming the field."""
    where = _where(error.absolute_path)
    prefix = f"{where} " if where else ""
    kind, value, inst = error.validator, error.validator_value, error.instance
    if kind == "required" and isinstance(inst, dict):
        missing = [k for k in value if k not in inst]
        return f"{where + ': ' if where else ''}missing {', '.join(repr(k) for k in missing)}"
    if kind == "enum":
        return f"{prefix}{inst!r} is not one of {', '.join(str(v) for v in value)}"
    if kind == "const":
        return f"{prefix}must be {value!r}, got {inst!r}"
    if kind == "additionalProperties" and value is False and isinstance(inst, dict):
        allowed = list(error.schema.get("properties", {}))
        extra = [k for k in inst if k not in allowed]
        return (f"{prefix}has unknown {', '.join(repr(k) for k in extra)} "
                f"(expected {', '.join(allowed)})")
    if kind == "type":
        expected = value if isinstance(value, str) else " or ".join(value)
        return f"{prefix}must be {expected}, got {type(inst).__name__} {_short(inst)}"
    if kind in ("minimum", "maximum") and "readout_ms" in error.absolute_path:
        return (f"{prefix}is {_short(inst)} ms: a rolling shutter's readout time must be 0-40 ms (a phone's is "
                "10-35 ms, 0 for a global shutter)")
    if kind == "anyOf" and error.schema is RIDE_SCHEMA:
        return ("needs clips.calibration (the board walk), a calibration_file, or "
                "calibration.method 'wand' with clips.wand and clips.close_up")
    return f"{prefix}{error.message}"


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _non_finite(doc: Any, path: tuple = ()) -> Iterator[str]:
    if isinstance(doc, float) and not math.isfinite(doc):
        yield f"{_where(path)} is {doc} (JSON numbers must be finite; use null for a gap)"
    elif isinstance(doc, dict):
        for key, val in doc.items():
            yield from _non_finite(val, (*path, key))
    elif isinstance(doc, list | tuple):
        for i, val in enumerate(doc):
            yield from _non_finite(val, (*path, i))


def _schema_problems(doc: Any, schema: dict) -> list[str]:
    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(doc), key=lambda e: (list(map(str, e.absolute_path)), e.message))
    # Errors that differ only in an array index (a bad sample in a long series) are told once.
    groups: dict[tuple, list[jsonschema.ValidationError]] = {}
    for e in errors:
        key = (tuple("[]" if isinstance(p, int) else p for p in e.absolute_path), e.validator)
        groups.setdefault(key, []).append(e)
    out = []
    for same in groups.values():
        text = _describe(same[0])
        # "required" errors come one per missing key, but the description already names them all.
        if len(same) > 1 and same[0].validator != "required":
            text += f" (and {len(same) - 1} more like it)"
        out.append(text)
    return out


def result_problems(doc: Any) -> list[str]:
    """Every problem of a result document, as readable strings (empty list: valid)."""
    problems = _schema_problems(doc, RESULT_SCHEMA)
    problems += list(_non_finite(doc))
    if isinstance(doc, dict):
        for group, keys in (("saddle", ("position_m", "velocity_m_s", "acceleration_m_s2")),
                            ("angular", ("omega_rad_s", "alpha_rad_s2"))):
            series = doc.get(group)
            t_s = (doc.get("saddle") or {}).get("t_s") if isinstance(doc.get("saddle"), dict) else None
            if not isinstance(series, dict) or not isinstance(t_s, list):
                continue
            for key in keys:
                arr = series.get(key)
                # Angular series may be empty where the rigid-body stage could not run.
                if isinstance(arr, list) and len(arr) != len(t_s) and not (group == "angular" and not arr):
                    problems.append(f"{group}.{key} has {len(arr)} samples but saddle.t_s has {len(t_s)}")
        problems += _interval_problems(doc)
        saddle = doc.get("saddle")
        if isinstance(saddle, dict) and isinstance(saddle.get("t_s"), list):
            t_s = [t for t in saddle["t_s"] if isinstance(t, int | float)]
            if any(b <= a for a, b in zip(t_s, t_s[1:], strict=False)):
                problems.append("saddle.t_s must increase strictly")
    return problems


def _interval_problems(doc: dict) -> list[str]:
    """An interval must hold its indicator (low <= value <= high) and belong to a reported indicator."""
    intervals, indicators = doc.get("indicators_interval_95"), doc.get("indicators")
    if not isinstance(intervals, dict) or not isinstance(indicators, dict):
        return []
    problems = []
    for key, pair in intervals.items():
        if key not in indicators:
            problems.append(f"indicators_interval_95.{key} has no indicator {key}")
            continue
        if not (isinstance(pair, list) and len(pair) == 2):
            continue
        lo, hi, value = pair[0], pair[1], indicators[key]
        if not all(isinstance(v, int | float | None) for v in (lo, hi)) or not isinstance(value, int | float):
            continue
        if (lo is not None and lo > value * (1 + 1e-9) + 1e-12) or (hi is not None and hi < value * (1 - 1e-9) - 1e-12):
            problems.append(f"indicators_interval_95.{key} [{lo}, {hi}] does not hold the indicator's value {value}")
    return problems


def validate_result(doc: Any) -> None:
    """Check a result document against CONTRACTS section 2.

    Raises
    ------
    InputError
        Listing the first few problems (missing keys, wrong types or shapes, non-finite numbers,
        series whose length differs from ``saddle.t_s``).
    """
    problems = result_problems(doc)
    if problems:
        raise InputError(_summarise("result", problems))


def ride_problems(meta: Any) -> list[str]:
    """Every problem of a ``ride.json`` document, as readable strings (empty list: valid)."""
    problems = _schema_problems(meta, RIDE_SCHEMA)
    problems += list(_non_finite(meta))
    if not isinstance(meta, dict):
        return problems
    problems += board_meta_problems(meta.get("board"))
    problems += _wand_problems(meta)
    sync, clips = meta.get("sync"), meta.get("clips")
    if isinstance(sync, dict) and sync.get("method") == "offsets" and isinstance(clips, dict):
        offsets = _object_at(sync, "offsets")
        for kind in clips:
            if kind in (*CLIP_KINDS, "wand") and kind not in offsets:  # close-ups: each camera alone
                problems.append(f"sync.offsets has no offsets for the {kind} clips")
    return problems


def _object_at(doc: dict, key: str) -> dict:
    """``doc[key]`` when it is an object, else an empty one (the schema's problems name a wrong type)."""
    value = doc.get(key)
    return value if isinstance(value, dict) else {}


def _wand_problems(meta: dict) -> list[str]:
    """A wand calibration needs its clip sets and the wand's length; wand clips need a way that uses them."""
    clips, cal = _object_at(meta, "clips"), _object_at(meta, "calibration")
    wand_sets = [k for k in WAND_CLIP_KINDS if k in clips]
    method = cal.get("method")
    if method not in ("wand", "board+wand"):
        if wand_sets:
            return [f"clips.{wand_sets[0]} is a wand's clip set: add \"calibration\": {{\"method\": \"wand\" (or "
                    "\"board+wand\" with clips.calibration), \"wand_length_m\": ...} or remove it"]
        return []
    problems = []
    if "wand_length_m" not in cal:
        problems.append(f"calibration.method {method!r} needs calibration.wand_length_m, the distance between the "
                        "wand's two markers' centres in metres (e.g. 1.0)")
    if meta.get("calibration_file"):
        problems.append(f"calibration.method {method!r} and a calibration_file contradict each other: give one")
    if "wand" not in clips:
        problems.append(f"calibration.method {method!r} needs clips.wand: the wand waved through the riding area "
                        "by the three cameras at once" + (", along the track the horse takes"
                                                          if method == "board+wand" else ""))
    if method == "wand":
        if "calibration" in clips:
            problems.append("calibration.method 'wand' and clips.calibration (a board walk) contradict each other: "
                            "give one way, or \"board+wand\" to refine the board walk by the wand")
        if "close_up" not in clips:
            problems.append("calibration.method 'wand' needs clips.close_up: the board filmed close to each camera, "
                            "for its lens")
        return problems
    if "calibration" not in clips:
        problems.append("calibration.method 'board+wand' needs clips.calibration: the board walk the wand refines")
    if "close_up" in clips:
        problems.append("calibration.method 'board+wand' takes each lens from the board walk: clips.close_up is "
                        "not used; remove it, or use the method 'wand'")
    return problems


def validate_ride_meta(meta: Any, *, source: str = "ride.json") -> None:
    """Check a ``ride.json`` document against CONTRACTS section 1 (fields only, not files).

    Raises
    ------
    BundleError
        ``"ride.json: gait 'gallop' is not one of walk, sitting_trot, rising_trot, canter"``, listing
        the first few problems.
    """
    problems = ride_problems(meta)
    if problems:
        raise BundleError(_summarise(source, problems))


def _summarise(source: str, problems: list[str]) -> str:
    shown = "; ".join(problems[:MAX_LISTED_PROBLEMS])
    more = len(problems) - MAX_LISTED_PROBLEMS
    return f"{source}: {shown}" + (f" (and {more} more)" if more > 0 else "")

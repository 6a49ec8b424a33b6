"""The result and ride.json schemas: valid documents pass, each kind of mistake is named."""

from __future__ import annotations

import copy
import json

import jsonschema
import pytest

from saddlescope.core.errors import BundleError, InputError
from saddlescope.core.vibration import CONTRACT_KEYS
from saddlescope.io.result_schema import (
    result_schema,
    ride_schema,
    validate_result,
    validate_ride_meta,
)

ROLES = ("left", "middle", "right")


def _result(n=6):
    eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    return {
        "format": "saddlescope.result/1",
        "fps": 30.0,
        "calibration": {
            "cameras": {r: {"K": [[720.0, 0, 320], [0, 720.0, 240], [0, 0, 1]], "dist": [0.1, 0, 0, 0, 0],
                            "image_size": [640, 480], "rms_px": 0.21} for r in ROLES},
            "extrinsics": {"middle": {"R": eye, "t_mm": [-230.0, 0, 0]},
                           "right": {"R": eye, "t_mm": [-460.0, 0, 0]}},
            "checks": {"board_square_error_mm": 0.3},
        },
        "sync": {"motion": {"left": 0.0, "middle": 53.0, "right": 126.0}},
        "period_s": 0.6,
        "window": {"start_s": 1.0, "duration_s": 1.2},
        "saddle": {"t_s": [i / 30 for i in range(n)], "position_m": [[0.1 * i, 0.0, 0.0] for i in range(n)],
                   "velocity_m_s": [[3.0, 0.0, 0.0]] * n, "acceleration_m_s2": [[0.0, None, 0.0]] * n},
        "angular": {"omega_rad_s": [[0.0, 0.1, 0.0]] * n, "alpha_rad_s2": [[0.0, 0.0, 0.0]] * n,
                    "singularity_index": 0.1},
        "indicators": {key: 1.0 for key in CONTRACT_KEYS},
        "quality": {"flags": []},
        "timings_s": {"total": 12.3, "detection": 4.0},
    }


def _ride():
    kinds = ("calibration", "plumb", "static", "motion")
    clip = {kind: {r: f"{kind}/{r}.mp4" for r in ROLES} for kind in kinds}
    return {
        "format": "saddlescope.ride/1",
        "cameras": ["left", "middle", "right"],
        "board": {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 50.0},
        "sync": {"method": "flash"},
        "markers": {"horse": 3, "plumb": 2, "saddle": 1},
        "horse": {"name": "Horse 2", "breed": "Dutch", "birth_year": 1999, "height_m": 1.73},
        "rider": {"name": "Rider B"},
        "gait": "canter",
        "direction": "CCW",
        "clips": clip,
    }


def test_schemas_are_valid_draft_2020_12():
    jsonschema.Draft202012Validator.check_schema(result_schema())
    jsonschema.Draft202012Validator.check_schema(ride_schema())


def test_schema_getters_return_copies():
    schema = result_schema()
    schema["required"].clear()
    assert "indicators" in result_schema()["required"]


def test_valid_result_passes_also_after_json_round_trip():
    doc = _result()
    validate_result(doc)
    validate_result(json.loads(json.dumps(doc)))


@pytest.mark.parametrize("key", CONTRACT_KEYS)
def test_each_contract_indicator_is_required(key):
    doc = _result()
    del doc["indicators"][key]
    with pytest.raises(InputError, match=f"indicators: missing '{key}'"):
        validate_result(doc)


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(format="saddlescope.result/2"), "format must be 'saddlescope.result/1'"),
    (lambda d: d.pop("timings_s"), "missing 'timings_s'"),
    (lambda d: d["indicators"].update(vdv_y_wb="high"), "indicators.vdv_y_wb must be number, got str"),
    (lambda d: d["indicators"].update(acc_y_max=float("nan")), "indicators.acc_y_max is nan"),
    (lambda d: d["calibration"]["cameras"].pop("middle"), "calibration.cameras: missing 'middle'"),
    (lambda d: d["calibration"]["cameras"]["left"].update(K=[[1, 0], [0, 1]]),
     r"calibration.cameras.left.K"),
    (lambda d: d["calibration"]["extrinsics"]["right"].pop("t_mm"),
     "calibration.extrinsics.right: missing 't_mm'"),
    (lambda d: d["sync"]["motion"].pop("right"), "sync.motion: missing 'right'"),
    (lambda d: d["window"].update(duration_s=0), "window.duration_s"),
    (lambda d: d["saddle"]["velocity_m_s"].pop(), "saddle.velocity_m_s has 5 samples but saddle.t_s has 6"),
    (lambda d: d["saddle"]["t_s"].reverse(), "saddle.t_s must increase strictly"),
    (lambda d: d["angular"].update(singularity_index=1.5), "angular.singularity_index"),
    (lambda d: d["timings_s"].update(total=-1.0), "timings_s.total"),
])
def test_result_mistakes_are_named(mutate, message):
    doc = _result()
    mutate(doc)
    with pytest.raises(InputError, match=message):
        validate_result(doc)


def test_many_problems_are_summarised():
    doc = _result()
    doc["indicators"] = {}
    doc["saddle"]["position_m"] = [[0.0, 0.0]] * 6
    with pytest.raises(InputError) as info:
        validate_result(doc)
    text = str(info.value)
    assert text.startswith("result: ")
    assert "saddle.position_m[0] [0.0, 0.0] is too short (and 5 more like it)" in text
    assert "vdv_y_wb" in text  # all missing indicator keys in one problem


def test_non_object_result():
    with pytest.raises(InputError, match="must be object, got list"):
        validate_result([])


# ------------------------------------------------------------------------------------- ride.json


def test_valid_ride_passes():
    validate_ride_meta(_ride())


def test_gait_message_is_exact():
    meta = _ride()
    meta["gait"] = "gallop"
    with pytest.raises(BundleError) as info:
        validate_ride_meta(meta)
    assert str(info.value) == "ride.json: gait 'gallop' is not one of walk, sitting_trot, rising_trot, canter"


@pytest.mark.parametrize("mutate, message", [
    (lambda m: m.update(cameras=["left", "centre", "right"]), r"cameras\[1\] 'centre' is not one of left"),
    (lambda m: m["clips"]["motion"].update(centre="motion/c.mp4"),
     "clips.motion has unknown 'centre' \\(expected left, middle, right\\)"),
    (lambda m: m["clips"]["static"].pop("left"), "clips.static: missing 'left'"),
    (lambda m: m["clips"].pop("motion"), "clips: missing 'motion'"),
    (lambda m: m["clips"].pop("calibration"),
     "a calibration_file, or calibration.method 'wand' with clips.wand and clips.close_up"),
    (lambda m: m.update(direction="left"), "direction 'left' is not one of CW, CCW"),
    (lambda m: m["board"].update(kind="charuco"), "board: missing 'dictionary', 'marker_mm'"),
    (lambda m: m["board"].update(kind="circles"), "board.kind 'circles' is not one of checkerboard, charuco"),
    (lambda m: m["board"].update(kind="charuco", dictionary="DICT_4X4_50", marker_mm=60.0),
     r"board.marker_mm \(60.0\) must be smaller than board.square_mm"),
    (lambda m: m.update(sync={"method": "offsets"}), "sync: missing 'offsets'"),
    (lambda m: m.update(sync={"method": "offsets",
                              "offsets": {"motion": {"left": 0, "middle": 53, "right": 1}}}),
     "sync.offsets has no offsets for the calibration clips"),
    (lambda m: m["markers"].update(horse=2), "markers.horse"),
    (lambda m: m.update(format="saddlescope.ride/0"), "format must be 'saddlescope.ride/1'"),
])
def test_ride_mistakes_are_named(mutate, message):
    meta = _ride()
    mutate(meta)
    with pytest.raises(BundleError, match=message):
        validate_ride_meta(meta)


def test_calibration_file_replaces_the_calibration_clips_and_plumb_is_optional():
    meta = _ride()
    del meta["clips"]["calibration"], meta["clips"]["plumb"]
    meta["calibration_file"] = "rig.toml"
    validate_ride_meta(meta)
    offsets = {k: {"left": 0, "middle": 53.5, "right": 126} for k in ("static", "motion")}
    meta["sync"] = {"method": "offsets", "offsets": offsets}
    validate_ride_meta(copy.deepcopy(meta))

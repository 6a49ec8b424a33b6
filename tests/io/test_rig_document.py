"""The one serialiser of a rig and of a ride's result: JSON out, the same objects back."""

from __future__ import annotations

import json

import numpy as np
import pytest
from factories import LOST, SQUARES, ride_result, two_camera_rig

from saddlescope.core.errors import InputError
from saddlescope.io.result_document import result_from_document, result_to_document
from saddlescope.io.rig_document import rig_from_dict, rig_to_dict


def test_rig_dict_round_trip_is_json():
    rig = two_camera_rig()
    d = json.loads(json.dumps(rig_to_dict(rig)))
    assert list(d["cameras"]) == ["left", "right"] and list(d["extrinsics"]) == ["right"]
    assert d["checks"] == {"board_square_error_mm": 0.1, "views": 40}  # numpy scalars as JSON numbers
    assert len(d["cameras"]["left"]["dist"]) == 5 and d["cameras"]["left"]["image_size"] == [640, 480]
    back = rig_from_dict(d)
    for n in rig.cameras:
        a, b = rig.cameras[n], back.cameras[n]
        assert np.allclose(a.K, b.K) and np.allclose(a.R, b.R) and np.allclose(a.t_mm, b.t_mm)
        assert b.rms_px == 0.2
    assert np.allclose(back.cameras["left"].K_std, rig.cameras["left"].K_std)
    assert back.flags == (SQUARES,)  # code, detail and values
    assert d["flags"] == [SQUARES.detail]  # the sentences still written for readers of the first format
    assert d["findings"][0]["severity"] == "problem" and d["findings"][0]["stage"] == "calibration"
    assert np.allclose(back.pairs["left-right"]["t_mm"], rig.cameras["right"].t_mm)
    with pytest.raises(InputError, match="camera right has no extrinsics"):
        rig_from_dict({"cameras": d["cameras"], "extrinsics": {}})
    with pytest.raises(InputError, match="camera left K"):
        rig_from_dict({"cameras": {"left": {**d["cameras"]["left"], "K": [[1, 2]]}}})


@pytest.mark.parametrize("calibrated", [True, False])
def test_result_document_round_trip(calibrated):
    result = ride_result(np.random.default_rng(3), calibrated=calibrated)
    doc = json.loads(json.dumps(result_to_document(result), allow_nan=False))  # strict JSON: no NaN, no inf
    assert doc["format"] == "saddlescope.result/1"
    assert doc["saddle"]["acceleration_m_s2"][2][1] is None
    assert doc["indicators"]["t_a8_action_wb_h"] is None
    assert ("n_views" in doc["calibration"]) == calibrated
    assert doc["angular"]["weak_axis_gain"] == {"omega": 0.5, "alpha": 0.25}
    back = result_from_document(doc)
    assert np.isnan(back.saddle.acceleration_m_s2[2, 1])
    assert np.allclose(back.saddle.position_m, result.saddle.position_m, atol=1e-9)
    assert np.array_equal(back.angular.omega_versions_excluded, result.angular.omega_versions_excluded)
    assert back.rig.names == ["left", "right"] and back.findings == (SQUARES, LOST)
    assert doc["quality"]["flags"] == [SQUARES.detail, LOST.detail]
    assert [f["code"] for f in doc["quality"]["findings"]] == ["calibration.square_error", "tracking.lost"]
    assert result_to_document(back) == doc  # written again, byte for byte the same document


def test_a_calibration_stored_with_sentences_only_reads_back_as_coded_findings():
    """A rig calibration stored before findings were data (``flags`` only) keeps its codes."""
    d = rig_to_dict(two_camera_rig())
    del d["findings"]
    d["flags"] = ["the joint adjustment moved every camera's principal point by about 9 px (x +9, y -1) from where",
                  "something a later version will not say"]
    back = rig_from_dict(d)
    assert [f.code for f in back.flags] == ["calibration.principal_point", "other"]
    assert [f.detail for f in back.flags] == d["flags"] and all(not f.values for f in back.flags)

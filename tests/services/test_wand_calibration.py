"""A rig calibrated from a wand calibration's clips (services.rigs.calibration.calibrate_wand_clips, issue 35): bad
input is refused in words before any clip is read."""

from __future__ import annotations

from pathlib import Path

import pytest

from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.services.rigs.calibration import calibrate_wand_clips

BOARD = {"kind": "checkerboard", "inner_corners": [9, 6], "square_mm": 30.0}
ROLES = ("left", "middle", "right")


def _paths(tmp_path: Path, kind: str, roles=ROLES) -> dict[str, Path]:
    return {r: tmp_path / kind / f"{r}.mp4" for r in roles}


@pytest.mark.parametrize("length_m", [100.0, 0.0, -1.0, float("nan")])
def test_a_wand_length_outside_5_cm_to_5_m_is_refused(tmp_path, length_m):
    with pytest.raises(InputError, match=r"(outside 0.05-5 m.*measure it between the centres|not a number of metres)"):
        calibrate_wand_clips(_paths(tmp_path, "wand"), _paths(tmp_path, "close_up"), board=BOARD,
                             wand_length_m=length_m)


def test_a_camera_without_its_wand_or_close_up_clip_is_named(tmp_path):
    with pytest.raises(CalibrationError, match="no close-up clip of the right camera"):
        calibrate_wand_clips(_paths(tmp_path, "wand"), _paths(tmp_path, "close_up", ("left", "middle")),
                             board=BOARD, wand_length_m=1.0)
    with pytest.raises(CalibrationError, match="no wand clip of the middle, right camera"):
        calibrate_wand_clips(_paths(tmp_path, "wand", ("left",)), _paths(tmp_path, "close_up"), board=BOARD,
                             wand_length_m=1.0)

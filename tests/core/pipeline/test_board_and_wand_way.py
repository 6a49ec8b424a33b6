"""The board walk refined by a wand as a way of the pipeline (issue 35).

ride.json's ``calibration`` read into a typed way, the clip sets it asks for, and the region where a refined lens is
known, which the ride uses.
"""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.core.pipeline.detection import _coverage_flags
from saddlescope.core.pipeline.inputs import CalibrationSpec, calibration_spec
from saddlescope.core.pipeline.run import _clip_kinds
from saddlescope.core.pipeline.setup import lens_coverage_of
from saddlescope.core.types import ImageTracks


def test_each_way_names_the_clip_sets_it_calibrates_from():
    assert calibration_spec({}) == CalibrationSpec("board", None)
    assert calibration_spec({"calibration": {"method": "board"}}).clip_kinds == ("calibration",)
    wand = calibration_spec({"calibration": {"method": "wand", "wand_length_m": 0.8}})
    assert wand.clip_kinds == ("wand",) and wand.wand_length_mm == 800.0
    both = calibration_spec({"calibration": {"method": "board+wand", "wand_length_m": 1}})
    assert both == CalibrationSpec("board+wand", 1.0) and both.clip_kinds == ("calibration", "wand")


@pytest.mark.parametrize(("calibration", "says"), [
    ("board+wand", "calibration must be an object such as {\"method\": \"board+wand\", \"wand_length_m\": 1.0}"),
    ({"method": "wand_and_board", "wand_length_m": 1.0}, "'wand_and_board' is not one of board, wand, board+wand"),
    ({"method": "board+wand"}, "'board+wand' needs calibration.wand_length_m, the distance between the wand's"),
    ({"method": "board+wand", "wand_length_m": 100}, "in centimetres? 100 cm is 1.00 m"),
    ({"method": "wand", "wand_length_m": "1 m"}, "the wand's length '1 m' is not a number of metres"),
])
def test_a_bad_calibration_is_said_in_words(calibration, says):
    with pytest.raises(InputError) as err:
        calibration_spec({"calibration": calibration})
    assert says in str(err.value)


class _Clips:
    """A ride's clip sets, only what `_clip_kinds` asks."""

    def __init__(self, *kinds: str):
        self.kinds = set(kinds)

    def has(self, kind: str) -> bool:
        return kind in self.kinds


def test_the_board_and_wand_way_synchronises_both_clip_sets_and_wants_both():
    meta = {"calibration": {"method": "board+wand", "wand_length_m": 1.0}}
    clips = _Clips("calibration", "wand", "plumb", "static", "motion")
    assert _clip_kinds(clips, None, meta) == ["calibration", "wand", "plumb", "static", "motion"]
    with pytest.raises(InputError, match="the ride's board\\+wand calibration has no wand clips"):
        _clip_kinds(_Clips("calibration", "static", "motion"), None, meta)
    with pytest.raises(InputError, match="has no calibration and no wand clips, and no calibration was given"):
        _clip_kinds(_Clips("static", "motion"), None, meta)
    # a calibration given (the rig's): neither set is needed nor synchronised
    assert _clip_kinds(_Clips("static", "motion", "wand"), object(), meta) == ["static", "motion"]


BAND = {"middle": {"hull_px": [[540, 260], [740, 260], [740, 460], [540, 460]], "area_fraction": 0.04}}
WHOLE = {"middle": {"hull_px": [[10, 10], [1270, 10], [1270, 710], [10, 710]], "area_fraction": 0.96}}


def test_a_kept_refinement_knows_its_lens_where_the_wand_went_and_the_ride_reads_that():
    assert lens_coverage_of({"board_coverage": BAND}) == BAND
    assert lens_coverage_of({"board_coverage": BAND, "lens_coverage": WHOLE}) == WHOLE
    assert lens_coverage_of(None) is None and lens_coverage_of({"n_views": {"left": 3}}) is None
    # markers at the image's edge: outside the band's region, inside the board's and the wand's
    edge = ImageTracks("middle", np.array([[[100.0, 100.0]], [[1200.0, 650.0]], [[640.0, 360.0]]]), np.arange(3))
    flags = _coverage_flags({"middle": edge}, {"board_coverage": BAND})
    assert [f.code for f in flags] == ["calibration.coverage"]
    assert "outside the region the calibration board covered in 67 %" in flags[0].detail
    assert _coverage_flags({"middle": edge}, {"board_coverage": BAND, "lens_coverage": WHOLE}) == []
    half = {"middle": {"hull_px": [[10, 10], [700, 10], [700, 710], [10, 710]]}}
    flags = _coverage_flags({"middle": edge}, {"board_coverage": BAND, "lens_coverage": half})
    assert "the calibration board and the wand covered in 33 %" in flags[0].detail
    assert "walk the wand along the whole track" in flags[0].detail

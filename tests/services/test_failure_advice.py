"""A failed job's stored error becomes one sentence naming the clip and camera, and the action to offer."""

from __future__ import annotations

import re

import pytest

from saddlescope.core.errors import CamerasMovedError
from saddlescope.services.jobs.failure_advice import explain_failure

JARGON = re.compile(r"sub-harmonic|autocorrelation|blob|px\b|Hz\b|\bclip '|camera '|Error\b")

# (the stored error, the action, camera, clip kind, words the sentence must hold)
CASES = [
    ("probe: ride 4: the motion clip of the left camera (GX01.MP4) is not a usable video: truncated or corrupt "
     "after frame 212 (Invalid data found)", "replace_clip", "left", "motion",
     ["motion clip of the left camera", "cannot be read", "upload the motion clip of the left camera again"]),
    ("analyze: camera 'middle', clip 'motion': markers not found on any of the 40 frames (brightest blob 12)",
     "replace_clip", "middle", "motion", ["markers could not be found in the motion clip of the middle camera"]),
    ("analyze: no sync flash found in the static clip of the right camera: the largest brightness rise is 3 "
     "grey levels", "replace_clip", "right", "static",
     ["sync flash is not seen in the static clip of the right camera"]),
    ("analyze: no sync flash, and the markers' motion in the right camera's motion clip matches no other camera",
     "replace_clip", "right", "motion", ["sync flash", "motion clip of the right camera"]),
    ("analyze: the motion clip: the right camera runs at 50 fps but the left camera at 25 fps; ...",
     "replace_clip", "right", "motion", ["another frame rate or size", "motion clip of the right camera"]),
    ("analyze: the dominant motion frequency 1.00 Hz has no sub-harmonic inside the stride range 0.70-2.20 Hz "
     "that fits in the 2.50 s ride; the ride may be too short", "film_again", None, "motion",
     ["No steady stride", "motion clips"]),
    ("analyze: no periodic motion found in the marker tracks (best autocorrelation 0.01 at any candidate "
     "stride period)", "film_again", None, "motion", ["No steady stride"]),
    ("calibrate: calibration board found in only 3 frame(s) of the calibration clip of the left camera; need 8",
     "recalibrate_rig", "left", "calibration", ["calibration board", "calibration clip of the left camera"]),
    (f"analyze: {CamerasMovedError('the cameras moved since the rig was calibrated: the motion clip markers ...')}",
     "recalibrate_rig", None, None, ["The cameras moved since the rig was calibrated", "calibrate the rig again"]),
    ("analyze: the left camera's view does not hold the spots that the other cameras see as the static clip's "
     "markers", "recalibrate_rig", "left", "static",
     ["left camera does not see the markers where the rig's calibration expects them in its static clip",
      "calibrate the rig again"]),
    ("analyze: its worker host:12 stopped (last heartbeat 300 s ago) on attempt 3 of 3; not retried again",
     "run_again", None, None, ["not in your clips", "run it again"]),
    ("analyze: internal error (ZeroDivisionError: division by zero)", "run_again", None, None, ["run it again"]),
    ("analyze: the rear marker was hidden again and again (31 % of the frames where the other markers were seen): "
     "the markers were seen together for at most 0.63 s, less than one stride of 0.74 s; place the rear marker "
     "where the rider's leg, the tail or a lunge line does not pass, and film the ride again",
     "film_again", None, "motion", ["The rear marker kept being hidden", "place the rear marker where nothing"]),
]


@pytest.mark.parametrize(("error", "action", "camera", "kind", "words"), CASES,
                         ids=[c[1] + str(i) for i, c in enumerate(CASES)])
def test_each_failure_is_one_plain_sentence_naming_its_clip(error, action, camera, kind, words):
    advice = explain_failure(error)
    assert advice is not None
    assert (advice.action, advice.camera, advice.clip_kind) == (action, camera, kind)
    for word in words:
        assert word in advice.sentence, advice.sentence
    assert not JARGON.search(advice.sentence), advice.sentence
    assert advice.sentence.endswith(".") and advice.sentence.count(". ") == 0  # one sentence
    assert advice.sentence[0].isupper()


def test_an_unknown_failure_keeps_its_reason_and_names_the_clip():
    advice = explain_failure("analyze: the static shot of the left camera's motion clip is upside down")
    assert advice is not None and advice.action == "replace_clip"
    assert advice.sentence.startswith("The analysis stopped in the motion clip of the left camera because")


def test_no_error_no_advice():
    assert explain_failure(None) is None and explain_failure("  ") is None

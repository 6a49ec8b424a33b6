"""A failed job's reason as one sentence a club can act on: which clip of which camera, and what to do.

A job stores its error as ``"<stage>: <the typed error's message>"`` (`services.jobs.runner.run_job`). The
pipeline's messages are written for an engineer ("the dominant motion frequency 1.00 Hz has no
sub-harmonic ..."); this module names the clip and the camera they concern (the messages of
`core.errors`' types name them in a few fixed forms) and says what to do, in one sentence, with the
action the ride page offers: replace that clip, calibrate the rig again, or run the job again.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

from saddlescope.core.types import CAMERA_ROLES, CLIP_KINDS

__all__ = ["CAMERAS_MOVED", "FailureAction", "FailureAdvice", "explain_failure"]

FailureAction = Literal["replace_clip", "recalibrate_rig", "film_again", "run_again"]

# What the pipeline says when a ride's markers no longer fit the rig's calibration (core.pipeline.consistency).
CAMERAS_MOVED = "the cameras moved since the rig was calibrated"

_CAM = "|".join(CAMERA_ROLES)
_KIND = "|".join(CLIP_KINDS)
# The forms in which the typed errors name a clip and its camera, most specific first.
_CLIP_PATTERNS = (
    re.compile(rf"\b(?P<kind>{_KIND}) clip of the (?P<cam>{_CAM}) camera"),
    re.compile(rf"\bthe (?P<cam>{_CAM}) camera's (?P<kind>{_KIND}) clip"),
    re.compile(rf"camera '(?P<cam>{_CAM})', clip '(?P<kind>{_KIND})'"),
    re.compile(rf"\bthe (?P<cam>{_CAM}) camera's view.*?\bthe (?P<kind>{_KIND}) clip"),
    re.compile(rf"\b(?P<kind>{_KIND}) clip: the (?P<cam>{_CAM}) camera"),
)
_KIND_ONLY = re.compile(rf"\b(?:the )?(?P<kind>{_KIND}) clip")
_CAMERA_ONLY = re.compile(rf"\b(?:the )?(?P<cam>{_CAM}) camera\b|camera '(?P<quoted>{_CAM})'")

_UNREADABLE = ("not a usable video", "not a readable", "truncated", "corrupt", "no frame decodes", "empty file",
               "decoding failed", "has no video stream", "file not found", "no frame could be read")
_MISMATCH = ("fps but the", "px but the", "frame rate", "runs at")
_TOO_SHORT = ("too short", "shorter than", "too few", "record a longer ride", "has only")
_NO_FLASH = ("no sync flash",)
_MARKERS = ("markers not found", "no bright markers", "marker-like blob", "marker candidates", "nothing moves",
            "does not hold the spots", "marker row runs to the edge", "never seen together",
            "markers are lost", "no instant where all cameras see", "lacks a horse marker", "static shot must show",
            "not found in any frame of the static shot", "no frame where every marker")
_BOARD = ("calibration board", "board view", "see the board", "no board pose", "stereo calibration",
          "has no calibration", "calibration of camera", "no 'board'")
_NO_STRIDE = ("no periodic motion", "sub-harmonic", "cannot resolve the frequency", "no period to estimate",
              "shorter than two periods")
_WORKER_LOST = ("its worker", "internal error", "gave up after", "file store", "not part of this installation")


@dataclass(frozen=True)
class FailureAdvice:
    """Why a job failed and what to do, for the ride page and the jobs list.

    ``sentence``: one plain sentence naming the clip and camera where known; ``camera`` and ``clip_kind``:
    the clip to replace (None when the failure is not one clip's); ``action``: what the page offers.
    """

    sentence: str
    action: FailureAction
    camera: str | None = None
    clip_kind: str | None = None


def _clip_named(message: str) -> tuple[str | None, str | None]:
    """(camera, clip kind) the message names, either may be None."""
    for pattern in _CLIP_PATTERNS:
        if m := pattern.search(message):
            return m.group("cam"), m.group("kind")
    kind = m.group("kind") if (m := _KIND_ONLY.search(message)) else None
    camera = (m.group("cam") or m.group("quoted")) if (m := _CAMERA_ONLY.search(message)) else None
    return camera, kind


def _any(message: str, words: tuple[str, ...]) -> bool:
    return any(w in message for w in words)


def _clip_words(camera: str | None, kind: str | None) -> str:
    """"the motion clip of the left camera", "the motion clips", "the left camera's clip" or "the clips"."""
    if camera and kind:
        return f"the {kind} clip of the {camera} camera"
    if kind:
        return f"the {kind} clips"
    if camera:
        return f"the {camera} camera's clip"
    return "the clips"


def _clip_failure(message: str, camera: str | None, kind: str | None) -> FailureAdvice | None:
    """A failure of one clip's content (unreadable, short, no flash, no markers), else None."""
    clip = _clip_words(camera, kind)
    one_clip = camera is not None and kind is not None
    upload = f"upload {clip} again" if one_clip else "upload the clips again"
    action: FailureAction = "replace_clip" if one_clip else "film_again"

    def advice(sentence: str) -> FailureAdvice:
        return FailureAdvice(sentence, action, camera, kind)

    if _any(message, _UNREADABLE):
        return advice(f"{clip.capitalize()} cannot be read (the file is damaged or cut short): {upload} "
                      "from the camera's card, and the analysis runs again.")
    if _any(message, _MISMATCH) and not _any(message, _NO_STRIDE):
        return advice(f"{clip.capitalize()} was filmed at another frame rate or size than the other cameras: "
                      f"set the camera like the others and {upload}.")
    if _any(message, _NO_FLASH):
        return advice(f"The sync flash is not seen in {clip}: {upload} with the flash in view of every camera "
                      "(or film the horse moving before the cameras).")
    if _any(message, _MARKERS):
        return advice(f"The markers could not be found in {clip}: check that this camera saw the horse with "
                      f"its three markers (lens clean, in focus, not against the light) and {upload}.")
    return None


def _ride_failure(message: str, camera: str | None, kind: str | None) -> FailureAdvice | None:
    """A failure of the whole ride or the rig (cameras moved, board, no stride, too short), else None."""
    if CAMERAS_MOVED in message:
        return FailureAdvice("The cameras moved since the rig was calibrated: calibrate the rig again (film the "
                             "board once more, or use a ride's own calibration clips) and run the analysis again.",
                             "recalibrate_rig", None, None)
    if "does not hold the spots that the other cameras see" in message and camera:
        # the rig's calibration says where the other cameras' markers must appear in this camera: a camera
        # moved since the rig was calibrated does this, as does a camera whose view of the horse is blocked
        where = f" in its {kind} clip" if kind else ""
        return FailureAdvice(f"The {camera} camera does not see the markers where the rig's calibration expects "
                             f"them{where}: if a camera was moved since the rig was "
                             "calibrated, calibrate the rig again; otherwise check that this camera sees the "
                             "horse's markers.", "recalibrate_rig", camera, kind)
    if _any(message, _BOARD) or (kind == "calibration" and not _any(message, _UNREADABLE)):
        where = f" in {_clip_words(camera, 'calibration')}" if camera else ""
        return FailureAdvice(f"The calibration board was not seen well enough{where}: film the board again, "
                             "moving it through the whole view of every camera, or pick another calibration for "
                             "the rig, then run the analysis again.", "recalibrate_rig", camera, "calibration")
    if "was hidden again and again" in message:
        marker = message.split(" marker was hidden", 1)[0].rsplit(" ", 1)[-1]
        return FailureAdvice(f"The {marker} marker kept being hidden (a rider's leg, the tail or a lunge line "
                             "passing over it), so the markers were never seen together for a whole stride: place "
                             f"the {marker} marker where nothing passes over it and film the ride again.",
                             "film_again", None, "motion")
    if _any(message, _NO_STRIDE):
        return FailureAdvice("No steady stride was found in the motion clips: film at least ten strides of one "
                             "steady gait with the horse in view of all three cameras, and upload the motion clips "
                             "again.", "film_again", None, "motion")
    if _any(message, _TOO_SHORT):
        clip = _clip_words(camera, kind)
        return FailureAdvice(f"{clip.capitalize()} is too short to analyse: film a longer stretch and upload "
                             f"{'it' if camera and kind else 'them'} again.",
                             "replace_clip" if camera and kind else "film_again", camera, kind)
    return None


def explain_failure(error: str | None) -> FailureAdvice | None:
    """The failed job's stored error (``"stage: message"``) as advice; None when there is no error."""
    if not error or not error.strip():
        return None
    message = error.strip()
    stage, sep, rest = message.partition(": ")
    if sep and re.fullmatch(r"[a-z_]+", stage):
        message = rest
    if _any(message, _WORKER_LOST):
        return FailureAdvice("The analysis stopped for a reason that is not in your clips (the server was "
                             "interrupted): run it again, and tell your administrator if it stops again.",
                             "run_again")
    camera, kind = _clip_named(message)
    advice = _ride_failure(message, camera, kind) or _clip_failure(message, camera, kind)
    if advice is not None:
        return advice
    reason = message.rstrip(". ")
    reason = reason[:1].lower() + reason[1:]
    where = f" in {_clip_words(camera, kind)}" if camera or kind else ""
    return FailureAdvice(f"The analysis stopped{where} because {reason}: correct that and run it again.",
                         "replace_clip" if camera and kind else "run_again", camera, kind)

"""One glossary of every code the service shows a person.

Indicators, gaits, directions, job kinds and stages, clip kinds, where gravity came from, the ways
rides are compared, saddle types, and the caveat shown with the exposure times.

``GET /api/glossary`` serves it; the dashboard takes every label from it, so a raw code (``lab_vertical``,
``dtw``, ``analyze``) never reaches a page. Indicators carry ``expert``: the thesis's eight comfort
indicators are the headline numbers, the rest (MTVV, the W_d axes, the worst-axis times, ...) are folded
under "expert detail".
"""

from __future__ import annotations

from dataclasses import dataclass

from saddlescope.core.similarity import METHODS
from saddlescope.core.types import CAMERA_ROLES
from saddlescope.core.vibration import COMFORT_INDICATORS, GAITS, INDICATORS, PASSIVE_SEATED_CAVEAT
from saddlescope.db.enums import SaddleType
from saddlescope.services.jobs.stage_labels import STAGE_LABELS
from saddlescope.services.jobs.stages import JOB_KINDS

__all__ = ["GLOSSARY_KINDS", "GlossaryEntry", "glossary", "label_of"]

GLOSSARY_KINDS = ("indicator", "gait", "direction", "job_kind", "job_stage", "clip_kind", "camera",
                  "gravity_source", "similarity_method", "saddle_type", "caveat")


@dataclass(frozen=True)
class GlossaryEntry:
    """What one code means to a person: its label, unit ("" when none) and a short explanation."""

    kind: str
    code: str
    label: str
    unit: str
    short: str
    expert: bool = False


GAIT_LABELS = {"walk": "walk", "sitting_trot": "sitting trot", "rising_trot": "rising trot", "canter": "canter"}
_GAIT_SHORT = {
    "walk": "four-beat gait; the rider sits",
    "sitting_trot": "two-beat trot with the rider sitting: the rider takes every bounce",
    "rising_trot": "two-beat trot with the rider rising every other beat: less time in the saddle",
    "canter": "three-beat gait with a rocking motion of the back",
}
_DIRECTIONS = {"CW": ("clockwise", "the horse went round the arena clockwise (right rein)"),
               "CCW": ("counter-clockwise", "the horse went round the arena counter-clockwise (left rein)")}
_JOB_KINDS = {
    "analyze": ("Ride analysis", "checks the clips, calibrates the cameras and measures the ride"),
    "probe": ("Clip check", "reads the clips' length, frame rate and size"),
    "similarity": ("Rides most alike", "compares the saddle's motion of the club's rides"),
    "calibrate_rig": ("Rig calibration", "calibrates a rig's three cameras from its board clips, or its wand and "
                      "close-up clips"),
    "selftest": ("Worker self-test", "checks that the workers run"),
    "check_calibration": ("Calibration check", "judges calibration clips before anyone rides: where the board reached"),
}
# every SaddleType, as a saddle fitter names it (the dashboard's saddle forms and pages show these)
_SADDLE_TYPES = {
    SaddleType.GP: "general purpose", SaddleType.DRESSAGE: "dressage", SaddleType.JUMP: "jumping",
    SaddleType.TREELESS: "treeless", SaddleType.ENDURANCE: "endurance", SaddleType.WESTERN: "western",
    SaddleType.OTHER: "other",
}
_CLIP_KINDS = {
    "motion": ("ride clip", "the horse ridden past the three cameras"),
    "calibration": ("calibration clip", "the calibration board shown to the three cameras"),
    "plumb": ("plumb-line clip", "a plumb line in view, for which way is down"),
    "static": ("still clip", "the markers standing still, for their layout"),
    "wand": ("wand clip", "a wand with two markers waved through the arena, for the cameras' places and scale"),
    "close_up": ("close-up clip", "a small board filmed close to one camera, for its lens"),
}
_GRAVITY_SOURCES = {
    "plumb": ("plumb line", "which way is down was measured from a plumb line in view"),
    "hint": ("the rig's down direction", "which way is down was taken from the rig's calibration"),
    "camera_down": ("the left camera's level", "which way is down was assumed from a level left camera"),
    "lab_vertical": ("the lab's vertical axis", "motion capture: down is the lab's vertical axis"),
}
_SIMILARITY_METHODS = {
    "dtw": ("shape of the stride (time-warped)", "strides compared point by point, allowing one to run "
            "faster or slower in parts (dynamic time warping)"),
    "chaincode": ("direction of the path", "strides compared by the directions the saddle moves in, step by step"),
}


def _indicator_short(key: str) -> str:  # noqa: C901 - one phrase per family of keys, read top to bottom
    """A one-line explanation of an indicator, by its family."""
    if key.startswith(("t_", "d_")):
        what = "riding time" if key.startswith("t_") else "riding distance"
        level = "limit" if "_limit_" in key else "action"
        return (f"{what} a day until the EU {level} value for whole-body vibration is reached (on the safe side: "
                "it assumes a passive seated person)")
    if key.startswith("mtvv"):
        return "the largest one-second r.m.s. of the weighted acceleration: the worst moment (ISO 2631-1)"
    if key.startswith("vdv"):
        return "vibration dose value: weighs jolts more than r.m.s. does (fourth power)"
    if key.startswith("crest_factor"):
        return "peak over r.m.s. of the weighted acceleration: high values mean jolts"
    if key.endswith("_rms") and "_w" in key:
        return "the weighted vibration the rider feels, averaged over the ride (r.m.s.)"
    if key.endswith("_rms"):
        return "the vertical acceleration averaged over the ride (r.m.s.), not weighted"
    if "_peak" in key or key.endswith("_max"):
        return "the largest acceleration of the analysed strides"
    return {
        "vel_x_avg_kmh": "how fast the horse moved along its path",
        "amplitude_y_m": "how far the saddle moves up and down in a stride",
        "stride_frequency_hz": "strides per second",
        "duration_s": "the length of the analysed part of the clip",
    }.get(key, "")


def _indicators() -> list[GlossaryEntry]:
    return [GlossaryEntry("indicator", key, info.label, info.unit, _indicator_short(key),
                          expert=key not in COMFORT_INDICATORS) for key, info in INDICATORS.items()]


def _table(kind: str, table: dict[str, tuple[str, str]]) -> list[GlossaryEntry]:
    return [GlossaryEntry(kind, code, label, "", short) for code, (label, short) in table.items()]


def glossary() -> list[GlossaryEntry]:
    """Every entry, kind by kind (`GLOSSARY_KINDS`' order)."""
    job_kinds = {**_JOB_KINDS, **{k: (k.replace("_", " ").capitalize(), "") for k in JOB_KINDS if k not in _JOB_KINDS}}
    return [
        *_indicators(),
        *[GlossaryEntry("gait", g, GAIT_LABELS.get(g, g.replace("_", " ")), "", _GAIT_SHORT.get(g, "")) for g in GAITS],
        *_table("direction", _DIRECTIONS),
        *_table("job_kind", job_kinds),
        *[GlossaryEntry("job_stage", code, label, "", "") for code, label in STAGE_LABELS.items()],
        *_table("clip_kind", _CLIP_KINDS),
        *[GlossaryEntry("camera", role, f"{role} camera", "", "") for role in CAMERA_ROLES],
        *_table("gravity_source", _GRAVITY_SOURCES),
        *_table("similarity_method", {m: _SIMILARITY_METHODS.get(m, (m, "")) for m in METHODS}),
        *[GlossaryEntry("saddle_type", t.value, _SADDLE_TYPES.get(t, t.value), "", "") for t in SaddleType],
        # the sentence shown with the exposure times (the EU limits assume a passive, seated person)
        GlossaryEntry("caveat", "passive_seated", PASSIVE_SEATED_CAVEAT, "", ""),
    ]


def label_of(kind: str, code: str) -> str:
    """The label of `code` of `kind`; the code in words (underscores as spaces) where it is not listed."""
    for entry in glossary():
        if entry.kind == kind and entry.code == code:
            return entry.label
    return code.replace("_", " ")

"""Plain-language notes on a result's quality flags: one table for the API, the ride page and the report.

The pipeline's flags are sentences written for an expert ("eigenvalue ratio 0.026 kept at 0 % in ω").
Each is matched here to a code, a severity a club can read at a glance (``ok``: nothing to do;
``check``: worth a look or a change next time; ``problem``: the numbers concerned are not to be
trusted) and ONE sentence saying what to do. The flag itself stays as the expert detail.

Flags carry numbers, so each entry is a regular expression matched at the start of the flag. The
first entry that matches wins: more specific patterns come before the general ones they share a
prefix with. ``tests/services/test_quality_notes.py`` reads every flag sentence in the source and
fails when one has no entry here.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

__all__ = ["NOTES", "SEVERITIES", "QualityNote", "note_for", "quality_notes", "quality_summary"]

Severity = Literal["ok", "check", "problem"]
SEVERITIES: tuple[Severity, ...] = ("ok", "check", "problem")


@dataclass(frozen=True)
class QualityNote:
    """One kind of flag: its code, how serious it is and what a club should do about it."""

    code: str
    pattern: str
    severity: Severity
    message: str


_MARKER_LAYOUT = "Move the middle marker about 10 cm below the line of the other two to measure roll."
_CALIBRATE_AGAIN = ("Calibrate again: carry the board slowly through the riding area and to the corners of "
                    "every camera's view.")
_PLUMB = "Film the plumb line (a weighted string with two markers) so every camera sees both of its markers."

# (code, pattern matched at the start of the flag, severity, the one sentence a club can act on)
_TABLE: tuple[tuple[str, str, Severity, str], ...] = (
    # calibration (core/calibration)
    ("calibration.no_shared_view", r"no board was seen by two cameras at once", "problem",
     "Calibrate again so that at least two cameras see the board at the same moment; distances are unchecked."),
    ("calibration.square_error", r"reconstructed board squares are off by", "problem", _CALIBRATE_AGAIN),
    ("calibration.corner_distances", r"distances between triangulated board corners are off by", "problem",
     _CALIBRATE_AGAIN),
    ("calibration.principal_point", r"the joint adjustment moved every camera's principal point", "check",
     "Next calibration, carry the board higher and lower and tilt it towards and away from the cameras."),
    # two-camera samples whose depth rests on the lens extrapolated beyond the board (core/saddle.py): the
    # broken case first, both sentences start alike
    ("calibration.guessed_depth_broken", r".*the run holds less than a stride without them", "problem",
     "Much of the crossing was seen where the board never went, so the numbers may be wrong; calibrate again."),
    ("calibration.guessed_depth", r"markers seen by two cameras only, one of them outside the region", "check",
     "The crossing's ends, seen where the board never went, were left out; carry the board to every view's corners."),
    ("calibration.coverage", r"the .+ camera saw the markers outside the region the calibration board", "check",
     "Carry the board to the corners of every camera's view when you calibrate."),
    ("calibration.units_guessed", r".+ states no units; its ", "check",
     "Say in ride.json (calibration_units) whether the calibration file is in mm or metres."),
    # clips and synchronisation (core/pipeline)
    ("video.variable_frame_rate", r"the .+ clip of the .+ camera has a variable frame rate", "ok",
     "The phone varied its frame rate and this was corrected; lock the frame rate in the camera app if you can."),
    ("sync.motion_uncertain", r"the .+ clip was synchronised from .+ motion \(no sync flash\), uncertain", "check",
     "The cameras were matched in time from the horse's motion, less surely than usual: film a flash at the "
     "start of each clip."),
    ("sync.motion", r"the .+ clip was synchronised from .+ motion \(no sync flash\)", "ok",
     "No flash was seen, so the cameras were matched in time from the horse's or the board's motion; nothing to do."),
    ("tracking.two_cameras_only", r"the .+ clip was triangulated from the .+ cameras only", "check",
     "One camera lost the markers in this clip: check that all three cameras see every marker throughout."),
    ("tracking.cameras_disagree", r"the cameras disagree on the .+ clip's markers", "check",
     "Check that each camera followed the real markers and that the flash is seen by all cameras."),
    ("tracking.lookalike_recovered", r"the moving spots each camera found were", "ok",
     "A shiny spot moving with the horse looked like a marker and was sorted out; cover shiny tack if it repeats."),
    ("tracking.lookalike", r"the tracked markers are .+ off the static shot's marker distances", "problem",
     "Film the static shot just before the ride without touching the markers, and cover shiny tack near them."),
    ("tracking.dropped_samples", r".+ broke the markers' distances", "check",
     "A few look-alike spots were dropped; cover shiny tack near the markers if this repeats."),
    ("tracking.gaps_bridged", r".+ with a short marker gap bridged", "ok",
     "Short moments where a marker was hidden were bridged; nothing to do."),
    ("tracking.lost_all_along", r"markers lost from .+ \(one or another, all along\)", "problem",
     "A marker was hidden for most of the ride: place the markers where every camera sees them the whole time."),
    ("tracking.not_in_view_at_start", r"markers not all in view before", "check",
     "Start filming with the horse already in view of all cameras."),
    ("tracking.not_in_view_at_end", r"markers not all in view after", "check",
     "Keep filming until the horse has left the view of all cameras."),
    ("tracking.lost", r"markers lost from", "check",
     "A marker was hidden for a moment: check that nothing (rider's leg, saddle pad) covers the markers."),
    ("markers.rigidity", r"the markers kept the static shot's layout only to", "problem",
     "Film the static shot just before the ride without moving the markers; the saddle point is unreliable."),
    ("rig.weak_depth", r"the rig fixes depth", "check",
     "Place the cameras 2-3 m apart so sideways sway and roll can be measured."),
    # plumb line and gravity (core/pipeline, core/kinematics/frames.py, io)
    ("plumb.missing", r"no plumb clips?(:|$)", "check", _PLUMB),
    ("plumb.leaning", r"plumb clip not used: the plumb line found leans", "check", _PLUMB),
    ("plumb.not_used", r"plumb clip not used", "check", _PLUMB),
    ("plumb.one_marker", r"only one plumb marker track was given", "check", _PLUMB),
    ("gravity.tilted", r"gravity \(.+\) is .+ deg from perpendicular to the travel", "check",
     "Ride on level ground and check that the plumb line hangs still when you film it."),
    ("gravity.from_hint", r"no plumb line: gravity taken as", "check", _PLUMB),
    ("gravity.from_camera", r"no plumb clip and no down hint", "check",
     "Film a plumb line before the ride; until then keep the left camera level."),
    ("gravity.lab_vertical", r"gravity along the lab's vertical", "ok",
     "The motion-capture lab's vertical was used as gravity; nothing to do."),
    # the indicators' intervals (core/vibration/intervals.py, docs/accuracy.md)
    ("indicators.too_uncertain", r"too uncertain for a decision", "problem",
     "Do not compare or rank this ride (leaderboards leave it out); fix what the other notes say and ride again."),
    # curve fits (core/kinematics)
    ("fit.wild_samples", r".+: \d+ wild samples left out of its fits", "ok",
     "A few stray samples of one marker were left out of its curve; nothing to do unless it repeats."),
    ("fit.fundamental_drift", r".+: the fitted fundamental \(", "check",
     "One marker's curve did not follow the stride rhythm: check its residuals below and that it was tracked cleanly."),
    ("fit.short_crossing", r"the markers were tracked together for .+ the fits saw", "check",
     "The cameras saw too few strides together: film a longer straight line in all cameras' view."),
    ("fit.no_fundamental", r"no fit determined the fundamental", "check",
     "The stride rhythm came from the stride period only: film at least two clean strides at an even pace."),
    # rotation of the back (core/kinematics/rigid_body.py)
    ("rotation.markers_in_line", r"the markers lie near a line", "check", _MARKER_LAYOUT),
    ("rotation.weak_axis", r"rotation about the markers' weakest axis", "check", _MARKER_LAYOUT),
    ("rotation.all_versions_excluded", r"all ω versions excluded in", "ok",
     "The rotation was taken from the robust least-squares estimate throughout; nothing to do."),
    ("rotation.near_singularity", r"ω is nearly in the markers' plane", "ok",
     "The quick closed-form rotation estimates were unreliable for this motion; the result uses the robust one."),
    ("rotation.versions_excluded", r".+ versions excluded near their singularity", "ok",
     "Some quick rotation estimates were left out where unreliable; the result uses the robust one."),
    # motion-capture files (io/mocap)
    ("mocap.no_units", r"no Units in the header; assumed mm", "check",
     "Check that the file's positions are in millimetres, or export it again with its units."),
    ("mocap.marker_names", r"the header declares .+ markers but line 4 names", "check",
     "Check the marker names in the file: some had none and were numbered."),
    ("mocap.short_rows", r".+ rows stop before the last declared marker", "check",
     "Some frames of the file miss their last markers: export the file again if that is unexpected."),
    ("mocap.extra_cells", r".+ rows hold cells beyond the .+ declared markers", "check",
     "Some frames of the file hold more values than markers; they were ignored."),
)

NOTES: dict[str, QualityNote] = {code: QualityNote(code, pattern, severity, message)
                                 for code, pattern, severity, message in _TABLE}
_COMPILED = tuple((NOTES[code], re.compile(pattern, re.DOTALL)) for code, pattern, _, _ in _TABLE)
_UNKNOWN = QualityNote("other", "", "check", "The analysis noted something unusual; the detail says what.")


def note_for(flag: str) -> QualityNote:
    """The table's entry for one flag sentence (a general 'check' note when none matches)."""
    text = str(flag).strip()
    for note, pattern in _COMPILED:
        if pattern.match(text):
            return note
    return _UNKNOWN


def quality_notes(flags: Iterable[Any]) -> list[dict[str, str]]:
    """``[{code, severity, message, detail}]`` for a result's flags, most serious first.

    ``detail`` is the flag itself (the expert's sentence with its numbers); flags of one code keep
    their own detail each, in the pipeline's order.
    """
    rank = {s: i for i, s in enumerate(reversed(SEVERITIES))}
    notes = [{"code": n.code, "severity": n.severity, "message": n.message, "detail": str(flag)}
             for flag in flags if str(flag).strip() for n in (note_for(str(flag)),)]
    return sorted(notes, key=lambda n: rank[n["severity"]])


def quality_summary(quality: Mapping[str, Any] | None) -> tuple[Severity, str]:
    """The result's overall severity and one line saying it, from its ``quality`` section."""
    notes = quality_notes((quality or {}).get("flags") or [])
    worst = notes[0]["severity"] if notes else "ok"
    counts = {s: sum(n["severity"] == s for n in notes) for s in SEVERITIES}
    if worst == "problem":
        return worst, f"{counts['problem']} problem(s) found: the numbers they concern are not to be trusted."
    if worst == "check":
        return worst, f"{counts['check']} point(s) to check; the main results stand."
    return "ok", "The recording and the analysis look good."

"""What the analysis found worth saying about a ride's quality, as typed values (issue 34, "flags as data").

Every stage raises a :class:`Finding`: a ``code`` naming its kind, the expert's sentence with its numbers
(``detail``) and the numbers behind it (``values``, named with their units). The one table
:data:`FINDING_KINDS` says, per code, how serious it is (``ok``: nothing to do; ``check``: worth a look or
a change next time; ``problem``: the numbers concerned are not to be trusted), the stage that raises it
and ONE sentence a club can act on. The codes are an API surface (the ride page, the report and stored
results name them): keep them, add new ones.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Literal

__all__ = ["FINDING_KINDS", "SEVERITIES", "Finding", "FindingKind", "Severity"]

Severity = Literal["ok", "check", "problem"]
SEVERITIES: tuple[Severity, ...] = ("ok", "check", "problem")


@dataclass(frozen=True)
class FindingKind:
    """One kind of finding: its code, how serious it is, the stage raising it, what a club should do."""

    code: str
    severity: Severity
    stage: str
    advice: str


_MARKER_LAYOUT = "Move the middle marker about 10 cm below the line of the other two to measure roll."
_CALIBRATE_AGAIN = ("Calibrate again: carry the board slowly through the riding area and to the corners of "
                    "every camera's view.")
_PLUMB = "Film the plumb line (a weighted string with two markers) so every camera sees both of its markers."

# (code, severity, stage, the one sentence a club can act on); stages are the analysis's progress stages
# (sync, calibration, detection, kinematics, indicators) plus "input" for what reading a file found
_TABLE: tuple[tuple[str, Severity, str, str], ...] = (
    # calibration (core/calibration)
    ("calibration.no_shared_view", "problem", "calibration",
     "Calibrate again so that at least two cameras see the board at the same moment; distances are unchecked."),
    ("calibration.cameras_moved", "problem", "detection",
     "The cameras moved since the rig was calibrated: calibrate the rig again, then run the analysis again."),
    ("calibration.square_error", "problem", "calibration", _CALIBRATE_AGAIN),
    ("calibration.corner_distances", "problem", "calibration", _CALIBRATE_AGAIN),
    ("calibration.lens_model", "check", "calibration",
     "Next calibration, carry the board to the edges and corners of this camera's view so its own views fix its lens."),
    ("calibration.wand_length", "problem", "calibration",
     "Calibrate again: wave the wand slowly through the whole riding area where every camera sees both ends."),
    ("calibration.principal_point", "check", "calibration",
     "Next calibration, carry the board higher and lower and tilt it towards and away from the cameras."),
    # two-camera samples whose depth rests on the lens extrapolated beyond the board (core/saddle.py)
    ("calibration.guessed_depth_broken", "problem", "kinematics",
     "Much of the crossing was seen where the board never went, so the numbers may be wrong; calibrate again."),
    ("calibration.guessed_depth", "check", "kinematics",
     "The crossing's ends, seen where the board never went, were left out; carry the board to every view's corners."),
    ("calibration.coverage", "check", "detection",
     "Carry the board to the corners of every camera's view when you calibrate."),
    # a calibration clip checked on upload, before anyone rides (core/calibration/coverage_check.py)
    ("calibration_check.board_not_seen", "problem", "calibration",
     "Film the calibration again with the whole board in view, sharp and well lit, held still in each place."),
    ("calibration_check.few_views", "problem", "calibration",
     "Film the calibration again for longer, carrying the board slowly through the whole view."),
    ("calibration_check.third_missed", "problem", "calibration",
     "Film the calibration again and carry the board into the part of the view it never reached, up to the edges."),
    ("calibration_check.corners_missed", "check", "calibration",
     "Usable; next time also carry the board into the corners of the view."),
    ("calibration_check.narrow_depth", "check", "calibration",
     "Usable; next time also carry the board nearer to and farther from the camera."),
    ("calibration_check.covered", "ok", "calibration", "Nothing to do: the board reached every part of the view."),
    # a wand calibration's clip checked the same way (core/calibration/coverage_check.py: check_wand_coverage)
    ("calibration_check.wand_not_seen", "problem", "calibration",
     "Film the wand again with both discs in view and nothing else as bright, waved slowly."),
    ("calibration_check.wand_few_frames", "problem", "calibration",
     "Film the wand again for longer, walking it slowly along the whole track through every view."),
    ("calibration_check.wand_third_missed", "problem", "calibration",
     "Film the wand again and walk it into the part of the view it never reached, up to the edges."),
    ("calibration_check.wand_corners_missed", "check", "calibration",
     "Usable; next time also take the wand higher and lower where the horse enters and leaves the view."),
    ("calibration_check.wand_narrow_depth", "check", "calibration",
     "Usable; next time also wave the wand nearer to and farther from the camera."),
    ("calibration_check.wand_covered", "ok", "calibration", "Nothing to do: the wand reached every part of the view."),
    ("calibration.units_guessed", "check", "input",
     "Say in ride.json (calibration_units) whether the calibration file is in mm or metres."),
    # clips and synchronisation (core/pipeline)
    ("video.variable_frame_rate", "ok", "sync",
     "The phone varied its frame rate and this was corrected; lock the frame rate in the camera app if you can."),
    ("sync.motion_uncertain", "check", "sync",
     "The cameras were matched in time from the horse's motion, less surely than usual: film a flash at the "
     "start of each clip."),
    ("sync.motion", "ok", "sync",
     "No flash was seen, so the cameras were matched in time from the horse's or the board's motion; nothing to do."),
    ("tracking.two_cameras_only", "check", "detection",
     "One camera lost the markers in this clip: check that all three cameras see every marker throughout."),
    ("tracking.cameras_disagree", "check", "detection",
     "Check that each camera followed the real markers and that the flash is seen by all cameras."),
    ("tracking.lookalike_recovered", "ok", "detection",
     "A shiny spot moving with the horse looked like a marker and was sorted out; cover shiny tack if it repeats."),
    ("tracking.lookalike", "problem", "detection",
     "Film the static shot just before the ride without touching the markers, and cover shiny tack near them."),
    ("tracking.dropped_samples", "check", "kinematics",
     "A few look-alike spots were dropped; cover shiny tack near the markers if this repeats."),
    ("tracking.partly_covered", "ok", "detection",
     "Moments where something passed in front of a marker were left out; nothing to do unless it is every stride."),
    # a marker hidden at the same moment of every stride (core/kinematics/hidden_phase.py): what that costs
    # is measured on the ride and carried by its intervals (which mark it too uncertain when too wide), or,
    # where it cannot be measured (too few strides fitted), the ride is too uncertain
    ("kinematics.stride_phase_unmeasured", "check", "kinematics",
     "Place the markers where the rider's leg, the tail or a lunge line does not pass in front of them."),
    ("kinematics.stride_phase_untested", "problem", "kinematics",
     "Place the markers where the rider's leg, the tail or a lunge line does not pass, and film more strides."),
    ("tracking.gaps_bridged", "ok", "kinematics",
     "Short moments where a marker was hidden were bridged; nothing to do."),
    ("tracking.lost_all_along", "problem", "kinematics",
     "A marker was hidden for most of the ride: place the markers where every camera sees them the whole time."),
    ("tracking.not_in_view_at_start", "check", "kinematics",
     "Start filming with the horse already in view of all cameras."),
    ("tracking.not_in_view_at_end", "check", "kinematics",
     "Keep filming until the horse has left the view of all cameras."),
    ("tracking.lost", "check", "kinematics",
     "A marker was hidden for a moment: check that nothing (rider's leg, saddle pad) covers the markers."),
    ("markers.rigidity", "problem", "kinematics",
     "Film the static shot just before the ride without moving the markers; the saddle point is unreliable."),
    ("rig.weak_depth", "check", "kinematics",
     "Place the cameras 2-3 m apart so sideways sway and roll can be measured."),
    # plumb line and gravity (core/pipeline, core/kinematics/frames.py, io)
    ("plumb.missing", "check", "detection", _PLUMB),
    ("plumb.leaning", "check", "detection", _PLUMB),
    ("plumb.not_used", "check", "detection", _PLUMB),
    ("plumb.one_marker", "check", "kinematics", _PLUMB),
    ("gravity.tilted", "check", "kinematics",
     "Ride on level ground and check that the plumb line hangs still when you film it."),
    ("gravity.from_hint", "check", "kinematics", _PLUMB),
    ("gravity.from_camera", "check", "kinematics",
     "Film a plumb line before the ride; until then keep the left camera level."),
    ("gravity.lab_vertical", "ok", "input",
     "The motion-capture lab's vertical was used as gravity; nothing to do."),
    # the indicators' intervals (core/vibration/intervals.py, docs/accuracy.md)
    ("indicators.too_uncertain", "problem", "indicators",
     "Do not compare or rank this ride (leaderboards leave it out); fix what the other notes say and ride again."),
    # curve fits (core/kinematics)
    ("fit.wild_samples", "ok", "kinematics",
     "A few stray samples of one marker were left out of its curve; nothing to do unless it repeats."),
    ("fit.fundamental_drift", "check", "kinematics",
     "One marker's curve did not follow the stride rhythm: check its residuals below and that it was tracked cleanly."),
    ("fit.short_crossing", "check", "kinematics",
     "The cameras saw too few strides together: film a longer straight line in all cameras' view."),
    # rides of several passes in front of the cameras (core/pipeline/passes.py, issue 38)
    ("passes.pooled", "ok", "kinematics",
     "The strides of every pass were pooled into the numbers; nothing to do."),
    ("passes.dropped", "check", "kinematics",
     "A pass too short to measure a stride was left out: ride each pass straight through the whole view."),
    ("fit.no_fundamental", "check", "kinematics",
     "The stride rhythm came from the stride period only: film at least two clean strides at an even pace."),
    # rotation of the back (core/kinematics/rigid_body.py)
    ("rotation.markers_in_line", "check", "kinematics", _MARKER_LAYOUT),
    ("rotation.weak_axis", "check", "kinematics", _MARKER_LAYOUT),
    ("rotation.all_versions_excluded", "ok", "kinematics",
     "The rotation was taken from the robust least-squares estimate throughout; nothing to do."),
    ("rotation.near_singularity", "ok", "kinematics",
     "The quick closed-form rotation estimates were unreliable for this motion; the result uses the robust one."),
    ("rotation.versions_excluded", "ok", "kinematics",
     "Some quick rotation estimates were left out where unreliable; the result uses the robust one."),
    # motion-capture files (io/mocap)
    ("mocap.no_units", "check", "input",
     "Check that the file's positions are in millimetres, or export it again with its units."),
    ("mocap.marker_names", "check", "input",
     "Check the marker names in the file: some had none and were numbered."),
    ("mocap.short_rows", "check", "input",
     "Some frames of the file miss their last markers: export the file again if that is unexpected."),
    ("mocap.extra_cells", "check", "input",
     "Some frames of the file hold more values than markers; they were ignored."),
    ("mocap.repeated_labels", "check", "input",
     "Give every marker its own label in the motion-capture software; repeated ones were told apart."),
    ("mocap.header_repaired", "ok", "input",
     "The file's header missed or contradicted a value that was taken from the file itself; nothing to do."),
    ("mocap.reader_note", "check", "input",
     "The C3D reader noted something unusual in the file; check its trajectories if the numbers look wrong."),
    # a sentence of a result stored before findings were data that no legacy pattern recognises
    ("other", "check", "unknown", "The analysis noted something unusual; the detail says what."),
)

FINDING_KINDS: Mapping[str, FindingKind] = MappingProxyType(
    {code: FindingKind(code, severity, stage, advice) for code, severity, stage, advice in _TABLE})


@dataclass(frozen=True)
class Finding:
    """One thing a stage found: its kind's ``code``, the expert's sentence, the numbers behind it.

    ``values`` name each number with its unit (``"share_pct"``, ``"gap_start_s"``; a non-finite one is
    left out); the sentence a club reads, the severity and the stage come from :data:`FINDING_KINDS` by
    code. An unknown code is a programming error and raises ``ValueError``.
    """

    code: str
    detail: str
    values: Mapping[str, float] = field(default_factory=dict, hash=False)

    def __post_init__(self) -> None:
        if self.code not in FINDING_KINDS:
            raise ValueError(f"unknown finding code {self.code!r}: add it to saddlescope.core.findings' table")
        if not self.detail.strip():
            raise ValueError(f"a {self.code} finding needs its detail sentence")
        # a number the stage could not determine (NaN) is left out rather than stored: JSON has no NaN
        values = {str(k): float(v) for k, v in self.values.items() if math.isfinite(float(v))}
        object.__setattr__(self, "values", MappingProxyType(values))

    @property
    def kind(self) -> FindingKind:
        """The table's entry for this finding's code."""
        return FINDING_KINDS[self.code]

    @property
    def severity(self) -> Severity:
        """``ok``, ``check`` or ``problem``."""
        return self.kind.severity

    @property
    def stage(self) -> str:
        """The analysis stage that raises this kind of finding."""
        return self.kind.stage

    def __str__(self) -> str:
        return self.detail

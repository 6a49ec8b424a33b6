"""Reader of quality flags stored as sentences only, by results and calibrations made before findings were data.

Until issue 34 the analysis wrote its quality flags as English sentences and the notes were found by
matching them against the ordered regular expressions below. New documents store typed findings
(``quality.findings``, ``calibration.findings``; :mod:`saddlescope.core.findings`), so this module is used
ONLY for a document that has ``flags`` but no ``findings``
(:func:`saddlescope.io.findings_document.findings_of`). It must keep giving those old results the codes
they were shown with: do not edit the patterns, and never match new sentences here.

Each pattern is matched at the start of the sentence; the first that matches wins (the specific ones
come before the general ones they share a prefix with). A sentence no pattern matches is ``other``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from saddlescope.core.findings import Finding

__all__ = ["LEGACY_PATTERNS", "finding_from_sentence", "findings_from_sentences"]

# (code, pattern matched at the start of an old flag sentence), in the order they were tried
LEGACY_PATTERNS: tuple[tuple[str, str], ...] = (
    ("calibration.no_shared_view", r"no board was seen by two cameras at once"),
    ("calibration.square_error", r"reconstructed board squares are off by"),
    ("calibration.corner_distances", r"distances between triangulated board corners are off by"),
    ("calibration.principal_point", r"the joint adjustment moved every camera's principal point"),
    ("calibration.guessed_depth_broken", r".*the run holds less than a stride without them"),
    ("calibration.guessed_depth", r"markers seen by two cameras only, one of them outside the region"),
    ("calibration.coverage", r"the .+ camera saw the markers outside the region the calibration board"),
    ("calibration.units_guessed", r".+ states no units; its "),
    ("video.variable_frame_rate", r"the .+ clip of the .+ camera has a variable frame rate"),
    ("sync.motion_uncertain", r"the .+ clip was synchronised from .+ motion \(no sync flash\), uncertain"),
    ("sync.motion", r"the .+ clip was synchronised from .+ motion \(no sync flash\)"),
    ("tracking.two_cameras_only", r"the .+ clip was triangulated from the .+ cameras only"),
    ("tracking.cameras_disagree", r"the cameras disagree on the .+ clip's markers"),
    ("tracking.lookalike_recovered", r"the moving spots each camera found were"),
    ("tracking.lookalike", r"the tracked markers are .+ off the static shot's marker distances"),
    ("tracking.dropped_samples", r".+ broke the markers' distances"),
    ("tracking.gaps_bridged", r".+ with a short marker gap bridged"),
    ("tracking.lost_all_along", r"markers lost from .+ \(one or another, all along\)"),
    ("tracking.not_in_view_at_start", r"markers not all in view before"),
    ("tracking.not_in_view_at_end", r"markers not all in view after"),
    ("tracking.lost", r"markers lost from"),
    ("markers.rigidity", r"the markers kept the static shot's layout only to"),
    ("rig.weak_depth", r"the rig fixes depth"),
    ("plumb.missing", r"no plumb clips?(:|$)"),
    ("plumb.leaning", r"plumb clip not used: the plumb line found leans"),
    ("plumb.not_used", r"plumb clip not used"),
    ("plumb.one_marker", r"only one plumb marker track was given"),
    ("gravity.tilted", r"gravity \(.+\) is .+ deg from perpendicular to the travel"),
    ("gravity.from_hint", r"no plumb line: gravity taken as"),
    ("gravity.from_camera", r"no plumb clip and no down hint"),
    ("gravity.lab_vertical", r"gravity along the lab's vertical"),
    ("indicators.too_uncertain", r"too uncertain for a decision"),
    ("fit.wild_samples", r".+: \d+ wild samples left out of its fits"),
    ("fit.fundamental_drift", r".+: the fitted fundamental \("),
    ("fit.short_crossing", r"the markers were tracked together for .+ the fits saw"),
    ("fit.no_fundamental", r"no fit determined the fundamental"),
    ("rotation.markers_in_line", r"the markers lie near a line"),
    ("rotation.weak_axis", r"rotation about the markers' weakest axis"),
    ("rotation.all_versions_excluded", r"all ω versions excluded in"),
    ("rotation.near_singularity", r"ω is nearly in the markers' plane"),
    ("rotation.versions_excluded", r".+ versions excluded near their singularity"),
    ("mocap.no_units", r"no Units in the header; assumed mm"),
    ("mocap.marker_names", r"the header declares .+ markers but line 4 names"),
    ("mocap.short_rows", r".+ rows stop before the last declared marker"),
    ("mocap.extra_cells", r".+ rows hold cells beyond the .+ declared markers"),
)
_COMPILED = tuple((code, re.compile(pattern, re.DOTALL)) for code, pattern in LEGACY_PATTERNS)


def finding_from_sentence(flag: str) -> Finding:
    """The finding an old flag sentence stands for (``other`` when no pattern matches); no values."""
    text = str(flag).strip()
    code = next((code for code, pattern in _COMPILED if pattern.match(text)), "other")
    return Finding(code, text)


def findings_from_sentences(flags: Iterable[object]) -> list[Finding]:
    """The findings of an old document's ``flags`` (blank entries skipped), in their order."""
    return [finding_from_sentence(str(f)) for f in flags if str(f).strip()]

"""Whether a ride's markers still fit its rig's calibration ("the cameras moved since the rig was calibrated").

A rig is calibrated once and reused for every ride filmed with it. When a camera is knocked or re-mounted
afterwards, the matched marker detections of a ride no longer meet at one point in space: the
triangulated markers reproject onto the images far worse than the calibration's own board corners did
(its reprojection check). That is what this module measures, so the failure that follows (commonly "no
periodic motion" or the cameras disagreeing) can be said as its cause, and fixed by calibrating again.
"""

from __future__ import annotations

import numpy as np

from saddlescope.core.findings import Finding
from saddlescope.core.types import MarkerTracks, Rig

__all__ = ["MOVED_FACTOR", "MOVED_MIN_PX", "cameras_moved_finding", "rig_reprojection_px"]

# A ride's markers are judged inconsistent with the rig when their median reprojection error exceeds
# MOVED_FACTOR times the rig's own check and MOVED_MIN_PX (marker centroids are blobs, a few pixels of
# error are normal for them even on a perfect rig).
MOVED_FACTOR = 10.0
MOVED_MIN_PX = 4.0
# Fewer triangulated samples than this say nothing either way.
_MIN_SAMPLES = 20


def rig_reprojection_px(rig: Rig) -> float | None:
    """The rig's own reprojection check in px: its triangulation check, else its cameras' worst RMS; None if unknown."""
    checked = rig.checks.get("triangulation_rms_px") if rig.checks else None
    if checked is not None and np.isfinite(checked) and checked > 0:
        return float(checked)
    per_camera = [c.rms_px for c in rig.cameras.values() if c.rms_px is not None and np.isfinite(c.rms_px)]
    return float(max(per_camera)) if per_camera else None


def cameras_moved_finding(rig: Rig, tracks: MarkerTracks, *, clip: str = "motion") -> Finding | None:
    """A ``calibration.cameras_moved`` finding when `tracks` reproject far worse than the rig's own check.

    Parameters
    ----------
    rig : Rig
        The calibration the ride was triangulated with.
    tracks : MarkerTracks
        The clip's triangulated markers with ``reprojection_error_px`` of shape (F, M).
    clip : str
        The clip's kind, for the sentence.

    Returns
    -------
    Finding or None
        None when the markers are consistent with the rig, or there is too little to judge.
    """
    if tracks.reprojection_error_px is None:
        return None
    err = np.asarray(tracks.reprojection_error_px, dtype=np.float64)
    err = err[np.isfinite(err)]
    if err.size < _MIN_SAMPLES:
        return None
    reference = rig_reprojection_px(rig)
    if reference is None:
        return None
    median = float(np.median(err))
    limit = max(MOVED_MIN_PX, MOVED_FACTOR * reference)
    if median <= limit:
        return None
    return Finding("calibration.cameras_moved",
                   f"the cameras moved since the rig was calibrated: the {clip} clip's markers reproject "
                   f"{median:.1f} px off (median) where the rig's own check is {reference:.2f} px",
                   {"median_px": median, "rig_check_px": reference, "limit_px": limit})

"""Marker detection (thesis 4.5): from grey video frames to 2-D marker tracks, one camera at a time.

The thesis's filter chain, with every choice the user used to make chosen automatically (and still
overridable): grey image, threshold (4.5.1), 8-connected labelling (4.5.2), area range (4.5.3), a
window that follows the markers' centre (4.5.4), vectors between markers that must match the last
frame within a tolerance (4.5.5, eq. 4.6-4.11, vectors rather than distances) and the sign of the cross
product for look-alikes (Fig. 4.13). A marker that is not found is a gap (NaN), never a guess.

- :mod:`.blobs`: thresholding, labelling and the candidate filters (:func:`detect_blobs`);
  :mod:`.refine`: intensity-weighted sub-pixel centroids over a local background (< 0.01 px on
  clean discs), each on its own patch of the whole image (a window's centroids equal the whole frame's).
- :mod:`.pattern`: the most plausible labelled marker set on one frame (:func:`initial_markers`).
- :mod:`.tracker` and :mod:`.tracking`: following the markers through a clip (:func:`track_markers`):
  constant-velocity prediction, a window around it, the best assignment of blobs to markers; flashes
  skipped; after a loss the search resumes and keeps the labels.
- :mod:`.detectors`: the marker detectors by name (the thesis's chain is ``"bright_discs"``) and the
  user's typed overrides of their choices (:class:`TrackOptions`), checked when given.
- :mod:`.search`: the horse markers, the plumb line or the standing horse's markers found with all
  calibrated cameras at once among look-alikes (:func:`find_markers_multiview`), to start the
  trackers from the right blobs.

Frames are grey uint8 (or uint16) arrays of shape (H, W), typically the Y plane of a decoded video
frame, possibly a strided view into the decoder's buffer.
"""

from saddlescope.core.detection.blobs import detect_blobs
from saddlescope.core.detection.detectors import (
    DetectionSettings,
    MarkerDetector,
    TrackOptions,
    detector_names,
    marker_detector,
    register_detector,
)
from saddlescope.core.detection.pattern import MarkerPattern, initial_markers
from saddlescope.core.detection.search import (
    SequentialFrames,
    bright_spots,
    camera_down,
    consistent_points,
    find_markers_multiview,
    find_plumb_multiview,
    find_static_multiview,
    in_image,
    plumb_candidates,
    static_marker_candidates,
    tilt_from_down_deg,
    triangle_candidates,
)
from saddlescope.core.detection.tracking import track_markers

__all__ = [
    "DetectionSettings",
    "MarkerDetector",
    "MarkerPattern",
    "TrackOptions",
    "detector_names",
    "marker_detector",
    "register_detector",
    "detect_blobs",
    "initial_markers",
    "track_markers",
    "bright_spots",
    "consistent_points",
    "triangle_candidates",
    "find_markers_multiview",
    "camera_down",
    "tilt_from_down_deg",
    "plumb_candidates",
    "static_marker_candidates",
    "find_plumb_multiview",
    "find_static_multiview",
    "in_image",
    "SequentialFrames",
]

"""Triangulation of marker image points into rig coordinates (thesis 5.1): the stage after detection.

Two methods:

- :func:`triangulate_thesis_pairs` (:mod:`.pairs`), the thesis's method: triangulate with each stereo
  pair (L-M, L-R, M-R) with ``cv2.triangulatePoints`` on undistorted points, move the pair results that
  live in another camera's frame into the left frame (eq. 5.3-5.4) and average them (eq. 5.5).
- :func:`triangulate_nview` (:mod:`.nview`), N-view least squares: a linear (DLT) solution on
  undistorted normalised points refined by Gauss-Newton on the reprojection error, with per-point
  reprojection error and rejection of a camera whose error is an outlier.

Image points are distorted pixels as detected, NaN where a camera did not see a marker; 3-D points are
in millimetres in rig coordinates (the left camera's frame, ``x_cam = R @ x_left + t_mm``).
:func:`triangulate_tracks` (:mod:`.tracks`) resamples each camera's 2-D tracks onto the left camera's
frame times with the sub-frame synchronisation offsets, matches the cameras' marker labels
(:mod:`.matching`), then triangulates them into ``MarkerTracks``. :func:`position_uncertainty`
(:mod:`.uncertainty`) tells how well a rig fixes a point; :mod:`.lens_reach` limits the lens model's
extrapolation beyond the image radius the calibration board reached. The camera model itself (projection,
distortion and its inverse) is :mod:`saddlescope.core.camera_model`.
"""

from saddlescope.core.triangulation.lens_reach import (
    board_reach_px,
    reach_by_camera,
    reach_radius,
    undistort_within_reach,
)
from saddlescope.core.triangulation.matching import match_markers_across_cameras
from saddlescope.core.triangulation.nview import triangulate_nview
from saddlescope.core.triangulation.pairs import triangulate_thesis_pairs
from saddlescope.core.triangulation.reprojection import reprojection_errors
from saddlescope.core.triangulation.tracks import ReachCheckedTracks, resample_tracks, triangulate_tracks
from saddlescope.core.triangulation.uncertainty import position_uncertainty

__all__ = [
    "board_reach_px",
    "reach_by_camera",
    "reach_radius",
    "undistort_within_reach",
    "reprojection_errors",
    "triangulate_nview",
    "triangulate_thesis_pairs",
    "match_markers_across_cameras",
    "ReachCheckedTracks",
    "resample_tracks",
    "triangulate_tracks",
    "position_uncertainty",
]

"""Board views: the corners of a calibration board found in one frame of one camera."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BoardView", "MIN_CORNERS", "MIN_POSE_CORNERS", "MIN_VIEWS"]

MIN_VIEWS = 6
MIN_CORNERS = 6  # a view that counts for a camera's lens (intrinsics) and a stereo pair
MIN_POSE_CORNERS = 4  # a partial view that counts for the board's pose in the joint adjustment


@dataclass(frozen=True)
class BoardView:
    """Board corners found in one frame of one camera.

    frame : int
        Frame index in the clip, or the common instant of a synchronised rig.
    corners_px : ndarray of shape (N, 2)
        Distorted pixel coordinates of the corners found.
    ids : ndarray of shape (N,)
        Index of each corner into the board's points (:func:`~saddlescope.core.calibration.boards.object_points_mm`).
    """

    frame: int
    corners_px: np.ndarray
    ids: np.ndarray

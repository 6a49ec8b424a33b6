"""The thesis's validation experiments (8.2-8.3), repeatable on any rig.

- Free fall (thesis 8.3): a ball thrown up and falling; a parabola fitted to its 3-D track gives the
  gravitational acceleration (:mod:`.gravity`), whose error against 9.81 m/s^2 measures the whole chain
  (calibration, synchronisation, detection, triangulation, differentiation). The thesis found
  9.5 m/s^2 (3.6 %). Finding the ball among look-alikes (:mod:`.spots`) and fitting its flight to
  every camera's pixels: :mod:`.freefall`.
- Board distances (thesis Fig. 8.6, Table 8.5): points A-D on a board held in several places; their
  triangulated distances against the board's geometry (thesis: 2.2-4.6 % error): :mod:`.board_distances`.
"""

from saddlescope.core.validation.board_distances import board_point_distances, grid_points_px
from saddlescope.core.validation.freefall import find_falling_ball, fit_flight, measure_free_fall
from saddlescope.core.validation.gravity import G_STANDARD_M_S2, gravity_from_freefall
from saddlescope.core.validation.spots import Spots, bright_spots, detect_spots, link_spots, moving_tracks

__all__ = [
    "G_STANDARD_M_S2",
    "gravity_from_freefall",
    "Spots",
    "bright_spots",
    "detect_spots",
    "link_spots",
    "moving_tracks",
    "find_falling_ball",
    "fit_flight",
    "measure_free_fall",
    "grid_points_px",
    "board_point_distances",
]

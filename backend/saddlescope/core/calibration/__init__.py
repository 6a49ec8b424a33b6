"""Camera calibration: board corners, intrinsics, stereo pairs, joint bundle adjustment, metric checks.

Thesis stages 3.4-3.6 and 8.2 (Bouguet's toolbox, done by hand there), automated:

1. :func:`find_board_corners` finds a checkerboard (``findChessboardCornersSB``, then the classic detector
   with ``cornerSubPix``) or a ChArUco board (normal, legacy or inverted print) in one grey frame.
   :func:`detect_board_views` runs it over frames; :func:`select_instants` keeps a well-spread subset.
2. :func:`calibrate_intrinsics` gives one camera's K and (k1, k2, p1, p2, k3) with standard deviations
   (``cv2.calibrateCameraExtended``), dropping outlier views.
3. :func:`stereo_extrinsics` gives the pose of one camera relative to another as the thesis did
   (``cv2.stereoCalibrate`` with fixed intrinsics; pairs L-M, L-R, M-R).
4. :func:`bundle_adjust` refines all cameras and all board poses jointly (robust loss, sparse Jacobian).
5. :func:`metric_checks` triangulates board corners seen by two or more cameras and compares square
   lengths and corner distances with the true board in millimetres (thesis Table 8.5).

:func:`calibrate_rig` runs 2-5 and returns a :class:`~saddlescope.core.types.Rig` whose first camera
is the reference (identity pose). Units: pixels in images, millimetres for board and poses.

Modules, in the order of the stages: ``views`` (BoardView), ``refinement`` (sub-pixel corners),
``boards`` (the board types: checkerboard, ChArUco, and their registry), ``detection`` (corner
finding), ``saddles`` and ``tracking`` (video), ``selection``, ``intrinsics``, ``stereo``,
``projection`` (vectorised projection model), ``bundle_adjustment``, ``checks`` (triangulation and
metric quality), ``rig`` (the whole rig) and ``simulation`` (synthetic views and rendered boards).
"""

from saddlescope.core.calibration.boards import make_board
from saddlescope.core.calibration.boards.checkerboard import canonical_checkerboard_order
from saddlescope.core.calibration.bundle_adjustment import bundle_adjust
from saddlescope.core.calibration.checks import board_distance_errors, metric_checks, triangulate_dlt
from saddlescope.core.calibration.detection import BoardFinder, find_board_corners, squares_hint
from saddlescope.core.calibration.intrinsics import calibrate_intrinsics
from saddlescope.core.calibration.rig import calibrate_rig, principal_point_common_shift
from saddlescope.core.calibration.selection import select_instants
from saddlescope.core.calibration.simulation import (
    board_texture,
    render_board,
    simulate_board_views,
    thesis_like_views,
)
from saddlescope.core.calibration.stereo import stereo_extrinsics
from saddlescope.core.calibration.tracking import BoardTracker, detect_board_views
from saddlescope.core.calibration.views import MIN_CORNERS, MIN_VIEWS, BoardView

__all__ = [
    "MIN_CORNERS",
    "MIN_VIEWS",
    "BoardFinder",
    "BoardTracker",
    "BoardView",
    "board_distance_errors",
    "board_texture",
    "bundle_adjust",
    "calibrate_intrinsics",
    "calibrate_rig",
    "canonical_checkerboard_order",
    "detect_board_views",
    "find_board_corners",
    "make_board",
    "metric_checks",
    "principal_point_common_shift",
    "render_board",
    "select_instants",
    "simulate_board_views",
    "squares_hint",
    "stereo_extrinsics",
    "thesis_like_views",
    "triangulate_dlt",
]

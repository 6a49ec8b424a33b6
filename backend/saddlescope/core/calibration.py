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
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.types import Board, Camera, Rig

MIN_VIEWS = 6
MIN_CORNERS = 6
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
_CALIB_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-9)
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)


@dataclass(frozen=True)
class BoardView:
    """Board corners found in one frame of one camera.

    frame : int
        Frame index in the clip, or the common instant of a synchronised rig.
    corners_px : ndarray of shape (N, 2)
        Distorted pixel coordinates of the corners found.
    ids : ndarray of shape (N,)
        Index of each corner into ``board.object_points_mm()``.
    """

    frame: int
    corners_px: np.ndarray
    ids: np.ndarray


# --------------------------------------------------------------------------------------------------
# Boards and corner detection
# --------------------------------------------------------------------------------------------------


def make_board(kind: str, inner_corners: tuple[int, int], square_mm: float, *,
               dictionary: str | None = None, marker_mm: float | None = None,
               legacy: bool = False) -> Board:
    """Validated :class:`Board`. For ChArUco, ``inner_corners`` is (squares_x - 1, squares_y - 1).

    ``marker_mm`` defaults to 0.75 of the square (caliscope's ``aruco_scale``); ``dictionary`` to
    ``DICT_4X4_50``.
    """
    if kind not in ("checkerboard", "charuco"):
        raise InputError(f"board kind {kind!r} is not 'checkerboard' or 'charuco'")
    cols, rows = (int(v) for v in inner_corners)
    if cols < 2 or rows < 2:
        raise InputError(f"board inner corners {cols}x{rows}: need at least 2x2")
    if not np.isfinite(square_mm) or square_mm <= 0:
        raise InputError(f"board square size {square_mm} mm must be positive")
    if kind == "checkerboard":
        return Board("checkerboard", (cols, rows), float(square_mm))
    dictionary = dictionary or "DICT_4X4_50"
    if not hasattr(cv2.aruco, dictionary):
        raise InputError(f"unknown ArUco dictionary {dictionary!r} (e.g. DICT_4X4_50, DICT_5X5_100)")
    marker_mm = 0.75 * square_mm if marker_mm is None else float(marker_mm)
    if not 0 < marker_mm < square_mm:
        raise InputError(f"ChArUco marker size {marker_mm} mm must be between 0 and the square "
                         f"({square_mm} mm)")
    return Board("charuco", (cols, rows), float(square_mm), dictionary=dictionary,
                 marker_mm=marker_mm, legacy=bool(legacy))


def _cv_charuco(board: Board):
    cols, rows = board.inner_corners
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, board.dictionary or "DICT_4X4_50"))
    cv_board = cv2.aruco.CharucoBoard((cols + 1, rows + 1), float(board.square_mm),
                                      float(board.marker_mm or 0.75 * board.square_mm), dictionary)
    cv_board.setLegacyPattern(bool(board.legacy))
    return cv_board


class BoardFinder:
    """Finds one board in grey frames; remembers a ChArUco board's print polarity once seen.

    Parameters
    ----------
    board : Board
    inverted : bool or None
        ChArUco printed white-on-black (caliscope's ``inverted = true``); None tries both.
    max_width : int
        Frames wider than this are searched downscaled first, then refined at full resolution.
    thorough : bool
        Also try ``findChessboardCornersSB``'s exhaustive mode and the full classic detector (about a
        second per frame without a board): right for a few still images; for video frames (many,
        mostly alike) False keeps a frame to tens of milliseconds.
    """

    def __init__(self, board: Board, *, inverted: bool | None = None, max_width: int = 1000,
                 thorough: bool = True):
        self.board = board
        self.inverted = inverted
        self.max_width = int(max_width)
        self.thorough = bool(thorough)
        self._upsample = 1.0
        self.refine_scale = 1.0  # of the last board found: the scale its corners were refined at
        self._last_box: tuple[int, int, int, int] | None = None
        if board.kind == "charuco":
            self._cv_board = _cv_charuco(board)
            self._detector = cv2.aruco.CharucoDetector(self._cv_board)

    def __call__(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Corners (N, 2) px and ids (N,) of the board in ``gray`` (H, W) uint8, or None."""
        gray = _as_gray(gray)
        if self._last_box is not None and self.board.kind == "checkerboard":
            # Video: the board is usually near where it was; search that region first (a fraction of
            # the frame's cost), then the whole frame.
            x0, y0, x1, y1 = self._last_box
            found = self._find_full(gray[y0:y1, x0:x1])
            if found is not None:
                corners = found[0] + np.array([x0, y0], dtype=np.float64)
                self._remember(corners, gray.shape)
                return corners, found[1]
        found = self._find_full(gray)
        if found is not None:
            self._remember(found[0], gray.shape)
        return found

    def _remember(self, corners: np.ndarray, shape) -> None:
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        pad = np.maximum(hi - lo, 40.0)
        x0, y0 = np.floor(np.maximum(lo - pad, 0)).astype(int)
        x1, y1 = np.ceil(np.minimum(hi + pad, [shape[1], shape[0]])).astype(int)
        self._last_box = (int(x0), int(y0), int(x1), int(y1))

    def _find_full(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        scale = 1.0
        small = gray
        if gray.shape[1] > 1.5 * self.max_width:
            scale = self.max_width / gray.shape[1]
            small = cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        found = self._find(small)
        if found is None:
            return None
        corners, ids = found
        self.refine_scale = self._upsample
        if scale != 1.0:
            corners = _refine_full_resolution(gray, _unscale(corners, scale), self.board, ids)
            self.refine_scale = 1.0
        return corners, ids

    def _find(self, gray):
        if self.board.kind == "checkerboard":
            # A board far away has squares of a few pixels, where the detectors fail at native size but
            # succeed on a 2x upsampled frame; remember which size worked, as frames of a clip are alike.
            scales = [self._upsample, 1.0 if self._upsample != 1.0 else 2.0] if gray.shape[1] <= self.max_width \
                else [1.0]
            for up in scales:
                big = gray if up == 1.0 else cv2.resize(gray, None, fx=up, fy=up, interpolation=cv2.INTER_CUBIC)
                found = _find_checkerboard(big, self.board, thorough=self.thorough and up == 1.0,
                                           upsampled=up != 1.0)
                if found is not None:
                    self._upsample = up
                    corners, ids = found
                    if up != 1.0:
                        corners = _unscale(corners, up)  # refined by cornerSubPix on the upsampled frame
                    return corners, ids
            return None
        polarities = [self.inverted] if self.inverted is not None else [False, True]
        for inverted in polarities:
            found = self._find_charuco(255 - gray if inverted else gray)
            if found is not None:
                self.inverted = inverted
                return found
        return None

    def _find_charuco(self, gray):
        corners, ids, _, _ = self._detector.detectBoard(gray)
        if ids is None or len(ids) < MIN_CORNERS:
            return None
        ids = ids.ravel().astype(np.int64)
        if self._cv_board.checkCharucoCornersCollinear(ids.reshape(-1, 1).astype(np.int32)):
            return None  # a line of corners says nothing about a plane's pose
        return corners.reshape(-1, 2).astype(np.float64), ids


def find_board_corners(gray: np.ndarray, board: Board, *,
                       inverted: bool | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """Board corners in one grey image.

    Parameters
    ----------
    gray : ndarray of shape (H, W), uint8 (a colour (H, W, 3) BGR image is converted)
    board : Board
    inverted : bool or None
        ChArUco print polarity; None tries normal then inverted.

    Returns
    -------
    (corners_px, ids) with shapes (N, 2) and (N,), or None if the board is not found. Checkerboard
    corners come in a canonical order (see :func:`canonical_checkerboard_order`), all of them.
    """
    return BoardFinder(board, inverted=inverted)(gray)


def _as_gray(img: np.ndarray) -> np.ndarray:
    img = np.asarray(img)
    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.ndim != 2:
        raise InputError(f"expected a grey image of shape (H, W), got shape {img.shape}")
    if img.dtype != np.uint8:
        img = cv2.normalize(img, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    return img


def _find_checkerboard(gray: np.ndarray, board: Board, *, thorough: bool = True, upsampled: bool = False):
    corners = _checkerboard_corners(gray, board, thorough=thorough)
    if corners is None:
        return None
    # cornerSubPix with a window scaled to the squares: on Bouguet's images it halves SB's residuals
    corners = _subpix(gray, corners, board, upsampled=upsampled)
    corners = canonical_checkerboard_order(gray, corners, board.inner_corners)
    return corners, np.arange(len(corners))


def _checkerboard_corners(gray: np.ndarray, board: Board, *, thorough: bool = True,
                          normalize: bool = True) -> np.ndarray | None:
    """A checkerboard's corners (N, 2) as the detectors give them (not refined, in their order), or None."""
    pattern = tuple(board.inner_corners)
    ok, corners = cv2.findChessboardCornersSB(gray, pattern, flags=cv2.CALIB_CB_NORMALIZE_IMAGE if normalize else 0)
    if not ok and thorough:
        ok, corners = cv2.findChessboardCornersSB(
            gray, pattern,
            flags=cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
    if not ok:
        # classic detector as a fallback (it finds fewer boards, Bouguet README); quick check on video
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        ok, corners = cv2.findChessboardCorners(gray, pattern,
                                                flags=flags if thorough else flags | cv2.CALIB_CB_FAST_CHECK)
        if not ok:
            return None
    return corners.reshape(-1, 2).astype(np.float64)


def _min_spacing_px(corners: np.ndarray, board: Board, ids: np.ndarray) -> float:
    cols, rows = board.inner_corners
    grid = np.full((cols * rows, 2), np.nan)
    grid[np.asarray(ids, dtype=np.int64)] = corners
    grid = grid.reshape(rows, cols, 2)
    d = np.concatenate([np.linalg.norm(np.diff(grid, axis=1), axis=2).ravel(),
                        np.linalg.norm(np.diff(grid, axis=0), axis=2).ravel()])
    d = d[np.isfinite(d)]
    return float(d.min()) if len(d) else 10.0


def _subpix(gray, corners, board, ids=None, *, upsampled=False):
    ids = np.arange(len(corners)) if ids is None else ids
    # On an upsampled frame a corner's blur spans more pixels: a window of 0.35 of the spacing (2-3 px for
    # squares of 4 px upsampled 2x) is too small, cornerSubPix then wanders and returns where it started
    # (synthetic thesis-rig ride: 0.26 px r.m.s. error against 0.16 px with 0.55).
    half = int(np.clip(round(_min_spacing_px(corners, board, ids) * (0.55 if upsampled else 0.35)), 2, 12))
    pts = corners.reshape(-1, 1, 2).astype(np.float32)
    cv2.cornerSubPix(gray, pts, (half, half), (-1, -1), _SUBPIX_CRITERIA)
    return pts.reshape(-1, 2).astype(np.float64)


def _refine_full_resolution(gray, corners, board, ids):
    return _subpix(gray, corners, board, ids)


def _unscale(xy: np.ndarray, scale: float) -> np.ndarray:
    """Pixel coordinates in a frame resized by ``scale`` (cv2.resize) back in the original frame.

    cv2.resize aligns pixel centres, so x / scale alone is off by (1 / scale - 1) / 2 px (0.25 px at 2x).
    """
    return (np.asarray(xy, np.float64) + 0.5) / scale - 0.5


def _rescale(xy: np.ndarray, scale: float) -> np.ndarray:
    """The inverse of :func:`_unscale`."""
    return (np.asarray(xy, np.float64) + 0.5) * scale - 0.5


def canonical_checkerboard_order(gray: np.ndarray, corners_px: np.ndarray,
                                 inner_corners: tuple[int, int]) -> np.ndarray:
    """Reorder detected checkerboard corners so that every camera labels them alike.

    OpenCV may return a board's corners starting from either end. For several cameras the labels must
    agree, so: (1) the grid is made right-handed in the image (the board's front faces the camera);
    (2) where the board has no 180-degree symmetry (cols + rows odd) the square between corners 0, 1,
    cols, cols+1 is made the dark one; otherwise corner 0 is the one nearer the image's top-left.
    Square boards (cols == rows) can still be labelled transposed between cameras.

    Parameters
    ----------
    gray : ndarray of shape (H, W)
    corners_px : ndarray of shape (cols*rows, 2), row-major
    inner_corners : (cols, rows)

    Returns
    -------
    ndarray of shape (cols*rows, 2)
    """
    cols, rows = inner_corners
    grid = np.asarray(corners_px, np.float64).reshape(rows, cols, 2)
    a = grid[0, 1] - grid[0, 0]
    b = grid[1, 0] - grid[0, 0]
    if a[0] * b[1] - a[1] * b[0] < 0:
        grid = grid[::-1]
    if (cols + rows) % 2 == 1:
        first = _patch_mean(gray, grid[:2, :2].reshape(-1, 2).mean(axis=0))
        nxt = grid[:2, 1:3] if cols >= 3 else grid[1:3, :2]
        second = _patch_mean(gray, nxt.reshape(-1, 2).mean(axis=0))
        if first > second:
            grid = grid[::-1, ::-1]
    elif grid[0, 0].sum() > grid[-1, -1].sum():
        grid = grid[::-1, ::-1]
    return np.ascontiguousarray(grid.reshape(-1, 2))


def _patch_mean(gray, xy, radius=2):
    h, w = gray.shape
    x, y = int(round(xy[0])), int(round(xy[1]))
    patch = gray[max(y - radius, 0): min(y + radius + 1, h), max(x - radius, 0): min(x + radius + 1, w)]
    return float(patch.mean()) if patch.size else 0.0


# Video: a board tracked from frame to frame, searched for only when lost

_TRACK_MAX_MOVE = 0.25  # of a corner's square spacing: moving further it may have slid onto the next one
_TRACK_MAX_FIT_GROWTH = 1.5  # r.m.s. distance of tracked corners from a board homography, over that when found
_MOVING_PX = 1.0  # board motion between frames above which a lost board is not searched for (still < 0.5 px)
_MIN_SQUARE_RATIO = 1.4  # of _square_checks: about 2 at a board's corner, at most 1 on its edge


@dataclass(frozen=True)
class _Track:
    corners: np.ndarray  # (N, 2) px in the frame
    scale: float  # the frame was resized by this before cornerSubPix (as when the board was found)
    sign: float  # of _square_checks' ratios: which squares are dark
    fit_rms: float  # px, r.m.s. distance of the corners from a board-to-image homography when found


class BoardTracker:
    """Checkerboard corners through the frames of a video: tracked from frame to frame, searched only when lost.

    A board found in one frame is followed into the next by ``cornerSubPix`` from its previous corners,
    on the frame resized as when it was found (tracked corners are as accurate as detected ones). They
    are kept only if every corner moved less than a quarter of its square, the squares round each corner
    still alternate as on the board (a board shifted by a whole square leaves corners on its edge, which
    the move test cannot see) and they fit a board-to-image homography about as well as when found.

    A lost board is looked for where strong saddle points (x-junctions) cluster, and only while that
    region, and the one where the board was last seen, are not moving (a moving board is blurred, and only
    boards held still are used): the board's grid is grown over the saddle points, else
    ``findChessboardCornersSB`` searches the region. The whole frame is searched every ``search_every``
    frames at most, so that boards the localizer misses are still found. A board found again is also
    tracked back into the frame before.

    Parameters
    ----------
    board : Board, a checkerboard
    max_width : int
        As :class:`BoardFinder`.
    search_every : int
        Frames between whole-frame searches while the board is lost (half a second of video suits).
    """

    def __init__(self, board: Board, *, max_width: int = 1000, search_every: int = 15):
        if board.kind != "checkerboard":
            raise InputError("BoardTracker follows checkerboards; ChArUco boards are found frame by frame")
        self.board = board
        self.max_width = int(max_width)
        self.search_every = max(1, int(search_every))
        self.finder = BoardFinder(board, max_width=max_width, thorough=False)
        self.ids = np.arange(board.inner_corners[0] * board.inner_corners[1])
        self._obj = board.object_points_mm()[:, :2].astype(np.float64)
        self.counts = {"tracked": 0, "tracked_back": 0, "found_from_saddles": 0, "found_near_saddles": 0,
                       "found_whole_frame": 0,
                       "skipped_moving": 0, "skipped_unchanged": 0, "whole_frame_searches": 0}
        self._failed: list[tuple[int, int, int, int]] = []  # boxes searched in vain in the frame before

    def views(self, frames: Iterable[tuple[int, np.ndarray]]) -> Iterable[BoardView]:
        """Board views of ``(frame index, grey image)`` pairs, in frame order (a generator)."""
        track: _Track | None = None
        prev: tuple[int, np.ndarray] | None = None  # the frame before, copied (decoders reuse buffers)
        last_box: tuple[slice, slice] | None = None  # round the board when last seen
        lost_for = 0  # frames since the board was last seen
        since_search = self.search_every  # frames since the board was seen or the whole frame searched
        for index, gray in frames:
            gray = _as_gray(gray)
            found = self._follow(gray, track) if track is not None else None
            if found is not None:
                self.counts["tracked"] += 1
            elif (prev is not None and last_box is not None and lost_for < self.search_every
                  and _motion_px(prev[1][last_box], gray[last_box]) > _MOVING_PX):
                self.counts["skipped_moving"] += 1  # the board is being moved away: wait until it is still
            else:
                found, near_moving = self._search_near_saddles(gray, None if prev is None else prev[1])
                if found is None and not near_moving and since_search >= self.search_every:
                    found = self._search_whole(gray)
                    since_search = 0
                if found is not None and prev is not None and lost_for > 0:
                    back = self._follow(prev[1], found)  # the frame before may show it still too
                    if back is not None:
                        self.counts["tracked_back"] += 1
                        yield BoardView(prev[0], back.corners, self.ids.copy())
            if found is not None:
                since_search = lost_for = 0
                last_box = _box_round(found.corners, gray.shape)
                yield BoardView(int(index), found.corners, self.ids.copy())
            else:
                since_search += 1
                lost_for += 1
            track = found
            prev = (int(index), gray.copy())

    def _state(self, gray: np.ndarray, corners: np.ndarray, scale: float) -> _Track:
        ratio, _ = _square_checks(gray, corners, self.board.inner_corners)
        return _Track(corners, float(scale), 1.0 if np.median(ratio) >= 0 else -1.0,
                      _homography_rms(self._obj, corners))

    def _follow(self, gray: np.ndarray, track: _Track) -> _Track | None:
        """The tracked board in ``gray``, or None if it is lost."""
        corners, up = track.corners, track.scale
        local = _local_spacing_px(corners, self.board.inner_corners)
        h, w = gray.shape
        pad = local.max() + 4.0  # the cornerSubPix window plus the largest accepted move
        x0, y0 = np.maximum(np.floor(corners.min(axis=0) - pad), 0).astype(int)
        x1, y1 = np.minimum(np.ceil(corners.max(axis=0) + pad), [w, h]).astype(int)
        crop = gray[y0:y1, x0:x1]
        img = crop if up == 1.0 else cv2.resize(crop, None, fx=up, fy=up, interpolation=cv2.INTER_CUBIC)
        refined = _subpix(img, _rescale(corners - [x0, y0], up), self.board, upsampled=up != 1.0)
        new = _unscale(refined, up) + [x0, y0]
        if np.any(np.linalg.norm(new - corners, axis=1) >= _TRACK_MAX_MOVE * local):
            return None
        ratio, span = _square_checks(gray, new, self.board.inner_corners)
        if np.any(ratio * track.sign < _MIN_SQUARE_RATIO) or np.any(span < 0.25 * np.median(span)):
            return None
        # the board fits a homography about as well as when it was found (lens distortion bends it a little)
        if _homography_rms(self._obj, new) > _TRACK_MAX_FIT_GROWTH * track.fit_rms + 0.05 * np.median(local):
            return None
        return _Track(new, up, track.sign, track.fit_rms)

    def _search_near_saddles(self, gray: np.ndarray, prev: np.ndarray | None) -> tuple[_Track | None, bool]:
        """The board searched for where saddle points cluster; also whether such a region was moving."""
        h, w = gray.shape
        scale = self.max_width / w if w > 1.5 * self.max_width else 1.0
        small = gray if scale == 1.0 else cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        moving = False
        failed, self._failed = self._failed, []
        for cluster in _saddle_clusters(small, len(self.ids))[:2]:
            x0, y0 = np.maximum(np.floor(_unscale(cluster.box[:2], scale)), 0).astype(int)
            x1, y1 = np.minimum(np.ceil(_unscale(cluster.box[2:], scale)), [w, h]).astype(int)
            crop = gray[y0:y1, x0:x1]
            motion = np.inf if prev is None else _motion_px(prev[y0:y1, x0:x1], crop)
            if np.isfinite(motion) and motion > _MOVING_PX:
                moving = True
                self.counts["skipped_moving"] += 1
                continue
            box = (x0, y0, x1, y1)
            if motion < 0.3 and any(_overlap(box, f) > 0.7 for f in failed):
                # the picture the search failed on in the frame before, unchanged: it would fail again
                self._failed.append(box)
                self.counts["skipped_unchanged"] += 1
                continue
            spacing = cluster.spacing / scale
            for grid in _grids_from_saddles(cluster, self.board.inner_corners):
                grid = _unscale(grid, scale)
                if self._looks_like_board(gray, grid):
                    refine = 2.0 if spacing < 6 else 1.0
                    corners = self._refined(crop, grid - [x0, y0], refine) + [x0, y0]
                    if self._looks_like_board(gray, corners):
                        self.counts["found_from_saddles"] += 1
                        return self._state(gray, corners, refine), False
                    break
            if max(x1 - x0, y1 - y0) > 3 * (max(self.board.inner_corners) + 5) * spacing:
                continue  # far larger than a board of such squares: a textured background, not worth SB
            found = self._find_in(crop, spacing)
            if found is not None:
                self.counts["found_near_saddles"] += 1
                return self._state(gray, found[0] + [x0, y0], found[1]), False
            self._failed.append(box)
        return None, moving

    def _refined(self, crop: np.ndarray, corners: np.ndarray, scale: float) -> np.ndarray:
        """Grid corners in a crop put in canonical order and refined on the crop resized by ``scale``."""
        img = crop if scale == 1.0 else cv2.resize(crop, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)
        big = canonical_checkerboard_order(img, _rescale(corners, scale), self.board.inner_corners)
        return _unscale(_subpix(img, big, self.board, upsampled=scale != 1.0), scale)

    def _looks_like_board(self, gray: np.ndarray, corners: np.ndarray) -> bool:
        """Every corner an x-junction of squares alternating as on the board (none on its edge), and all of
        them on a plane's perspective image."""
        ratio, span = _square_checks(gray, corners, self.board.inner_corners)
        ratio = ratio * np.sign(np.median(ratio))
        if np.any(ratio < _MIN_SQUARE_RATIO) or np.any(span < 0.25 * np.median(span)):
            return False
        local = _local_spacing_px(corners, self.board.inner_corners)
        return _homography_rms(self._obj, corners) < 0.2 * float(np.median(local))

    def _find_in(self, crop: np.ndarray, spacing: float) -> tuple[np.ndarray, float] | None:
        """Board corners in a crop whose squares are about ``spacing`` px, and the scale they were refined at.

        ``findChessboardCornersSB`` fails on squares of a few pixels, costing more than it takes to find a
        board, and also now and then on an upsampled crop: so search the crop upsampled 3x when the squares
        are small, else as it is, then the other way. Corners are refined as :class:`BoardFinder` does
        (on the crop upsampled 2x if it had to be upsampled, else as it is).
        """
        if crop.shape[1] > 1.5 * self.max_width:  # a big board: searched downscaled, refined as it is
            found = self.finder._find_full(crop)
            return None if found is None else (found[0], self.finder.refine_scale)
        scales = (3.0, 2.0) if spacing < 6 else (1.0, 3.0) if spacing < 12 else (1.0, 2.0)
        for up in scales:
            img = crop if up == 1.0 else cv2.resize(crop, None, fx=up, fy=up, interpolation=cv2.INTER_CUBIC)
            # a crop round the board needs no histogram equalisation (without it SB is faster, as reliable)
            corners = _checkerboard_corners(img, self.board, thorough=False, normalize=False)
            if corners is None:
                continue
            refine = 1.0 if up == 1.0 else 2.0
            return self._refined(crop, _unscale(corners, up), refine), refine
        return None

    def _search_whole(self, gray: np.ndarray) -> _Track | None:
        self.counts["whole_frame_searches"] += 1
        found = self.finder._find_full(gray)
        if found is None:
            return None
        self.counts["found_whole_frame"] += 1
        return self._state(gray, found[0], self.finder.refine_scale)


def _homography_rms(obj_xy: np.ndarray, img_xy: np.ndarray) -> float:
    """R.m.s. distance (px) of ``img_xy`` from the least-squares homography of board (x, y) to them."""
    H, _ = cv2.findHomography(obj_xy, img_xy, 0)
    if H is None:
        return np.inf
    fit = cv2.perspectiveTransform(obj_xy.reshape(-1, 1, 2), H).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum((img_xy - fit) ** 2, axis=1))))


def _local_spacing_px(corners: np.ndarray, inner_corners: tuple[int, int]) -> np.ndarray:
    """Per corner of a full grid, the distance (px) to its nearest neighbour along the grid."""
    cols, rows = inner_corners
    g = corners.reshape(rows, cols, 2)
    d = np.full((rows, cols), np.inf)
    dx = np.linalg.norm(np.diff(g, axis=1), axis=2)
    dy = np.linalg.norm(np.diff(g, axis=0), axis=2)
    d[:, :-1] = np.minimum(d[:, :-1], dx)
    d[:, 1:] = np.minimum(d[:, 1:], dx)
    d[:-1] = np.minimum(d[:-1], dy)
    d[1:] = np.minimum(d[1:], dy)
    return d.ravel()


def _square_checks(gray: np.ndarray, corners: np.ndarray, inner_corners: tuple[int, int]) -> tuple[np.ndarray,
                                                                                                   np.ndarray]:
    """Per corner, from the grey levels at the centres of the four squares round it: (one diagonal's sum
    minus the other's) / (their range), sign alternating along the grid, and that range.

    About +-2 everywhere on a board (the sign says which squares are dark); at most 1 where a corner
    lies on the board's edge (two of its "squares" are the margin), as after a shift by a whole square.
    """
    cols, rows = inner_corners
    g = corners.reshape(rows, cols, 2)
    ext = np.empty((rows + 2, cols + 2, 2))
    ext[1:-1, 1:-1] = g
    ext[1:-1, 0], ext[1:-1, -1] = 2 * g[:, 0] - g[:, 1], 2 * g[:, -1] - g[:, -2]
    ext[0], ext[-1] = 2 * ext[1] - ext[2], 2 * ext[-2] - ext[-3]
    centre = 0.25 * (ext[:-1, :-1] + ext[1:, :-1] + ext[:-1, 1:] + ext[1:, 1:])  # (rows + 1, cols + 1, 2)
    v = cv2.remap(gray, centre[..., 0].astype(np.float32), centre[..., 1].astype(np.float32), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
    four = np.stack([v[:-1, :-1], v[1:, 1:], v[:-1, 1:], v[1:, :-1]])
    span = four.max(axis=0) - four.min(axis=0)
    alt = np.where(np.add.outer(np.arange(rows), np.arange(cols)) % 2 == 0, 1.0, -1.0)
    ratio = alt * (four[0] + four[1] - four[2] - four[3]) / np.maximum(span, 1e-6)
    return ratio.ravel(), span.ravel()


@dataclass(frozen=True)
class _Cluster:
    box: np.ndarray  # (x0, y0, x1, y1) px round the points, with room for the board's outer squares
    spacing: float  # px, typical distance between neighbouring points
    points: np.ndarray  # (M, 2) px, the saddle points
    theta: np.ndarray  # (M,) rad, direction of each point's positive curvature (it turns 90 degrees from
    # a board's corner to the next along the grid, as the dark squares swap diagonals)


def _saddle_clusters(gray: np.ndarray, n_corners: int) -> list[_Cluster]:
    """Dense clusters of strong saddle points (minus the Hessian determinant: checkerboard corners) that
    may hold a board of ``n_corners`` corners, the largest first."""
    g = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), 1.0)
    xx = cv2.Sobel(g, cv2.CV_32F, 2, 0, ksize=3)
    yy = cv2.Sobel(g, cv2.CV_32F, 0, 2, ksize=3)
    xy = cv2.Sobel(g, cv2.CV_32F, 1, 1, ksize=3)
    s = np.maximum(xy * xy - xx * yy, 0.0)
    k = max(n_corners // 2, 2)
    # the board's corners are the strongest saddles of the frame: keep those within 5x of its middle one
    s[[0, -1], :] = 0
    s[:, [0, -1]] = 0
    peaks = (s >= cv2.dilate(s, np.ones((3, 3), np.uint8))) & (s > 0)
    values = s[peaks]
    if len(values) < k:
        return []
    ys, xs = np.nonzero(peaks & (s > 0.2 * np.partition(values, -k)[-k]))
    if len(xs) < k:
        return []
    # sub-pixel peaks (a parabola through three samples each way)
    c, l, r, u, d = s[ys, xs], s[ys, xs - 1], s[ys, xs + 1], s[ys - 1, xs], s[ys + 1, xs]
    dx = 0.5 * (l - r) / np.minimum(l + r - 2 * c, -1e-12)
    dy = 0.5 * (u - d) / np.minimum(u + d - 2 * c, -1e-12)
    pts = np.column_stack([xs + np.clip(dx, -0.5, 0.5), ys + np.clip(dy, -0.5, 0.5)]).astype(np.float64)
    theta = 0.5 * np.arctan2(2 * xy[ys, xs], xx[ys, xs] - yy[ys, xs]).astype(np.float64)
    tree = cKDTree(pts)
    nearest = tree.query(pts, k=2)[0][:, 1]
    pairs = tree.query_pairs(2.0 * float(np.median(nearest)), output_type="ndarray")
    graph = csr_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts)))
    _, label = connected_components(graph, directed=False)
    clusters = []
    for lab, count in zip(*np.unique(label, return_counts=True), strict=True):
        if count >= k:
            member = label == lab
            p = pts[member]
            spacing = float(np.median(nearest[member]))
            pad = 2.5 * spacing  # the outer squares and a margin round the inner corners
            clusters.append(_Cluster(np.concatenate([p.min(axis=0) - pad, p.max(axis=0) + pad]), spacing, p,
                                     theta[member]))
    return sorted(clusters, key=lambda cl: -len(cl.points))


def _grids_from_saddles(cluster: _Cluster, inner_corners: tuple[int, int]) -> list[np.ndarray]:
    """Candidate board corners (rows * cols, 2), row-major, from a lattice grown over a cluster's saddle
    points from the one nearest its middle: every full cols x rows window of it (the lattice also takes
    in the corners of the board's outer squares, and perhaps points beyond). The caller checks them.

    Neighbours along the grid are about a step away, where the step (which perspective changes slowly)
    predicts them, and of the other polarity.
    """
    cols, rows = inner_corners
    pts, theta = cluster.points, cluster.theta
    if len(pts) < cols * rows:
        return []
    # a lattice point's four neighbours along the grid are among its eight nearest points
    _, nearest = cKDTree(pts).query(pts, k=min(9, len(pts)))
    xy, th, near8 = pts.tolist(), theta.tolist(), nearest[:, 1:].tolist()

    def across(i: int, j: int) -> bool:  # neighbours along the grid: positive curvature turned 90 degrees
        return math.cos(2 * (th[i] - th[j])) < 0

    seed = int(np.argmin(np.sum((pts - pts.mean(axis=0)) ** 2, axis=1)))
    near = [j for j in near8[seed] if across(seed, j)
            and math.dist(xy[seed], xy[j]) < 1.8 * cluster.spacing]
    if len(near) < 2:
        return []
    u = pts[near[0]] - pts[seed]
    v = max((pts[j] - pts[seed] for j in near[1:]),
            key=lambda w: abs(u[0] * w[1] - u[1] * w[0]) / np.linalg.norm(w))
    if abs(u[0] * v[1] - u[1] * v[0]) < 0.5 * np.linalg.norm(u) * np.linalg.norm(v):
        return []  # no second direction
    node = {(0, 0): seed}
    steps = {(0, 0): (tuple(u), tuple(v))}
    taken = {seed}
    todo = [(0, 0)]
    while todo:
        i, j = todo.pop()
        (ux, uy), (vx, vy) = steps[(i, j)]
        here = node[(i, j)]
        hx, hy = xy[here]
        for di, dj, sx, sy in ((1, 0, ux, uy), (-1, 0, -ux, -uy), (0, 1, vx, vy), (0, -1, -vx, -vy)):
            key = (i + di, j + dj)
            if key in node:
                continue
            px, py = hx + sx, hy + sy
            k = min(near8[here], key=lambda m: (xy[m][0] - px) ** 2 + (xy[m][1] - py) ** 2)
            if math.dist(xy[k], (px, py)) > 0.3 * math.hypot(sx, sy) or not across(here, k):
                continue
            if k in taken:
                return []  # one point on two grid places: not a lattice
            node[key] = k
            taken.add(k)
            fx, fy = xy[k][0] - hx, xy[k][1] - hy
            steps[key] = ((di * fx, di * fy), (vx, vy)) if di else ((ux, uy), (dj * fx, dj * fy))
            todo.append(key)
        if len(node) > (cols + 4) * (rows + 4):
            return []
    ij = np.array(list(node))
    lo = ij.min(axis=0)
    ni, nj = ij.max(axis=0) - lo + 1
    have = np.zeros((ni, nj), bool)
    where = np.zeros((ni, nj, 2))
    have[ij[:, 0] - lo[0], ij[:, 1] - lo[1]] = True
    where[ij[:, 0] - lo[0], ij[:, 1] - lo[1]] = pts[list(node.values())]
    grids = []
    for a, b in {(cols, rows), (rows, cols)}:  # the board's columns along the lattice's first axis or second
        for oi, oj in itertools.product(range(ni - a + 1), range(nj - b + 1)):
            if have[oi:oi + a, oj:oj + b].all():
                win = where[oi:oi + a, oj:oj + b]
                grids.append((win.transpose(1, 0, 2) if a == cols else win).reshape(-1, 2))
    return grids


def _box_round(corners: np.ndarray, shape: tuple[int, int]) -> tuple[slice, slice]:
    """Slices of the image round a board's corners, with a margin of half the board's size."""
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    pad = 0.5 * (hi - lo)
    x0, y0 = np.maximum(np.floor(lo - pad), 0).astype(int)
    x1, y1 = np.minimum(np.ceil(hi + pad), [shape[1], shape[0]]).astype(int)
    return slice(y0, y1), slice(x0, x1)


def _overlap(a, b) -> float:
    """Intersection over union of two boxes (x0, y0, x1, y1)."""
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    if w <= 0 or h <= 0:
        return 0.0
    inter = w * h
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)


def _motion_px(before: np.ndarray, after: np.ndarray) -> float:
    """Rough motion (px) of the picture between two crops: grey-level change over the mean gradient along a
    random direction (a shift by d changes a pixel by about d times that gradient)."""
    a = cv2.GaussianBlur(before.astype(np.float32), (0, 0), 1.0)
    b = cv2.GaussianBlur(after.astype(np.float32), (0, 0), 1.0)
    gx = cv2.Sobel(b, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(b, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    # E|grad . u| over random unit u is half of E(|gx| + |gy|) for isotropic gradients
    return float(np.mean(np.abs(b - a)) / (0.5 * np.mean(np.abs(gx) + np.abs(gy)) + 1e-6))


def detect_board_views(frames: Iterable[tuple[int, np.ndarray]], board: Board, *,
                       inverted: bool | None = None, max_width: int = 1000,
                       thorough: bool = False, track: bool = True,
                       search_every: int = 15) -> tuple[list[BoardView], tuple[int, int] | None]:
    """Board views in frames.

    Parameters
    ----------
    frames : iterable of (frame index, grey image of shape (H, W))
    board : Board
    track : bool
        Frames are consecutive frames of a video (or every ``step``-th): a checkerboard is tracked from
        frame to frame (:class:`BoardTracker`) instead of searched for in each frame. Not with ``thorough``.
    search_every : int
        While a tracked board is lost, frames between whole-frame searches (about half a second of video).

    Returns
    -------
    views : list of BoardView, in frame order
    image_size : (width, height) of the frames, or None when there were no frames

    Raises
    ------
    InputError
        If the frames do not all have the same size.
    """
    size = None

    def checked():
        nonlocal size
        for index, gray in frames:
            this = (int(gray.shape[1]), int(gray.shape[0]))
            if size is None:
                size = this
            elif this != size:
                raise InputError(f"frame {index} is {this[0]}x{this[1]} px, "
                                 f"earlier frames {size[0]}x{size[1]} px")
            yield index, gray

    if track and not thorough and board.kind == "checkerboard":
        tracker = BoardTracker(board, max_width=max_width, search_every=search_every)
        return list(tracker.views(checked())), size
    finder = BoardFinder(board, inverted=inverted, max_width=max_width, thorough=thorough)
    views: list[BoardView] = []
    for index, gray in checked():
        found = finder(gray)
        if found is not None:
            views.append(BoardView(int(index), found[0], found[1]))
    return views, size


# --------------------------------------------------------------------------------------------------
# View selection
# --------------------------------------------------------------------------------------------------


def _guess_normal(view: BoardView, board: Board, image_size) -> np.ndarray:
    """Board normal in the camera from a PnP with a guessed K (f = image width): for pose diversity."""
    w, h = image_size
    K = np.array([[w, 0, w / 2], [0, w, h / 2], [0, 0, 1.0]])
    obj = board.object_points_mm()[view.ids]
    ok, rvec, _ = cv2.solvePnP(obj, view.corners_px, K, None, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return np.array([0.0, 0.0, 1.0])
    return cv2.Rodrigues(rvec)[0][:, 2]


def _coverage_cells(view: BoardView, image_size, grid) -> set[int]:
    w, h = image_size
    gw, gh = grid
    mask = np.zeros((gh, gw), np.uint8)
    pts = view.corners_px * [gw / w, gh / h]
    hull = cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2)
    cv2.fillConvexPoly(mask, np.round(hull * 16).astype(np.int32), 1, shift=4)
    cells = set(np.flatnonzero(mask).tolist())
    cells.update((np.clip(pts[:, 1].astype(int), 0, gh - 1) * gw
                  + np.clip(pts[:, 0].astype(int), 0, gw - 1)).tolist())
    return cells


def select_instants(views_by_camera: Mapping[str, list[BoardView]], board: Board,
                    image_sizes: Mapping[str, tuple[int, int]], *, max_instants: int = 60,
                    grid: tuple[int, int] = (8, 6), diversity_weight: float = 0.5) -> list[int]:
    """Choose up to ``max_instants`` frames that spread the board over every camera's image and poses.

    Greedy: each step takes the instant adding the most not-yet-covered image cells (per camera, on a
    ``grid`` of cells), plus ``diversity_weight`` times its board tilt's angular distance (capped at
    30 degrees) to the already chosen views of the same camera, summed over the cameras that see it.

    Returns
    -------
    list of int, the chosen instants (frame keys), sorted.
    """
    cells: dict[int, dict[str, set[int]]] = {}
    normals: dict[int, dict[str, np.ndarray]] = {}
    for cam, views in views_by_camera.items():
        for v in views:
            cells.setdefault(v.frame, {})[cam] = _coverage_cells(v, image_sizes[cam], grid)
            normals.setdefault(v.frame, {})[cam] = _guess_normal(v, board, image_sizes[cam])
    candidates = sorted(cells)
    if len(candidates) <= max_instants:
        return candidates
    n_cells = grid[0] * grid[1]
    covered = {cam: set() for cam in views_by_camera}
    # per instant and camera: the largest |cos| of the angle to the normals chosen so far (None: none yet),
    # kept up to date as instants are chosen rather than recomputed for every candidate at every step
    max_cos: dict[int, dict[str, float | None]] = {inst: dict.fromkeys(cells[inst]) for inst in candidates}
    chosen: list[int] = []
    remaining = set(candidates)
    while remaining and len(chosen) < max_instants:
        best, best_score = None, -1.0
        for inst in sorted(remaining):
            score = 0.0
            for cam, c in cells[inst].items():
                score += len(c - covered[cam]) / n_cells
                cos = max_cos[inst][cam]
                ang = 30.0 if cos is None else math.degrees(math.acos(min(cos, 1.0)))
                score += diversity_weight * min(ang, 30.0) / 30.0
            if score > best_score:
                best, best_score = inst, score
        chosen.append(best)
        remaining.discard(best)
        for cam, c in cells[best].items():
            covered[cam] |= c
            n_best = normals[best][cam]
            for inst in remaining:
                if cam in max_cos[inst]:
                    cos = abs(float(normals[inst][cam] @ n_best))
                    old = max_cos[inst][cam]
                    max_cos[inst][cam] = cos if old is None else max(old, cos)
    return sorted(chosen)


# --------------------------------------------------------------------------------------------------
# Intrinsics
# --------------------------------------------------------------------------------------------------


def _check_views(views: list[BoardView], board: Board, camera: str, clip: str | None, *,
                 min_views: int) -> list[BoardView]:
    where = f"{clip} clip of the {camera} camera" if clip else f"camera {camera}"
    n_points = len(board.object_points_mm())
    good = []
    for v in views:
        corners = np.asarray(v.corners_px, np.float64)
        ids = np.asarray(v.ids, np.int64)
        if corners.ndim != 2 or corners.shape[1] != 2 or len(ids) != len(corners):
            raise InputError(f"{where}, frame {v.frame}: corners must have shape (N, 2) and ids (N,), "
                             f"got {corners.shape} and {ids.shape}")
        if ids.size and (ids.min() < 0 or ids.max() >= n_points):
            raise InputError(f"{where}, frame {v.frame}: corner ids outside the board's 0..{n_points - 1}")
        if len(ids) >= MIN_CORNERS and np.all(np.isfinite(corners)):
            good.append(BoardView(int(v.frame), corners, ids))
    if not good:
        raise CalibrationError(f"no calibration board found in the {where}")
    if len(good) < min_views:
        raise CalibrationError(f"calibration board found in only {len(good)} frame(s) of the {where}; "
                               f"need at least {min_views} views")
    return good


def _calib_flags(fix_k3: bool) -> int:
    return cv2.CALIB_FIX_K3 if fix_k3 else 0


def calibrate_intrinsics(views: list[BoardView], board: Board, image_size: tuple[int, int], *,
                         camera: str = "camera", clip: str | None = None, fix_k3: bool = True,
                         min_views: int = MIN_VIEWS, outlier_factor: float = 3.0,
                         min_outlier_px: float = 0.5, max_rounds: int = 3,
                         guess: Camera | None = None) -> tuple[Camera, dict]:
    """Intrinsics of one camera from board views (Zhang / Bouguet; thesis 3.4, Tables 8.1-8.3).

    Parameters
    ----------
    views : list of BoardView
    board : Board
    image_size : (width, height) px
    camera, clip : str
        Names used in error messages.
    fix_k3 : bool
        Keep k3 = 0 (narrow lenses: k3 is poorly determined and trades off against k1, k2).
    outlier_factor, min_outlier_px : float
        A view whose RMS error exceeds ``max(outlier_factor * median, min_outlier_px)`` is dropped and
        the calibration repeated (at most ``max_rounds`` times).
    guess : Camera, optional
        Start from these intrinsics instead of OpenCV's distortion-free initial estimate.

    Returns
    -------
    camera : Camera
        At identity pose, with ``K_std``, ``dist_std`` (one standard deviation) and ``rms_px``.
    report : dict
        ``rms_px``, ``residual_std_px`` (x, y), ``per_view_rms_px`` {frame: px}, ``dropped_frames``,
        ``n_views``, ``n_points``, ``fix_k3``, ``poses`` {frame: (rvec (3,), tvec_mm (3,))}.

    Raises
    ------
    CalibrationError
        No board, fewer than ``min_views`` views, or OpenCV failing to converge.
    """
    views = _check_views(views, board, camera, clip, min_views=min_views)
    obj_all = board.object_points_mm().astype(np.float32)
    dropped: list[int] = []
    w, h = (int(v) for v in image_size)
    start = (None, None) if guess is None else (np.array(guess.K, np.float64),
                                                np.array(guess.dist, np.float64).ravel()[:5].copy())
    flags = _calib_flags(fix_k3) | (0 if guess is None else cv2.CALIB_USE_INTRINSIC_GUESS)
    for round_ in range(max_rounds + 1):
        obj = [obj_all[v.ids] for v in views]
        img = [v.corners_px.astype(np.float32).reshape(-1, 1, 2) for v in views]
        try:
            rms, K, dist, rvecs, tvecs, std_intr, _, per_view = cv2.calibrateCameraExtended(
                obj, img, (w, h), *start, flags=flags, criteria=_CALIB_CRITERIA)
        except cv2.error as exc:
            raise CalibrationError(f"calibration of camera {camera} failed in OpenCV: "
                                   f"{str(exc).strip().splitlines()[-1]}") from None
        per_view = per_view.ravel()
        limit = max(outlier_factor * float(np.median(per_view)), min_outlier_px)
        bad = per_view > limit
        if not bad.any() or len(views) - bad.sum() < min_views or round_ == max_rounds:
            break  # (views are dropped only where a round follows to fit without them)
        dropped += [v.frame for v, b in zip(views, bad, strict=True) if b]
        views = [v for v, b in zip(views, bad, strict=True) if not b]
    residuals = []
    for v, rv, tv in zip(views, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(obj_all[v.ids], rv, tv, K, dist)
        residuals.append(proj.reshape(-1, 2) - v.corners_px)
    res = np.concatenate(residuals)
    std_intr = std_intr.ravel()
    dist = dist.ravel()[:5]
    cam = Camera(camera, K, np.pad(dist, (0, 5 - len(dist))), (w, h), rms_px=float(rms),
                 K_std=np.array([[std_intr[0], 0, std_intr[2]], [0, std_intr[1], std_intr[3]], [0, 0, 0]]),
                 dist_std=std_intr[4:9].copy())
    report = {
        "rms_px": float(rms),
        "residual_std_px": res.std(axis=0).tolist(),
        "per_view_rms_px": {int(v.frame): float(e) for v, e in zip(views, per_view, strict=True)},
        "dropped_frames": sorted(dropped),
        "n_views": len(views),
        "n_points": int(len(res)),
        "fix_k3": bool(fix_k3),
        "poses": {int(v.frame): (np.asarray(rv, np.float64).ravel(), np.asarray(tv, np.float64).ravel())
                  for v, rv, tv in zip(views, rvecs, tvecs, strict=True)},
    }
    return cam, report


# --------------------------------------------------------------------------------------------------
# Stereo pairs (thesis 3.5: L-M, L-R, M-R)
# --------------------------------------------------------------------------------------------------


def _choose_k3(cam: Camera, report: dict, views: list[BoardView], board: Board, image_size, *,
               camera: str, clip: str | None, min_views: int) -> tuple[Camera, dict]:
    """Keep k3 = 0 unless the views call for it: the free k3 must lower the Bayesian information
    criterion of the reprojection residuals and stand three standard deviations from zero.

    A wide-angle lens whose k3 is fixed at zero bends the rest: on the synthetic wide rig (k3 about
    -0.02) the left camera's principal point came out 10 px off and its markers 50 mm aside. A narrow
    lens's k3 is not determined and trades off against k1 and k2, so it stays at zero there.
    """
    dropped = set(report["dropped_frames"])
    kept = [v for v in views if v.frame not in dropped]  # both models judged on the same corners
    try:
        # From the fixed-k3 fit: from OpenCV's distortion-free start, a wide lens's free fit stopped
        # in a wrong minimum (action camera, exact corners: f 5 % long, k3 = -0.005 for -0.013).
        free_cam, free_rep = calibrate_intrinsics(kept, board, image_size, camera=camera, clip=clip,
                                                  fix_k3=False, min_views=min_views, guess=cam, max_rounds=0)
    except CalibrationError:
        return cam, report
    free_rep["dropped_frames"] = report["dropped_frames"]
    n_fixed, n_free = 2 * report["n_points"], 2 * free_rep["n_points"]
    bic_fixed = n_fixed * np.log(report["rms_px"] ** 2) + 8 * np.log(n_fixed)
    bic_free = n_free * np.log(free_rep["rms_px"] ** 2) + 9 * np.log(n_free)
    k3, k3_std = float(free_cam.dist[4]), float(free_cam.dist_std[4]) if free_cam.dist_std is not None else np.inf
    significant = np.isfinite(k3_std) and abs(k3) > 3.0 * k3_std
    free = significant and bic_free < bic_fixed and n_free == n_fixed
    report["k3_test"] = {"k3_free": k3, "k3_std": k3_std, "bic_fixed": float(bic_fixed),
                         "bic_free": float(bic_free), "chosen": "free" if free else "fixed"}
    if free:
        free_rep["k3_test"] = report["k3_test"]
        return free_cam, free_rep
    return cam, report


def _shared(views_a: list[BoardView], views_b: list[BoardView]):
    """Per shared instant: common ids, their corners in a and b."""
    by_frame = {v.frame: v for v in views_b}
    out = []
    for va in views_a:
        vb = by_frame.get(va.frame)
        if vb is None:
            continue
        common, ia, ib = np.intersect1d(va.ids, vb.ids, return_indices=True)
        if len(common) >= MIN_CORNERS:
            out.append((va.frame, common, va.corners_px[ia], vb.corners_px[ib]))
    return out


def stereo_extrinsics(views_a: list[BoardView], views_b: list[BoardView], cam_a: Camera, cam_b: Camera,
                      board: Board, *, min_shared: int = 3) -> dict:
    """Pose of camera b relative to camera a from instants both see (thesis 3.5, Table 8.4).

    ``cv2.stereoCalibrate`` with both cameras' intrinsics fixed.

    Returns
    -------
    dict with ``R`` (3, 3) and ``t_mm`` (3,) such that ``x_b = R @ x_a + t_mm``, ``rms_px``,
    ``n_views`` and ``frames``.

    Raises
    ------
    CalibrationError
        Fewer than ``min_shared`` instants where both cameras see at least 6 common corners.
    """
    shared = _shared(views_a, views_b)
    if len(shared) < min_shared:
        raise CalibrationError(f"cameras {cam_a.name} and {cam_b.name} see the board together in only "
                               f"{len(shared)} frame(s); need at least {min_shared}")
    obj_all = board.object_points_mm().astype(np.float32)
    obj = [obj_all[ids] for _, ids, _, _ in shared]
    img_a = [a.astype(np.float32).reshape(-1, 1, 2) for _, _, a, _ in shared]
    img_b = [b.astype(np.float32).reshape(-1, 1, 2) for _, _, _, b in shared]
    try:
        out = cv2.stereoCalibrate(obj, img_a, img_b, cam_a.K, cam_a.dist, cam_b.K, cam_b.dist,
                                  tuple(cam_a.image_size), flags=cv2.CALIB_FIX_INTRINSIC,
                                  criteria=_CALIB_CRITERIA)
    except cv2.error as exc:
        raise CalibrationError(f"stereo calibration of {cam_a.name}-{cam_b.name} failed in OpenCV: "
                               f"{str(exc).strip().splitlines()[-1]}") from None
    rms, R, T = out[0], out[5], out[6]
    return {"R": np.asarray(R, np.float64), "t_mm": np.asarray(T, np.float64).ravel(), "rms_px": float(rms),
            "n_views": len(shared), "frames": [int(f) for f, _, _, _ in shared]}


# --------------------------------------------------------------------------------------------------
# Projection model (vectorised; OpenCV's 5-coefficient model, thesis eq. 3.4-3.10 with the
# standard tangential terms instead of the typo in eq. 3.8)
# --------------------------------------------------------------------------------------------------


def _rotation_matrices(rvecs: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of rotation vectors (N, 3) (Rodrigues' formula)."""
    theta = np.linalg.norm(rvecs, axis=1)
    small = theta < 1e-12
    k = rvecs / np.where(small, 1.0, theta)[:, None]
    kx = np.zeros((len(rvecs), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx -= kx.transpose(0, 2, 1)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    R = np.eye(3) + s * kx + (1 - c) * (kx @ kx)
    R[small] = np.eye(3)
    return R


def _distort_project(xc: np.ndarray, intr: np.ndarray) -> np.ndarray:
    """Camera-frame points (M, 3) -> distorted px (M, 2); intr (M, 9) = fx fy cx cy k1 k2 p1 p2 k3."""
    z = xc[:, 2]
    x, y = xc[:, 0] / z, xc[:, 1] / z
    fx, fy, cx, cy, k1, k2, p1, p2, k3 = intr.T
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.column_stack([fx * xd + cx, fy * yd + cy])


def _intr_vector(cam: Camera) -> np.ndarray:
    K, d = cam.K, np.asarray(cam.dist, np.float64).ravel()
    d = np.pad(d, (0, max(0, 5 - len(d))))[:5]
    return np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2], *d])


def _camera_from_vector(name, intr, rvec, t, image_size, **kw) -> Camera:
    K = np.array([[intr[0], 0, intr[2]], [0, intr[1], intr[3]], [0, 0, 1.0]])
    R = cv2.Rodrigues(np.asarray(rvec, np.float64))[0]
    return Camera(name, K, np.asarray(intr[4:9], np.float64), tuple(image_size), R=R,
                  t_mm=np.asarray(t, np.float64), **kw)


# --------------------------------------------------------------------------------------------------
# Bundle adjustment
# --------------------------------------------------------------------------------------------------


def _pose_of_view(cam: Camera, view_obj, view_img):
    ok, rvec, tvec = cv2.solvePnP(view_obj, view_img, cam.K, cam.dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        ok, rvec, tvec = cv2.solvePnP(view_obj, view_img, cam.K, cam.dist)
    return ok, rvec.ravel(), tvec.ravel()


def _robust_weights(sq_err: np.ndarray, loss: str, f_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """IRLS weights rho'(s) and costs rho(s) of squared residual norms s (per observation)."""
    z = sq_err / f_scale ** 2
    if loss == "linear":
        return np.ones_like(z), sq_err
    if loss == "soft_l1":
        root = np.sqrt(1 + z)
        return 1 / root, 2 * f_scale ** 2 * (root - 1)
    if loss == "huber":
        r = np.sqrt(z)
        w = np.where(r <= 1, 1.0, 1 / np.maximum(r, 1e-300))
        return w, f_scale ** 2 * np.where(r <= 1, z, 2 * r - 1)
    raise InputError(f"unknown bundle-adjustment loss {loss!r} (linear, soft_l1, huber)")


_NCAM = 15  # per camera: fx fy cx cy k1 k2 p1 p2 k3 | rvec (3) t_mm (3)


class _Bundle:
    """Observations and the residual model of the joint bundle adjustment."""

    def __init__(self, obj, obs_cam, obs_inst, obs_pt, obs_xy, n_cams, n_inst):
        self.obj, self.cam, self.inst, self.pt, self.xy = obj, obs_cam, obs_inst, obs_pt, obs_xy
        self.C, self.I = n_cams, n_inst
        self.inst_onehot = csr_matrix((np.ones(len(obs_cam)), (obs_inst, np.arange(len(obs_cam)))),
                                      shape=(n_inst, len(obs_cam)))
        self.cam_onehot = csr_matrix((np.ones(len(obs_cam)), (obs_cam, np.arange(len(obs_cam)))),
                                     shape=(n_cams, len(obs_cam)))
        key = obs_cam * n_inst + obs_inst
        self.pair_onehot = csr_matrix((np.ones(len(obs_cam)), (key, np.arange(len(obs_cam)))),
                                      shape=(n_cams * n_inst, len(obs_cam)))

    def board_points(self, boards: np.ndarray) -> np.ndarray:
        """Corners in the reference frame (M, 3) for board poses (I, 6)."""
        R = _rotation_matrices(boards[:, :3])
        return np.einsum("mij,mj->mi", R[self.inst], self.obj[self.pt]) + boards[self.inst, 3:]

    def camera_points(self, cams: np.ndarray, xr: np.ndarray) -> np.ndarray:
        R = _rotation_matrices(cams[:, 9:12])
        return np.einsum("mij,mj->mi", R[self.cam], xr) + cams[self.cam, 12:]

    def project(self, cams: np.ndarray, xc: np.ndarray) -> np.ndarray:
        return _distort_project(xc, cams[self.cam, :9]) - self.xy

    def residuals(self, cams: np.ndarray, boards: np.ndarray) -> np.ndarray:
        """(M, 2) px for cams (C, 15) and boards (I, 6)."""
        return self.project(cams, self.camera_points(cams, self.board_points(boards)))

    def jacobians(self, cams, boards, r0):
        """Forward-difference blocks: A (M, 2, 15) w.r.t. the observing camera, B (M, 2, 6) board."""
        M = len(self.cam)
        A = np.empty((M, 2, _NCAM))
        B = np.empty((M, 2, 6))
        xr = self.board_points(boards)
        xc = self.camera_points(cams, xr)
        for k in range(_NCAM):
            h = 1e-6 * np.maximum(np.abs(cams[:, k]), 1.0)
            step = cams.copy()
            step[:, k] += h
            # intrinsics leave the camera-frame points alone; poses leave the board points alone
            r = self.project(step, xc if k < 9 else self.camera_points(step, xr))
            A[:, :, k] = (r - r0) / h[self.cam, None]
        for k in range(6):
            h = 1e-6 * np.maximum(np.abs(boards[:, k]), 1.0)
            step = boards.copy()
            step[:, k] += h
            B[:, :, k] = (self.residuals(cams, step) - r0) / h[self.inst, None]
        return A, B

    def normal_equations(self, A, B, r, w):
        """Blocks of J^T W J and J^T W r: U (C, 15, 15), V (I, 6, 6), W (C, I, 15, 6), gc, gb."""
        Aw = A * w[:, None, None]
        Bw = B * w[:, None, None]
        M = len(w)
        # U: one matrix product per camera (its observations stacked), cheaper than per-observation blocks
        U = np.zeros((self.C, _NCAM, _NCAM))
        for c in range(self.C):
            sel = self.cam == c
            U[c] = Aw[sel].reshape(-1, _NCAM).T @ A[sel].reshape(-1, _NCAM)
        # V and W: per-observation outer products (two rows each), summed by instant / camera-instant
        BtB = Bw[:, 0, :, None] * B[:, 0, None, :] + Bw[:, 1, :, None] * B[:, 1, None, :]
        V = (self.inst_onehot @ BtB.reshape(M, -1)).reshape(self.I, 6, 6)
        AtB = Aw[:, 0, :, None] * B[:, 0, None, :] + Aw[:, 1, :, None] * B[:, 1, None, :]
        W = (self.pair_onehot @ AtB.reshape(M, -1)).reshape(self.C, self.I, _NCAM, 6)
        gc = (self.cam_onehot @ (Aw[:, 0] * r[:, :1] + Aw[:, 1] * r[:, 1:])).reshape(self.C, _NCAM)
        gb = (self.inst_onehot @ (Bw[:, 0] * r[:, :1] + Bw[:, 1] * r[:, 1:])).reshape(self.I, 6)
        return U, V, W, gc, gb


def _schur_solve(U, V, W, gc, gb, free, lam):
    """Damped Gauss-Newton step by the Schur complement over the board poses.

    Returns (dc (C, 15), db (I, 6), S) where S is the reduced camera system on the free parameters.
    """
    C, I = W.shape[:2]
    n = C * _NCAM
    Ufull = np.zeros((n, n))
    for c in range(C):
        Ufull[c * _NCAM:(c + 1) * _NCAM, c * _NCAM:(c + 1) * _NCAM] = U[c]
    Vd = V + lam * np.einsum("ijj->ij", V)[:, :, None] * np.eye(6) + 1e-12 * np.eye(6)
    Vinv = np.linalg.inv(Vd)
    Wi = W.transpose(1, 0, 2, 3).reshape(I, n, 6)  # per instant, all cameras stacked
    WV = np.einsum("iaj,ijk->iak", Wi, Vinv)
    S = Ufull - np.einsum("iak,ibk->ab", WV, Wi)
    rhs = -(gc.ravel() - np.einsum("iak,ik->a", WV, gb))
    Sf = S[np.ix_(free, free)]
    Sf = Sf + lam * np.diag(np.diag(Sf)) + 1e-12 * np.eye(len(free))
    dc = np.zeros(n)
    dc[free] = np.linalg.solve(Sf, rhs[free])
    db = np.einsum("ijk,ik->ij", Vinv, -gb - np.einsum("iaj,a->ij", Wi, dc))
    return dc.reshape(C, _NCAM), db, S


def bundle_adjust(cameras: Mapping[str, Camera], views_by_camera: Mapping[str, list[BoardView]],
                  board: Board, *, fix_k3: bool | Mapping[str, bool] = True, loss: str = "soft_l1",
                  f_scale_px: float = 1.0,
                  outlier_px: float = 5.0, max_iterations: int = 60) -> tuple[dict[str, Camera], dict]:
    """Refine all cameras (intrinsics, distortion, pose) and all board poses jointly.

    The first camera is the reference (identity pose). Board poses are parameters per instant (a
    frame key shared by all cameras). Each residual is a corner's reprojection error in px; the loss
    is robust (``soft_l1`` or ``huber`` with scale ``f_scale_px``, solved by reweighting). The solver
    is Levenberg-Marquardt on the normal equations with the board poses eliminated by the Schur
    complement (the classic sparse bundle adjustment), so a step costs one small dense solve.

    Parameters
    ----------
    cameras : dict name -> Camera
        Initial values: intrinsics and poses relative to the first camera.
    views_by_camera : dict name -> list of BoardView
        Frame keys must be synchronised instants.
    outlier_px : float
        After a first pass, corners reprojecting worse than this are dropped and the fit repeated.

    Returns
    -------
    cameras : dict name -> Camera, refined, with ``K_std``/``dist_std`` (one standard deviation) from
        the Gauss-Newton covariance with the board poses marginalised
    report : dict with ``rms_px`` (all), ``rms_px_by_camera``, ``n_observations``, ``n_dropped``,
        ``n_instants``, ``iterations``, ``pose_std`` {camera: (rvec std (3,), t std mm (3,))},
        ``board_poses`` {instant: (6,) rvec and t_mm in the reference camera}.
    """
    names = list(cameras)
    obj_all = board.object_points_mm()
    for name in names:
        if not views_by_camera.get(name):
            raise CalibrationError(f"bundle adjustment: camera {name} has no board view")

    # board pose per instant, initialised from the camera seeing most corners
    inst_pose: dict[int, np.ndarray] = {}
    by_inst: dict[int, list[tuple[str, BoardView]]] = {}
    for cam in names:
        for v in views_by_camera.get(cam, []):
            by_inst.setdefault(v.frame, []).append((cam, v))
    for inst, entries in by_inst.items():
        cam, v = max(entries, key=lambda e: len(e[1].ids))
        c = cameras[cam]
        ok, rvec, tvec = _pose_of_view(c, obj_all[v.ids], v.corners_px)
        if ok:
            Rb = c.R.T @ cv2.Rodrigues(rvec)[0]
            inst_pose[inst] = np.concatenate([cv2.Rodrigues(Rb)[0].ravel(), c.R.T @ (tvec - c.t_mm)])
    instants = sorted(inst_pose)
    if not instants:
        raise CalibrationError("bundle adjustment: no board pose could be initialised")
    inst_index = {f: i for i, f in enumerate(instants)}
    parts = [(ci, inst_index[v.frame], v) for ci, cam in enumerate(names)
             for v in views_by_camera.get(cam, []) if v.frame in inst_index]
    obs_cam = np.concatenate([np.full(len(v.ids), ci) for ci, _, v in parts])
    obs_inst = np.concatenate([np.full(len(v.ids), ii) for _, ii, v in parts])
    obs_pt = np.concatenate([v.ids for _, _, v in parts])
    obs_xy = np.concatenate([v.corners_px for _, _, v in parts])

    C, I = len(names), len(instants)
    cams = np.array([np.concatenate([_intr_vector(cameras[n]), cameras[n].rvec, cameras[n].t_mm])
                     for n in names])
    boards = np.array([inst_pose[f] for f in instants])
    free_mask = np.ones((C, _NCAM), bool)
    free_mask[0, 9:] = False  # the reference camera defines the rig frame
    k3_fixed = fix_k3 if isinstance(fix_k3, Mapping) else {n: bool(fix_k3) for n in names}
    for i, n in enumerate(names):
        free_mask[i, 8] = not k3_fixed.get(n, True)
    free = np.flatnonzero(free_mask.ravel())

    keep = np.ones(len(obs_cam), bool)
    n_dropped = 0
    iterations = 0
    for _pass in range(2):
        bundle = _Bundle(obj_all, obs_cam[keep], obs_inst[keep], obs_pt[keep], obs_xy[keep], C, I)
        r = bundle.residuals(cams, boards)
        w, rho = _robust_weights(np.sum(r ** 2, axis=1), loss, f_scale_px)
        cost = float(rho.sum())
        lam = 1e-4
        for _ in range(max_iterations):
            iterations += 1
            A, B = bundle.jacobians(cams, boards, r)
            U, V, W, gc, gb = bundle.normal_equations(A, B, r, w)
            improved = False
            for _try in range(10):
                dc, db, _ = _schur_solve(U, V, W, gc, gb, free, lam)
                c_new, b_new = cams + dc, boards + db
                r_new = bundle.residuals(c_new, b_new)
                w_new, rho_new = _robust_weights(np.sum(r_new ** 2, axis=1), loss, f_scale_px)
                cost_new = float(rho_new.sum())
                if np.isfinite(cost_new) and cost_new < cost:
                    improved = True
                    break
                lam *= 10
            if not improved:
                break
            rel = (cost - cost_new) / max(cost, 1e-300)
            cams, boards, r, w, cost = c_new, b_new, r_new, w_new, cost_new
            lam = max(lam / 10, 1e-9)
            if rel < 1e-10:
                break
        err = np.full(len(keep), np.inf)
        err[keep] = np.hypot(r[:, 0], r[:, 1])
        new_keep = keep & (err <= outlier_px)
        if new_keep.sum() == keep.sum() or new_keep.sum() < 0.5 * keep.sum():
            break
        n_dropped = int((~new_keep).sum())
        keep = new_keep

    # covariance of the camera parameters with the board poses marginalised: sigma^2 S^-1
    A, B = bundle.jacobians(cams, boards, r)
    U, V, W, gc, gb = bundle.normal_equations(A, B, r, w)
    _, _, S = _schur_solve(U, V, W, gc, gb, free, 0.0)
    dof = max(2 * len(r) - len(free) - 6 * I, 1)
    sigma2 = float(np.sum(w * np.sum(r ** 2, axis=1)) / dof)
    std = np.zeros(C * _NCAM)
    try:
        std[free] = np.sqrt(np.clip(np.diag(np.linalg.inv(S[np.ix_(free, free)])), 0, None) * sigma2)
    except np.linalg.LinAlgError:
        std[free] = np.nan
    std = std.reshape(C, _NCAM)

    out, pose_std, rms_by_cam = {}, {}, {}
    for ci, name in enumerate(names):
        sel = bundle.cam == ci
        rms_c = float(np.sqrt(np.mean(np.sum(r[sel] ** 2, axis=1)))) if sel.any() else float("nan")
        rms_by_cam[name] = rms_c
        s = std[ci]
        K_std = np.array([[s[0], 0, s[2]], [0, s[1], s[3]], [0, 0, 0]])
        out[name] = _camera_from_vector(name, cams[ci, :9], cams[ci, 9:12], cams[ci, 12:],
                                        cameras[name].image_size, rms_px=rms_c, K_std=K_std,
                                        dist_std=s[4:9].copy())
        if ci > 0:
            pose_std[name] = (s[9:12].copy(), s[12:].copy())
    report = {
        "rms_px": float(np.sqrt(np.mean(np.sum(r ** 2, axis=1)))),
        "rms_px_by_camera": rms_by_cam,
        "n_observations": int(keep.sum()),
        "n_dropped": n_dropped,
        "n_instants": I,
        "iterations": iterations,
        "pose_std": pose_std,
        "board_poses": {f: boards[inst_index[f]].copy() for f in instants},
    }
    return out, report


# --------------------------------------------------------------------------------------------------
# Triangulation for checks and metric quality
# --------------------------------------------------------------------------------------------------


def _normalized(cam: Camera, xy_px: np.ndarray) -> np.ndarray:
    """Distorted px (N, 2) -> undistorted normalised image coordinates (N, 2), NaN kept."""
    out = np.full(xy_px.shape, np.nan)
    ok = np.all(np.isfinite(xy_px), axis=1)
    if ok.any():
        und = cv2.undistortPoints(xy_px[ok].reshape(-1, 1, 2).astype(np.float64), cam.K, cam.dist,
                                  criteria=_UNDISTORT_CRITERIA)
        out[ok] = und.reshape(-1, 2)
    return out


def triangulate_dlt(cameras: list[Camera], xy_px: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear N-view triangulation (DLT on undistorted normalised coordinates).

    Parameters
    ----------
    cameras : list of C Camera (poses relative to a common frame, mm)
    xy_px : ndarray of shape (C, N, 2)
        Distorted pixel coordinates, NaN where a camera does not see the point.

    Returns
    -------
    xyz_mm : ndarray of shape (N, 3), NaN where fewer than two cameras see the point
    reprojection_error_px : ndarray of shape (N,), RMS over the cameras that see the point
    """
    xy_px = np.asarray(xy_px, np.float64)
    C, N = xy_px.shape[:2]
    if len(cameras) != C:
        raise InputError(f"{len(cameras)} cameras but points for {C}")
    A = np.zeros((N, 2 * C, 4))
    seen = np.zeros((C, N), bool)
    for c, cam in enumerate(cameras):
        xn = _normalized(cam, xy_px[c])
        ok = np.all(np.isfinite(xn), axis=1)
        seen[c] = ok
        P = np.hstack([cam.R, np.reshape(cam.t_mm, (3, 1)) / 1000.0])  # metres: better conditioned
        xn0 = np.where(ok[:, None], xn, 0.0)
        A[:, 2 * c] = (xn0[:, :1] * P[2] - P[0]) * ok[:, None]
        A[:, 2 * c + 1] = (xn0[:, 1:] * P[2] - P[1]) * ok[:, None]
    _, _, vt = np.linalg.svd(A)
    X = vt[:, -1, :]
    n_seen = seen.sum(axis=0)
    w = np.where((n_seen >= 2) & (np.abs(X[:, 3]) > 1e-15), X[:, 3], np.nan)
    xyz = X[:, :3] / w[:, None] * 1000.0
    sq = np.zeros(N)
    for c, cam in enumerate(cameras):
        proj = cam.project(xyz)
        d2 = np.sum((proj - xy_px[c]) ** 2, axis=1)
        sq += np.where(seen[c] & np.isfinite(d2), d2, 0.0)
    err = np.sqrt(sq / np.maximum(n_seen, 1))
    err[n_seen < 2] = np.nan
    return xyz, err


def _instant_points(views_by_camera, names):
    """instant -> (ids (K,), xy (C, K, 2) with NaN)."""
    frames = sorted({v.frame for n in names for v in views_by_camera.get(n, [])})
    by = {n: {v.frame: v for v in views_by_camera.get(n, [])} for n in names}
    out = {}
    for f in frames:
        ids = np.unique(np.concatenate([by[n][f].ids for n in names if f in by[n]]))
        xy = np.full((len(names), len(ids), 2), np.nan)
        for c, n in enumerate(names):
            v = by[n].get(f)
            if v is not None:
                xy[c, np.searchsorted(ids, v.ids)] = v.corners_px
        if np.sum(np.any(np.isfinite(xy[..., 0]), axis=1)) >= 2:
            out[f] = (ids, xy)
    return out


def _similarity_fit(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray]:
    """Scale s and residuals (K, 3) of the best dst ~ s R src + t (Umeyama's closed form)."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_s, dst - mu_d
    U, sv, Vt = np.linalg.svd(b.T @ a / len(src))
    d = np.ones(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        d[-1] = -1
    R = U @ np.diag(d) @ Vt
    var_a = np.mean(np.sum(a ** 2, axis=1))
    s = float(np.sum(sv * d) / var_a)
    return s, b - s * a @ R.T


def board_distance_errors(rig: Rig, views_by_camera: Mapping[str, list[BoardView]], board: Board, *,
                          cameras: list[str] | None = None, max_pair_corners: int = 60) -> dict:
    """Metric errors of the triangulated board (thesis Table 8.5, for every corner pair).

    For each instant, corners seen by two or more of ``cameras`` are triangulated. Then (1) the true
    board is fitted to them by a similarity transform (rotation, translation, scale): the scale
    times the square size is the reconstructed square length, averaged over the whole board so that
    it measures the calibration's systematic scale error rather than one corner's noise; (2) every
    pair of neighbouring corners and every pair among up to ``max_pair_corners`` corners spread over
    the board is compared with its true distance (noise and systematic error together).

    Returns
    -------
    dict with ``scales`` (I,) fitted scale per instant, ``fit_residuals_mm`` (P,) point distances to
    the fitted board, ``adjacent_errors_mm`` (S,) neighbouring-corner distance errors,
    ``distance_errors_mm`` (D,) and ``true_distances_mm`` (D,) for all corner pairs,
    ``reprojection_error_px`` (P,), ``n_instants``, ``n_points``.
    """
    names = list(cameras or rig.cameras)
    cams = [rig.cameras[n] for n in names]
    obj = board.object_points_mm()
    cols = board.inner_corners[0]
    scales, fit_res, adj_err, d_err, d_true, reproj = [], [], [], [], [], []
    n_pts = 0
    for ids, xy in _instant_points(views_by_camera, names).values():
        xyz, err = triangulate_dlt(cams, xy)
        ok = np.isfinite(xyz[:, 0])
        if ok.sum() < 4:
            continue
        ids, xyz = ids[ok], xyz[ok]
        rows_cols = np.column_stack(np.divmod(ids, cols))
        if np.linalg.matrix_rank(rows_cols - rows_cols.mean(axis=0)) < 2:
            continue  # collinear corners fix no plane
        s, res = _similarity_fit(obj[ids], xyz)
        scales.append(s)
        fit_res.append(np.linalg.norm(res, axis=1))
        reproj.append(err[ok])
        n_pts += len(ids)
        # neighbours: all of them
        pos = {int(k): n for n, k in enumerate(ids)}
        right = [(pos[k], pos[k + 1]) for k in pos if (k % cols) + 1 < cols and k + 1 in pos]
        below = [(pos[k], pos[k + cols]) for k in pos if k + cols in pos]
        nb = np.array(right + below, dtype=np.int64).reshape(-1, 2)
        adj_err.append(np.linalg.norm(xyz[nb[:, 0]] - xyz[nb[:, 1]], axis=1) - board.square_mm)
        # all pairs among at most max_pair_corners evenly spread corners (a large board has 10^5 pairs)
        sub = np.unique(np.linspace(0, len(ids) - 1, min(len(ids), max_pair_corners)).round().astype(int))
        iu, ju = np.triu_indices(len(sub), 1)
        iu, ju = sub[iu], sub[ju]
        meas = np.linalg.norm(xyz[iu] - xyz[ju], axis=1)
        true = np.linalg.norm(obj[ids[iu]] - obj[ids[ju]], axis=1)
        d_err.append(meas - true)
        d_true.append(true)
    cat = lambda parts: np.concatenate(parts) if parts else np.zeros(0)
    return {"scales": np.asarray(scales), "fit_residuals_mm": cat(fit_res),
            "adjacent_errors_mm": cat(adj_err),
            "distance_errors_mm": cat(d_err), "true_distances_mm": cat(d_true),
            "reprojection_error_px": cat(reproj), "n_instants": len(scales), "n_points": n_pts}


def _summary(err: np.ndarray, prefix: str) -> dict[str, float]:
    if err.size == 0:
        return {}
    return {f"{prefix}_mean_mm": float(np.mean(err)), f"{prefix}_rms_mm": float(np.sqrt(np.mean(err ** 2))),
            f"{prefix}_max_mm": float(np.max(np.abs(err)))}


def metric_checks(rig: Rig, views_by_camera: Mapping[str, list[BoardView]], board: Board, *,
                  max_square_error_pct: float = 1.0, max_square_error_mm: float | None = None,
                  max_distance_rms_mm: float | None = None) -> tuple[dict[str, float], list[str], dict]:
    """Metric quality of a rig in mm (thesis Table 8.5), overall and per camera pair.

    Returns
    -------
    checks : dict of float
        ``board_square_error_mm``: RMS over instants of the reconstructed square length (from the
        board's fitted scale, :func:`board_distance_errors`) minus the true one; ``board_square_error_pct``;
        ``board_scale_error_pct``: mean signed scale error (the systematic part);
        ``board_fit_rms_mm``: RMS distance of the triangulated corners to the fitted board (point
        noise); ``adjacent_distance_error_{mean,rms,max}_mm`` (neighbouring corners) and
        ``corner_distance_error_{mean,rms,max}_mm`` (all corner pairs within an instant);
        ``corner_distance_error_pct`` (RMS error / RMS true distance); ``triangulation_rms_px``;
        ``check_instants``; ``check_points``.
    flags : list of str
        A sentence per threshold exceeded: square error over ``max_square_error_pct`` percent or over
        ``max_square_error_mm``; corner-distance RMS over ``max_distance_rms_mm`` (None: not checked,
        since on a narrow-baseline rig it is dominated by each corner's depth noise, not the
        calibration).
    per_pair : dict "a-b" -> dict of the same numbers using only those two cameras.
    """
    names = list(rig.cameras)
    if len(names) < 2:
        return {}, [], {}

    def numbers(errs):
        out: dict[str, float] = {}
        scales = errs["scales"]
        if scales.size:
            out["board_square_error_mm"] = float(np.sqrt(np.mean((scales - 1) ** 2)) * board.square_mm)
            out["board_square_error_pct"] = 100.0 * out["board_square_error_mm"] / board.square_mm
            out["board_scale_error_pct"] = float(100 * np.mean(scales - 1))
            out["board_fit_rms_mm"] = float(np.sqrt(np.mean(errs["fit_residuals_mm"] ** 2)))
        out.update(_summary(errs["adjacent_errors_mm"], "adjacent_distance_error"))
        d, true = errs["distance_errors_mm"], errs["true_distances_mm"]
        if d.size:
            out.update(_summary(d, "corner_distance_error"))
            out["corner_distance_error_pct"] = float(100 * np.sqrt(np.mean(d ** 2) / np.mean(true ** 2)))
        if errs["reprojection_error_px"].size:
            out["triangulation_rms_px"] = float(np.sqrt(np.mean(errs["reprojection_error_px"] ** 2)))
        out["check_instants"] = float(errs["n_instants"])
        out["check_points"] = float(errs["n_points"])
        return out

    checks = numbers(board_distance_errors(rig, views_by_camera, board))
    per_pair = {f"{a}-{b}": numbers(board_distance_errors(rig, views_by_camera, board, cameras=[a, b]))
                for a, b in itertools.combinations(names, 2)}
    flags: list[str] = []
    if "board_square_error_mm" not in checks:
        flags.append("no board was seen by two cameras at once: the rig's metric accuracy is unchecked")
        return checks, flags, per_pair
    sq_mm, sq_pct = checks["board_square_error_mm"], checks["board_square_error_pct"]
    if sq_pct > max_square_error_pct or (max_square_error_mm is not None and sq_mm > max_square_error_mm):
        limit = f"{max_square_error_pct:g} %"
        if max_square_error_mm is not None:
            limit += f" / {max_square_error_mm:g} mm"
        flags.append(f"reconstructed board squares are off by {sq_mm:.2f} mm RMS ({sq_pct:.2f} % of "
                     f"{board.square_mm:g} mm, over the {limit} limit): recalibrate before trusting "
                     f"distances")
    rms = checks.get("corner_distance_error_rms_mm", 0.0)
    if max_distance_rms_mm is not None and rms > max_distance_rms_mm:
        flags.append(f"distances between triangulated board corners are off by {rms:.2f} mm RMS, over the "
                     f"{max_distance_rms_mm:g} mm limit")
    return checks, flags, per_pair


# --------------------------------------------------------------------------------------------------
# The whole rig
# --------------------------------------------------------------------------------------------------


def _initial_poses(names, pairs, ref) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Chain pair poses from the reference along the pairs with most shared views (spanning tree)."""
    poses = {ref: (np.eye(3), np.zeros(3))}
    while len(poses) < len(names):
        best = None
        for (a, b), p in pairs.items():
            for src, dst, R, t in ((a, b, p["R"], p["t_mm"]), (b, a, p["R"].T, -p["R"].T @ p["t_mm"])):
                if src in poses and dst not in poses and (best is None or p["n_views"] > best[0]):
                    best = (p["n_views"], src, dst, R, t)
        if best is None:
            missing = [n for n in names if n not in poses]
            raise CalibrationError(f"camera(s) {', '.join(missing)} never see the board together with "
                                   f"camera {ref} or a camera linked to it: cannot place them in the rig")
        _, src, dst, R, t = best
        Rs, ts = poses[src]
        poses[dst] = (R @ Rs, R @ ts + t)
    return poses


def _fix_flipped_views(cameras, views_by_camera, board, *, max_px=20.0):
    """Relabel (180-degree) or drop views inconsistent with the board pose the other cameras see.

    Symmetric checkerboards can be labelled from the opposite corner in one camera; this finds such
    views from the initial rig and tries the rotated labels.
    """
    names = list(cameras)
    obj_all = board.object_points_mm()
    n = len(obj_all)
    cols, rows = board.inner_corners
    symmetric = board.kind == "checkerboard" and (cols + rows) % 2 == 0
    by_inst: dict[int, dict[str, BoardView]] = {}
    for cam in names:
        for v in views_by_camera.get(cam, []):
            by_inst.setdefault(v.frame, {})[cam] = v
    out = {cam: [] for cam in names}
    n_fixed = n_dropped = 0
    for per_cam in by_inst.values():
        if len(per_cam) < 2:
            for cam, v in per_cam.items():
                out[cam].append(v)
            continue
        poses = {}
        for cam, v in per_cam.items():
            c = cameras[cam]
            ok, rvec, tvec = _pose_of_view(c, obj_all[v.ids], v.corners_px)
            if ok:
                Rb = c.R.T @ cv2.Rodrigues(rvec)[0]
                poses[cam] = (Rb, c.R.T @ (tvec - c.t_mm))

        def err_of(cam, v, pose):
            Rb, tb = pose
            pts = obj_all[v.ids] @ Rb.T + tb
            proj = cameras[cam].project(pts)
            return float(np.sqrt(np.mean(np.sum((proj - v.corners_px) ** 2, axis=1))))

        # the pose most cameras agree with
        best_pose, best_votes = None, -1
        for pose in poses.values():
            votes = sum(err_of(c2, v2, pose) < max_px for c2, v2 in per_cam.items())
            if votes > best_votes:
                best_pose, best_votes = pose, votes
        for cam, v in per_cam.items():
            if best_pose is None or err_of(cam, v, best_pose) < max_px:
                out[cam].append(v)
                continue
            if symmetric:
                flipped = BoardView(v.frame, v.corners_px, n - 1 - v.ids)
                if err_of(cam, flipped, best_pose) < max_px:
                    out[cam].append(flipped)
                    n_fixed += 1
                    continue
            n_dropped += 1
    for cam in names:
        out[cam].sort(key=lambda v: v.frame)
    return out, n_fixed, n_dropped


def principal_point_common_shift(single: Mapping[str, Camera], joint: Mapping[str, Camera]) -> np.ndarray:
    """The mean over cameras of (joint - single-camera) principal point, (2,) px.

    With the board held in a band across the images (a person carrying it at chest height) a common
    shift of every principal point and a common tilt of the rig fit the views almost equally well:
    each camera alone still finds its principal point within a few pixels, but in the joint
    adjustment a hundredth of a pixel of disagreement between the cameras' corners moved all three
    together by 10-40 px (50-60 fps synthetic thesis-rig rides), bending the markers' heights by
    3-4 mm across the view. Each camera's own estimate scatters; their mean shift does not."""
    names = [n for n in joint if n in single]
    d = [np.asarray(joint[n].K)[:2, 2] - np.asarray(single[n].K)[:2, 2] for n in names]
    return np.mean(d, axis=0) if d else np.zeros(2)


def calibrate_rig(views_by_camera: Mapping[str, list[BoardView]], board: Board,
                  image_sizes: Mapping[str, tuple[int, int]], *, fix_k3: bool | None = None,
                  bundle: bool = True, loss: str = "soft_l1", min_views: int = MIN_VIEWS, min_shared: int = 3,
                  max_square_error_pct: float = 1.0, max_square_error_mm: float | None = None,
                  max_distance_rms_mm: float | None = None, max_principal_point_shift: float = 0.02,
                  clip: str | None = "calibration") -> tuple[Rig, dict]:
    """Calibrate one or more cameras into a :class:`Rig` (first camera = reference, identity pose).

    Steps: intrinsics per camera (:func:`calibrate_intrinsics`); stereo pairs for every pair of cameras
    that see the board together (:func:`stereo_extrinsics`, thesis 3.5); initial poses chained from
    the reference; joint bundle adjustment (:func:`bundle_adjust`); metric checks in mm
    (:func:`metric_checks`), whose failures become ``Rig.flags``.

    Parameters
    ----------
    views_by_camera : dict name -> list of BoardView
        Frame keys are synchronised instants (apply the sync offsets before).
    board : Board
    image_sizes : dict name -> (width, height)
    fix_k3 : bool or None
        Keep k3 = 0 for every camera (True), fit it for every camera (False), or (None, default) fit
        it for the cameras whose views call for it (:func:`_choose_k3`).
    max_principal_point_shift : float
        Flag the rig when the bundle adjustment moves all principal points together by more than
        this fraction of the smaller image side (:func:`principal_point_common_shift`).

    Returns
    -------
    rig : Rig
        ``checks`` holds the metric numbers, ``flags`` their failures, ``pairs`` the stereo results
        {"a-b": {"R", "t_mm", "rms_px", "n_views"}}.
    report : dict
        ``intrinsics`` {name: report}, ``bundle`` report (or None), ``per_pair_checks``,
        ``n_relabelled_views``, ``n_dropped_views``.
    """
    names = list(views_by_camera)
    if not names:
        raise InputError("no cameras to calibrate")
    missing = [n for n in names if n not in image_sizes]
    if missing:
        raise InputError(f"image size missing for camera(s) {', '.join(missing)}")
    intrinsics: dict[str, Camera] = {}
    intr_reports: dict[str, dict] = {}
    for name in names:
        intrinsics[name], intr_reports[name] = calibrate_intrinsics(
            views_by_camera[name], board, image_sizes[name], camera=name, clip=clip,
            fix_k3=True if fix_k3 is None else fix_k3, min_views=min_views)
        if fix_k3 is None:
            intrinsics[name], intr_reports[name] = _choose_k3(intrinsics[name], intr_reports[name],
                                                              views_by_camera[name], board, image_sizes[name],
                                                              camera=name, clip=clip, min_views=min_views)
    k3_fixed = {n: intr_reports[n]["fix_k3"] for n in names}
    # views kept by the intrinsic step (outlier views dropped)
    views = {n: [v for v in views_by_camera[n] if v.frame in intr_reports[n]["per_view_rms_px"]]
             for n in names}
    report: dict = {"intrinsics": intr_reports, "bundle": None, "per_pair_checks": {},
                    "n_relabelled_views": 0, "n_dropped_views": 0}
    if len(names) == 1:
        return Rig({names[0]: intrinsics[names[0]]}), report

    pairs_cv: dict[tuple[str, str], dict] = {}
    for a, b in itertools.combinations(names, 2):
        try:
            pairs_cv[(a, b)] = stereo_extrinsics(views[a], views[b], intrinsics[a], intrinsics[b], board,
                                                 min_shared=min_shared)
        except CalibrationError:
            continue  # the pair may be linked through other cameras
    init = _initial_poses(names, pairs_cv, names[0])
    cams = {n: Camera(n, intrinsics[n].K, intrinsics[n].dist, intrinsics[n].image_size, R=init[n][0],
                      t_mm=init[n][1], rms_px=intrinsics[n].rms_px, K_std=intrinsics[n].K_std,
                      dist_std=intrinsics[n].dist_std) for n in names}
    views, n_fixed, n_dropped = _fix_flipped_views(cams, views, board)
    report["n_relabelled_views"], report["n_dropped_views"] = n_fixed, n_dropped
    if bundle:
        cams, report["bundle"] = bundle_adjust(cams, views, board, fix_k3=k3_fixed, loss=loss)
    pairs = {}
    for (a, b), p in pairs_cv.items():
        pairs[f"{a}-{b}"] = {"R": p["R"], "t_mm": p["t_mm"], "rms_px": p["rms_px"], "n_views": p["n_views"]}
    rig = Rig(cams, pairs=pairs)
    checks, flags, per_pair = metric_checks(rig, views, board, max_square_error_pct=max_square_error_pct,
                                            max_square_error_mm=max_square_error_mm,
                                            max_distance_rms_mm=max_distance_rms_mm)
    for key, p in pairs.items():
        p.update({f"check_{k}": v for k, v in per_pair.get(key, {}).items()})
    if report["bundle"] is not None:
        checks["bundle_rms_px"] = report["bundle"]["rms_px"]
        shift = principal_point_common_shift(intrinsics, cams)
        checks["principal_point_common_shift_px"] = float(np.hypot(*shift))
        limit = max_principal_point_shift * min(min(image_sizes[n]) for n in names)
        if checks["principal_point_common_shift_px"] > limit:
            flags.append(
                f"the joint adjustment moved every camera's principal point by about "
                f"{checks['principal_point_common_shift_px']:.0f} px (x {shift[0]:+.0f}, y {shift[1]:+.0f}) from where "
                "each camera's own views put it: the board's positions do not tell the cameras' aim from their "
                "principal points, so heights and depths may bend by millimetres across the view; carry the board "
                "higher and lower and tilt it towards and away from the cameras")
    report["per_pair_checks"] = per_pair
    return Rig(cams, checks=checks, flags=tuple(flags), pairs=pairs), report


# --------------------------------------------------------------------------------------------------
# Synthetic views (tests and `saddlescope bench`)
# --------------------------------------------------------------------------------------------------


def simulate_board_views(rig: Rig, board: Board, board_rvecs: np.ndarray, board_t_mm: np.ndarray, *,
                         noise_px: float, rng: np.random.Generator) -> dict[str, list[BoardView]]:
    """Project board poses through a rig, with Gaussian pixel noise; keep views fully inside images.

    Parameters
    ----------
    board_rvecs, board_t_mm : ndarray of shape (P, 3)
        Board poses in the rig (reference camera) frame: ``x = R(rvec) @ X_board + t``.

    Returns
    -------
    dict name -> list of BoardView, frame = pose index
    """
    obj = board.object_points_mm()
    out: dict[str, list[BoardView]] = {n: [] for n in rig.cameras}
    ids = np.arange(len(obj))
    for k, (rv, t) in enumerate(zip(np.asarray(board_rvecs), np.asarray(board_t_mm), strict=True)):
        pts = obj @ cv2.Rodrigues(rv)[0].T + t
        for name, cam in rig.cameras.items():
            depth = (pts @ cam.R.T + cam.t_mm)[:, 2]
            if np.any(depth <= 0):
                continue
            xy = cam.project(pts) + rng.normal(0.0, noise_px, (len(obj), 2))
            w, h = cam.image_size
            if np.all((xy[:, 0] >= 1) & (xy[:, 0] <= w - 2) & (xy[:, 1] >= 1) & (xy[:, 1] <= h - 2)):
                out[name].append(BoardView(k, xy, ids))
    return out


def thesis_like_views(n_poses: int = 90, *, rng: np.random.Generator, noise_px: float = 0.1,
                      board: Board | None = None) -> tuple[Rig, Board, dict[str, list[BoardView]],
                                                           dict[str, tuple[int, int]]]:
    """A thesis-like rig (3 cameras, 640x480, f ~ 730 px, 0.23 m apart, scene 7.5 m away) and views.

    The board (default 15 x 8 inner corners of 100 mm, as large as the thesis's 800 x 1500 mm board)
    slides across the scene in six stations and tilts (thesis 8.2: six slides, 15 images each).

    Returns
    -------
    rig (truth), board, views_by_camera, image_sizes
    """
    board = board or make_board("checkerboard", (15, 8), 100.0)
    size = (640, 480)
    names = ("left", "middle", "right")
    cams = {}
    for i, name in enumerate(names):
        f = 730.0 + rng.normal(0, 5)
        K = np.array([[f, 0, 320 + rng.normal(0, 5)], [0, f * (1 + rng.normal(0, 0.002)),
                                                      240 + rng.normal(0, 5)], [0, 0, 1]])
        dist = np.array([-0.13 + rng.normal(0, 0.005), 0.03 + rng.normal(0, 0.01),
                         rng.normal(0, 0.001), rng.normal(0, 0.001), 0.0])
        # cameras on a line 230 mm apart, turned slightly inwards
        yaw = np.radians(-1.5 * (i - 1))
        R = cv2.Rodrigues(np.array([rng.normal(0, 0.005), yaw, rng.normal(0, 0.005)]))[0]
        centre = np.array([230.0 * i, rng.normal(0, 3), rng.normal(0, 10)])
        cams[name] = Camera(name, K, dist, size, R=R, t_mm=-R @ centre)
    # express relative to the left camera
    R0, t0 = cams["left"].R, cams["left"].t_mm
    rel = {n: Camera(n, c.K, c.dist, size, R=c.R @ R0.T, t_mm=c.t_mm - c.R @ R0.T @ t0)
           for n, c in cams.items()}
    rig = Rig(rel)
    cols, rows = board.inner_corners
    half = np.array([(cols - 1) * board.square_mm / 2, (rows - 1) * board.square_mm / 2, 0.0])
    rvecs, ts = [], []
    stations = np.linspace(-2000, 2000, 6) + 230
    for k in range(n_poses):
        x = stations[k % 6] + rng.uniform(-250, 250)
        centre = np.array([x, rng.uniform(-300, 300), rng.uniform(6800, 8200)])
        tilt = np.radians([rng.uniform(-35, 35), rng.uniform(-35, 35), rng.uniform(-15, 15)])
        R = cv2.Rodrigues(tilt)[0]
        rvecs.append(tilt)
        ts.append(centre - R @ half)
    views = simulate_board_views(rig, board, np.array(rvecs), np.array(ts), noise_px=noise_px, rng=rng)
    return rig, board, views, {n: size for n in names}


def board_texture(board: Board, *, px_per_square: int = 40) -> tuple[np.ndarray, float, np.ndarray]:
    """Image of the board with a one-square white margin.

    Returns
    -------
    texture : ndarray (H, W) uint8
    px_per_mm : float
    origin_px : ndarray (2,), texture pixel of board point (0, 0) (inner corner 0)
    """
    cols, rows = board.inner_corners
    sq = int(px_per_square)
    if board.kind == "charuco":
        size = ((cols + 1) * sq + 2 * sq, (rows + 1) * sq + 2 * sq)
        tex = _cv_charuco(board).generateImage(size, marginSize=sq, borderBits=1)
        origin = np.array([2 * sq, 2 * sq], np.float64)  # margin + first square
    else:
        tex = np.full(((rows + 3) * sq, (cols + 3) * sq), 255, np.uint8)
        for j in range(rows + 1):
            for i in range(cols + 1):
                if (i + j) % 2 == 0:  # the square left of and above corner 0 is dark (canonical order)
                    tex[(j + 1) * sq:(j + 2) * sq, (i + 1) * sq:(i + 2) * sq] = 0
        origin = np.array([2 * sq, 2 * sq], np.float64)
    return tex, sq / board.square_mm, origin - 0.5


def render_board(board: Board, camera: Camera, board_rvec: np.ndarray, board_t_mm: np.ndarray, *,
                 background: int = 128, supersample: int = 2, px_per_square: int = 40) -> np.ndarray:
    """Synthetic grey image (H, W) uint8 of the board seen by a camera (with its lens distortion).

    The board pose is in the camera's frame: ``x_cam = R(board_rvec) @ X_board + board_t_mm``. For
    tests, demos and benchmarks; anti-aliased by rendering ``supersample`` times larger.
    """
    tex, px_per_mm, origin = board_texture(board, px_per_square=px_per_square)
    w, h = camera.image_size
    s = int(supersample)
    # undistort a coarse grid and interpolate: the distortion field is smooth, undistortPoints is slow
    step = 8
    gy, gx = np.arange(0, h * s + step, step), np.arange(0, w * s + step, step)
    ys, xs = np.meshgrid(gy, gx, indexing="ij")
    pix = np.column_stack([(xs.ravel() + 0.5) / s - 0.5, (ys.ravel() + 0.5) / s - 0.5])
    coarse = cv2.undistortPoints(pix.reshape(-1, 1, 2), camera.K, camera.dist,
                                 criteria=_UNDISTORT_CRITERIA).reshape(len(gy), len(gx), 2)
    mx, my = np.meshgrid(np.arange(w * s, dtype=np.float32) / step, np.arange(h * s, dtype=np.float32) / step)
    xn = cv2.remap(np.ascontiguousarray(coarse[..., 0], np.float32), mx, my, cv2.INTER_LINEAR)
    yn = cv2.remap(np.ascontiguousarray(coarse[..., 1], np.float32), mx, my, cv2.INTER_LINEAR)
    R = cv2.Rodrigues(np.asarray(board_rvec, np.float64))[0]
    # the board plane maps to normalised image coordinates by H = [r1 r2 t]; invert it per pixel
    Hi = np.linalg.inv(np.column_stack([R[:, 0], R[:, 1], np.asarray(board_t_mm, np.float64)]))
    den = Hi[2, 0] * xn + Hi[2, 1] * yn + Hi[2, 2]
    behind = den <= 0
    den[behind] = 1.0
    u = (Hi[0, 0] * xn + Hi[0, 1] * yn + Hi[0, 2]) / den * px_per_mm + origin[0]
    v = (Hi[1, 0] * xn + Hi[1, 1] * yn + Hi[1, 2]) / den * px_per_mm + origin[1]
    u[behind] = -1e6
    v[behind] = -1e6
    big = cv2.remap(tex, u.astype(np.float32), v.astype(np.float32), cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_CONSTANT, borderValue=int(background))
    return cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA) if s > 1 else big

"""Boards and corner detection in still images and video frames."""

from __future__ import annotations

import cv2
import numpy as np

from saddlescope.core.calibration.refinement import _as_gray, _refine_full_resolution, _subpix, _unscale
from saddlescope.core.calibration.views import MIN_CORNERS
from saddlescope.core.errors import InputError
from saddlescope.core.types import Board

__all__ = ["BoardFinder", "canonical_checkerboard_order", "find_board_corners", "make_board"]


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

"""The checkerboard: found by OpenCV's detectors at one or two sizes, its corners in a canonical order."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import cv2
import numpy as np

from saddlescope.core.calibration.boards.protocol import BoardOption, grid_from_meta, grid_meta
from saddlescope.core.calibration.refinement import refine_corners_subpixel, search_downscaled, unscale_px
from saddlescope.core.types import Board

__all__ = ["BOARD_TYPE", "KIND", "CheckerboardFinder", "CheckerboardType", "canonical_checkerboard_order"]

KIND = "checkerboard"


class CheckerboardType:
    """The plain checkerboard (:class:`~saddlescope.core.calibration.boards.protocol.BoardType`)."""

    kind = KIND
    label = "checkerboard"
    short = "black and white squares: the simplest to print; every square must be in view"
    trackable = True
    options: tuple[BoardOption, ...] = ()
    # the detector also searches a 2x enlarged frame for smaller squares, but finds them less often and
    # less exactly
    min_square_px = 8

    def from_meta(self, meta: Mapping[str, Any]) -> Board:
        """The validated board of a board section (kind, inner_corners, square_mm)."""
        inner_corners, square_mm = grid_from_meta(meta)
        return Board(self.kind, inner_corners, square_mm)

    def to_meta(self, board: Board) -> dict[str, Any]:
        """The board section of a board."""
        return grid_meta(board)

    def describe(self, board: Board) -> str:
        """The board in words: checkerboard, 9 × 6 inner corners, squares 50 mm."""
        cols, rows = board.inner_corners
        return f"{self.label}, {cols} \u00d7 {rows} inner corners, squares {board.square_mm:g} mm"

    def meta_problems(self, meta: Mapping[str, Any]) -> list[str]:
        """None: the schema states all a checkerboard's section needs."""
        return []

    def object_points_mm(self, board: Board) -> np.ndarray:
        """Inner-corner coordinates, shape (cols*rows, 3) mm, row-major as OpenCV returns them."""
        return board.object_points_mm()

    def detector(self, board: Board, *, inverted: bool | None = None, max_width: int = 1000,
                 thorough: bool = True) -> CheckerboardFinder:
        """A :class:`CheckerboardFinder` (a checkerboard has no print polarity: ``inverted`` is ignored)."""
        return CheckerboardFinder(board, max_width=max_width, thorough=thorough)

    def half_turn_ids(self, board: Board, ids: np.ndarray) -> np.ndarray | None:
        """Ids (N,) counted from the opposite corner where cols + rows is even, else None.

        A board with cols + rows even is alike after a half turn: :func:`canonical_checkerboard_order`
        cannot tell its ends apart.
        """
        cols, rows = board.inner_corners
        if (cols + rows) % 2 != 0:
            return None
        return cols * rows - 1 - ids

    def cv_board(self, board: Board) -> None:
        """None: OpenCV's checkerboard detectors take the pattern size only."""
        return None

    def texture(self, board: Board, *, px_per_square: int = 40) -> tuple[np.ndarray, float, np.ndarray]:
        """Image of the board with a one-square white margin.

        Returns
        -------
        texture : ndarray of shape (H, W), uint8
        px_per_mm : float
        origin_px : ndarray of shape (2,), the texture pixel of inner corner 0
        """
        cols, rows = board.inner_corners
        sq = int(px_per_square)
        tex = np.full(((rows + 3) * sq, (cols + 3) * sq), 255, np.uint8)
        for j in range(rows + 1):
            for i in range(cols + 1):
                if (i + j) % 2 == 0:  # the square left of and above corner 0 is dark (canonical order)
                    tex[(j + 1) * sq:(j + 2) * sq, (i + 1) * sq:(i + 2) * sq] = 0
        origin = np.array([2 * sq, 2 * sq], np.float64)
        return tex, sq / board.square_mm, origin - 0.5


BOARD_TYPE = CheckerboardType()


class CheckerboardFinder:
    """Finds a checkerboard in the grey frames of one camera.

    In video the board is usually near where it was: that region is searched first. A board far away
    has squares of a few pixels, found only on a frame upsampled 2x: the size that worked is tried
    first in the next frame.

    Parameters
    ----------
    board : Board
    max_width : int
        Frames wider than this are searched downscaled first, then refined at full resolution.
    thorough : bool
        Also try ``findChessboardCornersSB``'s exhaustive mode and the full classic detector (about a
        second per frame without a board): right for a few still images; for video frames (many,
        mostly alike) False keeps a frame to tens of milliseconds.
    """

    def __init__(self, board: Board, *, max_width: int = 1000, thorough: bool = True):
        self.board = board
        self.max_width = int(max_width)
        self.thorough = bool(thorough)
        self._upsample = 1.0
        self.refine_scale = 1.0  # of the last board found: the scale its corners were refined at
        self._last_box: tuple[int, int, int, int] | None = None

    def __call__(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Corners (N, 2) px and ids (N,) of the board in ``gray`` (H, W) uint8, or None."""
        if self._last_box is not None:
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
        found, refined_here = search_downscaled(gray, self.board, self.max_width, self._find)
        if found is not None:
            self.refine_scale = 1.0 if refined_here else self._upsample
        return found

    def _find(self, gray):
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
                    corners = unscale_px(corners, up)  # refined by cornerSubPix on the upsampled frame
                return corners, ids
        return None


def _find_checkerboard(gray: np.ndarray, board: Board, *, thorough: bool = True, upsampled: bool = False):
    corners = _checkerboard_corners(gray, board, thorough=thorough)
    if corners is None:
        return None
    # cornerSubPix with a window scaled to the squares: on Bouguet's images it halves SB's residuals
    corners = refine_corners_subpixel(gray, corners, board, upsampled=upsampled)
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

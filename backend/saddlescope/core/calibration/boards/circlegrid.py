"""The asymmetric circle grid: OpenCV's ``acircles`` pattern of black dots, found by ``findCirclesGrid``.

Rows of ``cols`` circles, ``square_mm`` apart; every other row is shifted by ``square_mm``, so circles
in a row are ``2 * square_mm`` apart (OpenCV's calibration sample and ``gen_pattern.py``: pattern 4 x 11).
``inner_corners`` is (circles in a row, rows). The rows must be odd in number: a grid of an even number
of rows looks alike turned half round and OpenCV numbers its circles either way. Dots keep their centre
under blur, where a checkerboard's corners smear; every circle must be in view for the grid to be found.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import cv2
import numpy as np

from saddlescope.core.calibration.boards.protocol import (
    BoardOption,
    grid_from_meta,
    grid_meta,
    option_number,
    read_options,
)
from saddlescope.core.errors import InputError
from saddlescope.core.types import Board

__all__ = ["BOARD_TYPE", "KIND", "CircleGridFinder", "CircleGridType", "circle_centres_mm"]

KIND = "acircles"
_DEFAULT_CIRCLE_SCALE = 0.5  # circle diameter, of square_mm (gen_pattern.py draws 0.4)
_MIN_CIRCULARITY = 0.8  # a quadrilateral (the board's own outline, one threshold's blob) is at most pi/4


def circle_centres_mm(board: Board) -> np.ndarray:
    """Circle centres on the board, shape (cols*rows, 3) mm, row by row as ``findCirclesGrid`` numbers them.

    Circle (i, j), i-th of row j, is at ((2 i + j mod 2) square_mm, j square_mm).
    """
    cols, rows = board.inner_corners
    j, i = np.mgrid[0:rows, 0:cols]
    xy = np.column_stack([(2 * i + j % 2).ravel(), j.ravel()]) * board.square_mm
    return np.column_stack([xy, np.zeros(len(xy))]).astype(np.float64)


class CircleGridType:
    """The asymmetric circle grid (:class:`~saddlescope.core.calibration.boards.protocol.BoardType`)."""

    kind = KIND
    label = "asymmetric circle grid"
    short = ("rows of black dots, every other row shifted (OpenCV's acircles pattern: circles in a row \u00d7 rows, "
             "an odd number of rows): dots stay sharp under motion blur; every dot must be in view")
    trackable = False
    options = (BoardOption("circle_mm", "number", "Circle diameter (mm)", unset="0.5 \u00d7 spacing",
                           greater_than=0, at_most=10_000),)
    # dots 3 px across (spacing 6 px) are found in sharp renders; twice that leaves room for blur and noise
    min_square_px = 10

    def from_meta(self, meta: Mapping[str, Any]) -> Board:
        """The validated board of a board section (kind, inner_corners, square_mm, circle_mm)."""
        (cols, rows), square_mm = grid_from_meta(meta)
        if cols < 3 or rows < 5 or rows % 2 == 0:
            raise InputError(f"an asymmetric circle grid of {cols} x {rows}: it needs at least 3 circles a row and "
                             "an odd number of rows, at least 5 (e.g. 4 x 11): an even number of rows looks "
                             "alike turned half round")
        options = read_options(meta, self.options, {"circle_mm": _DEFAULT_CIRCLE_SCALE * square_mm})
        circle_mm = float(dict(options)["circle_mm"])
        if not 0 < circle_mm < square_mm:
            raise InputError(f"circle diameter {circle_mm:g} mm must be between 0 and the spacing of the rows "
                             f"({square_mm:g} mm)")
        return Board(self.kind, (cols, rows), square_mm, options=options)

    def to_meta(self, board: Board) -> dict[str, Any]:
        """The board section of a board."""
        return grid_meta(board)

    def describe(self, board: Board) -> str:
        """The board in words: asymmetric circle grid, 4 × 11 circles, rows 20 mm apart, circles of 10 mm."""
        cols, rows = board.inner_corners
        return (f"{self.label}, {cols} \u00d7 {rows} circles (a row \u00d7 rows), rows {board.square_mm:g} mm "
                f"apart, circles of {option_number(board, 'circle_mm', _DEFAULT_CIRCLE_SCALE * board.square_mm):g} mm")

    def meta_problems(self, meta: Mapping[str, Any]) -> list[str]:
        """The circles must be smaller than the rows' spacing."""
        circle, square = meta.get("circle_mm"), meta.get("square_mm")
        if isinstance(circle, int | float) and isinstance(square, int | float) and circle >= square:
            return [f"board.circle_mm ({circle}) must be smaller than board.square_mm ({square})"]
        return []

    def object_points_mm(self, board: Board) -> np.ndarray:
        """Circle centres (cols*rows, 3) mm (:func:`circle_centres_mm`)."""
        return circle_centres_mm(board)

    def detector(self, board: Board, *, inverted: bool | None = None, max_width: int = 1000,
                 thorough: bool = True) -> CircleGridFinder:
        """A :class:`CircleGridFinder` (black dots on white: ``inverted``, ``max_width``, ``thorough`` are ignored)."""
        return CircleGridFinder(board)

    def half_turn_ids(self, board: Board, ids: np.ndarray) -> np.ndarray | None:
        """None: with an odd number of rows the grid is unlike itself turned half round."""
        return None

    def cv_board(self, board: Board) -> None:
        """None: ``findCirclesGrid`` takes the pattern size only."""
        return None

    def texture(self, board: Board, *, px_per_square: int = 40) -> tuple[np.ndarray, float, np.ndarray]:
        """Image of the board, the centres two spacings in from its edges (as a checkerboard's corners).

        Returns
        -------
        texture : ndarray of shape (H, W), uint8
        px_per_mm : float
        origin_px : ndarray of shape (2,), the texture pixel of circle 0's centre
        """
        cols, rows = board.inner_corners
        sq = int(px_per_square)
        px_per_mm = sq / board.square_mm
        tex = np.full(((rows - 1) * sq + 4 * sq, (2 * cols - 1) * sq + 4 * sq), 255, np.uint8)
        shift = 4  # cv2.circle's fractional bits: centres and radius to 1/16 px
        radius = int(round(0.5 * option_number(board, "circle_mm", _DEFAULT_CIRCLE_SCALE * board.square_mm)
                           * px_per_mm * (1 << shift)))
        for x, y, _ in circle_centres_mm(board) * px_per_mm:
            centre = (int(round((x + 2 * sq - 0.5) * (1 << shift))), int(round((y + 2 * sq - 0.5) * (1 << shift))))
            cv2.circle(tex, centre, radius, 0, -1, cv2.LINE_AA, shift)
        return tex, px_per_mm, np.array([2 * sq, 2 * sq], np.float64) - 0.5


BOARD_TYPE = CircleGridType()


class CircleGridFinder:
    """Finds an asymmetric circle grid in grey frames: all of its circles, numbered as the board's.

    Parameters
    ----------
    board : Board
    """

    def __init__(self, board: Board):
        self.board = board
        self._detectors: dict[tuple[int, int], cv2.SimpleBlobDetector] = {}

    def __call__(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Centres (N, 2) px and ids (N,) of the board's circles in ``gray`` (H, W) uint8, or None."""
        found, centres = cv2.findCirclesGrid(gray, tuple(self.board.inner_corners),
                                             flags=cv2.CALIB_CB_ASYMMETRIC_GRID,
                                             blobDetector=self._blob_detector(gray.shape))
        if not found:
            return None
        # numbered row by row from the corner circle_centres_mm numbers 0, at any turn of the board: an odd
        # number of rows leaves OpenCV one way to fit the grid to the dots (the tests turn it all round)
        xy = np.ascontiguousarray(centres.reshape(-1, 2), dtype=np.float64)
        return xy, np.arange(len(xy))

    def _blob_detector(self, shape: tuple[int, ...]) -> cv2.SimpleBlobDetector:
        key = (int(shape[0]), int(shape[1]))
        if key not in self._detectors:
            cols, rows = self.board.inner_corners
            params = cv2.SimpleBlobDetector.Params()
            params.minArea = 3.0  # dots of 2-3 px (spacing 5 px) are still found in a sharp frame
            # a dot is far smaller than a frame's share of the board: larger blobs (the board's white, seen
            # as one threshold's hole) would pull the nearest dot's centre off
            params.maxArea = key[0] * key[1] / (2.0 * cols * rows)
            params.minDistBetweenBlobs = 1.0
            params.filterByCircularity = True
            params.minCircularity = _MIN_CIRCULARITY
            self._detectors[key] = cv2.SimpleBlobDetector.create(params)
        return self._detectors[key]

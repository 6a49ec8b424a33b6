"""The ChArUco board: a checkerboard with ArUco markers in its white squares (normal, legacy or inverted print).

Its corners are found frame by frame, each by its id: part of the board may be hidden. ``inner_corners``
is (squares_x - 1, squares_y - 1); ``marker_mm`` defaults to 0.75 of the square (caliscope's
``aruco_scale``), ``dictionary`` to ``DICT_4X4_50``.
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
from saddlescope.core.calibration.refinement import search_downscaled
from saddlescope.core.calibration.views import MIN_POSE_CORNERS
from saddlescope.core.errors import InputError
from saddlescope.core.types import Board

__all__ = ["ARUCO_DICTIONARIES", "BOARD_TYPE", "KIND", "CharucoFinder", "CharucoType"]

KIND = "charuco"
_DEFAULT_DICTIONARY = "DICT_4X4_50"
# The ArUco dictionaries this OpenCV knows (the names its `cv2.aruco` module gives them).
ARUCO_DICTIONARIES = tuple(sorted(name for name in dir(cv2.aruco)
                                  if name.startswith("DICT_") and isinstance(getattr(cv2.aruco, name), int)))
_DEFAULT_MARKER_SCALE = 0.75  # of the square


class CharucoType:
    """The ChArUco board (:class:`~saddlescope.core.calibration.boards.protocol.BoardType`)."""

    kind = KIND
    label = "ChArUco"
    short = ("a checkerboard with small square codes (ArUco markers) in its white squares: found when partly "
             "hidden or at the frame's edge")
    trackable = False
    options = (
        BoardOption("dictionary", "text", "Marker dictionary", unset=_DEFAULT_DICTIONARY,
                    pattern=r"^DICT_[A-Za-z0-9_]+$", max_length=40, required=True,
                    offered=(_DEFAULT_DICTIONARY, "DICT_4X4_100", "DICT_5X5_100", "DICT_6X6_250")),
        BoardOption("marker_mm", "number", "Marker size (mm)", unset="0.75 \u00d7 square", greater_than=0,
                    at_most=10_000, required=True),
        BoardOption("legacy", "flag", "Printed in OpenCV's legacy pattern (before 4.6)"),
    )
    min_square_px = 16  # its markers' cells are an eighth of a square and need 2 px each

    def from_meta(self, meta: Mapping[str, Any]) -> Board:
        """The validated board of a board section.

        Fields: kind, inner_corners, square_mm, dictionary, marker_mm, legacy; a missing or None field
        takes its default.
        """
        inner_corners, square_mm = grid_from_meta(meta)
        options = dict(read_options(meta, self.options, {"dictionary": _DEFAULT_DICTIONARY,
                                                         "marker_mm": _DEFAULT_MARKER_SCALE * square_mm,
                                                         "legacy": False}))
        if options["dictionary"] not in ARUCO_DICTIONARIES:
            raise InputError(f"board.dictionary {options['dictionary']!r} is not an OpenCV ArUco dictionary; the "
                             f"dictionaries are {', '.join(ARUCO_DICTIONARIES)}")
        marker_mm = float(options["marker_mm"])
        if not 0 < marker_mm < square_mm:
            raise InputError(f"ChArUco marker size {marker_mm} mm must be between 0 and the square "
                             f"({square_mm} mm)")
        return Board(self.kind, inner_corners, square_mm, options=tuple(options.items()))

    def to_meta(self, board: Board) -> dict[str, Any]:
        """The board section of a board."""
        return grid_meta(board)

    def describe(self, board: Board) -> str:
        """The board in words: ChArUco, 7 × 5 inner corners, squares 30 mm, markers 22 mm, DICT_4X4_50."""
        cols, rows = board.inner_corners
        return (f"{self.label}, {cols} \u00d7 {rows} inner corners, squares {board.square_mm:g} mm, markers "
                f"{option_number(board, 'marker_mm', _DEFAULT_MARKER_SCALE * board.square_mm):g} mm, "
                f"{board.option('dictionary', _DEFAULT_DICTIONARY)}")

    def meta_problems(self, meta: Mapping[str, Any]) -> list[str]:
        """The markers must be smaller than the squares they sit in."""
        marker, square = meta.get("marker_mm"), meta.get("square_mm")
        if isinstance(marker, int | float) and isinstance(square, int | float) and marker >= square:
            return [f"board.marker_mm ({marker}) must be smaller than board.square_mm ({square})"]
        return []

    def object_points_mm(self, board: Board) -> np.ndarray:
        """Inner-corner coordinates, shape (cols*rows, 3) mm, indexed by OpenCV's ChArUco corner ids."""
        return board.object_points_mm()

    def detector(self, board: Board, *, inverted: bool | None = None, max_width: int = 1000,
                 thorough: bool = True) -> CharucoFinder:
        """A :class:`CharucoFinder` (one detector for still images and video: ``thorough`` is ignored)."""
        return CharucoFinder(board, inverted=inverted, max_width=max_width)

    def half_turn_ids(self, board: Board, ids: np.ndarray) -> np.ndarray | None:
        """None: the markers tell the board's ends apart (``ids`` of shape (N,) need no relabelling)."""
        return None

    def cv_board(self, board: Board) -> cv2.aruco.CharucoBoard:
        """OpenCV's ``CharucoBoard`` of the board (its squares are ``inner_corners`` + 1)."""
        cols, rows = board.inner_corners
        name = str(board.option("dictionary", _DEFAULT_DICTIONARY))
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
        marker_mm = option_number(board, "marker_mm", _DEFAULT_MARKER_SCALE * board.square_mm)
        cv_board = cv2.aruco.CharucoBoard((cols + 1, rows + 1), float(board.square_mm), marker_mm, dictionary)
        cv_board.setLegacyPattern(bool(board.option("legacy", False)))
        return cv_board

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
        size = ((cols + 1) * sq + 2 * sq, (rows + 1) * sq + 2 * sq)
        tex = self.cv_board(board).generateImage(size, marginSize=sq, borderBits=1)
        origin = np.array([2 * sq, 2 * sq], np.float64)  # margin + first square
        return tex, sq / board.square_mm, origin - 0.5


BOARD_TYPE = CharucoType()


class CharucoFinder:
    """Finds a ChArUco board in grey frames; remembers its print polarity once seen.

    Parameters
    ----------
    board : Board
    inverted : bool or None
        Printed white-on-black (caliscope's ``inverted = true``); None tries both.
    max_width : int
        Frames wider than this are searched downscaled first, then refined at full resolution.
    """

    def __init__(self, board: Board, *, inverted: bool | None = None, max_width: int = 1000):
        self.board = board
        self.inverted = inverted
        self.max_width = int(max_width)
        self._cv_board = BOARD_TYPE.cv_board(board)
        self._detector = cv2.aruco.CharucoDetector(self._cv_board)

    def __call__(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Corners (N, 2) px and ids (N,) of the board in ``gray`` (H, W) uint8, or None."""
        found, _ = search_downscaled(gray, self.board, self.max_width, self._find)
        return found

    def _find(self, gray):
        polarities = [self.inverted] if self.inverted is not None else [False, True]
        for inverted in polarities:
            found = self._find_charuco(255 - gray if inverted else gray)
            if found is not None:
                self.inverted = inverted
                return found
        return None

    def _find_charuco(self, gray):
        corners, ids, _, _ = self._detector.detectBoard(gray)
        if ids is None or len(ids) < MIN_POSE_CORNERS:  # partial views count for the board's pose
            return None
        ids = ids.ravel().astype(np.int64)
        if self._cv_board.checkCharucoCornersCollinear(ids.reshape(-1, 1).astype(np.int32)):
            return None  # a line of corners says nothing about a plane's pose
        return corners.reshape(-1, 2).astype(np.float64), ids

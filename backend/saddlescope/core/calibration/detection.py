"""Corner detection of any registered board kind in still images and video frames."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace

import numpy as np

from saddlescope.core.calibration.boards import board_type
from saddlescope.core.calibration.refinement import _as_gray
from saddlescope.core.types import Board

__all__ = ["BoardFinder", "find_board_corners", "squares_hint"]


class BoardFinder:
    """Finds one board in grey frames with its kind's detector.

    The detector learns from frame to frame: where a checkerboard was and at which size it was found,
    a ChArUco board's print polarity.

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
        self.detector = board_type(board.kind).detector(board, inverted=inverted, max_width=int(max_width),
                                                        thorough=bool(thorough))

    def __call__(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Corners (N, 2) px and ids (N,) of the board in ``gray`` (H, W) uint8 (or BGR), or None."""
        return self.detector(_as_gray(gray))


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
    corners come in a canonical order (see
    :func:`~saddlescope.core.calibration.boards.checkerboard.canonical_checkerboard_order`), all of them.
    """
    return BoardFinder(board, inverted=inverted)(gray)


SQUARES_HINT_FRAMES = 60  # frames searched for the board one corner smaller (only where no board was found)


def squares_hint(frames: Iterable[np.ndarray], board: Board, *, inverted: bool | None = None) -> str:
    """The sentence to say where a board's pattern was given in squares, not inner corners; else "".

    A board of C x R squares has (C - 1) x (R - 1) inner corners (OpenCV's pattern size; caliscope's
    ``columns`` and ``rows`` count squares). Where the board one corner smaller in each direction is found in
    one of the first :data:`SQUARES_HINT_FRAMES` ``frames`` (grey images), that is the pattern to use.
    """
    cols, rows = board.inner_corners
    if cols < 3 or rows < 3:
        return ""
    smaller = replace(board, inner_corners=(cols - 1, rows - 1))
    finder = BoardFinder(smaller, inverted=inverted, thorough=False)
    for n, gray in enumerate(frames):
        if n >= SQUARES_HINT_FRAMES:
            break
        if finder(gray) is not None:
            return (f"this board has {cols}x{rows} squares, i.e. {cols - 1}x{rows - 1} inner corners: use "
                    f"--pattern {cols - 1}x{rows - 1} (the pattern counts inner corners, not squares)")
    return ""

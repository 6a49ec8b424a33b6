"""The protocol every calibration board type implements, and the grid fields all of them share.

A board type tells the rest of SaddleScope everything that differs between kinds of board: how a
ride.json ``board`` section describes it, where its corners are, how to find them in a frame, how it
looks when printed or rendered. Every board is a plane of inner corners on a grid of
``inner_corners`` = (cols, rows), ``square_mm`` apart, with ids numbering them row-major
(:meth:`~saddlescope.core.types.Board.object_points_mm`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.types import Board

__all__ = ["BoardDetector", "BoardType", "grid_from_meta", "grid_meta"]


class BoardDetector(Protocol):
    """Finds one board in the grey frames of one camera, remembering what it learnt between frames."""

    def __call__(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The board's corners in one frame.

        Parameters
        ----------
        gray : ndarray of shape (H, W), uint8

        Returns
        -------
        (corners_px, ids) of shapes (N, 2) and (N,), or None where the board is not found.
        """


class BoardType(Protocol):
    """One kind of calibration board.

    Attributes
    ----------
    kind : str
        Its name in ride.json's ``board.kind``, the API and ``saddlescope calibrate --board``.
    label : str
        Its name in sentences (e.g. "ChArUco").
    trackable : bool
        Every inner corner is an x-junction of alternating squares and all of them are found at once
        (a plain checkerboard): :class:`~saddlescope.core.calibration.tracking.BoardTracker` can follow
        it from frame to frame of a video.
    meta_schema : Mapping
        JSON schema of the fields a board section of this kind adds to kind, inner_corners and
        square_mm: their ``properties`` and the ``required`` ones.
    """

    kind: str
    label: str
    trackable: bool
    meta_schema: Mapping[str, Any]

    def from_meta(self, meta: Mapping[str, Any]) -> Board:
        """The validated board of a board section (kind, inner_corners, square_mm and its own fields).

        Raises
        ------
        InputError
            A field out of range; KeyError, TypeError or ValueError for a missing or malformed one.
        """

    def to_meta(self, board: Board) -> dict[str, Any]:
        """The board section of a board (JSON types only), as :meth:`from_meta` reads it."""

    def meta_problems(self, meta: Mapping[str, Any]) -> list[str]:
        """Problems of a board section that its JSON schema cannot state, naming the fields (``board.x``)."""

    def object_points_mm(self, board: Board) -> np.ndarray:
        """Corner coordinates on the board.

        Returns
        -------
        ndarray of shape (cols*rows, 3), mm, z = 0, indexed by the corners' ids.
        """

    def detector(self, board: Board, *, inverted: bool | None, max_width: int, thorough: bool) -> BoardDetector:
        """A detector of the board in the frames of one camera.

        ``inverted``: print polarity where the kind has one (None tries both); ``max_width``: frames
        wider than this are searched downscaled first; ``thorough``: also the slow detectors (for a few
        still images rather than many video frames).
        """

    def half_turn_ids(self, board: Board, ids: np.ndarray) -> np.ndarray | None:
        """The ids of the same corners labelled from the opposite end, or None.

        Parameters
        ----------
        ids : ndarray of shape (N,)

        Returns
        -------
        ndarray of shape (N,) where a half turn of the board leaves its pattern alike (the detector may
        have labelled it from either end), else None.
        """

    def cv_board(self, board: Board) -> Any | None:
        """The OpenCV board object (``cv2.aruco.CharucoBoard`` ...) where OpenCV needs one, else None."""

    def texture(self, board: Board, *, px_per_square: int) -> tuple[np.ndarray, float, np.ndarray]:
        """Image of the board with a one-square white margin, for printing and rendering.

        Returns
        -------
        texture : ndarray of shape (H, W), uint8
        px_per_mm : float
        origin_px : ndarray of shape (2,), the texture pixel of board point (0, 0) (inner corner 0)
        """


def grid_from_meta(meta: Mapping[str, Any]) -> tuple[tuple[int, int], float]:
    """The validated inner corners (cols, rows) and square size (mm) of a board section.

    Raises
    ------
    InputError
        Fewer than 2 x 2 inner corners, or a square size that is not positive.
    """
    cols, rows = (int(v) for v in meta["inner_corners"])
    if cols < 2 or rows < 2:
        raise InputError(f"board inner corners {cols}x{rows}: need at least 2x2")
    square_mm = float(meta["square_mm"])
    if not np.isfinite(square_mm) or square_mm <= 0:
        raise InputError(f"board square size {square_mm:g} mm must be positive")
    return (cols, rows), square_mm


def grid_meta(board: Board) -> dict[str, Any]:
    """The fields every board section has: kind, inner_corners and square_mm."""
    return {"kind": board.kind, "inner_corners": list(board.inner_corners), "square_mm": board.square_mm}

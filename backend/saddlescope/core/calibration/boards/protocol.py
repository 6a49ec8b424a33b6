"""The protocol every calibration board type implements, and the grid fields all of them share.

A board type tells the rest of SaddleScope everything that differs between kinds of board: how a
ride.json ``board`` section describes it (the grid and its own typed fields, :class:`BoardOption`),
where its points are, how to find them in a frame, how it looks when printed or rendered. Every board
is a plane of points counted on a grid of ``inner_corners`` = (cols, rows), ``square_mm`` apart, with
ids numbering them row-major.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.types import Board, BoardOptionValue

__all__ = ["BoardDetector", "BoardOption", "BoardType", "grid_from_meta", "grid_meta", "option_number",
           "options_schema", "read_options"]

_FLAG_WORDS = {"true": True, "yes": True, "1": True, "false": False, "no": False, "0": False}


@dataclass(frozen=True)
class BoardOption:
    """One field a kind of board adds to a board section's kind, inner_corners and square_mm.

    The API's board, ride.json's schema, ``saddlescope calibrate --board-option`` and the rig page's form
    are all made from these declarations.

    Attributes
    ----------
    name : its key in the board section (``marker_mm``); a unit suffix where it has one.
    value : "number", "text" or "flag" (a JSON number, string or boolean).
    label : how the rig page asks for it ("Marker size (mm)").
    unset : what leaving it out means ("0.75 x square"); "" where it must be given.
    greater_than, at_most : a number's bounds (exclusive below, inclusive above), None for none.
    pattern, max_length : a text's regular expression and length.
    offered : a text's values the rig page offers, the default first (others may be typed elsewhere).
    required : ride.json must state it (the API and the CLI leave it to the kind's default).
    """

    name: str
    value: Literal["number", "text", "flag"]
    label: str
    unset: str = ""
    greater_than: float | None = None
    at_most: float | None = None
    pattern: str | None = None
    max_length: int | None = None
    offered: tuple[str, ...] = ()
    required: bool = False

    def json_schema(self) -> dict[str, Any]:
        """The JSON schema of its value (ride.json's board section)."""
        if self.value == "flag":
            return {"type": "boolean"}
        if self.value == "text":
            schema: dict[str, Any] = {"type": "string"}
            if self.pattern is not None:
                schema["pattern"] = self.pattern
            if self.max_length is not None:
                schema["maxLength"] = self.max_length
            return schema
        schema = {"type": "number"}
        if self.greater_than is not None:
            schema["exclusiveMinimum"] = self.greater_than
        if self.at_most is not None:
            schema["maximum"] = self.at_most
        return schema

    def parse(self, text: str) -> BoardOptionValue:
        """Its value from a command line's text.

        Raises
        ------
        InputError
            Not a number, a flag word or a text of its form (naming the option).
        """
        if self.value == "flag":
            if text.strip().lower() not in _FLAG_WORDS:
                raise InputError(f"board option {self.name} is a flag: true or false, not {text!r}")
            return _FLAG_WORDS[text.strip().lower()]
        if self.value == "text":
            if self.pattern is not None and not re.search(self.pattern, text):
                raise InputError(f"board option {self.name} {text!r} is not of the form {self.pattern}")
            return text
        try:
            number = float(text)
        except ValueError:
            raise InputError(f"board option {self.name} is a number, not {text!r}") from None
        if not np.isfinite(number) or (self.greater_than is not None and number <= self.greater_than):
            raise InputError(f"board option {self.name} must be a number greater than {self.greater_than:g}")
        return number


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
    short : str
        What it is and when to choose it, in a sentence (the rig page's form).
    trackable : bool
        Every inner corner is an x-junction of alternating squares and all of them are found at once
        (a plain checkerboard): :class:`~saddlescope.core.calibration.tracking.BoardTracker` can follow
        it from frame to frame of a video.
    options : tuple of BoardOption
        The fields a board section of this kind adds to kind, inner_corners and square_mm.
    min_square_px : int
        Pixels one ``square_mm`` must cover in a frame for the board to be found surely (the print
        advice's reach of a board).
    """

    kind: str
    label: str
    short: str
    trackable: bool
    options: tuple[BoardOption, ...]
    min_square_px: int

    def from_meta(self, meta: Mapping[str, Any]) -> Board:
        """The validated board of a board section (kind, inner_corners, square_mm and its own fields).

        Raises
        ------
        InputError
            A field out of range; KeyError, TypeError or ValueError for a missing or malformed one.
        """

    def to_meta(self, board: Board) -> dict[str, Any]:
        """The board section of a board (JSON types only), as :meth:`from_meta` reads it."""

    def describe(self, board: Board) -> str:
        """The board in words, as a club checks it against the print ("checkerboard, 9 × 6 inner corners, ...")."""

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
    """The board section of a board: kind, inner_corners, square_mm and the kind's own fields."""
    return {"kind": board.kind, "inner_corners": list(board.inner_corners), "square_mm": board.square_mm,
            **dict(board.options)}


def read_options(meta: Mapping[str, Any], options: Iterable[BoardOption],
                 defaults: Mapping[str, BoardOptionValue]) -> tuple[tuple[str, BoardOptionValue], ...]:
    """A board's ``options`` from a board section: each declared field as its JSON type, else its default.

    A field missing or None takes ``defaults[name]``; a field without a value or a default is left out.

    Raises
    ------
    TypeError
        A field of the wrong JSON type (naming it).
    """
    out: list[tuple[str, BoardOptionValue]] = []
    for option in options:
        value = meta.get(option.name)
        if value is None:
            if option.name in defaults:
                out.append((option.name, defaults[option.name]))
            continue
        if option.value == "number":
            if isinstance(value, bool) or not isinstance(value, int | float | str):
                raise TypeError(f"board.{option.name} must be a number, not {value!r}")
            value = float(value)
        elif option.value == "flag":
            value = bool(value)
        elif not isinstance(value, str):
            raise TypeError(f"board.{option.name} must be a text, not {value!r}")
        out.append((option.name, value))
    return tuple(out)


def option_number(board: Board, name: str, default: float) -> float:
    """A number field of the board's kind (a size in mm ...), or ``default`` where it has none."""
    value = board.option(name)
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else float(default)


def options_schema(options: Iterable[BoardOption]) -> dict[str, Any]:
    """The JSON schema of the fields ``options`` add to a board section: their properties, the required ones."""
    options = list(options)
    return {"properties": {o.name: o.json_schema() for o in options},
            "required": [o.name for o in options if o.required]}

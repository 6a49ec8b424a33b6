"""The board types by kind: one registry that ride.json, the API, the CLI, the rig page and the calibration consult.

A board type registers itself by being a module of :mod:`saddlescope.core.calibration.boards` with a
``BOARD_TYPE``; code elsewhere (a test, a plug-in) may :func:`register` one too. The fields each kind
adds (:class:`~saddlescope.core.calibration.boards.protocol.BoardOption`) are listed here as well: the
API's board and the CLI's ``--board-option`` accept every registered kind's.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from saddlescope.core.calibration.boards.protocol import BoardOption, BoardType
from saddlescope.core.errors import InputError
from saddlescope.core.types import Board

__all__ = [
    "BOARD_KINDS",
    "DEFAULT_BOARD_KIND",
    "board_from_meta",
    "board_meta_problems",
    "board_option",
    "board_options",
    "board_to_meta",
    "board_type",
    "board_types",
    "make_board",
    "object_points_mm",
    "register",
    "unregister",
]

DEFAULT_BOARD_KIND = "checkerboard"  # a board section without a kind describes a checkerboard

# The registered kinds, the default first, then in the order they were registered. A live list
# (register and unregister change it in place), so that schemas and argument parsers holding it
# accept a kind registered after they were built; change it only through them.
BOARD_KINDS: list[str] = []

_TYPES: dict[str, BoardType] = {}


def register(board_type: BoardType, *, replace: bool = False) -> BoardType:
    """Make a board type known by its ``kind``; returns it (registering it again changes nothing).

    Raises
    ------
    InputError
        Another type of that kind is registered already (unless ``replace``), or it declares a field
        another kind declares otherwise (one name, one meaning: the API's board holds every kind's).
    """
    kind = board_type.kind
    if _TYPES.get(kind) is board_type:
        return board_type  # registered already: nothing changes
    if kind in _TYPES and not replace:
        raise InputError(f"board kind {kind!r} is registered already")
    for option in board_type.options:
        other = next((o for k, t in _TYPES.items() if k != kind for o in t.options if o.name == option.name), None)
        if other is not None and other != option:
            raise InputError(f"board kind {kind!r} declares board.{option.name} otherwise than another kind does")
    if kind == DEFAULT_BOARD_KIND and kind not in _TYPES:
        BOARD_KINDS.insert(0, kind)
    elif kind not in _TYPES:
        BOARD_KINDS.append(kind)
    _TYPES[kind] = board_type
    return board_type


def unregister(kind: str) -> None:
    """Forget a board kind (a no-op for an unknown one)."""
    if _TYPES.pop(kind, None) is not None:
        BOARD_KINDS.remove(kind)


def board_type(kind: str) -> BoardType:
    """The board type of a kind.

    Raises
    ------
    InputError
        An unknown kind, naming the known ones.
    """
    try:
        return _TYPES[kind]
    except (KeyError, TypeError):
        raise InputError(f"board kind {kind!r} is not one of {', '.join(BOARD_KINDS)}") from None


def board_types() -> list[BoardType]:
    """The registered board types, in the order of :data:`BOARD_KINDS` (the default first)."""
    return [_TYPES[kind] for kind in BOARD_KINDS]


def board_options() -> list[BoardOption]:
    """Every field a registered kind adds to a board section, once each, in the kinds' order."""
    seen: dict[str, BoardOption] = {}
    for kind in board_types():
        for option in kind.options:
            seen.setdefault(option.name, option)
    return list(seen.values())


def board_option(name: str) -> BoardOption:
    """The field ``name`` some registered kind adds.

    Raises
    ------
    InputError
        No kind declares it, naming those that are declared.
    """
    options = {option.name: option for option in board_options()}
    if name not in options:
        raise InputError(f"board option {name!r} is not one of {', '.join(options) or 'none'}")
    return options[name]


def make_board(kind: str, inner_corners: tuple[int, int], square_mm: float, **options: Any) -> Board:
    """Validated :class:`~saddlescope.core.types.Board` of a kind.

    ``options`` are the kind's own fields (:attr:`BoardType.options`, e.g. ChArUco's ``dictionary``,
    ``marker_mm``, ``legacy``; None leaves a field at its default); other kinds ignore them. For
    ChArUco, ``inner_corners`` is (squares_x - 1, squares_y - 1).
    """
    return board_type(kind).from_meta({"inner_corners": inner_corners, "square_mm": square_mm, **options})


def board_from_meta(meta: Mapping[str, Any] | None) -> Board:
    """The calibration board of a ride.json ``board`` section (or a rig's board, which has its form).

    Raises
    ------
    InputError
        No section, an unknown kind, or a field missing, malformed or out of range.
    """
    if not isinstance(meta, Mapping):
        raise InputError("ride.json has no 'board' section describing the calibration board")
    kind = board_type(str(meta.get("kind", DEFAULT_BOARD_KIND)))
    try:
        return kind.from_meta(meta)
    except InputError:
        raise  # out of range: its message names the field
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"ride.json board section is incomplete or wrong: {exc}") from None


def board_to_meta(board: Board) -> dict[str, Any]:
    """The ride.json ``board`` section of a board (what :func:`board_from_meta` reads back)."""
    return board_type(board.kind).to_meta(board)


def board_meta_problems(meta: Any) -> list[str]:
    """Problems of a board section its kind's JSON schema cannot state ([] for an unknown kind)."""
    kind = meta.get("kind", DEFAULT_BOARD_KIND) if isinstance(meta, Mapping) else None
    if not isinstance(kind, str) or kind not in _TYPES:
        return []
    return _TYPES[kind].meta_problems(meta)


def object_points_mm(board: Board) -> np.ndarray:
    """The board's corner coordinates, shape (N, 3) mm, indexed by the corners' ids."""
    return board_type(board.kind).object_points_mm(board)

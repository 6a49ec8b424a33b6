"""Calibration board types and their registry: adding a kind of board is one new module here.

A module of this package that defines ``BOARD_TYPE`` (an object implementing
:class:`~saddlescope.core.calibration.boards.protocol.BoardType`) is registered when the package is
imported: ride.json's ``board`` section and its schema, the API's boards and ``GET /api/board-types``
(the rig page's choice of kind and its fields), ``saddlescope calibrate --board`` and
``--board-option``, corner detection, printing, rendering and the calibration all find it through
:func:`board_type`, :func:`board_types` and :func:`board_options`. Its test beside the others
(``tests/core/calibration/``) is the only other file a new kind needs.
"""

import importlib
import pkgutil

from saddlescope.core.calibration.boards.protocol import (
    BoardDetector,
    BoardOption,
    BoardType,
    grid_from_meta,
    grid_meta,
    option_number,
    options_schema,
    read_options,
)
from saddlescope.core.calibration.boards.registry import (
    BOARD_KINDS,
    DEFAULT_BOARD_KIND,
    board_from_meta,
    board_meta_problems,
    board_option,
    board_options,
    board_to_meta,
    board_type,
    board_types,
    make_board,
    object_points_mm,
    register,
    unregister,
)

__all__ = [
    "BOARD_KINDS",
    "DEFAULT_BOARD_KIND",
    "BoardDetector",
    "BoardOption",
    "BoardType",
    "board_from_meta",
    "board_meta_problems",
    "board_option",
    "board_options",
    "board_to_meta",
    "board_type",
    "board_types",
    "grid_from_meta",
    "grid_meta",
    "make_board",
    "object_points_mm",
    "option_number",
    "options_schema",
    "read_options",
    "register",
    "unregister",
]


def _register_package_board_types() -> None:
    """Register the ``BOARD_TYPE`` of every module of this package.

    Modules are imported by name; :data:`BOARD_KINDS` lists the default kind first all the same.
    """
    for module_info in pkgutil.iter_modules(__path__):
        module = importlib.import_module(f"{__name__}.{module_info.name}")
        if hasattr(module, "BOARD_TYPE"):
            register(module.BOARD_TYPE)


_register_package_board_types()

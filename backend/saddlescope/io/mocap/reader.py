"""Read a motion-capture file whatever its format."""

from __future__ import annotations

from pathlib import Path

from saddlescope.core.errors import MocapFileError
from saddlescope.io.mocap.c3d import read_c3d
from saddlescope.io.mocap.data import MocapData
from saddlescope.io.mocap.trc import read_trc

__all__ = ["read_mocap"]


def read_mocap(path: str | Path) -> MocapData:
    """Read a C3D or TRC file, chosen by its extension.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    MocapData
        points of shape (F, M, 3), NaN where a marker is missing.

    Raises
    ------
    MocapFileError
        Missing, empty, truncated or malformed file, or an unknown extension.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".c3d":
        return read_c3d(path)
    if suffix == ".trc":
        return read_trc(path)
    raise MocapFileError(f"{path.name}: unknown motion-capture file type {path.suffix or '(no extension)'!r};"
                         " expected .c3d or .trc")

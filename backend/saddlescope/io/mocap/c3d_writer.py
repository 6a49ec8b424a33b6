"""C3D writing: marker trajectories as an Intel float C3D file that every reader reads whole.

The file is written here, not with ezc3d: ezc3d's writer stores at most 65,535 frames in the header
and POINT:FRAMES and silently leaves the readers the first 65,535. C3D keeps the frame count in
16-bit words; past 65,535 frames the header's last frame reads 65,535 and the true last frame is
TRIAL:ACTUAL_END_FIELD (two 16-bit words, low first), which ezc3d and the ``c3d`` package both read,
with POINT:LONG_FRAMES (a float) for readers that look there.

Layout: block 1 the header, blocks 2.. the parameter section (groups POINT, TRIAL, ANALOG), then
the points, each frame M x (x, y, z, residual) float32; a missing marker has residual -1.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.io.mocap.data import _check_tracks

__all__ = ["C3D_MAX_FRAMES", "C3D_MAX_LABEL", "write_c3d"]

_BLOCK = 512
_INTEL = 84
C3D_MAX_LABEL = 30
# TRIAL:ACTUAL_END_FIELD holds the last frame in two unsigned 16-bit words.
C3D_MAX_FRAMES = 2 ** 32 - 1


def _record(name: str, group_id: int, body: bytes, description: str = "") -> bytes:
    """One parameter-section record: name, group id, offset to the next record, body, description."""
    raw_name = name.upper().encode("ascii")
    desc = description.encode("latin-1")[:255]
    tail = body + bytes([len(desc)]) + desc
    # the offset counts from its own first byte to the next record's first byte
    return struct.pack("<bb", len(raw_name), group_id) + raw_name + struct.pack("<h", 2 + len(tail)) + tail


def _group(name: str, group_id: int, description: str) -> bytes:
    return _record(name, -group_id, b"", description)


def _param(name: str, group_id: int, kind: str, values, description: str = "") -> bytes:
    """A parameter record: ``kind`` "int16" / "uint16" (stored as 16-bit words), "float" or "str"."""
    if kind == "str":
        strings = [values] if isinstance(values, str) else list(values)
        width = max([1] + [len(s) for s in strings])
        data = b"".join(s.ljust(width).encode("latin-1") for s in strings)
        dims = [width] if isinstance(values, str) else [width, len(strings)]
        if max(dims) > 255:
            raise InputError(f"C3D parameter {name} is too large ({dims})")
        body = struct.pack("<bB", -1, len(dims)) + bytes(dims)
        return _record(name, group_id, body + data, description)
    vals = list(values)
    code, fmt = {"int16": (2, "h"), "uint16": (2, "H"), "float": (4, "f")}[kind]
    dims = [] if len(vals) == 1 else [len(vals)]
    body = struct.pack("<bB", code, len(dims)) + bytes(dims) + struct.pack(f"<{len(vals)}{fmt}", *vals)
    return _record(name, group_id, body, description)


def _parameter_section(labels, descriptions, n_frames: int, rate_hz: float, data_block: int) -> bytes:
    point, trial, analog = 1, 2, 3
    records = [
        _group("POINT", point, "3-D point parameters"),
        _param("USED", point, "int16", [len(labels)], "Number of points"),
        _param("FRAMES", point, "uint16", [min(n_frames, 65535)], "Number of frames (at most 65535)"),
        _param("DATA_START", point, "int16", [data_block], "First block of the point data"),
        _param("SCALE", point, "float", [-1.0], "Negative: float point data"),
        _param("RATE", point, "float", [float(rate_hz)], "Frames per second"),
        _param("LABELS", point, "str", list(labels), "Point labels"),
        _param("DESCRIPTIONS", point, "str", list(descriptions), "Point descriptions"),
        _param("UNITS", point, "str", "mm", "Length unit"),
        _param("X_SCREEN", point, "str", "+X", "Screen right"),
        _param("Y_SCREEN", point, "str", "+Z", "Screen up: the vertical"),
    ]
    if n_frames > 65535:
        records.append(_param("LONG_FRAMES", point, "float", [float(n_frames)], "Number of frames"))
    records += [
        _group("TRIAL", trial, "Trial"),
        _param("ACTUAL_START_FIELD", trial, "uint16", [1, 0], "First frame (two 16-bit words)"),
        _param("ACTUAL_END_FIELD", trial, "uint16", [n_frames & 0xFFFF, n_frames >> 16],
               "Last frame (two 16-bit words, low first)"),
        _group("ANALOG", analog, "Analog channels"),
        _param("USED", analog, "int16", [0], "No analog channels"),
        _param("RATE", analog, "float", [0.0], "Analog rate (no channels)"),
    ]
    # the last record's offset is 0: the section ends there
    last = records[-1]
    name_len = last[0]
    records[-1] = last[:2 + name_len] + struct.pack("<h", 0) + last[4 + name_len:]
    return b"".join(records)


def write_c3d(path: str | Path, labels, points_mm: np.ndarray, rate_hz: float, *,
                   descriptions=None) -> Path:
    """Write marker trajectories to an Intel float C3D file, every frame readable by every reader.

    Parameters
    ----------
    path : path-like
        Output file.
    labels : sequence of str, length M
        Marker names (at most 30 characters each, C3D's limit).
    points_mm : ndarray of shape (F, M, 3)
        Positions in mm; NaN marks a missing marker (written with residual -1).
    rate_hz : float
        Sampling rate.
    descriptions : sequence of str, length M, optional
        The markers' descriptions (POINT:DESCRIPTIONS).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    InputError
        Bad tracks, labels over 30 characters, more than 2**32 - 1 frames or 255 markers.
    """
    labels, pts = _check_tracks(labels, points_mm, rate_hz)
    n_frames, n_markers, _ = pts.shape
    if any(len(s) > C3D_MAX_LABEL for s in labels):
        raise InputError(f"C3D marker labels are limited to {C3D_MAX_LABEL} characters")
    if n_markers > 255:
        raise InputError(f"C3D point labels are stored in one parameter of at most 255 points, got {n_markers}")
    if n_frames > C3D_MAX_FRAMES:
        raise InputError(f"a C3D file holds at most {C3D_MAX_FRAMES} frames, got {n_frames}")
    descriptions = [str(d) for d in (descriptions or [""] * n_markers)]
    if len(descriptions) != n_markers:
        raise InputError(f"{len(descriptions)} descriptions for {n_markers} markers")
    # the parameter section's size does not depend on the data block number: size it, then write it
    n_param_blocks = -(-(4 + len(_parameter_section(labels, descriptions, n_frames, rate_hz, 0))) // _BLOCK)
    data_block = 2 + n_param_blocks
    params = _parameter_section(labels, descriptions, n_frames, rate_hz, data_block)
    section = struct.pack("<BBBB", 1, 0x50, n_param_blocks, _INTEL) + params
    section = section.ljust(n_param_blocks * _BLOCK, b"\0")

    header = bytearray(_BLOCK)
    struct.pack_into("<BBHHHHHfHHf", header, 0, 2, 0x50, n_markers, 0, 1, min(n_frames, 65535), 0, -1.0,
                     data_block, 0, float(rate_hz))
    frames = np.empty((n_frames, n_markers, 4), dtype="<f4")
    missing = np.isnan(pts).any(axis=2)
    frames[..., :3] = np.where(missing[..., None], 0.0, pts)
    frames[..., 3] = np.where(missing, -1.0, 0.0)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as fh:
        fh.write(bytes(header))
        fh.write(section)
        # no padding after the last frame: past 65,535 frames ezc3d counts the frames to the file's end
        fh.write(frames.tobytes())
    return path

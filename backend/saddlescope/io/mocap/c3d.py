"""C3D files read with the ``c3d`` package (pure Python and numpy), with what it repaired said as notes.

The ``c3d`` package reads every flavour (Intel, DEC and SGI/MIPS processors; integer and float
points) and files with faulty headers that well-kept readers tolerate: a missing or zero
POINT:DATA_START (the header's data block is used), missing POINT:SCALE / POINT:RATE (the header's
values), repeated labels, zero-length description strings. Being pure Python it cannot crash the
process on a corrupt file (ezc3d, native code, had to run in a child process for that, and it does
not read MIPS files nor the PhoeniX files of BTK's sample13). What stays ours: the one-sentence
errors for files no reader can read (empty, not C3D, truncated, corrupt parameter section), the
notes naming what was repaired, telling repeated labels apart and the file's stated vertical.
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import c3d as c3d_lib
import numpy as np

from saddlescope.core.errors import MocapFileError
from saddlescope.core.findings import Finding
from saddlescope.io.mocap.data import MocapData, _normalise_units, _read_bytes

__all__ = ["distinct_labels", "read_c3d"]

_BLOCK = 512
_C3D_KEY = 0x50
# Library warnings that say nothing the user needs, or that our own notes say in plain words.
_QUIET = ("missing parameter", "no analog data", "inconsistent data block", "no pointer available",
          "reached end of file")  # the last: our own note or error says it


def _open(data: bytes, handle, name: str):
    """The ``c3d`` package's reader on the open file, or a MocapFileError saying why not."""
    if len(data) < _BLOCK:
        raise MocapFileError(f"{name}: {len(data)} bytes is too short for a C3D header (needs {_BLOCK})")
    if data[1] != _C3D_KEY:
        raise MocapFileError(f"{name}: not a C3D file (header key byte is 0x{data[1]:02x}, expected 0x50)")
    try:
        reader = c3d_lib.Reader(handle)
    except Exception as exc:  # noqa: BLE001 - any failure of the parameter walk is a corrupt file
        raise MocapFileError(f"{name}: not a readable C3D file: its parameter section is corrupt "
                             f"({_reason(exc)})") from None
    if reader.get("POINT:USED") is None:
        # The library stops at a record whose offset points out of the section: nothing names the points.
        raise MocapFileError(f"{name}: not a readable C3D file: its parameter section is corrupt "
                             "(no POINT:USED parameter can be reached)")
    return reader


def _reason(exc: Exception) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text[:160]


def _number(reader, key: str) -> float | None:
    """A numeric parameter's first value, None where the file does not have it."""
    p = reader.get(key)
    if p is None or p.bytes_per_element == -1 or not p.bytes:
        return None
    return float(p.float_value if p.bytes_per_element == 4 else p.int16_value)


def _strings(reader, key: str) -> list[str]:
    """A character parameter as stripped strings (``KEY``, ``KEY2``, ... continued), [] if absent."""
    out: list[str] = []
    for name in [key] + [f"{key}{i}" for i in range(2, 100)]:
        p = reader.get(name)
        if p is None:
            break
        if p.bytes_per_element != -1:
            return out
        if len(p.dimensions) <= 1:
            out.append(_clean(p.bytes))
        elif p.dimensions[0] > 0:
            width = p.dimensions[0]
            out += [_clean(p.bytes[i:i + width]) for i in range(0, len(p.bytes), width)]
    return out


def _clean(raw: bytes) -> str:
    # Writers pad C3D strings with spaces or NUL bytes.
    return raw.decode("latin-1").replace("\x00", " ").strip()


def _repairs(reader) -> list[str]:
    """What the header and parameters disagree on or lack, and what was used instead."""
    header = reader.header
    notes = []
    start = _number(reader, "POINT:DATA_START")
    if start is None or start <= 1:
        what = "missing" if start is None else f"{start:.0f}"
        notes.append(f"POINT:DATA_START is {what}; the header's data block {header.data_block} was used")
    elif int(start) != header.data_block:
        notes.append(f"POINT:DATA_START ({start:.0f}) and the header's data block ({header.data_block}) "
                     "disagree; the header's was used")
    if _number(reader, "POINT:SCALE") is None:
        notes.append(f"POINT:SCALE is missing; the header's scale ({header.scale_factor:g}) was used")
    if _number(reader, "POINT:RATE") is None:
        notes.append(f"POINT:RATE is missing; the header's rate ({header.frame_rate:g} Hz) was used")
    if reader.get("POINT:UNITS") is None:
        notes.append("POINT:UNITS is missing; millimetres assumed (the C3D default)")
    return notes


def _points(reader, name: str, n_bytes: int) -> tuple[np.ndarray, list[str]]:
    """(F, M, 3) positions, NaN where the residual is negative (an invalid point), and a note or None.

    The note says the file holds fewer frames than POINT:FRAMES says but as many as its header's last frame.
    """
    declared = int(reader.frame_count)
    bytes_per_word = 4 if reader.point_scale < 0 else 2
    frame_bytes = max(1, (4 * int(reader.point_used) + int(reader.analog_used) * int(reader.analog_per_frame))
                      * bytes_per_word)
    room = max(0, n_bytes - (int(reader.header.data_block) - 1) * _BLOCK) // frame_bytes
    out = np.full((min(declared, room), int(reader.point_used), 3), np.nan)
    n = 0
    try:
        for n, (_, pts, _) in enumerate(reader.read_frames(copy=False, analog_transform=False), start=1):
            if n > out.shape[0]:
                n -= 1
                break
            valid = pts[:, 3] >= 0
            out[n - 1][valid] = pts[valid, :3]
    except Exception as exc:  # noqa: BLE001 - corrupt point data
        raise MocapFileError(f"{name}: the point data cannot be read ({_reason(exc)})") from None
    if n == declared:
        return out, []
    header_frames = int(reader.header.last_frame) - int(reader.header.first_frame) + 1
    if 0 < header_frames <= n:  # POINT:FRAMES counts one more than the header and the file hold
        return out[:header_frames], [f"POINT:FRAMES says {declared} frames, the header and the file hold "
                                     f"{header_frames}; those were read"]
    raise MocapFileError(f"{name}: truncated: the header declares {declared} frames but the file holds "
                         f"only {n}")


def read_c3d(path: str | Path) -> MocapData:
    """Read the 3-D points of a C3D file (Intel, DEC or SGI/MIPS; integer or float data).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    MocapData
        points of shape (F, M, 3), NaN where the residual is negative (invalid point); ``warnings``
        names what the reader repaired (a missing POINT:DATA_START, SCALE, RATE, repeated labels).

    Raises
    ------
    MocapFileError
        Empty, too short, truncated or malformed file (not C3D, corrupt parameter section).
    """
    path = Path(path)
    data = _read_bytes(path)
    with warnings.catch_warnings(record=True) as caught, path.open("rb") as handle:
        warnings.simplefilter("always")
        reader = _open(data, handle, path.name)
        rate = float(reader.point_rate)
        if not (math.isfinite(rate) and rate > 0):
            raise MocapFileError(f"{path.name}: the point rate ({rate}) is not a positive number")
        if not (math.isfinite(reader.point_scale) and reader.point_scale != 0):
            raise MocapFileError(f"{path.name}: the point scale factor ({reader.point_scale}) is zero or not a number")
        xyz, short = _points(reader, path.name, len(data))
    notes = [Finding("mocap.header_repaired", text) for text in _repairs(reader) + short]
    notes += [Finding("mocap.reader_note", note) for w in caught if (note := _library_note(w))]
    units = (_strings(reader, "POINT:UNITS") or [""])[0] or "mm"  # the C3D default
    xyz, units = _normalise_units(xyz, units, path.name)
    n_points = xyz.shape[1]
    stored = _strings(reader, "POINT:LABELS")[:n_points]
    stored += [f"point{j + 1}" for j in range(len(stored), n_points)]  # unnamed points still need names
    described = _strings(reader, "POINT:DESCRIPTIONS")
    descriptions = tuple(described[:n_points]) if len(described) >= n_points else ()
    labels, repeated = distinct_labels([s or f"point{j + 1}" for j, s in enumerate(stored)], descriptions)
    return MocapData(labels=labels, rate_hz=rate, points=xyz, units=units, first_frame=int(reader.first_frame),
                     source_format="c3d", source=path.name, warnings=tuple(notes) + repeated,
                     descriptions=descriptions, up_axis=_screen_up(reader))


def _library_note(w: warnings.WarningMessage) -> str | None:
    text = " ".join(str(w.message).split())
    return None if not text or text.lower().startswith(_QUIET) else f"C3D reader: {text}"


def _screen_up(reader) -> str | None:
    """The lab's vertical as the file states it: POINT:Y_SCREEN ("+Z" -> "+z"), else None."""
    text = (_strings(reader, "POINT:Y_SCREEN") or [""])[0].strip().lower()
    return text if re.fullmatch(r"[+-][xyz]", text) else None


def distinct_labels(labels: Sequence[str],
                    descriptions: Sequence[str] = ()) -> tuple[tuple[str, ...], tuple[Finding, ...]]:
    """Labels made distinct where a file repeats one, and a warning naming the repeated ones.

    Parameters
    ----------
    labels : sequence of str, length M
        The labels as stored.
    descriptions : sequence of str, length M, or empty
        The points' descriptions (C3D POINT:DESCRIPTIONS).

    Returns
    -------
    labels : tuple of str, length M
        Every repeated label told apart by its description (``"RKNE (R.Knee.Medial)"``) where the
        descriptions of its points differ, else by its rank (``"RKNE#2"``); other labels unchanged.
    warnings : tuple of Finding
        One (``mocap.repeated_labels``) when labels repeat, else empty.
    """
    labels = list(labels)
    repeated = [s for s in dict.fromkeys(labels) if labels.count(s) > 1]
    if not repeated:
        return tuple(labels), ()
    for label in repeated:
        where = [j for j, s in enumerate(labels) if s == label]
        texts = [descriptions[j].strip() if len(descriptions) == len(labels) else "" for j in where]
        by_description = all(texts) and len(set(texts)) == len(texts)
        for rank, j in enumerate(where, start=1):
            labels[j] = f"{label} ({texts[rank - 1]})" if by_description else f"{label}#{rank}"
    taken = set()
    for j, s in enumerate(labels):  # a made-up name may still meet a stored one
        labels[j] = s if s not in taken else f"{s}#{j + 1}"
        taken.add(labels[j])
    names = ", ".join(repeated)
    example = ", ".join(repr(s) for s in labels if s.startswith((repeated[0] + " (", repeated[0] + "#")))
    return tuple(labels), (Finding("mocap.repeated_labels",
                                   f"labels used by more than one marker: {names}; told apart by their descriptions "
                                   f"(POINT:DESCRIPTIONS) or rank, e.g. {example}", {"labels": len(repeated)}),)

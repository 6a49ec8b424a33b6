"""C3D files: the header and parameter section walked and validated here, the points read with ezc3d.

C3D files are read with ezc3d. Before ezc3d sees a file its header and parameter section are walked
here record by record (every offset checked against the file size), because a C++ reader can crash or
read garbage on a corrupt pointer; a file that fails the walk gets a :class:`MocapFileError` naming
what is wrong. ezc3d does not read the SGI/MIPS (big-endian) flavour of C3D, so those files are read
here from the validated parameters with numpy.
"""

from __future__ import annotations

import math
import struct
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from saddlescope.core.errors import MocapFileError
from saddlescope.core.findings import Finding
from saddlescope.io.mocap.data import MocapData, _normalise_units, _read_bytes

__all__ = ["distinct_labels", "read_c3d"]

_BLOCK = 512
_PROCESSORS = {84: "intel", 85: "dec", 86: "mips"}
_PARAM_BYTES = {-1: 1, 1: 1, 2: 2, 4: 4}


@dataclass(frozen=True)
class _C3DParam:
    type_code: int  # -1 char, 1 byte, 2 int16, 4 float
    dims: tuple[int, ...]
    raw: bytes


@dataclass(frozen=True)
class _C3DLayout:
    """What the header and parameter walk established about a C3D file."""

    processor: str
    n_points: int
    analog_per_frame: int
    first_frame: int
    n_frames: int
    scale: float
    rate_hz: float
    data_start: int  # byte offset
    labels: tuple[str, ...]
    units: str
    params: dict[tuple[str, str], _C3DParam]


class _C3DCodec:
    """Integer and float decoding for one processor type (Intel, DEC, MIPS)."""

    def __init__(self, processor: str):
        self.processor = processor
        self.endian = ">" if processor == "mips" else "<"

    def int16(self, raw: bytes, offset: int = 0) -> int:
        return struct.unpack_from(self.endian + "h", raw, offset)[0]

    def uint16(self, raw: bytes, offset: int = 0) -> int:
        return struct.unpack_from(self.endian + "H", raw, offset)[0]

    def float32(self, raw: bytes, offset: int = 0) -> float:
        b = raw[offset:offset + 4]
        if self.processor == "dec":
            # DEC F_floating: 16-bit words swapped against IEEE little-endian, exponent bias 2 higher.
            return struct.unpack("<f", b[2:4] + b[0:2])[0] / 4.0
        return struct.unpack(self.endian + "f", b)[0]


def _decode_param(codec: _C3DCodec, p: _C3DParam) -> list:
    """Values of a numeric parameter as a flat list (column-major, as stored)."""
    n = len(p.raw) // abs(p.type_code)
    if p.type_code == 1:
        return list(struct.unpack(f"{n}b", p.raw))
    if p.type_code == 2:
        return [codec.int16(p.raw, 2 * i) for i in range(n)]
    if p.type_code == 4:
        return [codec.float32(p.raw, 4 * i) for i in range(n)]
    raise ValueError("character parameter")


def _decode_strings(p: _C3DParam) -> list[str]:
    """A character parameter as a list of strings (first dimension is the string length)."""
    if p.type_code != -1:
        return []
    if len(p.dims) <= 1:
        return [_clean(p.raw)]
    width = p.dims[0]
    if width == 0:
        return []
    return [_clean(p.raw[i:i + width]) for i in range(0, len(p.raw), width)]


def _clean(raw: bytes) -> str:
    # Writers pad C3D strings with spaces or NUL bytes.
    return raw.decode("latin-1").replace("\x00", " ").strip()


def _walk_c3d(data: bytes, name: str) -> _C3DLayout:
    """Validate the C3D header and parameter section; return the layout of the point data.

    Every record offset is checked to stay inside the parameter section and move forward, so a corrupt
    file gives a clear error instead of a crash in a native reader.
    """
    size = len(data)
    if size < _BLOCK:
        raise MocapFileError(f"{name}: {size} bytes is too short for a C3D header (needs {_BLOCK})")
    if data[1] != 0x50:
        raise MocapFileError(f"{name}: not a C3D file (header key byte is 0x{data[1]:02x}, expected 0x50)")
    param_block = data[0]
    p0 = (param_block - 1) * _BLOCK
    if param_block < 2 or p0 + 4 > size:
        raise MocapFileError(f"{name}: bad parameter section pointer (block {param_block}) in the C3D header")
    processor_code = data[p0 + 3]
    if processor_code not in _PROCESSORS:
        raise MocapFileError(f"{name}: unknown C3D processor type {processor_code} at the start of the "
                             "parameter section (expected 84 Intel, 85 DEC or 86 MIPS)")
    codec = _C3DCodec(_PROCESSORS[processor_code])
    n_blocks = data[p0 + 2]
    # Some writers miscount the blocks; the file end is the hard limit.
    p_end = min(size, p0 + max(n_blocks, 1) * _BLOCK) if n_blocks else size
    params = _walk_parameters(data, name, codec, p0, p_end)
    return _point_layout(data, name, codec, params, param_block)


def _walk_parameters(data: bytes, name: str, codec: _C3DCodec, p0: int, p_end: int
                     ) -> dict[tuple[str, str], _C3DParam]:
    """The parameters of the section at bytes ``p0``-``p_end``, by (group name, parameter name)."""
    groups: dict[int, str] = {}
    pending: list[tuple[int, str, _C3DParam]] = []
    pos = p0 + 4
    while pos + 2 <= p_end:
        name_len = struct.unpack_from("b", data, pos)[0]
        if name_len == 0:
            break
        group_id, rec_name, offset, body, next_pos = _record_head(data, name, codec, pos, p0, p_end)
        if group_id < 0:
            if body + 1 > next_pos or body + 1 + data[body] > next_pos:
                raise MocapFileError(f"{name}: group {rec_name!r} overruns its record at byte {pos}")
            groups[-group_id] = rec_name.upper()
        else:
            pending.append((group_id, rec_name.upper(), _parameter_body(data, name, rec_name, pos, body, next_pos)))
        if not offset:
            break
        pos = next_pos

    params: dict[tuple[str, str], _C3DParam] = {}
    for group_id, pname, param in pending:
        if group_id not in groups:
            raise MocapFileError(f"{name}: parameter {pname!r} belongs to group {group_id}, which the "
                                 "parameter section does not define")
        params[(groups[group_id], pname)] = param
    if "POINT" not in groups.values():
        raise MocapFileError(f"{name}: the parameter section has no POINT group")
    return params


def _record_head(data: bytes, name: str, codec: _C3DCodec, pos: int, p0: int, p_end: int
                 ) -> tuple[int, str, int, int, int]:
    """Group id, name, offset to the next record, body start and next position of the record at ``pos``."""
    name_len = struct.unpack_from("b", data, pos)[0]
    group_id = struct.unpack_from("b", data, pos + 1)[0]
    n = abs(name_len)
    head_end = pos + 2 + n + 2
    if group_id == 0 or head_end > p_end:
        raise MocapFileError(f"{name}: corrupt parameter record at byte {pos} (group id {group_id}, "
                             f"name length {n})")
    rec_name = data[pos + 2:pos + 2 + n].decode("latin-1")
    if not all(33 <= ord(c) < 127 for c in rec_name):
        raise MocapFileError(f"{name}: corrupt parameter record name {rec_name[:32]!r} at byte {pos}")
    offset = codec.int16(data, pos + 2 + n)
    body = pos + 2 + n + 2
    next_pos = pos + 2 + n + offset if offset else p_end
    if offset and (offset < 2 or next_pos > p_end):
        raise MocapFileError(f"{name}: bad parameter offset {offset} for {rec_name!r} at byte {pos} "
                             f"(points outside the parameter section, bytes {p0}-{p_end})")
    return group_id, rec_name, offset, body, next_pos


def _parameter_body(data: bytes, name: str, rec_name: str, pos: int, body: int, next_pos: int) -> _C3DParam:
    """Type, dimensions and raw values of the parameter whose body starts at ``body``."""
    if body + 2 > next_pos:
        raise MocapFileError(f"{name}: parameter {rec_name!r} overruns its record at byte {pos}")
    type_code = struct.unpack_from("b", data, body)[0]
    n_dims = data[body + 1]
    if type_code not in _PARAM_BYTES or n_dims > 7:
        raise MocapFileError(f"{name}: parameter {rec_name!r} has a bad type ({type_code}) or "
                             f"dimension count ({n_dims}) at byte {pos}")
    dims = tuple(data[body + 2:body + 2 + n_dims])
    n_values = math.prod(dims) if n_dims else 1
    raw_start = body + 2 + n_dims
    raw_end = raw_start + n_values * _PARAM_BYTES[type_code]
    if raw_end + 1 > next_pos or raw_end + 1 + data[raw_end] > next_pos:
        raise MocapFileError(f"{name}: parameter {rec_name!r} overruns its record at byte {pos} "
                             f"(declares {n_values} values of {_PARAM_BYTES[type_code]} bytes)")
    return _C3DParam(type_code, dims, bytes(data[raw_start:raw_end]))


def _point_layout(data: bytes, name: str, codec: _C3DCodec, params: dict[tuple[str, str], _C3DParam],
                  param_block: int) -> _C3DLayout:
    """The point data's layout from the header, where the POINT parameters do not override it."""
    size = len(data)
    p0 = (param_block - 1) * _BLOCK

    def number(group: str, pname: str, default: float | None) -> float | None:
        p = params.get((group, pname))
        if p is None or p.type_code == -1 or not p.raw:
            return default
        return float(_decode_param(codec, p)[0])

    h_points = codec.uint16(data, 2)
    h_analog = codec.uint16(data, 4)
    h_first = codec.uint16(data, 6)
    h_scale = codec.float32(data, 12)
    h_data_block = codec.uint16(data, 16)
    h_rate = codec.float32(data, 20)

    n_points = int(number("POINT", "USED", h_points))
    if n_points < 0 or n_points != h_points:
        raise MocapFileError(f"{name}: POINT:USED ({n_points}) disagrees with the header point count "
                             f"({h_points})")
    n_frames = _frame_count(data, codec, params)
    scale = number("POINT", "SCALE", h_scale)
    rate = number("POINT", "RATE", h_rate)
    if not (rate and math.isfinite(rate) and rate > 0):
        raise MocapFileError(f"{name}: the point rate ({rate}) is not a positive number")
    if not (scale and math.isfinite(scale)):
        raise MocapFileError(f"{name}: the point scale factor ({scale}) is zero or not a number")
    data_block = int(number("POINT", "DATA_START", h_data_block) or h_data_block)
    data_start = (data_block - 1) * _BLOCK
    if data_block < 2 or data_start <= p0 or data_start > size:
        raise MocapFileError(f"{name}: bad data start block {data_block} (file has {size // _BLOCK} blocks, "
                             f"parameters start at block {param_block})")
    value_bytes = 4 if scale < 0 else 2
    frame_bytes = (4 * n_points + h_analog) * value_bytes
    if data_start + n_frames * frame_bytes > size:
        have = max(0, (size - data_start) // frame_bytes) if frame_bytes else 0
        raise MocapFileError(f"{name}: truncated: the header declares {n_frames} frames but the file holds "
                             f"only {have}")
    labels, units = _labels_and_units(params, n_points)
    return _C3DLayout(codec.processor, n_points, h_analog, h_first, n_frames, float(scale), float(rate),
                      data_start, labels, units, params)


def _frame_count(data: bytes, codec: _C3DCodec, params: dict[tuple[str, str], _C3DParam]) -> int:
    """Number of frames: from the header's first and last frame, or TRIAL:ACTUAL_END_FIELD past 65535."""
    h_first = codec.uint16(data, 6)
    h_last = codec.uint16(data, 8)
    n_frames = h_last - h_first + 1 if h_last >= h_first else 0
    actual_end = params.get(("TRIAL", "ACTUAL_END_FIELD"))
    if h_last == 65535 and actual_end is not None and actual_end.type_code == 2:
        # More than 65535 frames: the true end is stored as two 16-bit words.
        lo, hi = (v & 0xFFFF for v in _decode_param(codec, actual_end)[:2])
        n_frames = lo + (hi << 16) - h_first + 1
    return n_frames


def _labels_and_units(params: dict[tuple[str, str], _C3DParam], n_points: int) -> tuple[tuple[str, ...], str]:
    """Point labels (POINT:LABELS, LABELS2, ...; unnamed points get ``point<j>``) and the length unit."""
    labels: list[str] = []
    for key in ["LABELS"] + [f"LABELS{i}" for i in range(2, 100)]:
        if ("POINT", key) not in params:
            break
        labels += _decode_strings(params[("POINT", key)])
    labels = labels[:n_points]
    # Unnamed points still need distinct names.
    labels += [f"point{j + 1}" for j in range(len(labels), n_points)]
    units_list = _decode_strings(params[("POINT", "UNITS")]) if ("POINT", "UNITS") in params else []
    units = (units_list[0] if units_list else "").strip() or "mm"  # the C3D default
    return tuple(labels), units


def _points_numpy(data: bytes, layout: _C3DLayout) -> np.ndarray:
    """Point data of a validated C3D file, decoded here (used for MIPS, which ezc3d does not read)."""
    is_float = layout.scale < 0
    if layout.processor == "dec" and is_float:
        raise MocapFileError("DEC float point data must be read with ezc3d")
    dtype = np.dtype("f4" if is_float else "i2").newbyteorder(">" if layout.processor == "mips" else "<")
    per_frame = 4 * layout.n_points + layout.analog_per_frame
    values = np.frombuffer(data, dtype=dtype, count=layout.n_frames * per_frame, offset=layout.data_start)
    values = values.reshape(layout.n_frames, per_frame)[:, :4 * layout.n_points]
    values = values.reshape(layout.n_frames, layout.n_points, 4).astype(np.float64)
    xyz = values[..., :3] if is_float else values[..., :3] * layout.scale
    # Negative 4th word = invalid point (C3D residual convention).
    xyz[values[..., 3] < 0] = np.nan
    return xyz


# ezc3d runs in a child process: it is native code and can crash (SIGSEGV) on a corrupt file that
# passes the parameter walk, which would take a web worker down with it.
_EZC3D_CHILD = """
import sys
import numpy as np
import ezc3d
c3d = ezc3d.c3d(sys.argv[1], extract_forceplat_data=False)
np.savez(sys.argv[2], points=np.asarray(c3d["data"]["points"], dtype=np.float64),
         residuals=np.asarray(c3d["data"]["meta_points"]["residuals"], dtype=np.float64))
"""
_EZC3D_TIMEOUT_S = 120.0


def _points_ezc3d(path: Path, layout: _C3DLayout) -> np.ndarray:
    with tempfile.TemporaryDirectory(prefix="saddlescope-c3d-") as tmp:
        out = Path(tmp) / "points.npz"
        try:
            proc = subprocess.run([sys.executable, "-c", _EZC3D_CHILD, str(path), str(out)],
                                  capture_output=True, text=True, timeout=_EZC3D_TIMEOUT_S, check=False)
        except subprocess.TimeoutExpired as exc:
            raise MocapFileError(f"{path.name}: reading the C3D data took over {_EZC3D_TIMEOUT_S:.0f} s; "
                                 "the file is probably malformed") from exc
        if proc.returncode < 0:
            raise MocapFileError(f"{path.name}: the C3D reader crashed on this file "
                                 f"(signal {-proc.returncode}); the file is malformed")
        if proc.returncode != 0 or not out.is_file():
            lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
            reason = lines[-1] if lines else f"exit status {proc.returncode}"
            raise MocapFileError(f"{path.name}: not a readable C3D file ({reason})")
        with np.load(out) as npz:
            pts = npz["points"]  # (4, M, F)
            residuals = npz["residuals"]  # (1, M, F)
    if pts.shape[1:] != (layout.n_points, layout.n_frames):
        raise MocapFileError(f"{path.name}: ezc3d read {pts.shape[1]} markers x {pts.shape[2]} frames, the "
                             f"header declares {layout.n_points} x {layout.n_frames}")
    xyz = np.ascontiguousarray(np.transpose(pts[:3], (2, 1, 0)))
    if residuals.size:
        xyz[residuals[0].T < 0] = np.nan
    return xyz


def read_c3d(path: str | Path) -> MocapData:
    """Read the 3-D points of a C3D file (Intel, DEC or SGI/MIPS; integer or float data).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    MocapData
        points of shape (F, M, 3), NaN where the residual is negative (invalid point).

    Raises
    ------
    MocapFileError
        Empty, truncated or malformed file (bad header, parameter offsets or sections).
    """
    path = Path(path)
    data = _read_bytes(path)
    layout = _walk_c3d(data, path.name)
    if layout.processor == "mips":
        xyz = _points_numpy(data, layout)
    else:
        xyz = _points_ezc3d(path, layout)
    xyz, units = _normalise_units(xyz, layout.units, path.name)
    descriptions = _point_strings(layout.params, "DESCRIPTIONS", layout.n_points)
    labels, warnings = distinct_labels(layout.labels, descriptions)
    return MocapData(labels=labels, rate_hz=layout.rate_hz, points=xyz, units=units,
                     first_frame=layout.first_frame, source_format="c3d", source=path.name,
                     warnings=warnings, descriptions=descriptions, up_axis=_screen_up(layout.params))


def _point_strings(params: dict[tuple[str, str], _C3DParam], key: str, n_points: int) -> tuple[str, ...]:
    """POINT:<key> (DESCRIPTIONS, ...) and its continuations <key>2, <key>3, ..., one per point."""
    out: list[str] = []
    for name in [key] + [f"{key}{i}" for i in range(2, 100)]:
        if ("POINT", name) not in params:
            break
        out += _decode_strings(params[("POINT", name)])
    return tuple(out[:n_points]) if len(out) >= n_points else ()


def _screen_up(params: dict[tuple[str, str], _C3DParam]) -> str | None:
    """The lab's vertical as the file states it: POINT:Y_SCREEN ("+Z" -> "+z"), else None."""
    p = params.get(("POINT", "Y_SCREEN"))
    text = (_decode_strings(p) or [""])[0].strip().lower() if p is not None else ""
    return text if text in ("+x", "-x", "+y", "-y", "+z", "-z") else None


def distinct_labels(labels, descriptions=()) -> tuple[tuple[str, ...], tuple[str, ...]]:
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

"""TRC files: the tab-separated marker trajectories of Motion Analysis / OpenSim.

TRC is the tab-separated text of Motion Analysis / OpenSim: a ``PathFileType`` line, a line of header
keys (DataRate, CameraRate, NumFrames, NumMarkers, Units, ...), a line of their values, a line of
``Frame#  Time  name1 (tab) (tab) name2 ...``, a line of ``X1 Y1 Z1 X2 ...``, then one row per frame;
an empty cell or ``NaN`` is a missing coordinate (the writer writes ``NaN``, so rows keep every column).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from saddlescope.core.errors import InputError, MocapFileError
from saddlescope.core.findings import Finding
from saddlescope.io.mocap.data import MocapData, _check_tracks, _normalise_units, _read_bytes

__all__ = ["read_trc", "write_trc"]


def read_trc(path: str | Path) -> MocapData:
    """Read a TRC (tab-separated marker trajectories) file.

    The header's NumMarkers sets the marker count. Real files are not always consistent, so the reader
    is tolerant where the meaning is clear and says so in ``MocapData.warnings``: markers the name line
    does not name get labels ``M034`` ...; a row that stops early (trailing empty cells left out) has
    its remaining markers missing; cells beyond the declared markers are ignored. A marker with any
    empty coordinate is missing in that frame (NaN for all three).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    MocapData
        points of shape (NumFrames, NumMarkers, 3), NaN for missing markers.

    Raises
    ------
    MocapFileError
        Empty file, missing header lines or values, fewer frame rows than NumFrames, a last row cut
        off mid-line, a row that ends inside a marker's X/Y/Z, cells that are not numbers.
    """
    path = Path(path)
    raw = _read_bytes(path)
    name = path.name
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    lines = text.splitlines()
    rate_hz, n_frames, n_markers, units, warnings = _trc_header(lines, name)
    labels = _trc_labels(lines[3], n_markers, name, warnings)
    points, first_frame = _trc_rows(lines[5:], text, name, n_frames, n_markers, warnings)
    points, units = _normalise_units(points, units, name)
    return MocapData(labels=labels, rate_hz=rate_hz, points=points, units=units, first_frame=first_frame,
                     source_format="trc", source=name, warnings=tuple(warnings))


def _trc_header(lines: list[str], name: str) -> tuple[float, int, int, str, list[Finding]]:
    """DataRate, NumFrames, NumMarkers and Units of the header lines, and the warnings they call for."""
    if not lines or not lines[0].startswith("PathFileType"):
        raise MocapFileError(f"{name}: not a TRC file (first line does not start with 'PathFileType')")
    if len(lines) < 5:
        raise MocapFileError(f"{name}: truncated TRC header: {len(lines)} lines, a TRC file needs at least 5 "
                             "(PathFileType, header keys, header values, marker names, X/Y/Z)")
    keys = [k.strip() for k in lines[1].split("\t")]
    values = [v.strip() for v in lines[2].split("\t")]
    header = dict(zip(keys, values, strict=False))
    for key in ("DataRate", "NumFrames", "NumMarkers"):
        if not header.get(key):
            raise MocapFileError(f"{name}: the TRC header has no value for {key}")
    try:
        rate_hz = float(header["DataRate"])
        n_frames = int(float(header["NumFrames"]))
        n_markers = int(float(header["NumMarkers"]))
    except ValueError as exc:
        raise MocapFileError(f"{name}: the TRC header values are not numbers ({exc})") from exc
    if not (math.isfinite(rate_hz) and rate_hz > 0) or n_frames < 0 or n_markers < 0:
        raise MocapFileError(f"{name}: bad TRC header: DataRate {rate_hz}, NumFrames {n_frames}, "
                             f"NumMarkers {n_markers}")
    warnings: list[Finding] = []
    units = header.get("Units", "")
    if not units:
        warnings.append(Finding("mocap.no_units", "no Units in the header; assumed mm"))
        units = "mm"
    return rate_hz, n_frames, n_markers, units, warnings


def _trc_labels(name_line: str, n_markers: int, name: str, warnings: list[Finding]) -> tuple[str, ...]:
    """Marker labels of line 4; markers it does not name are labelled ``M034`` ... (with a warning)."""
    name_fields = name_line.split("\t")
    if len(name_fields) < 2 or name_fields[0].strip() != "Frame#":
        raise MocapFileError(f"{name}: line 4 should start with 'Frame#' and 'Time' then the marker names")
    named = [f.strip() for f in name_fields[2:] if f.strip()]
    if len(named) > n_markers:
        raise MocapFileError(f"{name}: line 4 names {len(named)} markers but the header declares {n_markers}")
    labels = tuple(named) + tuple(f"M{j + 1:03d}" for j in range(len(named), n_markers))
    if len(named) < n_markers:
        warnings.append(Finding("mocap.marker_names",
                                f"the header declares {n_markers} markers but line 4 names {len(named)}; the others "
                                f"are labelled {labels[len(named)]}..{labels[-1]}",
                                {"markers_declared": n_markers, "markers_named": len(named)}))
    return labels


def _trc_rows(body: list[str], text: str, name: str, n_frames: int, n_markers: int, warnings: list[Finding]
              ) -> tuple[np.ndarray, int]:
    """Points (NumFrames, NumMarkers, 3) of the data rows (``body``: line 6 on) and the first frame number."""
    n_cols = 3 * n_markers
    points = np.full((n_frames, n_markers, 3), np.nan)
    first_frame = 1
    short_rows = extra_rows = 0
    row = 0
    for line_no, line in enumerate(body, start=6):
        if not line.strip():
            continue
        if row >= n_frames:
            raise MocapFileError(f"{name}: more data rows than the {n_frames} frames the header declares "
                                 f"(line {line_no})")
        cut_off = line_no - 6 == len(body) - 1 and not text.endswith(("\n", "\r"))
        cells = _coordinate_cells(line, line_no, name, n_cols, cut_off)
        if len(cells) > n_cols:
            extra_rows += 1
            cells = cells[:n_cols]
        elif len(cells) < n_cols:
            short_rows += 1
        try:
            if row == 0:
                first_frame = int(float(line.split("\t")[0]))
            coords = np.array([float(c) if c else math.nan for c in cells], dtype=np.float64)
        except ValueError as exc:
            raise MocapFileError(f"{name}: a cell at line {line_no} is not a number ({exc})") from exc
        xyz = coords.reshape(-1, 3)
        xyz[np.isnan(xyz).any(axis=1)] = np.nan
        points[row, :xyz.shape[0]] = xyz
        row += 1
    if row < n_frames:
        raise MocapFileError(f"{name}: truncated: the header declares {n_frames} frames but the file holds "
                             f"{row}")
    if short_rows:
        warnings.append(Finding("mocap.short_rows", f"{short_rows} rows stop before the last declared marker; their "
                                "trailing markers are missing", {"rows": short_rows}))
    if extra_rows:
        warnings.append(Finding("mocap.extra_cells",
                                f"{extra_rows} rows hold cells beyond the {n_markers} declared markers; ignored",
                                {"rows": extra_rows, "markers_declared": n_markers}))
    return points, first_frame


def _coordinate_cells(line: str, line_no: int, name: str, n_cols: int, cut_off: bool) -> list[str]:
    """The X/Y/Z cells of a data row, trailing empty cells dropped.

    ``cut_off``: the row is the file's last and has no line end, so a short row means a truncated file.
    """
    cells = line.split("\t")
    if len(cells) < 2:
        raise MocapFileError(f"{name}: line {line_no} has no Frame# and Time columns")
    cells = [c.strip() for c in cells[2:]]
    while cells and not cells[-1]:
        cells.pop()
    if len(cells) % 3:
        raise MocapFileError(f"{name}: line {line_no} is truncated: it ends inside a marker's X/Y/Z "
                             f"({len(cells)} coordinate cells)")
    if cut_off and len(cells) < n_cols:
        raise MocapFileError(f"{name}: the last row (line {line_no}) is cut off: {len(cells)} of "
                             f"{n_cols} coordinate cells and no line end")
    return cells


def write_trc(path: str | Path, labels, points: np.ndarray, rate_hz: float, *, units: str = "mm",
              first_frame: int = 1) -> Path:
    """Write marker trajectories to a TRC file, every row with every column.

    A missing coordinate is written ``NaN``, as OpenSim writes it: an empty cell at a row's end is
    lost to readers that trim the line (OpenSim's TRC reader then refuses the row as too short).

    Parameters
    ----------
    path : path-like
        Output file.
    labels : sequence of str, length M
        Marker names.
    points : ndarray of shape (F, M, 3)
        Positions in ``units``; NaN marks a missing coordinate.
    rate_hz : float
        Sampling rate (DataRate and CameraRate).
    units : {'mm', 'm'}
        Length unit of ``points``.
    first_frame : int
        Frame number of the first row.

    Returns
    -------
    Path
        The file written.
    """
    labels, pts = _check_tracks(labels, points, rate_hz)
    if units not in ("mm", "m"):
        raise InputError(f"units must be 'mm' or 'm', got {units!r}")
    path = Path(path)
    n_frames, n_markers, _ = pts.shape
    digits = 6 if units == "mm" else 9
    rate = f"{rate_hz:.10g}"
    out = [f"PathFileType\t4\t(X/Y/Z)\t{path.name}",
           "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
           f"{rate}\t{rate}\t{n_frames}\t{n_markers}\t{units}\t{rate}\t{first_frame}\t{n_frames}",
           "Frame#\tTime\t" + "\t".join(f"{s}\t\t" for s in labels),
           "\t\t" + "\t".join(f"X{j}\tY{j}\tZ{j}" for j in range(1, n_markers + 1)),
           ""]
    flat = pts.reshape(n_frames, -1)
    for i in range(n_frames):
        cells = ["NaN" if math.isnan(v) else f"{v:.{digits}f}" for v in flat[i]]
        out.append(f"{first_frame + i}\t{i / rate_hz:.6f}\t" + "\t".join(cells))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
    return path

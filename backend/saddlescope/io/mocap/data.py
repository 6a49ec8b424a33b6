"""Marker trajectories read from a motion-capture file, and what the readers and writers share."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from saddlescope.core.errors import InputError, MocapFileError
from saddlescope.core.findings import Finding

__all__ = ["MocapData"]

# Length units we accept, and the factor that brings them to the unit we report.
_UNIT_ALIASES = {"mm": ("mm", 1.0), "millimeters": ("mm", 1.0), "millimetres": ("mm", 1.0),
                 "cm": ("mm", 10.0), "m": ("m", 1.0), "meters": ("m", 1.0), "metres": ("m", 1.0)}
_SUMMARY_MARKERS = 5


@dataclass(frozen=True, eq=False)
class MocapData:
    """Marker trajectories read from a motion-capture file.

    Attributes
    ----------
    labels : tuple of str, length M
        Marker names in file order.
    rate_hz : float
        Sampling rate of the points.
    points : ndarray of shape (F, M, 3), float64
        Marker positions in ``units``; NaN where a marker is missing in a frame.
    units : {'mm', 'm'}
        Length unit of ``points``.
    first_frame : int
        Frame number of ``points[0]`` as stored in the file (usually 1).
    source_format : {'c3d', 'trc'}
        Format the data came from.
    source : str
        File name, for messages.
    warnings : tuple of Finding
        What the reader tolerated in an inconsistent file (e.g. unnamed markers), for the user to see.
    descriptions : tuple of str
        The markers' descriptions where the file has them (C3D POINT:DESCRIPTIONS), else empty.
    up_axis : str or None
        The vertical axis the file states ("+z", "-y", ...; C3D POINT:Y_SCREEN, the screen's up
        direction), None where it states none.
    """

    labels: tuple[str, ...]
    rate_hz: float
    points: np.ndarray
    units: str
    first_frame: int
    source_format: str
    source: str = ""
    warnings: tuple[Finding, ...] = ()
    descriptions: tuple[str, ...] = ()
    up_axis: str | None = None

    @property
    def n_frames(self) -> int:
        """Number of frames F."""
        return int(self.points.shape[0])

    @property
    def n_markers(self) -> int:
        """Number of markers M."""
        return int(self.points.shape[1])

    @property
    def duration_s(self) -> float:
        """Recorded duration, n_frames / rate_hz (each frame covers one sampling interval)."""
        return self.n_frames / self.rate_hz

    def marker(self, label: str) -> np.ndarray:
        """Trajectory of one marker.

        Parameters
        ----------
        label : str
            The marker's label.

        Returns
        -------
        ndarray of shape (F, 3)
            Its positions in ``units`` (a view of ``points``), NaN where missing.
        """
        return self.points[:, self.index(label)]

    def index(self, label: str) -> int:
        """Column of the marker labelled ``label`` in ``points``.

        Parameters
        ----------
        label : str
            The marker's label; a label the file repeats is told apart by its description
            (``"RKNE (R.Knee.Medial)"``), as :attr:`labels` lists it.

        Returns
        -------
        int
            Its index j in ``points[:, j]``.

        Raises
        ------
        InputError
            No such label (the message lists the labels that begin alike, e.g. a repeated label's
            versions).
        """
        if label in self.labels:
            return self.labels.index(label)
        alike = [s for s in self.labels if s.startswith((label + " (", label + "#"))]
        where = self.source or "mocap data"
        if alike:
            raise InputError(f"{where}: the label {label!r} is used by {len(alike)} markers; choose one of "
                             + ", ".join(repr(s) for s in alike))
        raise InputError(f"{where}: no marker labelled {label!r} (the file has {', '.join(self.labels[:12])}"
                         + (", ..." if len(self.labels) > 12 else "") + ")")

    def summary(self) -> dict:
        """JSON-able description: format, labels, rate, frame and marker counts, units, first points.

        Returns
        -------
        dict
            ``format``, ``file``, ``labels``, ``rate_hz``, ``n_frames``, ``n_markers``, ``units``,
            ``first_frame``, ``first_frame_points``, ``duration_s``, ``missing_fraction``,
            ``warnings`` and ``up_axis``. ``first_frame_points`` maps the first few labels to their [x, y, z] in the
            first frame (None where missing there).
        """
        first: dict[str, list[float] | None] = {}
        for j, label in enumerate(self.labels[:_SUMMARY_MARKERS]):
            xyz = self.points[0, j] if self.n_frames else np.full(3, np.nan)
            first[label] = [float(v) for v in xyz] if np.all(np.isfinite(xyz)) else None
        return {
            "format": self.source_format,
            "file": self.source,
            "labels": list(self.labels),
            "rate_hz": float(self.rate_hz),
            "n_frames": self.n_frames,
            "n_markers": self.n_markers,
            "units": self.units,
            "first_frame": int(self.first_frame),
            "first_frame_points": first,
            "duration_s": float(self.duration_s),
            "missing_fraction": float(np.mean(np.isnan(self.points[..., 0]))) if self.points.size else 0.0,
            "warnings": [str(w) for w in self.warnings],
            "up_axis": self.up_axis,
        }


def _read_bytes(path: Path) -> bytes:
    if not path.is_file():
        raise MocapFileError(f"{path.name}: file not found ({path})")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise MocapFileError(f"{path.name}: cannot be read ({exc.strerror})") from exc
    if not data:
        raise MocapFileError(f"{path.name}: the file is empty (0 bytes)")
    return data


def _normalise_units(points: np.ndarray, units: str, name: str) -> tuple[np.ndarray, str]:
    key = units.strip().lower()
    if key not in _UNIT_ALIASES:
        raise MocapFileError(f"{name}: unsupported length unit {units!r} (expected mm, cm or m)")
    out_units, factor = _UNIT_ALIASES[key]
    return (points * factor if factor != 1.0 else points), out_units


def _check_tracks(labels, points, rate_hz: float) -> tuple[tuple[str, ...], np.ndarray]:
    labels = tuple(str(s) for s in labels)
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 3 or pts.shape[2] != 3:
        raise InputError(f"points must have shape (F, M, 3), got {pts.shape}")
    if len(labels) != pts.shape[1]:
        raise InputError(f"{len(labels)} labels for {pts.shape[1]} markers in points of shape {pts.shape}")
    if len(set(labels)) != len(labels) or any(not s.strip() for s in labels):
        raise InputError(f"marker labels must be distinct and non-empty, got {list(labels)}")
    if any(ch in s for s in labels for ch in "\t\r\n"):
        raise InputError("marker labels must not contain tabs or line breaks")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"rate_hz must be a positive number, got {rate_hz}")
    if np.isinf(pts).any():
        raise InputError("points must be finite or NaN (missing), not infinite")
    return labels, pts

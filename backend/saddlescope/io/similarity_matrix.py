"""Many recordings at once: the files named (folders opened) and the similarity matrix written.

``saddlescope similar`` over a folder or a list (:func:`saddlescope.services.similarity.compare.similarity_matrix`)
writes its matrix as CSV and as a heat map (OpenCV; matplotlib is not a dependency).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from saddlescope.core.errors import InputError

__all__ = ["MOCAP_SUFFIXES", "recording_paths", "write_matrix_csv", "write_matrix_png"]


MOCAP_SUFFIXES = (".c3d", ".trc")


def recording_paths(items) -> list:
    """The recordings named: files, and the C3D / TRC files of any folder (sorted by name)."""
    out = []
    for item in items:
        path = Path(item)
        if path.is_dir():
            out += sorted(p for p in path.iterdir() if p.suffix.lower() in MOCAP_SUFFIXES and p.is_file())
        else:
            out.append(path)
    return out


def write_matrix_csv(matrix: dict, path) -> None:
    """The matrix as CSV: a header row of file names, then one row per file (empty: not compared)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["file"] + matrix["files"])
        for name, row in zip(matrix["files"], matrix["similarity"], strict=True):
            out.writerow([name] + ["" if v is None else f"{v:.4f}" for v in row])


def write_matrix_png(matrix: dict, path) -> None:
    """The matrix as a heat map (OpenCV).

    Dark red alike, pale unlike, grey not compared; names on the rows, numbers (columns) on top; the colour scale
    spans the off-diagonal values.
    """
    import cv2

    sim = np.array([[np.nan if v is None else v for v in row] for row in matrix["similarity"]], dtype=np.float64)
    n = sim.shape[0]
    off = sim[~np.eye(n, dtype=bool)]
    off = off[np.isfinite(off)]
    lo, hi = (float(off.min()), float(off.max())) if off.size else (0.0, 1.0)
    cell, left, top = 40, 12 + 9 * max(len(f"{k + 1} {name}") for k, name in enumerate(matrix["files"])), 30
    img = np.full((top + n * cell + 30, left + n * cell + 10, 3), 255, np.uint8)
    scaled = np.clip((sim - lo) / (hi - lo if hi > lo else 1.0), 0.0, 1.0)
    colours = cv2.applyColorMap(np.uint8(255 * (1.0 - np.nan_to_num(scaled))).reshape(-1, 1), cv2.COLORMAP_HOT)
    for i in range(n):
        cv2.putText(img, f"{i + 1} {matrix['files'][i]}", (4, top + i * cell + 25), cv2.FONT_HERSHEY_SIMPLEX,
                    0.4, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(img, str(i + 1), (left + i * cell + 12, top - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
        for j in range(n):
            colour = (200, 200, 200) if not np.isfinite(sim[i, j]) else tuple(int(c) for c in colours[i * n + j, 0])
            x0, y0 = left + j * cell, top + i * cell
            cv2.rectangle(img, (x0, y0), (x0 + cell - 1, y0 + cell - 1), colour, -1)
    cv2.putText(img, f"{matrix['measure']}: white {lo:.3f} ... dark {hi:.3f}", (4, top + n * cell + 20),
                cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), img):
        raise InputError(f"{Path(path).name}: the heat map cannot be written (use a .png name)")

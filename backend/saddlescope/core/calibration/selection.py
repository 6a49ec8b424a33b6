"""View selection: instants that spread the board over every camera's image and tilts."""

from __future__ import annotations

import math
from collections.abc import Mapping

import cv2
import numpy as np

from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.types import Board

__all__ = ["select_instants"]


def _guess_normal(view: BoardView, board: Board, image_size) -> np.ndarray:
    """Board normal in the camera from a PnP with a guessed K (f = image width): for pose diversity."""
    w, h = image_size
    K = np.array([[w, 0, w / 2], [0, w, h / 2], [0, 0, 1.0]])
    obj = object_points_mm(board)[view.ids]
    ok, rvec, _ = cv2.solvePnP(obj, view.corners_px, K, None, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return np.array([0.0, 0.0, 1.0])
    return cv2.Rodrigues(rvec)[0][:, 2]


def _coverage_cells(view: BoardView, image_size, grid) -> set[int]:
    w, h = image_size
    gw, gh = grid
    mask = np.zeros((gh, gw), np.uint8)
    pts = view.corners_px * [gw / w, gh / h]
    hull = cv2.convexHull(pts.astype(np.float32)).reshape(-1, 2)
    cv2.fillConvexPoly(mask, np.round(hull * 16).astype(np.int32), 1, shift=4)
    cells = set(np.flatnonzero(mask).tolist())
    cells.update((np.clip(pts[:, 1].astype(int), 0, gh - 1) * gw
                  + np.clip(pts[:, 0].astype(int), 0, gw - 1)).tolist())
    return cells


def select_instants(views_by_camera: Mapping[str, list[BoardView]], board: Board,
                    image_sizes: Mapping[str, tuple[int, int]], *, max_instants: int = 60,
                    grid: tuple[int, int] = (8, 6), diversity_weight: float = 0.5) -> list[int]:
    """Choose up to ``max_instants`` frames that spread the board over every camera's image and poses.

    Greedy: each step takes the instant adding the most not-yet-covered image cells (per camera, on a
    ``grid`` of cells), plus ``diversity_weight`` times its board tilt's angular distance (capped at
    30 degrees) to the already chosen views of the same camera, summed over the cameras that see it.

    Returns
    -------
    list of int, the chosen instants (frame keys), sorted.
    """
    cells: dict[int, dict[str, set[int]]] = {}
    normals: dict[int, dict[str, np.ndarray]] = {}
    for cam, views in views_by_camera.items():
        for v in views:
            cells.setdefault(v.frame, {})[cam] = _coverage_cells(v, image_sizes[cam], grid)
            normals.setdefault(v.frame, {})[cam] = _guess_normal(v, board, image_sizes[cam])
    candidates = sorted(cells)
    if len(candidates) <= max_instants:
        return candidates
    n_cells = grid[0] * grid[1]
    covered: dict[str, set[int]] = {cam: set() for cam in views_by_camera}
    # per instant and camera: the largest |cos| of the angle to the normals chosen so far (None: none yet),
    # kept up to date as instants are chosen rather than recomputed for every candidate at every step
    max_cos: dict[int, dict[str, float | None]] = {inst: dict.fromkeys(cells[inst]) for inst in candidates}
    chosen: list[int] = []
    remaining = set(candidates)
    while remaining and len(chosen) < max_instants:
        best, best_score = None, -1.0
        for inst in sorted(remaining):
            score = 0.0
            for cam, c in cells[inst].items():
                score += len(c - covered[cam]) / n_cells
                cos = max_cos[inst][cam]
                ang = 30.0 if cos is None else math.degrees(math.acos(min(cos, 1.0)))
                score += diversity_weight * min(ang, 30.0) / 30.0
            if score > best_score:
                best, best_score = inst, score
        assert best is not None  # remaining is not empty and every score beats -1
        chosen.append(best)
        remaining.discard(best)
        for cam, c in cells[best].items():
            covered[cam] |= c
            n_best = normals[best][cam]
            for inst in remaining:
                if cam in max_cos[inst]:
                    cos = abs(float(normals[inst][cam] @ n_best))
                    old = max_cos[inst][cam]
                    max_cos[inst][cam] = cos if old is None else max(old, cos)
    return sorted(chosen)

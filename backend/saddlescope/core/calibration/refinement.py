"""Grey frames and sub-pixel corner refinement shared by the board detectors and the tracker."""

from __future__ import annotations

import cv2
import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.types import Board

__all__ = ["refine_corners_subpixel", "search_downscaled", "unscale_px"]  # for the board detectors

_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)


def _as_gray(img: np.ndarray) -> np.ndarray:
    img = np.asarray(img)
    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.ndim != 2:
        raise InputError(f"expected a grey image of shape (H, W), got shape {img.shape}")
    if img.dtype != np.uint8:
        img = cv2.normalize(img, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)  # type: ignore[call-overload]  # cv2's stubs: dst=None is allowed
    return img


def _min_spacing_px(corners: np.ndarray, board: Board, ids: np.ndarray) -> float:
    cols, rows = board.inner_corners
    grid = np.full((cols * rows, 2), np.nan)
    grid[np.asarray(ids, dtype=np.int64)] = corners
    grid3 = grid.reshape(rows, cols, 2)
    d = np.concatenate([np.linalg.norm(np.diff(grid3, axis=1), axis=2).ravel(),
                        np.linalg.norm(np.diff(grid3, axis=0), axis=2).ravel()])
    d = d[np.isfinite(d)]
    return float(d.min()) if len(d) else 10.0


def refine_corners_subpixel(gray, corners, board, ids=None, *, upsampled=False):
    """Board corners (N, 2) refined to a fraction of a pixel, with a window sized to the corners' spacing."""
    ids = np.arange(len(corners)) if ids is None else ids
    # On an upsampled frame a corner's blur spans more pixels: a window of 0.35 of the spacing (2-3 px for
    # squares of 4 px upsampled 2x) is too small, cornerSubPix then wanders and returns where it started
    # (synthetic thesis-rig ride: 0.26 px r.m.s. error against 0.16 px with 0.55).
    half = int(np.clip(round(_min_spacing_px(corners, board, ids) * (0.55 if upsampled else 0.35)), 2, 12))
    pts = corners.reshape(-1, 1, 2).astype(np.float32)
    cv2.cornerSubPix(gray, pts, (half, half), (-1, -1), _SUBPIX_CRITERIA)
    return pts.reshape(-1, 2).astype(np.float64)


def _refine_full_resolution(gray, corners, board, ids):
    return refine_corners_subpixel(gray, corners, board, ids)


def unscale_px(xy: np.ndarray, scale: float) -> np.ndarray:
    """Pixel coordinates in a frame resized by ``scale`` (cv2.resize) back in the original frame.

    cv2.resize aligns pixel centres, so x / scale alone is off by (1 / scale - 1) / 2 px (0.25 px at 2x).
    """
    return (np.asarray(xy, np.float64) + 0.5) / scale - 0.5


def _rescale(xy: np.ndarray, scale: float) -> np.ndarray:
    """The inverse of :func:`unscale_px`."""
    return (np.asarray(xy, np.float64) + 0.5) * scale - 0.5


def search_downscaled(gray: np.ndarray, board: Board, max_width: int, find) -> tuple[tuple | None, bool]:
    """Run ``find`` on a frame, downscaled first when it is wide.

    ``find`` maps a grey frame to (corners (N, 2), ids (N,)) or None. A frame over 1.5 times
    ``max_width`` wide is downscaled to ``max_width``; corners found there are then refined at full
    resolution.

    Returns
    -------
    found : (corners_px, ids) in the frame, or None
    refined_here : bool
        Whether the corners were refined on the full-resolution frame.
    """
    scale = 1.0
    small = gray
    if gray.shape[1] > 1.5 * max_width:
        scale = max_width / gray.shape[1]
        small = cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    found = find(small)
    if found is None:
        return None, False
    corners, ids = found
    if scale == 1.0:
        return (corners, ids), False
    return (_refine_full_resolution(gray, unscale_px(corners, scale), board, ids), ids), True

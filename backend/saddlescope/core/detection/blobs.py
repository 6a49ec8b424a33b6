"""Bright blobs of a grey image: the thesis's filter chain up to the candidates (4.5.1-4.5.3).

Grey image, threshold (4.5.1), 8-connected labelling (4.5.2), area range (4.5.3), then sub-pixel
centroids (:mod:`.refine`). For the first-frame search (:mod:`.pattern`) the candidates are also
cut to those that are round, whole (not cut by the image border), not where a still spot was, and
bright enough above the frame's noise; for rides, only the part of the frame that changed is searched.

Frames are grey uint8 (or uint16) arrays of shape (H, W), possibly strided views into a decoder's
buffer; only the window searched is read.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from saddlescope.core.detection.refine import _above, _refine
from saddlescope.core.errors import InputError

__all__ = ["detect_blobs"]


def _where(camera: str, clip: str) -> str:
    parts = [f"camera {camera!r}" if camera else "", f"clip {clip!r}" if clip else ""]
    text = ", ".join(p for p in parts if p)
    return f"{text}: " if text else ""


def _check_gray(gray, camera: str = "", clip: str = "", index=None) -> np.ndarray:
    if not isinstance(gray, np.ndarray) or gray.ndim != 2:
        shape = getattr(gray, "shape", type(gray).__name__)
        frame = f"frame {index}: " if index is not None else ""
        raise InputError(f"{_where(camera, clip)}{frame}expected a grey image of shape (H, W), got {shape}")
    if gray.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{_where(camera, clip)}expected a uint8 or uint16 grey image, got {gray.dtype}")
    return gray


@dataclass
class _Blobs:
    """Per-blob arrays of one detection pass (K blobs), coordinates in the full image."""

    xy: np.ndarray          # (K, 2)
    area: np.ndarray        # (K,)
    peak: np.ndarray        # (K,)
    background: np.ndarray  # (K,)
    fill: np.ndarray        # (K,) area / bounding-box area
    aspect: np.ndarray      # (K,) bounding box's long side / short side

    @property
    def contrast(self) -> np.ndarray:
        return np.maximum(self.peak - self.background, 1.0)

    def take(self, idx) -> _Blobs:
        return _Blobs(self.xy[idx], self.area[idx], self.peak[idx], self.background[idx], self.fill[idx],
                      self.aspect[idx])

    def __len__(self) -> int:
        return self.xy.shape[0]


def _empty_blobs() -> _Blobs:
    z = np.zeros(0)
    return _Blobs(np.zeros((0, 2)), z, z.copy(), z.copy(), z.copy(), z.copy())


def _label(win: np.ndarray, threshold: float):
    """8-connected blobs above ``threshold``: (n, labels, stats, centroids) as ``cv2.connectedComponentsWithStats``.

    The labels come from ``cv2.connectedComponents`` and the statistics from the foreground pixels
    alone: OpenCV's statistics visit every pixel of the window, which cost several times the labelling
    on the sparse windows of tracking (markers on a dark horse). The background's row (0) holds its
    pixel count and the whole window.
    """
    binary = _above(win, threshold)
    H, W = binary.shape
    # 8-connected blobs are at most a quarter of the pixels: 16-bit labels hold them in small windows
    ltype = cv2.CV_16U if binary.size <= 4 * 65535 else cv2.CV_32S
    n, labels = cv2.connectedComponents(binary, connectivity=8, ltype=ltype)
    stats = np.zeros((n, 5), np.int32)
    cents = np.zeros((n, 2))
    pts = cv2.findNonZero(binary)
    if pts is not None and n > 1:
        xy = pts.reshape(-1, 2)
        lab = labels[xy[:, 1], xy[:, 0]]
        order = np.argsort(lab, kind="stable")
        lab, xs, ys = lab[order], xy[order, 0], xy[order, 1]
        area = np.bincount(lab, minlength=n)[1:]
        starts = np.concatenate(([0], np.cumsum(area)[:-1]))
        x0, y0 = np.minimum.reduceat(xs, starts), np.minimum.reduceat(ys, starts)
        stats[1:, cv2.CC_STAT_LEFT] = x0
        stats[1:, cv2.CC_STAT_TOP] = y0
        stats[1:, cv2.CC_STAT_WIDTH] = np.maximum.reduceat(xs, starts) - x0 + 1
        stats[1:, cv2.CC_STAT_HEIGHT] = np.maximum.reduceat(ys, starts) - y0 + 1
        stats[1:, cv2.CC_STAT_AREA] = area
        cents[1:, 0] = np.add.reduceat(xs.astype(np.float64), starts) / area
        cents[1:, 1] = np.add.reduceat(ys.astype(np.float64), starts) / area
    stats[0] = (0, 0, W, H, binary.size - (0 if pts is None else len(pts)))
    return n, labels, stats, cents


def _centroids(gray: np.ndarray, labels: np.ndarray, stats: np.ndarray, keep: np.ndarray, offset,
               pad_px: int, threshold: float) -> _Blobs:
    """Sub-pixel centroids (see :func:`_refine`) of components of a window, in full-image pixels.

    ``keep`` are components of the window at ``offset`` (x0, y0) of ``gray``, labelled at ``threshold``.
    """
    out = _refine(gray, labels, keep, stats[keep, :4], pad_px, threshold, offset)
    area = stats[keep, cv2.CC_STAT_AREA].astype(np.float64)
    w, h = stats[keep, cv2.CC_STAT_WIDTH], stats[keep, cv2.CC_STAT_HEIGHT]
    fill = area / (w * h)
    aspect = np.maximum(w, h) / np.minimum(w, h)
    return _Blobs(out[:, :2].copy(), area, out[:, 2].copy(), out[:, 3].copy(), fill, aspect)


def _roi_bounds(roi, shape) -> tuple[int, int, int, int]:
    H, W = shape
    if roi is None:
        return 0, 0, W, H
    x0, y0, x1, y1 = (int(round(v)) for v in roi)
    x0, y0 = min(max(x0, 0), W), min(max(y0, 0), H)
    x1, y1 = min(max(x1, x0), W), min(max(y1, y0), H)
    return x0, y0, x1, y1


def _detect(gray: np.ndarray, threshold: float, area_range_px, roi=None, pad_px: int = 2) -> _Blobs:
    x0, y0, x1, y1 = _roi_bounds(roi, gray.shape)
    if x1 - x0 < 1 or y1 - y0 < 1:
        return _empty_blobs()
    win = gray[y0:y1, x0:x1]  # a view: only the window is ever read
    n, labels, stats, _ = _label(win, threshold)
    area = stats[1:n, cv2.CC_STAT_AREA]
    lo, hi = area_range_px
    keep = np.flatnonzero((area >= lo) & (area <= hi)) + 1
    return _centroids(gray, labels, stats, keep, (x0, y0), pad_px, threshold)


def detect_blobs(gray: np.ndarray, *, threshold: float, area_range_px: tuple[float, float] = (1, np.inf),
                 roi: tuple[int, int, int, int] | None = None, pad_px: int = 2):
    """Bright blobs of a grey image: threshold, 8-connected labels, area filter, sub-pixel centroids.

    Parameters
    ----------
    gray : ndarray of shape (H, W), uint8 or uint16
        May be a strided view (e.g. a decoder's Y plane); only the ``roi`` is read.
    threshold : float, keyword-only
        Pixels brighter than this belong to blobs (eq. 4.5).
    area_range_px : (float, float), keyword-only
        Blobs with an area (pixel count) outside [min, max] are dropped (4.5.3).
    roi : (x0, y0, x1, y1), keyword-only
        Window to search, in pixels (end exclusive); clipped to the image. Default: the whole image.
    pad_px : int, keyword-only
        Dilation of each blob's bounding box for the weighted centroid.

    Returns
    -------
    xy : ndarray of shape (K, 2)
        Intensity-weighted centroids (x, y) in full-image pixels.
    area : ndarray of shape (K,)
        Pixel count above threshold.
    peak : ndarray of shape (K,)
        Brightest grey level of each blob.
    """
    _check_gray(gray)
    blobs = _detect(gray, threshold, area_range_px, roi, pad_px)
    return blobs.xy, blobs.area, blobs.peak


@dataclass(frozen=True)
class _Scene:
    """Whole-frame numbers the first-frame search needs: levels to try, noise, a coarse background."""

    background: float
    levels: list[float]
    noise_sigma: float
    coarse: np.ndarray  # the frame shrunk 8x by area averaging: background around any blob
    min_contrast: float


def _scene(gray: np.ndarray, threshold: float | None = None) -> _Scene:
    sample = gray[::4, ::4]
    background = float(np.median(sample))
    brightest = float(gray.max())
    if threshold is None:
        span = brightest - background
        levels = sorted({round(background + f * span, 1) for f in (0.4, 0.6, 0.8)})
    else:
        levels = [float(threshold)]
    # Sensor noise from neighbouring pixels (robust to edges and texture): median |difference| / 0.954.
    rows = gray[::4].astype(np.int16)
    noise = float(np.median(np.abs(np.diff(rows, axis=1)))) / 0.954
    H, W = gray.shape
    coarse = cv2.resize(gray, (max(W // 8, 1), max(H // 8, 1)), interpolation=cv2.INTER_AREA)
    # A retro-reflective marker under a lamp stands far above the noise; flicker does not.
    return _Scene(background, levels, noise, coarse, max(16.0, 6.0 * noise))


def _all_blobs(gray: np.ndarray, threshold: float, area_range_px, max_candidates: int, pad_px: int,
               scene: _Scene, exclude_xy: np.ndarray | None = None, exclude_radius_px: float = 1.0,
               roi=None) -> _Blobs:
    """Marker candidates of the image (or its ``roi``) at one threshold, in full-image coordinates.

    Blobs in the area range, round (not streaks, stripes or rings), whole (not cut by the image
    border), not within ``exclude_radius_px`` of ``exclude_xy`` and with enough contrast, cut to the
    ``max_candidates`` that stand out most from their surroundings.
    """
    x0, y0, x1, y1 = _roi_bounds(roi, gray.shape)
    if x1 - x0 < 3 or y1 - y0 < 3:
        return _empty_blobs()
    win = gray[y0:y1, x0:x1]
    n, labels, stats, cents = _label(win, threshold)
    if n <= 1 or n > 20_000:  # nothing, or a level inside the texture: no marker stands out there
        return _empty_blobs()
    cents = cents + (x0, y0)
    area = stats[1:, cv2.CC_STAT_AREA]
    lo, hi = area_range_px
    keep = np.flatnonzero((area >= lo) & (area <= hi)) + 1
    if keep.size == 0:
        return _empty_blobs()
    w, h = stats[keep, cv2.CC_STAT_WIDTH], stats[keep, cv2.CC_STAT_HEIGHT]
    small = stats[keep, cv2.CC_STAT_AREA] <= 12
    fill = stats[keep, cv2.CC_STAT_AREA] / (w * h)
    aspect = np.maximum(w, h) / np.minimum(w, h)
    keep = keep[small | ((fill > 0.3) & (aspect <= 3))]  # drop streaks, stripes and rings
    H, W = gray.shape
    bx, by = stats[keep, 0] + x0, stats[keep, 1] + y0
    cut = (bx == 0) | (by == 0) | (bx + stats[keep, 2] == W) | (by + stats[keep, 3] == H)
    keep = keep[~cut]  # cut by the image border: not a whole marker
    if exclude_xy is not None and len(exclude_xy) and keep.size:
        d, _ = cKDTree(np.asarray(exclude_xy)).query(cents[keep], distance_upper_bound=exclude_radius_px)
        keep = keep[~np.isfinite(d)]  # nothing still within the radius
    if keep.size > max_candidates:
        fg = labels > 0
        sums = np.bincount(labels[fg], weights=win[fg], minlength=n)
        mean = sums[keep] / stats[keep, cv2.CC_STAT_AREA]
        ch, cw = scene.coarse.shape
        cx = np.clip((cents[keep, 0] / 8).astype(int), 0, cw - 1)
        cy = np.clip((cents[keep, 1] / 8).astype(int), 0, ch - 1)
        rank = np.argsort(-(mean - scene.coarse[cy, cx]))  # standing out most from the surroundings
        keep = np.sort(keep[rank[:max_candidates]])
    blobs = _centroids(gray, labels, stats, keep, (x0, y0), pad_px, threshold)
    return blobs.take(np.flatnonzero(blobs.contrast >= scene.min_contrast))


def _bright_spots(gray: np.ndarray, levels, area_range_px, roi=None) -> np.ndarray:
    """Plain centroids (S, 2) of every blob at any of ``levels`` (in ``roi``): what a frame shows, cheaply."""
    x0, y0, x1, y1 = _roi_bounds(roi, gray.shape)
    win = gray[y0:y1, x0:x1]
    lo, hi = area_range_px
    spots = [np.zeros((0, 2))]
    for level in levels:
        n, _, stats, cents = _label(win, level)
        area = stats[1:n, cv2.CC_STAT_AREA]
        spots.append(cents[1:n][(area >= lo) & (area <= hi)] + (x0, y0))
    return np.concatenate(spots)


def _coarse(gray: np.ndarray) -> np.ndarray:
    H, W = gray.shape
    return cv2.resize(gray, (max(W // 8, 1), max(H // 8, 1)), interpolation=cv2.INTER_AREA).astype(np.int16)


def _moving_roi(coarse: np.ndarray, previous: np.ndarray, noise_sigma: float, shape):
    """Bounding box (x0, y0, x1, y1) of what changed between two 8x-shrunk frames, or None."""
    # An 8x8 average has 1/8 of the pixel noise; ask for 6 of those sigmas and a few grey levels.
    changed = np.abs(coarse - previous) > max(3.0, 6.0 * noise_sigma / 8.0)
    if not changed.any():
        return None
    rows = np.flatnonzero(changed.any(axis=1))
    cols = np.flatnonzero(changed.any(axis=0))
    H, W = shape
    return (max(8 * (int(cols[0]) - 2), 0), max(8 * (int(rows[0]) - 2), 0),
            min(8 * (int(cols[-1]) + 3), W), min(8 * (int(rows[-1]) + 3), H))

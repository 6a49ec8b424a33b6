"""Retro-reflective marker detection and tracking in one camera's clip (thesis 4.5).

The thesis's filter chain, with every choice the user used to make chosen automatically (and still
overridable): grey image, threshold (4.5.1), 8-connected labelling (4.5.2), area range (4.5.3), a
window that follows the markers' centre (4.5.4), vectors between markers that must match the last
frame within a tolerance (4.5.5, eq. 4.6-4.11, vectors rather than distances) and the sign of the cross
product for look-alikes (Fig. 4.13). A marker that is not found is a gap (NaN), never a guess.

- Automatic choices: thresholds between the background and the brightest pixel, a contrast floor from
  the frame's own noise, blobs that are round and not cut by the image border, and the most plausible
  set of n blobs (alike in size and brightness, close together; horse markers in a near-horizontal
  row with similar gaps, plumb markers one above the other). Ambiguity is an error, not a coin toss.
- Rides (``moving=True``): only the part of the frame that changed is searched, and spots that stood
  still since the previous frame (glints, lamps) are not markers.
- Centroids: intensity weighted, grey minus a local background from a grey opening (so the step of a
  saddle pad's edge or a thin line across the marker does not pull them); < 0.01 px on clean discs.
- Tracking: constant-velocity prediction, a window around it, the best assignment of blobs to markers
  (gate, area, pattern); flashes skipped; after a loss the search resumes and keeps the labels.

Frames are grey uint8 (or uint16) arrays of shape (H, W), typically the Y plane of a decoded video
frame, possibly a strided view into the decoder's buffer. While tracking only a window around the
predicted markers is read, so detection costs little next to decoding.
"""
from __future__ import annotations

import itertools
import math
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from saddlescope.core.errors import DetectionError, InputError
from saddlescope.core.types import ImageTracks

__all__ = [
    "MarkerPattern",
    "detect_blobs",
    "initial_markers",
    "track_markers",
]

# A disc's area over its bounding box's area.
_DISC_FILL = math.pi / 4


@dataclass(frozen=True)
class MarkerPattern:
    """Markers found on one frame, labelled, with the detection settings that found them.

    xy_px : ndarray of shape (M, 2), intensity-weighted centroids (x right, y down, pixel centres at
    integers); area_px, peak, background : ndarray of shape (M,) (pixels above threshold, brightest
    grey level, local background grey level); threshold : grey level used; area_range_px : (min, max)
    area for the tracker; diameter_px : typical equivalent diameter; score : implausibility of the
    pattern (lower is better; 0 = identical, perfectly round blobs in a perfect row).
    """

    xy_px: np.ndarray
    area_px: np.ndarray
    peak: np.ndarray
    background: np.ndarray
    threshold: float
    area_range_px: tuple[float, float]
    diameter_px: float
    score: float = 0.0


# --------------------------------------------------------------------------------------------------
# Blobs
# --------------------------------------------------------------------------------------------------

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
    if win.dtype == np.uint8:
        _, binary = cv2.threshold(win, min(float(threshold), 255.0), 1, cv2.THRESH_BINARY)
    else:
        binary = (win > threshold).view(np.uint8)
    return cv2.connectedComponentsWithStats(binary, connectivity=8, ltype=cv2.CV_32S)


def _refine(win: np.ndarray, labels: np.ndarray, ids: np.ndarray, boxes: np.ndarray, pad_px: int,
            ring_gap_px: int = 2) -> np.ndarray:
    """Intensity-weighted centroids of components ``ids`` of a labelled window, all at once.

    Weights are grey minus the local background inside each component's bounding box dilated by
    ``pad_px`` (more for big blobs, which are blurred over more pixels), with the pixels of other
    components left out; the faint rim below threshold counts too, which removes the bias a hard
    threshold gives on a blurred disc. The background is a plane fitted to the free (unlabelled) border
    pixels of a box ``ring_gap_px`` further out: level and gradient, because texture or vignetting under
    a small blob would otherwise pull the centroid, far enough out that the blob's own blur does not
    tilt it. The blobs are processed as one stack of equally sized patches (a few numpy calls per
    frame instead of a few per blob).

    Parameters
    ----------
    win : ndarray of shape (H, W)
    labels : ndarray of shape (H, W), int32
    ids : ndarray of shape (K,), int
    boxes : ndarray of shape (K, 4), int
        Bounding boxes (x, y, w, h) as ``cv2.connectedComponentsWithStats`` gives them.

    Returns
    -------
    ndarray of shape (K, 4)
        (x, y, peak grey level, background grey level under the centroid) in window pixels.
    """
    K = ids.size
    if K == 0:
        return np.zeros((0, 4))
    H, W = win.shape
    x, y, w, h = (boxes[:, j].astype(np.int64) for j in range(4))
    pad = pad_px + (0.15 * np.maximum(w, h)).astype(np.int64)
    side = (np.maximum(w, h) + 2 * pad + 1) | 1  # the opening's square (odd): wider than the blob, blur too
    g = pad + ring_gap_px                 # the ring where the background level is read
    G = g + side                          # the patch: the opening needs a square's width around the ring
    X0, Y0 = np.maximum(x - G, 0), np.maximum(y - G, 0)
    X1, Y1 = np.minimum(x + w + G, W), np.minimum(y + h + G, H)
    sw, sh = int((X1 - X0).max()), int((Y1 - Y0).max())
    xs = X0[:, None] + np.arange(sw)  # (K, sw) window columns of each patch
    ys = Y0[:, None] + np.arange(sh)
    vx, vy = xs < X1[:, None], ys < Y1[:, None]
    xi, yi = np.minimum(xs, W - 1), np.minimum(ys, H - 1)
    patch = win[yi[:, :, None], xi[:, None, :]].astype(np.float32)
    lab = labels[yi[:, :, None], xi[:, None, :]]
    valid = vy[:, :, None] & vx[:, None, :]
    free = valid & (lab == 0)
    rx0, ry0 = np.maximum(x - g, 0), np.maximum(y - g, 0)
    rx1, ry1 = np.minimum(x + w + g, W) - 1, np.minimum(y + h + g, H) - 1
    in_x = (xs >= rx0[:, None]) & (xs <= rx1[:, None])
    in_y = (ys >= ry0[:, None]) & (ys <= ry1[:, None])
    edge = (((xs == rx0[:, None]) | (xs == rx1[:, None])) & in_x)[:, None, :] & in_y[:, :, None] \
        | (((ys == ry0[:, None]) | (ys == ry1[:, None])) & in_y)[:, :, None] & in_x[:, None, :]
    ring = edge & free
    # Background: a grey opening with a square wider than the blob (white top-hat). It erases the blob
    # and keeps whatever is larger - a flat or sloping background, and the step of an edge the marker
    # sits on (saddle pad against the horse), where a fitted plane would pull the centroid. A small
    # closing first fills thin dark lines (a stripe on the wall behind a plumb marker), which the
    # marker hides: left in, they would count the marker twice along the line.
    opened = np.empty_like(patch)
    for k in range(K):
        closed = cv2.morphologyEx(patch[k], cv2.MORPH_CLOSE, _square(5))
        opened[k] = cv2.morphologyEx(closed, cv2.MORPH_OPEN, _square(int(side[k])))
    top = patch - opened
    # The top-hat of pure noise is positive: remove its level, measured on the free ring.
    n = ring.sum(axis=(1, 2))
    floor = np.where(n > 0, np.where(ring, top, 0.0).sum(axis=(1, 2)) / np.maximum(n, 1), 0.0)
    own = lab == ids[:, None, None]
    # Weights only near the blob: its pixels grown by ``pad`` (a thin bright line through the marker,
    # such as a plumb line, survives the opening and must not pull the centroid along itself).
    near = np.empty_like(own)
    own_u8 = own.view(np.uint8)
    for k in range(K):
        near[k] = cv2.dilate(own_u8[k], _square(2 * int(pad[k]) + 1)).view(bool)
    keep = near & valid & (own | (lab == 0))
    wts = np.where(keep, np.maximum(top - floor[:, None, None], 0.0), 0.0)
    total = wts.sum(axis=(1, 2))
    out = np.empty((K, 4))
    ok = total > 0
    tz = np.where(ok, total, 1.0)
    out[:, 0] = np.where(ok, (wts.sum(axis=1) * xs).sum(axis=1) / tz, x + (w - 1) / 2)
    out[:, 1] = np.where(ok, (wts.sum(axis=2) * ys).sum(axis=1) / tz, y + (h - 1) / 2)
    out[:, 2] = np.where(own, patch, -np.inf).max(axis=(1, 2))
    own_n = np.maximum(own.sum(axis=(1, 2)), 1)
    out[:, 3] = np.where(own, opened, 0.0).sum(axis=(1, 2)) / own_n
    return out


_SQUARES: dict[int, np.ndarray] = {}


def _square(side: int) -> np.ndarray:
    kernel = _SQUARES.get(side)
    if kernel is None:
        kernel = _SQUARES[side] = np.ones((side, side), np.uint8)
    return kernel


def _centroids(win: np.ndarray, labels: np.ndarray, stats: np.ndarray, keep: np.ndarray, offset,
               pad_px: int) -> _Blobs:
    """Sub-pixel centroids (see :func:`_refine`) of the components ``keep``, in full-image pixels."""
    out = np.empty((keep.size, 4))
    # Blobs of similar size share one stack of patches (one big blob must not inflate every patch).
    size = np.maximum(stats[keep, cv2.CC_STAT_WIDTH], stats[keep, cv2.CC_STAT_HEIGHT])
    bucket = np.ceil(np.log2(np.maximum(size, 1))).astype(int)
    for b in np.unique(bucket):
        sel = np.flatnonzero(bucket == b)
        out[sel] = _refine(win, labels, keep[sel], stats[keep[sel], :4], pad_px)
    xy = out[:, :2] + np.asarray(offset, dtype=np.float64)
    area = stats[keep, cv2.CC_STAT_AREA].astype(np.float64)
    w, h = stats[keep, cv2.CC_STAT_WIDTH], stats[keep, cv2.CC_STAT_HEIGHT]
    fill = area / (w * h)
    aspect = np.maximum(w, h) / np.minimum(w, h)
    return _Blobs(xy, area, out[:, 2].copy(), out[:, 3].copy(), fill, aspect)


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
    return _centroids(win, labels, stats, keep, (x0, y0), pad_px)


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


# --------------------------------------------------------------------------------------------------
# First-frame initialisation
# --------------------------------------------------------------------------------------------------

def _default_layout(n_markers: int) -> str:
    return {1: "single", 2: "vertical", 3: "row"}.get(n_markers, "any")


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
    """Blobs of the image (or its ``roi``) at one threshold with enough contrast, cut to the
    ``max_candidates`` that stand out most from their surroundings; full-image coordinates."""
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
    blobs = _centroids(win, labels, stats, keep, (x0, y0), pad_px)
    return blobs.take(np.flatnonzero(blobs.contrast >= scene.min_contrast))


def _pattern_scores(blobs: _Blobs, combos: np.ndarray, layout: str) -> np.ndarray:
    """Implausibility of each combination (ncomb, n) of blobs as the marker pattern; lower is better."""
    la = np.log(blobs.area)[combos]
    lc = np.log(blobs.contrast)[combos]
    # Round: a disc fills pi/4 of its square bounding box (tiny blobs are too coarse to tell).
    shape_pen = np.where(blobs.area > 12, np.abs(blobs.fill / _DISC_FILL - 1) + 0.5 * np.log(blobs.aspect),
                         0.0)[combos]
    score = shape_pen.mean(axis=1)
    score = score + 0.5 * np.mean(np.log(blobs.contrast.max()) - lc, axis=1)  # prefer the brightest
    n = combos.shape[1]
    if n == 1:
        return score
    score = score + la.std(axis=1) + lc.std(axis=1)
    pts = blobs.xy[combos]  # (ncomb, n, 2)
    diff = pts[:, :, None, :] - pts[:, None, :, :]
    dist = np.linalg.norm(diff, axis=-1)
    diam = 2 * np.sqrt(np.exp(la).mean(axis=1) / np.pi)
    # Close together: horse markers sit within a hand's breadth or two of each other; a plumb's two
    # markers are deliberately far apart, so there spacing says nothing.
    spread_weight = {"row": 0.5, "any": 0.2}.get(layout, 0.0)
    score = score + spread_weight * np.log(np.maximum(dist.max(axis=(1, 2)) / diam, 1.0))
    if layout == "row" and n >= 3:
        centred = pts - pts.mean(axis=1, keepdims=True)
        _, sv, vt = np.linalg.svd(centred, full_matrices=False)
        score = score + 2 * sv[:, -1] / np.maximum(sv[:, 0], 1e-9)
        score = score + 0.5 * np.abs(vt[:, 0, 1])  # |sin| of the row's angle from horizontal
        # Markers along a back are spaced alike: neighbours' gaps along the row should match.
        along = np.sort(np.einsum("cnk,ck->cn", centred, vt[:, 0]), axis=1)
        gaps = np.maximum(np.diff(along, axis=1), 1e-6)
        score = score + np.log(gaps).std(axis=1)
    elif layout == "vertical" and n == 2:
        d = pts[:, 1] - pts[:, 0]
        score = score + 2 * np.abs(d[:, 0]) / np.maximum(np.linalg.norm(d, axis=1), 1e-9)
    elif layout == "row" and n == 2:
        d = pts[:, 1] - pts[:, 0]
        score = score + 2 * np.abs(d[:, 1]) / np.maximum(np.linalg.norm(d, axis=1), 1e-9)
    return score


def _plausible(blobs: _Blobs, combos: np.ndarray, layout: str) -> np.ndarray:
    """Markers of one set look alike (areas within 4x, contrasts within 3x of each other), stand apart,
    and a "row" is one: near horizontal, at most 30 % as wide as long, gaps within 3x of each other."""
    a = blobs.area[combos]
    c = blobs.contrast[combos]
    ok = (a.max(axis=1) <= 4 * a.min(axis=1)) & (c.max(axis=1) <= 3 * c.min(axis=1))
    if combos.shape[1] >= 2:
        # Separate markers stand apart by at least two diameters; closer blobs are pieces of one thing.
        pts = blobs.xy[combos]
        dist = np.linalg.norm(pts[:, :, None, :] - pts[:, None, :, :], axis=-1)
        dist[:, np.arange(combos.shape[1]), np.arange(combos.shape[1])] = np.inf
        ok &= dist.min(axis=(1, 2)) >= 2 * 2 * np.sqrt(a.max(axis=1) / np.pi)
    if layout == "row" and combos.shape[1] >= 3:
        pts = blobs.xy[combos]
        centred = pts - pts.mean(axis=1, keepdims=True)
        _, sv, vt = np.linalg.svd(centred, full_matrices=False)
        ok &= sv[:, -1] <= 0.3 * sv[:, 0]
        ok &= np.abs(vt[:, 0, 1]) <= 0.5  # within 30 degrees of horizontal: along a horse's back
        along = np.sort(np.einsum("cnk,ck->cn", centred, vt[:, 0]), axis=1)
        gaps = np.diff(along, axis=1)
        ok &= gaps.max(axis=1) <= 3 * gaps.min(axis=1)
    return ok


def _order(xy: np.ndarray, layout: str) -> np.ndarray:
    """Default labels: left to right, or top to bottom for a vertical (plumb) pair."""
    if layout == "vertical":
        return np.lexsort((xy[:, 0], xy[:, 1]))
    return np.lexsort((xy[:, 1], xy[:, 0]))


def _pattern_from(blobs: _Blobs, idx: np.ndarray, threshold: float, area_range_px,
                  score: float) -> MarkerPattern:
    sel = blobs.take(idx)
    if area_range_px is None:
        area_range_px = (max(1.0, 0.25 * float(sel.area.min())), 4.0 * float(sel.area.max()) + 4.0)
    diameter = 2 * math.sqrt(float(np.median(sel.area)) / math.pi)
    return MarkerPattern(sel.xy.copy(), sel.area.copy(), sel.peak.copy(), sel.background.copy(),
                         float(threshold), (float(area_range_px[0]), float(area_range_px[1])), diameter,
                         float(score))


def initial_markers(gray: np.ndarray, n_markers: int, *, threshold: float | None = None,
                    area_range_px: tuple[float, float] | None = None, first_frame_xy=None,
                    layout: str | None = None, max_candidates: int = 24, ambiguity_margin: float = 0.03,
                    exclude_xy=None, roi: tuple[int, int, int, int] | None = None, pad_px: int = 2,
                    camera: str = "", clip: str = "") -> MarkerPattern:
    """Find and label ``n_markers`` markers on one frame (a static shot or a clip's first frame).

    Without ``first_frame_xy``, the n blobs forming the most plausible marker pattern win: similar
    areas and brightness, round, among the brightest, close together, and for ``layout="row"``
    (3 horse markers) roughly in a near-horizontal row, for ``"vertical"`` (plumb, 2 markers) one above
    the other. Several thresholds between the background and the brightest pixel are tried unless
    ``threshold`` is given. Labels run left to right (top to bottom for a vertical pair).

    Parameters
    ----------
    gray : ndarray of shape (H, W), uint8 or uint16
    n_markers : int
        1 (free-fall ball), 2 (plumb), 3 (horse), 4 (3 horse markers + saddle point, or board points
        A-D), up to 6.
    threshold : float, keyword-only
        Grey level; default automatic.
    area_range_px : (float, float), keyword-only
        Accepted blob areas; default 2 px up to 0.05 % of the image (154 px at 640x480, a disc 14 px
        across; 1037 px at 1920x1080) for the search, then a range around
        the markers found (a quarter of the smallest to four times the largest) for tracking.
    first_frame_xy : array_like of shape (n_markers, 2), keyword-only
        Approximate marker positions (labels in this order): the nearest blob to each is taken.
    layout : {"row", "vertical", "any", "single"}, keyword-only
        Default: "single" for 1, "vertical" for 2, "row" for 3, "any" otherwise.
    max_candidates : int, keyword-only
        Blobs kept per threshold for the combinatorial search (brightest first).
    ambiguity_margin : float, keyword-only
        A second, different set of blobs scoring within this of the best makes the frame ambiguous.
    exclude_xy : array_like of shape (E, 2), keyword-only
        Blobs within 1 px of these positions are not markers (e.g. spots that did not move).
    roi : (x0, y0, x1, y1), keyword-only
        Search only this window (end exclusive); coordinates stay full-image.
    camera, clip : str, keyword-only
        Named in error messages.

    Returns
    -------
    MarkerPattern

    Raises
    ------
    DetectionError
        Fewer marker-like blobs than markers, or several equally plausible sets.
    """
    _check_gray(gray, camera, clip)
    where = _where(camera, clip)
    if not 1 <= int(n_markers) <= 6:
        raise InputError(f"{where}n_markers must be between 1 and 6, got {n_markers}")
    n = int(n_markers)
    layout = layout or _default_layout(n)
    if layout not in ("row", "vertical", "any", "single"):
        raise InputError(f"{where}unknown marker layout {layout!r}")
    return _find_pattern(gray, n, threshold=threshold, area_range_px=area_range_px,
                         first_frame_xy=first_frame_xy, layout=layout, max_candidates=max_candidates,
                         ambiguity_margin=ambiguity_margin, exclude_xy=exclude_xy, roi=roi, pad_px=pad_px,
                         where=where, scene=_scene(gray, threshold))


def _default_area_range(shape) -> tuple[float, float]:
    H, W = shape
    return 2.0, max(50.0, 0.0005 * H * W)


def _find_pattern(gray, n, *, threshold, area_range_px, first_frame_xy, layout, max_candidates,
                  ambiguity_margin, exclude_xy, roi, pad_px, where, scene: _Scene) -> MarkerPattern:
    """The work of :func:`initial_markers`, with the frame's :class:`_Scene` given (the tracker reuses it)."""
    search_range = area_range_px or _default_area_range(gray.shape)
    exclude = None if exclude_xy is None else np.asarray(exclude_xy, dtype=np.float64).reshape(-1, 2)
    levels = scene.levels
    x0, y0, x1, y1 = _roi_bounds(roi, gray.shape)
    brightest = float(gray[y0:y1, x0:x1].max()) if x1 > x0 and y1 > y0 else 0.0
    if threshold is None and brightest - scene.background < scene.min_contrast:
        raise DetectionError(f"{where}no bright markers: the brightest pixel ({brightest:.0f}) is "
                             f"barely above the background ({scene.background:.0f})")

    if first_frame_xy is not None:
        pattern = _pattern_near(gray, n, np.asarray(first_frame_xy, dtype=np.float64), scene,
                                search_range, area_range_px, max_candidates, pad_px, where)
        if threshold is not None:
            return pattern
        return _retune(gray, pattern, fixed_area=area_range_px is not None, pad_px=pad_px)

    best = None  # (score, threshold, blobs, idx, runner_up)
    most = 0
    for level in levels:
        blobs = _all_blobs(gray, level, search_range, max_candidates, pad_px, scene, exclude, roi=roi)
        most = max(most, len(blobs))
        if len(blobs) < n:
            continue
        combos = np.array(list(itertools.combinations(range(len(blobs)), n)), dtype=np.intp)
        combos = combos[_plausible(blobs, combos, layout)] if n > 1 else combos
        if combos.size == 0:
            continue
        scores = _pattern_scores(blobs, combos, layout)
        order = np.argsort(scores)
        s1 = float(scores[order[0]])
        s2 = float(scores[order[1]]) if order.size > 1 else np.inf
        if best is None or s1 < best[0]:
            best = (s1, level, blobs, combos[order[0]], s2)
    if best is None:
        raise DetectionError(f"{where}found at most {most} marker-like blob(s), need {n}: markers not all "
                             "visible (occluded, out of frame, or not lit)")
    s1, level, blobs, idx, s2 = best
    if s2 - s1 < ambiguity_margin:
        raise DetectionError(f"{where}too many equally plausible marker candidates ({len(blobs)} blobs for "
                             f"{n} markers); give the threshold, area range or first-frame positions")
    idx = idx[_order(blobs.xy[idx], layout)]
    pattern = _pattern_from(blobs, idx, level, area_range_px, s1)
    if threshold is not None:
        return pattern
    return _retune(gray, pattern, fixed_area=area_range_px is not None, pad_px=pad_px)


def _pattern_near(gray, n, xy0, scene, search_range, area_range_px, max_candidates, pad_px, where):
    if xy0.shape != (n, 2) or not np.all(np.isfinite(xy0)):
        raise InputError(f"{where}first_frame_xy must be {n} finite (x, y) pairs, got shape {xy0.shape}")
    if n > 1:
        gaps = np.linalg.norm(xy0[:, None] - xy0[None], axis=-1)[np.triu_indices(n, 1)]
        radius = max(6.0, 0.4 * float(gaps.min()))
    else:
        radius = 15.0
    best = None
    for level in scene.levels:
        blobs = _all_blobs(gray, level, search_range, max(max_candidates, 200), pad_px, scene)
        if len(blobs) == 0:
            continue
        d = np.linalg.norm(xy0[:, None, :] - blobs.xy[None, :, :], axis=-1)
        idx = np.argmin(d, axis=1)
        dmin = d[np.arange(n), idx]
        if np.all(dmin <= radius) and len(set(idx.tolist())) == n:
            total = float(dmin.sum())
            if best is None or total < best[0]:
                best = (total, level, blobs, idx)
    if best is None:
        raise DetectionError(f"{where}no blob within {radius:.0f} px of every given first-frame marker "
                             "position")
    _, level, blobs, idx = best
    return _pattern_from(blobs, idx, level, area_range_px, 0.0)


# Tracking threshold: this fraction of the way from the markers' background up to the dimmest marker's
# peak. Above one half, so that a light patch next to a marker on dark hair (a saddle pad's edge)
# does not join the marker's blob; the weighted centroid still uses the blob's faint rim.
_THRESHOLD_FRACTION = 0.6


def _tracking_threshold(pattern: MarkerPattern) -> float:
    """The tracking threshold for markers like these (see ``_THRESHOLD_FRACTION``)."""
    bg = float(np.median(pattern.background))
    level = bg + _THRESHOLD_FRACTION * max(float(pattern.peak.min()) - bg, 2.0)
    return _above_surrounds(level, pattern.background.tolist(), (pattern.peak - pattern.background).tolist())


def _above_surrounds(level: float, backgrounds: list, contrasts: list) -> float:
    """``level``, or higher where a marker's own surround is as bright as it: a marker against the
    sky (a plumb line's top marker) merges with the sky below the sky's grey level, and the whole
    window reads as glare. Then the level is ``_THRESHOLD_FRACTION`` of the way from each marker's
    surround to its peak, the highest of those, if every marker's peak stays above it."""
    if max(backgrounds) + 2.0 < level:
        return level
    own = [b + _THRESHOLD_FRACTION * max(c, 2.0) for b, c in zip(backgrounds, contrasts, strict=True)]
    peaks = [b + c for b, c in zip(backgrounds, contrasts, strict=True)]
    return max(own) if max(own) < min(peaks) - 2.0 else level


def _retune(gray, pattern: MarkerPattern, *, fixed_area: bool, pad_px: int) -> MarkerPattern:
    """Re-detect the chosen markers at the tracking threshold so areas and centroids match tracking."""
    level = _tracking_threshold(pattern)
    r = max(3.0, pattern.diameter_px)
    x0, y0 = np.floor(pattern.xy_px.min(axis=0) - 2 * r).astype(int)
    x1, y1 = np.ceil(pattern.xy_px.max(axis=0) + 2 * r).astype(int) + 1
    blobs = _detect(gray, level, (1, np.inf), (x0, y0, x1, y1), pad_px)
    if len(blobs) < len(pattern.xy_px):
        return pattern
    d = np.linalg.norm(pattern.xy_px[:, None] - blobs.xy[None], axis=-1)
    idx = np.argmin(d, axis=1)
    if len(set(idx.tolist())) != idx.size or np.any(d[np.arange(idx.size), idx] > r):
        return pattern  # the lower threshold merged markers with something: keep the search result
    area_range = pattern.area_range_px if fixed_area else None
    return _pattern_from(blobs, idx, level, area_range, pattern.score)


# --------------------------------------------------------------------------------------------------
# Tracking
# --------------------------------------------------------------------------------------------------

def _cross_signs(xy: np.ndarray, min_sine: float = 0.1) -> dict[tuple[int, int, int], float]:
    """Sign of (r_ij x r_jk)_3 for every marker triple that is clearly not collinear (Fig. 4.13)."""
    out = {}
    for i, j, k in itertools.combinations(range(xy.shape[0]), 3):
        a, b = xy[j] - xy[i], xy[k] - xy[j]
        cross = a[0] * b[1] - a[1] * b[0]
        norm = math.hypot(*a) * math.hypot(*b)
        if norm > 0 and abs(cross) / norm > min_sine:
            out[(i, j, k)] = math.copysign(1.0, cross)
    return out


class _Tracker:
    """The per-frame state of :func:`track_markers` (kept private: the public API is the function).

    Per frame: predict (constant velocity), label the window around the prediction, assign blobs to
    markers on the labeller's plain centroids (cheap), then compute sub-pixel centroids of the
    assigned blobs only. The state is a handful of numbers per marker, kept in plain Python lists:
    at 640x480 the whole step must cost well under a millisecond.
    """

    def __init__(self, pattern: MarkerPattern, *, threshold_fixed: bool, window_px, distance_tol: float,
                 pad_px: int, shape):
        self.M = pattern.xy_px.shape[0]
        self.est = pattern.xy_px.tolist()          # [[x, y], ...] estimated positions
        self.vel = [0.0, 0.0]  # px / frame, shared by the markers (one body)
        self.ref_area = pattern.area_px.astype(float).tolist()
        self.ref_contrast = np.maximum(pattern.peak - pattern.background, 2.0).tolist()
        self.background = float(np.median(pattern.background))
        self.ref_background = pattern.background.astype(float).tolist()  # per marker
        self.threshold = pattern.threshold
        self.threshold_fixed = threshold_fixed
        self.area_range = pattern.area_range_px
        # vec_ref[a][b] = x_b - x_a on the last frame where both markers were seen
        self.vec_ref = [[(q[0] - p[0], q[1] - p[1]) for q in self.est] for p in self.est]
        self.signs = _cross_signs(pattern.xy_px)
        self.tol = distance_tol
        self.pad = pad_px
        self.window_px = window_px
        self.H, self.W = shape
        self.base_margin = max(3.0 * pattern.diameter_px, 12.0)
        self.speed_cap = 3 * self.base_margin
        self.lost = 0
        self.steps = 0
        self.level: float | None = None  # running mean grey level of the window (flash guard)

    def window(self, pred) -> tuple[tuple[int, int, int, int], float]:
        grow = 1.5 ** min(self.lost, 12)
        if self.steps < 3:  # the speed is not known yet
            grow *= 2.0
        speed = math.hypot(*self.vel)
        margin = self.base_margin * grow + 0.5 * speed  # the prediction already moved by the speed
        xs = [p[0] for p in pred]
        ys = [p[1] for p in pred]
        if self.window_px is not None:
            w, h = self.window_px
            cx, cy = sum(xs) / len(xs), sum(ys) / len(ys)
            box = (cx - grow * w / 2, cy - grow * h / 2, cx + grow * w / 2, cy + grow * h / 2)
        else:
            box = (min(xs) - margin, min(ys) - margin, max(xs) + margin + 1, max(ys) + margin + 1)
        x0, y0 = max(math.floor(box[0]), 0), max(math.floor(box[1]), 0)
        x1, y1 = min(math.ceil(box[2]), self.W), min(math.ceil(box[3]), self.H)
        return (x0, y0, x1, y1), margin

    def assign(self, xy: list, area: list, pred: list, gate: float) -> list[int]:
        """Best candidate index per marker (-1 = missing): near the prediction, similar area, same pattern."""
        if not xy:
            return [-1] * self.M
        g2 = gate * gate
        options = []
        costs = []
        for i, (px, py) in enumerate(pred):
            lo, hi = 0.25 * self.ref_area[i], 4.0 * self.ref_area[i]
            row = [((x - px) ** 2 + (y - py) ** 2) / g2 for x, y in xy]
            cand = [k for k, c in enumerate(row) if c <= 1.0 and lo <= area[k] <= hi]
            if len(cand) > 4:
                cand = sorted(cand, key=row.__getitem__)[:4]
            options.append(cand + [-1])
            costs.append(row)
        def i_of(combo):
            return next(i for i, c in enumerate(combo) if c >= 0)

        # After a loss, one lone blob proves nothing: ask for two markers that keep their pattern.
        min_found = 2 if self.lost > 0 and self.M >= 2 else 0
        best_cost, best = math.inf, None
        for combo in itertools.product(*options):
            if min_found and sum(c >= 0 for c in combo) < min_found:
                continue
            if self.M >= 2 and sum(c >= 0 for c in combo) == 1 and costs[i_of(combo)][max(combo)] > 0.25:
                continue  # a lone marker has no pattern to vouch for it: it must sit close to its prediction
            total = 0.0
            seen = set()
            for i, c in enumerate(combo):
                if c < 0:
                    total += 2.0  # a gap costs more than any blob within the gate
                elif c in seen:
                    total = math.inf
                    break
                else:
                    seen.add(c)
                    total += costs[i][c]
            if total >= best_cost:
                continue
            total += self._pattern_cost(combo, xy)
            if total < best_cost:
                best_cost, best = total, combo
        return list(best) if best is not None else [-1] * self.M

    def _pattern_cost(self, combo, xy) -> float:
        """Distance filter (eq. 4.11) and cross-product filter; inf when the combination breaks either.

        The distance filter compares the vector between two markers with the last one seen, not just
        its length: a look-alike mirrored across a nearly straight row of markers keeps the distances
        (and, for a straight row, an unreliable cross-product sign) but not the direction.
        """
        found = [i for i, c in enumerate(combo) if c >= 0]
        if len(found) < 2:
            return 0.0
        cost = 0.0
        scale = 0.5 / (len(found) - 1)
        for a, b in itertools.combinations(found, 2):
            rx, ry = self.vec_ref[a][b]
            ref_len = math.hypot(rx, ry)
            if ref_len <= 0:
                continue
            pa, pb = xy[combo[a]], xy[combo[b]]
            rel = math.hypot(pb[0] - pa[0] - rx, pb[1] - pa[1] - ry) / ref_len
            if rel > self.tol:
                return math.inf
            cost += scale * (rel / self.tol) ** 2
        for (i, j, k), sign in self.signs.items():
            if combo[i] >= 0 and combo[j] >= 0 and combo[k] >= 0:
                pi, pj, pk = xy[combo[i]], xy[combo[j]], xy[combo[k]]
                cross = (pj[0] - pi[0]) * (pk[1] - pj[1]) - (pj[1] - pi[1]) * (pk[0] - pj[0])
                if math.copysign(1.0, cross) != sign:
                    return math.inf
        return cost

    def step(self, gray: np.ndarray) -> tuple[list, list]:
        """Markers on one frame: ([x, y] or None per marker, area or None per marker)."""
        self.steps += 1
        vx, vy = self.vel
        pred = [[p[0] + vx, p[1] + vy] for p in self.est]
        (x0, y0, x1, y1), margin = self.window(pred)
        M = self.M
        found: list = [None] * M
        areas: list = [None] * M
        if x1 - x0 < 1 or y1 - y0 < 1:
            self._update(pred, found, areas, [], [])
            return found, areas
        win = gray[y0:y1, x0:x1]  # a view: only the window is read
        level = cv2.mean(win)[0]
        if self.level is None:
            self.level = level
        n, labels, stats, cents = _label(win, self.threshold)
        lo, hi = self.area_range
        area_all = stats[1:n, cv2.CC_STAT_AREA]
        if abs(level - self.level) > 0.25 * min(self.ref_contrast) or area_all.sum() > 0.25 * win.size:
            # The window's brightness jumped (a flash, glare, the sun): whatever shines now is not
            # to be trusted. Skip the frame as if the markers were hidden.
            self._update(pred, found, areas, [], [])
            return found, areas
        self.level += 0.2 * (level - self.level)
        keep = np.flatnonzero((area_all >= lo) & (area_all <= hi)) + 1
        cand_xy = (cents[keep] + (x0, y0)).tolist()
        cand_area = stats[keep, cv2.CC_STAT_AREA].tolist()
        combo = self.assign(cand_xy, cand_area, pred, margin)
        marks = [m for m, c in enumerate(combo) if c >= 0]
        peaks: list = []
        bgs: list = []
        if marks:
            ids = keep[[combo[m] for m in marks]]
            out = _refine(win, labels, ids, stats[ids, :4], self.pad).tolist()
            for m, c, (cx, cy, peak, bg) in zip(marks, ids.tolist(), out, strict=True):
                bx, by, bw, bh = (int(v) for v in stats[c, :4])
                if bx + x0 == 0 or by + y0 == 0 or bx + x0 + bw == self.W or by + y0 + bh == self.H:
                    # Cut by the image border: part of the marker is outside, its centroid is not the
                    # marker's centre. A gap, not a biased point (the prediction still follows it).
                    continue
                found[m] = [cx + x0, cy + y0]
                areas[m] = float(stats[c, cv2.CC_STAT_AREA])
                peaks.append(peak)
                bgs.append(bg)
        self._update(pred, found, areas, peaks, bgs)
        return found, areas

    def _update(self, pred, found, areas, peaks, bgs) -> None:
        seen = [m for m in range(self.M) if found[m] is not None]
        if not seen:
            self.lost += 1
            self.est = pred
            self.vel = [0.9 * self.vel[0], 0.9 * self.vel[1]]
            return
        self.lost = 0
        # The markers sit on one body and turn little between frames: they share one velocity (the
        # median of those seen), and a marker not seen is placed by the pattern, from those seen and
        # the vectors last measured between them. Per-marker velocities let a marker taken on a
        # wrong blob for a frame fling its prediction away: a pole passing a thesis-rig walk merged
        # two predictions onto one marker, and two markers were lost for the rest of the ride.
        new = []
        for m in range(self.M):
            if found[m] is not None:
                new.append(found[m])
                continue
            px = sum(found[s][0] + self.vec_ref[s][m][0] for s in seen) / len(seen)
            py = sum(found[s][1] + self.vec_ref[s][m][1] for s in seen) / len(seen)
            new.append([px, py])
        vx, vy = (statistics.median(found[m][k] - self.est[m][k] for m in seen) for k in (0, 1))
        speed = math.hypot(vx, vy)
        # a wrong match must not fling the window away
        cap = min(1.0, self.speed_cap / speed) if speed > 0 else 1.0
        self.vel = [cap * vx, cap * vy]
        self.est = new
        for a, b in itertools.combinations(seen, 2):
            pa, pb = found[a], found[b]
            self.vec_ref[a][b] = (pb[0] - pa[0], pb[1] - pa[1])
            self.vec_ref[b][a] = (pa[0] - pb[0], pa[1] - pb[1])
        for m, peak, bg in zip(seen, peaks, bgs, strict=True):
            self.ref_area[m] += 0.1 * (areas[m] - self.ref_area[m])
            self.ref_contrast[m] += 0.1 * (max(peak - bg, 2.0) - self.ref_contrast[m])
            self.ref_background[m] += 0.1 * (bg - self.ref_background[m])
        self.background += 0.1 * (sorted(bgs)[len(bgs) // 2] - self.background)
        if not self.threshold_fixed:
            # Follow slow lighting changes: a fixed fraction up the dimmest marker's contrast.
            self.threshold = _above_surrounds(
                self.background + _THRESHOLD_FRACTION * max(min(self.ref_contrast), 2.0),
                self.ref_background, self.ref_contrast)


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


def _relabel(pattern: MarkerPattern, vec_ref) -> MarkerPattern:
    """Order a re-found pattern like the markers were before (the permutation that best keeps the
    vectors between markers), so labels survive losing the markers for a while."""
    M = pattern.xy_px.shape[0]
    if M < 2:
        return pattern
    xy = pattern.xy_px
    best, best_cost = None, math.inf
    for perm in itertools.permutations(range(M)):
        cost = 0.0
        for a, b in itertools.combinations(range(M), 2):
            rx, ry = vec_ref[a][b]
            d = xy[perm[b]] - xy[perm[a]]
            cost += math.hypot(d[0] - rx, d[1] - ry) / max(math.hypot(rx, ry), 1e-9)
        if cost < best_cost:
            best, best_cost = perm, cost
    idx = np.asarray(best)
    return MarkerPattern(xy[idx], pattern.area_px[idx], pattern.peak[idx], pattern.background[idx],
                         pattern.threshold, pattern.area_range_px, pattern.diameter_px, pattern.score)


def _row_runs_out_of_view(pattern: MarkerPattern, shape: tuple[int, int]) -> bool:
    """Whether one more marker, the row's widest gap beyond either end, would not be whole in the
    image (a diameter and 2 px from the edge): then the row found may be the part of the markers in
    view, completed by a look-alike."""
    xy = pattern.xy_px
    if len(xy) < 2:
        return False
    centred = xy - xy.mean(axis=0)
    direction = np.linalg.svd(centred, full_matrices=False)[2][0]
    along = centred @ direction
    step = float(np.diff(np.sort(along)).max())
    margin = pattern.diameter_px + 2.0
    h, w = shape
    ends = np.array([xy[np.argmin(along)] - step * direction, xy[np.argmax(along)] + step * direction])
    return bool(np.any((ends < margin) | (ends > (w - 1 - margin, h - 1 - margin))))


def track_markers(frames: Iterable[tuple[int, np.ndarray]], *, n_markers: int, camera: str = "",
                  clip: str = "", threshold: float | None = None,
                  area_range_px: tuple[float, float] | None = None,
                  window_px: int | Sequence[int] | None = None,
                  first_frame_xy=None, layout: str | None = None, distance_tol: float = 0.25,
                  moving: bool = False, max_init_frames: int = 150, confirm_frames: int = 5,
                  lost_frames: int = 5, search_every: int = 3, pad_px: int = 2) -> ImageTracks:
    """Detect and follow ``n_markers`` markers through a clip.

    Search: the first frame on which all markers are visible is searched whole with
    :func:`initial_markers` (with ``moving=True`` only where the image changed, and without the spots
    that stood still since the previous frame). Track: later frames only inside a window around the
    markers' constant-velocity prediction, which grows while markers are lost. In the window, blobs pass
    the threshold and area filters, then the best assignment of blobs to markers is chosen: near the
    prediction, similar area, vectors between markers within ``distance_tol`` of the last frame
    (eq. 4.11) and the same cross-product signs as the first frame (Fig. 4.13). A marker without an
    acceptable blob is a gap (NaN).

    If some marker is missing on two of the first ``confirm_frames`` frames after a search, the pattern
    found was not the markers: those frames become gaps and the search goes on. After ``lost_frames``
    frames without any marker (the horse left the view, a rider's leg, the pole), tracking stops and the
    search resumes every ``search_every`` frames; a re-found pattern keeps the old labels.

    Parameters
    ----------
    frames : iterable of (int, ndarray of shape (H, W))
        Frame index and grey frame, consumed lazily (stream the video); arrays may be views that the
        producer reuses after the next item.
    n_markers : int, keyword-only
    camera, clip : str, keyword-only
        Named in errors and flags.
    threshold, area_range_px, first_frame_xy, layout : keyword-only
        Overrides of the automatic choices, see :func:`initial_markers`. A given threshold stays
        fixed; otherwise it follows the markers' brightness.
    window_px : int or (int, int), keyword-only
        Fixed window width and height; default automatic (the markers' bounding box plus a margin of
        three marker diameters plus half the markers' speed in px/frame).
    distance_tol : float, keyword-only
        Relative tolerance of the vector between two markers (length and direction) against the last
        frame where both were seen.
    moving : bool, keyword-only
        The markers move (a ride): blobs that stay put from one frame to the next (glints, lamps,
        scenery) are not markers, and only changing parts of the image are searched. The search then
        needs two frames.
    max_init_frames : int, keyword-only
        Frames to wait for the first sight of all markers before giving up (the horse may enter late).
    confirm_frames, lost_frames, search_every : int, keyword-only
        See above.

    Returns
    -------
    ImageTracks
        ``xy_px`` (F, M, 2), ``area_px`` (F, M) and ``frame_index`` (F,) for every frame consumed,
        NaN where a marker was not found; ``flags`` list markers that were missing in some frames.

    Raises
    ------
    DetectionError
        The markers cannot be found on any of the first ``max_init_frames`` frames, or no frames.
    """
    where = _where(camera, clip)
    if window_px is not None:
        if np.isscalar(window_px):
            window_px = (int(window_px), int(window_px))
        else:
            window_px = tuple(int(v) for v in window_px)
        if len(window_px) != 2 or min(window_px) < 3:
            raise InputError(f"{where}window_px must be a size >= 3 px or (width, height), got {window_px}")
    if not 0 < distance_tol < 1:
        raise InputError(f"{where}distance_tol must be in (0, 1), got {distance_tol}")
    n = int(n_markers)
    layout = layout or _default_layout(n)
    xy_rows: list = []
    area_rows: list = []
    indices: list[int] = []
    tracker: _Tracker | None = None
    ever_found = False
    confirmed = False  # a pattern followed through its first frames
    tracked_from = 0            # row where the current tracker started
    since_search = 10 ** 6       # frames since the last search attempt
    last_error: DetectionError | None = None
    scene: _Scene | None = None
    scene_age = 0
    previous: np.ndarray | None = None        # moving mode: the previous frame (a copy) ...
    previous_coarse: np.ndarray | None = None  # ... and its 8x-shrunk version
    vec_ref = None               # vectors between markers when they were last tracked

    for index, gray in frames:
        indices.append(int(index))
        if tracker is not None:
            if gray.shape != (tracker.H, tracker.W):
                raise InputError(f"{where}frame {index} has shape {gray.shape}, earlier frames "
                                 f"{(tracker.H, tracker.W)}")
            found, areas = tracker.step(gray)
            xy_rows.append(found)
            area_rows.append(areas)
            recent = xy_rows[tracked_from + 1:]
            confirmed = confirmed or len(recent) > confirm_frames
            if len(recent) <= confirm_frames and sum(any(p is None for p in row) for row in recent) >= 2:
                # Not followed at once: the pattern found was not the markers. Forget it, search again.
                for r in range(tracked_from, len(xy_rows)):
                    xy_rows[r] = [None] * n
                    area_rows[r] = [None] * n
                tracker, since_search = None, 0
            elif tracker.lost >= lost_frames:
                vec_ref = tracker.vec_ref
                tracker, since_search = None, 0
            if tracker is None and moving:
                previous, previous_coarse = gray.copy(), _coarse(gray)
            continue

        # Searching.
        _check_gray(gray, camera, clip, index)
        xy_rows.append([None] * n)
        area_rows.append([None] * n)
        since_search += 1
        # A search costs some ten frames of tracking: after a loss look every few frames only, and for
        # a ride (the horse walks in) every other frame.
        every = search_every if ever_found else (2 if moving else 1)
        if since_search < every:
            continue
        since_search = 0
        coarse = _coarse(gray)
        if scene is None or scene_age >= 30 or scene.coarse.shape != coarse.shape:
            scene, scene_age = _scene(gray, threshold), 0
        scene_age += 1
        try:
            roi = exclude = None
            if moving:
                if previous_coarse is None or previous_coarse.shape != coarse.shape:
                    raise DetectionError(f"{where}needs a second frame to tell moving markers from still "
                                         "glints")
                roi = _moving_roi(coarse, previous_coarse, scene.noise_sigma, gray.shape)
                if roi is None:
                    raise DetectionError(f"{where}nothing moves")
                span = area_range_px or _default_area_range(gray.shape)
                exclude = _bright_spots(previous, scene.levels, span, roi)
            # Given positions hold for the first search, and in a still clip until a pattern is
            # followed: a start lost over its first frames is looked for there again, not among glints.
            look_near_start = first_frame_xy is not None and (not ever_found or (not moving and not confirmed))
            pattern = _find_pattern(gray, n, threshold=threshold, area_range_px=area_range_px,
                                    first_frame_xy=first_frame_xy if look_near_start else None, layout=layout,
                                    max_candidates=24, ambiguity_margin=0.03, exclude_xy=exclude, roi=roi,
                                    pad_px=pad_px, where=where, scene=scene)
            if moving and not look_near_start and layout == "row" and _row_runs_out_of_view(pattern, gray.shape):
                # The horse is entering (or leaving) the view: a marker of the row may still be outside
                # it, and a look-alike moving with the horse (a D-ring) would stand in for it; the tracker
                # would keep the look-alike once the marker came in (a 120 fps canter: 16 % instead of 6 %).
                raise DetectionError(f"{where}the marker row runs to the edge of the image: a marker may "
                                     "still be outside the view")
        except DetectionError as exc:
            last_error = exc
            if moving:
                previous, previous_coarse = gray.copy(), coarse
            if not ever_found and len(indices) >= max_init_frames:
                raise DetectionError(f"{where}markers not found on any of the first {len(indices)} "
                                     f"frames (last: {exc})") from None
            continue
        if vec_ref is not None:
            pattern = _relabel(pattern, vec_ref)
        ever_found = True
        tracker = _Tracker(pattern, threshold_fixed=threshold is not None, window_px=window_px,
                           distance_tol=distance_tol, pad_px=pad_px, shape=gray.shape)
        tracked_from = len(xy_rows) - 1
        xy_rows[-1] = pattern.xy_px.tolist()
        area_rows[-1] = pattern.area_px.tolist()
    if not indices:
        raise DetectionError(f"{where}no frames to detect markers in")
    if all(all(p is None for p in row) for row in xy_rows):
        raise DetectionError(f"{where}markers not found on any of the {len(indices)} frames "
                             f"(last: {last_error})")
    xy_all = np.full((len(indices), n, 2), np.nan)
    area_all = np.full((len(indices), n), np.nan)
    for f, (row, arow) in enumerate(zip(xy_rows, area_rows, strict=True)):
        for m in range(n):
            if row[m] is not None:
                xy_all[f, m] = row[m]
                area_all[f, m] = arow[m]
    missing = np.isnan(xy_all[..., 0]).sum(axis=0)
    flags = tuple(f"{where}marker {m + 1} missing in {int(k)} of {len(indices)} frames"
                  for m, k in enumerate(missing) if k)
    return ImageTracks(camera=camera, xy_px=xy_all, frame_index=np.asarray(indices, dtype=np.int64),
                       area_px=area_all, flags=flags)

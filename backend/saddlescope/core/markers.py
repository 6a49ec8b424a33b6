"""Retro-reflective marker detection and tracking in one camera's clip (thesis 4.5).

The thesis's filter chain, with every choice the user used to make chosen automatically (and still
overridable): grey image, threshold (4.5.1), 8-connected labelling (4.5.2), area range (4.5.3), a
window that follows the markers' centre (4.5.4), pairwise distances that must match the pattern
within a tolerance (4.5.5, eq. 4.6-4.11) and the sign of the cross product for look-alikes
(Fig. 4.13). Centroids are intensity weighted (grey minus local background) for sub-pixel accuracy.
A marker that is not found is a gap (NaN), never a guess.

Frames are grey uint8 (or uint16) arrays of shape (H, W), typically the Y plane of a decoded video
frame, possibly a strided view into the decoder's buffer. After the first frame only a window around
the predicted markers is read, so detection costs little next to decoding.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

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

    @property
    def contrast(self) -> np.ndarray:
        return np.maximum(self.peak - self.background, 1.0)

    def take(self, idx) -> _Blobs:
        return _Blobs(self.xy[idx], self.area[idx], self.peak[idx], self.background[idx], self.fill[idx])

    def __len__(self) -> int:
        return self.xy.shape[0]


def _empty_blobs() -> _Blobs:
    z = np.zeros(0)
    return _Blobs(np.zeros((0, 2)), z, z.copy(), z.copy(), z.copy())


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
    g = pad + ring_gap_px
    X0, Y0 = np.maximum(x - g, 0), np.maximum(y - g, 0)
    X1, Y1 = np.minimum(x + w + g, W), np.minimum(y + h + g, H)
    sw, sh = int((X1 - X0).max()), int((Y1 - Y0).max())
    xs = X0[:, None] + np.arange(sw)  # (K, sw) window columns of each patch
    ys = Y0[:, None] + np.arange(sh)
    vx, vy = xs < X1[:, None], ys < Y1[:, None]
    xi, yi = np.minimum(xs, W - 1), np.minimum(ys, H - 1)
    patch = win[yi[:, :, None], xi[:, None, :]].astype(np.float64)
    lab = labels[yi[:, :, None], xi[:, None, :]]
    valid = vy[:, :, None] & vx[:, None, :]
    free = valid & (lab == 0)
    edge = ((xs == X0[:, None]) | (xs == X1[:, None] - 1))[:, None, :] \
        | ((ys == Y0[:, None]) | (ys == Y1[:, None] - 1))[:, :, None]
    ring = (edge & free).astype(np.float64)
    n = ring.sum(axis=(1, 2))
    X = xs[:, None, :].astype(np.float64)
    Y = ys[:, :, None].astype(np.float64)
    nz = np.maximum(n, 1.0)
    xm = (ring * X).sum(axis=(1, 2)) / nz
    ym = (ring * Y).sum(axis=(1, 2)) / nz
    gm = (ring * patch).sum(axis=(1, 2)) / nz
    dx, dy, dg = X - xm[:, None, None], Y - ym[:, None, None], patch - gm[:, None, None]
    rdx, rdy = ring * dx, ring * dy
    sxx, syy, sxy = (rdx * dx).sum(axis=(1, 2)), (rdy * dy).sum(axis=(1, 2)), (rdx * dy).sum(axis=(1, 2))
    sxg, syg = (rdx * dg).sum(axis=(1, 2)), (rdy * dg).sum(axis=(1, 2))
    det = sxx * syy - sxy * sxy
    fit = (n >= 8) & (det > 1e-9)
    safe = np.where(fit, det, 1.0)
    ax = np.where(fit, (syy * sxg - sxy * syg) / safe, 0.0)
    ay = np.where(fit, (sxx * syg - sxy * sxg) / safe, 0.0)
    if not (n >= 8).all():  # crowded or at the image edge: a flat level from the darkest free pixel
        darkest = np.where(free, patch, np.inf).min(axis=(1, 2))
        own_min = np.where(lab == ids[:, None, None], patch, np.inf).min(axis=(1, 2)) - 1.0
        gm = np.where(n >= 8, gm, np.where(np.isfinite(darkest), darkest, own_min))
    inner = (valid & ((xs >= (x - pad)[:, None]) & (xs < (x + w + pad)[:, None]))[:, None, :]
             & ((ys >= (y - pad)[:, None]) & (ys < (y + h + pad)[:, None]))[:, :, None])
    own = lab == ids[:, None, None]
    keep = inner & (own | (lab == 0))
    wts = patch - (gm[:, None, None] + ax[:, None, None] * dx + ay[:, None, None] * dy)
    wts = np.where(keep, np.maximum(wts, 0.0), 0.0)
    total = wts.sum(axis=(1, 2))
    out = np.empty((K, 4))
    ok = total > 0
    tz = np.where(ok, total, 1.0)
    out[:, 0] = np.where(ok, (wts.sum(axis=1) * xs).sum(axis=1) / tz, x + (w - 1) / 2)
    out[:, 1] = np.where(ok, (wts.sum(axis=2) * ys).sum(axis=1) / tz, y + (h - 1) / 2)
    out[:, 2] = np.where(own, patch, -np.inf).max(axis=(1, 2))
    out[:, 3] = gm + ax * (out[:, 0] - xm) + ay * (out[:, 1] - ym)
    return out


def _centroids(win: np.ndarray, labels: np.ndarray, stats: np.ndarray, keep: np.ndarray, offset,
               pad_px: int) -> _Blobs:
    """Sub-pixel centroids (see :func:`_refine`) of the components ``keep``, in full-image pixels."""
    out = _refine(win, labels, keep, stats[keep, :4], pad_px)
    xy = out[:, :2] + np.asarray(offset, dtype=np.float64)
    area = stats[keep, cv2.CC_STAT_AREA].astype(np.float64)
    fill = area / (stats[keep, cv2.CC_STAT_WIDTH] * stats[keep, cv2.CC_STAT_HEIGHT])
    return _Blobs(xy, area, out[:, 2].copy(), out[:, 3].copy(), fill)


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


def _candidate_thresholds(gray: np.ndarray) -> tuple[float, list[float]]:
    """Background level and a few thresholds between it and the brightest pixel."""
    sample = gray[::4, ::4]
    background = float(np.median(sample))
    brightest = float(gray.max())
    span = brightest - background
    levels = [background + f * span for f in (0.3, 0.5, 0.7, 0.85)]
    return background, sorted({round(v, 1) for v in levels})


def _all_blobs(gray: np.ndarray, threshold: float, area_range_px, max_candidates: int, pad_px: int) -> _Blobs:
    """Whole-image blobs at one threshold, cut to the brightest round-ish ``max_candidates``."""
    n, labels, stats, _ = _label(gray, threshold)
    if n <= 1:
        return _empty_blobs()
    area = stats[1:, cv2.CC_STAT_AREA]
    lo, hi = area_range_px
    keep = np.flatnonzero((area >= lo) & (area <= hi)) + 1
    if keep.size == 0:
        return _empty_blobs()
    fill = stats[keep, cv2.CC_STAT_AREA] / (stats[keep, cv2.CC_STAT_WIDTH] * stats[keep, cv2.CC_STAT_HEIGHT])
    keep = keep[(fill > 0.3) | (stats[keep, cv2.CC_STAT_AREA] <= 12)]  # drop streaks and rings
    if keep.size > max_candidates:
        fg = labels > 0
        lab = labels[fg]
        sums = np.bincount(lab, weights=gray[fg], minlength=n)
        mean = sums[keep] / stats[keep, cv2.CC_STAT_AREA]
        sizes = stats[keep, cv2.CC_STAT_AREA]
        rank = np.lexsort((-sizes, -mean))  # brightest (on average) first, then biggest
        keep = np.sort(keep[rank[:max_candidates]])
    return _centroids(gray, labels, stats, keep, (0, 0), pad_px)


def _pattern_scores(blobs: _Blobs, combos: np.ndarray, layout: str) -> np.ndarray:
    """Implausibility of each combination (ncomb, n) of blobs as the marker pattern; lower is better."""
    la = np.log(blobs.area)[combos]
    lc = np.log(blobs.contrast)[combos]
    shape_pen = np.where(blobs.area > 12, np.clip(1 - blobs.fill / _DISC_FILL, 0, None), 0.0)[combos]
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
    score = score + 0.2 * np.log(np.maximum(dist.max(axis=(1, 2)) / diam, 1.0))  # close together
    if layout == "row" and n >= 3:
        centred = pts - pts.mean(axis=1, keepdims=True)
        sv = np.linalg.svd(centred, compute_uv=False)
        score = score + 4 * sv[:, -1] / np.maximum(sv[:, 0], 1e-9)
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        score = score + 0.5 * np.abs(vt[:, 0, 1])  # |sin| of the row's angle from horizontal
    elif layout == "vertical" and n == 2:
        d = pts[:, 1] - pts[:, 0]
        score = score + 2 * np.abs(d[:, 0]) / np.maximum(np.linalg.norm(d, axis=1), 1e-9)
    elif layout == "row" and n == 2:
        d = pts[:, 1] - pts[:, 0]
        score = score + 2 * np.abs(d[:, 1]) / np.maximum(np.linalg.norm(d, axis=1), 1e-9)
    return score


def _plausible(blobs: _Blobs, combos: np.ndarray, layout: str) -> np.ndarray:
    """Markers of one set look alike (areas within 4x, contrasts within 3x of each other), and a "row"
    is one: its width across is at most 30 % of its length."""
    a = blobs.area[combos]
    c = blobs.contrast[combos]
    ok = (a.max(axis=1) <= 4 * a.min(axis=1)) & (c.max(axis=1) <= 3 * c.min(axis=1))
    if layout == "row" and combos.shape[1] >= 3:
        pts = blobs.xy[combos]
        sv = np.linalg.svd(pts - pts.mean(axis=1, keepdims=True), compute_uv=False)
        ok &= sv[:, -1] <= 0.3 * sv[:, 0]
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
                    pad_px: int = 2, camera: str = "", clip: str = "") -> MarkerPattern:
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
        Accepted blob areas; default 2 px up to 0.5 % of the image for the search, then a range around
        the markers found (a quarter of the smallest to four times the largest) for tracking.
    first_frame_xy : array_like of shape (n_markers, 2), keyword-only
        Approximate marker positions (labels in this order): the nearest blob to each is taken.
    layout : {"row", "vertical", "any", "single"}, keyword-only
        Default: "single" for 1, "vertical" for 2, "row" for 3, "any" otherwise.
    max_candidates : int, keyword-only
        Blobs kept per threshold for the combinatorial search (brightest first).
    ambiguity_margin : float, keyword-only
        A second, different set of blobs scoring within this of the best makes the frame ambiguous.
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
    H, W = gray.shape
    search_range = area_range_px or (2.0, max(50.0, 0.005 * H * W))
    if threshold is None:
        background, levels = _candidate_thresholds(gray)
        if float(gray.max()) - background < 16:
            raise DetectionError(f"{where}no bright markers: the brightest pixel ({int(gray.max())}) is "
                                 f"barely above the background ({background:.0f})")
    else:
        levels = [float(threshold)]

    if first_frame_xy is not None:
        pattern = _pattern_near(gray, n, np.asarray(first_frame_xy, dtype=np.float64), levels,
                                search_range, area_range_px, max_candidates, pad_px, where)
        if threshold is not None:
            return pattern
        return _retune(gray, pattern, fixed_area=area_range_px is not None, pad_px=pad_px)

    best = None  # (score, threshold, blobs, idx, runner_up)
    most = 0
    for level in levels:
        blobs = _all_blobs(gray, level, search_range, max_candidates, pad_px)
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


def _pattern_near(gray, n, xy0, levels, search_range, area_range_px, max_candidates, pad_px, where):
    if xy0.shape != (n, 2) or not np.all(np.isfinite(xy0)):
        raise InputError(f"{where}first_frame_xy must be {n} finite (x, y) pairs, got shape {xy0.shape}")
    if n > 1:
        gaps = np.linalg.norm(xy0[:, None] - xy0[None], axis=-1)[np.triu_indices(n, 1)]
        radius = max(6.0, 0.4 * float(gaps.min()))
    else:
        radius = 15.0
    best = None
    for level in levels:
        blobs = _all_blobs(gray, level, search_range, max(max_candidates, 200), pad_px)
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


def _tracking_threshold(pattern: MarkerPattern) -> float:
    """Half way between the markers' background and the dimmest marker's peak."""
    bg = float(np.median(pattern.background))
    return bg + 0.5 * max(float(pattern.peak.min()) - bg, 2.0)


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
        self.M = M = pattern.xy_px.shape[0]
        self.est = pattern.xy_px.tolist()          # [[x, y], ...] estimated positions
        self.vel = [[0.0, 0.0] for _ in range(M)]  # px / frame
        self.ref_area = pattern.area_px.astype(float).tolist()
        self.ref_contrast = np.maximum(pattern.peak - pattern.background, 2.0).tolist()
        self.background = float(np.median(pattern.background))
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

    def window(self, pred) -> tuple[tuple[int, int, int, int], float]:
        grow = 1.5 ** min(self.lost, 12)
        if self.steps < 3:  # the speed is not known yet
            grow *= 2.0
        speed = max(math.hypot(vx, vy) for vx, vy in self.vel)
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
        best_cost, best = math.inf, None
        for combo in itertools.product(*options):
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
        pred = [[p[0] + v[0], p[1] + v[1]] for p, v in zip(self.est, self.vel, strict=True)]
        (x0, y0, x1, y1), margin = self.window(pred)
        M = self.M
        found: list = [None] * M
        areas: list = [None] * M
        if x1 - x0 < 1 or y1 - y0 < 1:
            self._update(pred, found, areas, [], [])
            return found, areas
        win = gray[y0:y1, x0:x1]  # a view: only the window is read
        n, labels, stats, cents = _label(win, self.threshold)
        lo, hi = self.area_range
        area_all = stats[1:n, cv2.CC_STAT_AREA]
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
            self.vel = [[0.9 * vx, 0.9 * vy] for vx, vy in self.vel]
            return
        self.lost = 0
        # Markers not seen are carried along by the mean correction of those seen.
        sx = sum(found[m][0] - pred[m][0] for m in seen) / len(seen)
        sy = sum(found[m][1] - pred[m][1] for m in seen) / len(seen)
        new = [found[m] if found[m] is not None else [pred[m][0] + sx, pred[m][1] + sy]
               for m in range(self.M)]
        vel = [[n[0] - e[0], n[1] - e[1]] for n, e in zip(new, self.est, strict=True)]
        if len(seen) < self.M:
            mvx = sum(vel[m][0] for m in seen) / len(seen)
            mvy = sum(vel[m][1] for m in seen) / len(seen)
            vel = [vel[m] if found[m] is not None else [mvx, mvy] for m in range(self.M)]
        for v in vel:  # a wrong match must not fling the window away
            speed = math.hypot(v[0], v[1])
            if speed > self.speed_cap:
                v[0] *= self.speed_cap / speed
                v[1] *= self.speed_cap / speed
        self.vel = vel
        self.est = new
        for a, b in itertools.combinations(seen, 2):
            pa, pb = found[a], found[b]
            self.vec_ref[a][b] = (pb[0] - pa[0], pb[1] - pa[1])
            self.vec_ref[b][a] = (pa[0] - pb[0], pa[1] - pb[1])
        for m, peak, bg in zip(seen, peaks, bgs, strict=True):
            self.ref_area[m] += 0.1 * (areas[m] - self.ref_area[m])
            self.ref_contrast[m] += 0.1 * (max(peak - bg, 2.0) - self.ref_contrast[m])
        self.background += 0.1 * (sorted(bgs)[len(bgs) // 2] - self.background)
        if not self.threshold_fixed:
            # Follow slow lighting changes: half way up the dimmest marker's contrast.
            self.threshold = self.background + 0.5 * max(min(self.ref_contrast), 2.0)


def track_markers(frames: Iterable[tuple[int, np.ndarray]], *, n_markers: int, camera: str = "",
                  clip: str = "", threshold: float | None = None,
                  area_range_px: tuple[float, float] | None = None,
                  window_px: int | Sequence[int] | None = None,
                  first_frame_xy=None, layout: str | None = None, distance_tol: float = 0.25,
                  max_init_frames: int = 10, pad_px: int = 2) -> ImageTracks:
    """Detect and follow ``n_markers`` markers through a clip.

    The first frame (or the first of ``max_init_frames`` on which all markers are visible) is searched
    whole with :func:`initial_markers`; later frames only inside a window around the markers'
    constant-velocity prediction, which grows while markers are lost. In the window, blobs pass the
    threshold and area filters, then the best assignment of blobs to markers is chosen: near the
    prediction, similar area and brightness, pairwise distances within ``distance_tol`` of the pattern
    (eq. 4.11) and the same cross-product signs as the first frame (Fig. 4.13). A marker without an
    acceptable blob is a gap (NaN).

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
        four marker diameters plus the markers' speed in px/frame).
    distance_tol : float, keyword-only
        Relative tolerance of the vector between two markers (length and direction) against the last
        frame where both were seen.
    max_init_frames : int, keyword-only
        Frames to try for initialisation before giving up.

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
    xy_rows: list[np.ndarray] = []
    area_rows: list[np.ndarray] = []
    indices: list[int] = []
    tracker: _Tracker | None = None
    last_error: DetectionError | None = None
    n = int(n_markers)
    for index, gray in frames:
        if tracker is None:
            _check_gray(gray, camera, clip, index)
            try:
                pattern = initial_markers(gray, n, threshold=threshold, area_range_px=area_range_px,
                                          first_frame_xy=first_frame_xy, layout=layout, pad_px=pad_px,
                                          camera=camera, clip=clip)
            except DetectionError as exc:
                last_error = exc
                xy_rows.append(np.full((n, 2), np.nan))
                area_rows.append(np.full(n, np.nan))
                indices.append(int(index))
                if len(indices) >= max_init_frames:
                    raise DetectionError(f"{where}markers not found on any of the first {len(indices)} "
                                         f"frames (last: {exc})") from None
                continue
            tracker = _Tracker(pattern, threshold_fixed=threshold is not None, window_px=window_px,
                               distance_tol=distance_tol, pad_px=pad_px, shape=gray.shape)
            xy_rows.append(pattern.xy_px.copy())
            area_rows.append(pattern.area_px.astype(np.float64))
            indices.append(int(index))
            continue
        if gray.shape != (tracker.H, tracker.W):
            raise InputError(f"{where}frame {index} has shape {gray.shape}, earlier frames "
                             f"{(tracker.H, tracker.W)}")
        found, areas = tracker.step(gray)
        xy_rows.append(found)
        area_rows.append(areas)
        indices.append(int(index))
    if not indices:
        raise DetectionError(f"{where}no frames to detect markers in")
    if tracker is None:
        raise DetectionError(f"{where}markers not found on any of the {len(indices)} frames "
                             f"(last: {last_error})")
    xy_all = np.full((len(indices), n, 2), np.nan)
    area_all = np.full((len(indices), n), np.nan)
    for f, (row, arow) in enumerate(zip(xy_rows, area_rows, strict=True)):
        for m in range(n):
            if row[m] is not None and np.all(np.isfinite(row[m])):
                xy_all[f, m] = row[m]
                area_all[f, m] = arow[m]
    missing = np.isnan(xy_all[..., 0]).sum(axis=0)
    flags = tuple(f"{where}marker {m + 1} missing in {int(k)} of {len(indices)} frames"
                  for m, k in enumerate(missing) if k)
    return ImageTracks(camera=camera, xy_px=xy_all, frame_index=np.asarray(indices, dtype=np.int64),
                       area_px=area_all, flags=flags)

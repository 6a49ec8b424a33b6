"""Which blobs are the markers: the labelled marker pattern on one frame (thesis 4.5, first frame).

Every choice the user used to make is chosen automatically (and still overridable): thresholds between
the background and the brightest pixel, and the most plausible set of n blobs (alike in size and
brightness, round, close together; horse markers in a near-horizontal row with similar gaps, plumb
markers one above the other). Ambiguity is an error, not a coin toss. The markers found are then
re-detected at the tracking threshold, so that their areas and centroids match what the tracker sees.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from saddlescope.core.detection.blobs import (
    _all_blobs,
    _Blobs,
    _check_gray,
    _detect,
    _roi_bounds,
    _Scene,
    _scene,
    _where,
)
from saddlescope.core.errors import DetectionError, InputError

__all__ = ["MarkerPattern", "initial_markers"]

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


def _default_layout(n_markers: int) -> str:
    return {1: "single", 2: "vertical", 3: "row"}.get(n_markers, "any")


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
    """Which combinations (ncomb, n) of blobs could be the markers at all.

    Markers of one set look alike (areas within 4x, contrasts within 3x of each other), stand apart,
    and a "row" is one: near horizontal, at most 30 % as wide as long, gaps within 3x of each other.
    """
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


# The whole-frame search starts on the frame shrunk this many times where frames are at least
# _COARSE_MIN_WIDTH_PX wide (1080p: markers some 6 px across stay 3 px, as at 640x480), then looks
# again at full resolution only around what it found: a fourth of the labelling work.
_COARSE_FACTOR = 2
_COARSE_MIN_WIDTH_PX = 1280


def _find_pattern_coarse_first(gray, n, *, threshold, area_range_px, first_frame_xy, layout, max_candidates,
                               ambiguity_margin, exclude_xy, roi, pad_px, where, scene: _Scene) -> MarkerPattern:
    """:func:`_find_pattern` on a shrunk frame first, then at full resolution around what it found.

    The pattern returned is always one found at full resolution, so its centroids, areas and threshold
    are those a full-resolution search gives the same blobs. The full-resolution search of the whole
    ``roi`` (or frame) runs only when the shrunk frame shows no pattern or the one it shows is not
    found again at full resolution. Given positions or a given threshold search at full resolution at once.
    """
    kwargs = dict(threshold=threshold, area_range_px=area_range_px, first_frame_xy=first_frame_xy, layout=layout,
                  max_candidates=max_candidates, ambiguity_margin=ambiguity_margin, pad_px=pad_px, where=where)
    f = _COARSE_FACTOR
    x0, y0, x1, y1 = _roi_bounds(roi, gray.shape)
    cx0, cy0 = x0 - x0 % f, y0 - y0 % f  # whole cells of f x f pixels
    w, h = (x1 - cx0) // f, (y1 - cy0) // f
    if gray.shape[1] < _COARSE_MIN_WIDTH_PX or first_frame_xy is not None or threshold is not None or min(w, h) < 8:
        return _find_pattern(gray, n, exclude_xy=exclude_xy, roi=roi, scene=scene, **kwargs)
    small = cv2.resize(gray[cy0:cy0 + f * h, cx0:cx0 + f * w], (w, h), interpolation=cv2.INTER_AREA)
    # pixel centres of an f x f area average: full = f * small + offset
    offset = np.array([cx0 + 0.5 * (f - 1), cy0 + 0.5 * (f - 1)])
    lo, hi = area_range_px or _default_area_range(gray.shape)
    exclude = None if exclude_xy is None else (np.asarray(exclude_xy, dtype=np.float64).reshape(-1, 2) - offset) / f
    try:
        coarse = _find_pattern(small, n, threshold=None, area_range_px=(max(1.0, lo / f ** 2), hi / f ** 2),
                               first_frame_xy=None, layout=layout, max_candidates=max_candidates,
                               ambiguity_margin=ambiguity_margin, exclude_xy=exclude, roi=None, pad_px=pad_px,
                               where=where, scene=_scene(small))
    except DetectionError:  # markers too small to see shrunk, or look-alikes as plausible there
        return _find_pattern(gray, n, exclude_xy=exclude_xy, roi=roi, scene=scene, **kwargs)
    xy = coarse.xy_px * f + offset
    # Around the pattern: a few diameters, enough for each blob's refinement patch and its neighbours.
    margin = 4.0 * f * max(coarse.diameter_px, 2.0) + 8.0
    around = (max(x0, math.floor(xy[:, 0].min() - margin)), max(y0, math.floor(xy[:, 1].min() - margin)),
              min(x1, math.ceil(xy[:, 0].max() + margin) + 1), min(y1, math.ceil(xy[:, 1].max() + margin) + 1))
    try:
        return _find_pattern(gray, n, exclude_xy=exclude_xy, roi=around, scene=scene, **kwargs)
    except DetectionError:
        return _find_pattern(gray, n, exclude_xy=exclude_xy, roi=roi, scene=scene, **kwargs)


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
    """``level``, or higher where a marker's own surround is as bright as it.

    A marker against the sky (a plumb line's top marker) merges with the sky below the sky's grey
    level, and the whole window reads as glare. Then the level is ``_THRESHOLD_FRACTION`` of the way
    from each marker's surround to its peak, the highest of those, if every marker's peak stays
    above it.
    """
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

"""Finding the horse markers among look-alikes with all cameras at once.

A ridden horse enters the view after the clip starts, and the arena holds bright look-alikes
(reflections, light patches, lamps) that one camera cannot tell from markers. Three calibrated cameras
can: a marker is a 3-D point seen consistently by every camera, and the three horse markers form the
triangle measured in the static shot. This module finds the first instant of a clip where such a
triangle is seen and returns each camera's image positions of markers 1-3 there, so the tracker of
thesis 4.5 starts from the right blobs instead of asking the user for labels.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Mapping

import cv2
import numpy as np

from saddlescope.core.errors import DetectionError
from saddlescope.core.triangulation import triangulate_nview
from saddlescope.core.types import Rig

__all__ = [
    "bright_spots",
    "consistent_points",
    "triangle_candidates",
    "find_markers_multiview",
    "camera_down",
    "tilt_from_down_deg",
    "plumb_candidates",
    "static_marker_candidates",
    "find_plumb_multiview",
    "find_static_multiview",
    "in_image",
    "SequentialFrames",
]


def bright_spots(gray: np.ndarray, *, max_spots: int = 40, radius_px: int | None = None,
                 min_contrast: float = 25.0, return_peaks: bool = False, split_lines: bool = False):
    """Centres of small bright spots (markers, glints), the most contrasted first.

    A white top-hat keeps what is brighter than its surroundings within ``radius_px`` (markers,
    glints) and drops large bright areas (sky, white boards); centroids are weighted by the top-hat.
    Thin lines pass the top-hat too: with ``split_lines`` a region too large for a spot is cut at
    half its height above the threshold, so markers on a plumb line's string come apart from it.

    Parameters
    ----------
    gray : ndarray of shape (H, W)
        Grey frame.
    max_spots : int, keyword-only
    radius_px : int, keyword-only
        Top-hat radius; default about 1/110 of the image width (at least 4 px).
    min_contrast : float, keyword-only
        Top-hat threshold floor in grey levels (the 99.5th percentile is used if higher).
    return_peaks : bool, keyword-only
    split_lines : bool, keyword-only

    Returns
    -------
    xy : ndarray of shape (K, 2)
        Spot centres in pixels.
    peaks : ndarray of shape (K,)
        The spots' top-hat peaks in grey levels; only with ``return_peaks``.
    """
    h, w = gray.shape
    r = int(radius_px or max(4, round(w / 110)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    tophat = cv2.morphologyEx(gray, cv2.MORPH_TOPHAT, kernel)
    thr = max(min_contrast, float(np.percentile(tophat, 99.5)))
    n, labels, stats, _ = cv2.connectedComponentsWithStats((tophat > thr).astype(np.uint8), connectivity=8)
    if n <= 1:
        return (np.empty((0, 2)), np.empty(0)) if return_peaks else np.empty((0, 2))
    area = stats[1:, cv2.CC_STAT_AREA]
    small = area <= (2 * r + 1) ** 2
    spots, peaks = [], []

    def add(patch: np.ndarray, x: int, y: int) -> None:
        # Centroid of what stands above half the spot's peak, weighted by the excess: a region can hold
        # more than the marker (a stretch of the string it hangs on, the bright edge of a plank beside
        # it), which pulled a plumb marker's centre 6 px up its string on a thesis-rig camera. Any
        # weighting by brightness alone keeps a symmetric spot's centre.
        top = patch.max()
        if top <= 0:
            return
        weights = np.maximum(patch - 0.5 * top, 0.0)
        total = weights.sum()
        yy, xx = np.mgrid[y:y + patch.shape[0], x:x + patch.shape[1]]
        spots.append(((xx * weights).sum() / total, (yy * weights).sum() / total))
        peaks.append(top)

    for i in np.flatnonzero(small) + 1:
        x, y, bw, bh = stats[i, :4]
        add(tophat[y:y + bh, x:x + bw].astype(np.float64) * (labels[y:y + bh, x:x + bw] == i), x, y)
    for i in (np.flatnonzero(~small) + 1) if split_lines else ():
        x, y, bw, bh = stats[i, :4]
        region = tophat[y:y + bh, x:x + bw].astype(np.float64) * (labels[y:y + bh, x:x + bw] == i)
        cut = thr + 0.5 * (region.max() - thr)
        m, sub, sub_stats, _ = cv2.connectedComponentsWithStats((region > cut).astype(np.uint8), connectivity=8)
        for j in range(1, m):
            if sub_stats[j, cv2.CC_STAT_AREA] <= (2 * r + 1) ** 2:
                sx, sy, sw, sh = sub_stats[j, :4]
                add(region[sy:sy + sh, sx:sx + sw] * (sub[sy:sy + sh, sx:sx + sw] == j), x + sx, y + sy)
    if not spots:
        return (np.empty((0, 2)), np.empty(0)) if return_peaks else np.empty((0, 2))
    order = np.argsort(peaks)[::-1][:max_spots]
    xy = np.asarray(spots, dtype=np.float64)[order]
    return (xy, np.asarray(peaks, dtype=np.float64)[order]) if return_peaks else xy


def _spots_at(frames: tuple[np.ndarray, np.ndarray | None], frac: float, max_spots: int) -> np.ndarray:
    """Spots at a fractional time between two consecutive frames.

    At a canter the markers move further between frames than they are apart, so nearest neighbours
    mix them up. Each spot instead takes the displacement that most spots share (a rigid patch moves
    as one): every candidate displacement is scored by how many spots it carries onto a spot of the
    next frame, and each spot keeps its best-supported one.
    """
    a = bright_spots(frames[0], max_spots=max_spots)
    if frac < 1e-3 or frames[1] is None or not len(a):
        return a
    b = bright_spots(frames[1], max_spots=max_spots)
    if not len(b):
        return np.empty((0, 2))
    gate = 0.06 * frames[0].shape[1]
    tol = max(1.5, 0.003 * frames[0].shape[1])
    disp = b[None, :, :] - a[:, None, :]  # (A, B, 2)
    ii, jj = np.nonzero(np.linalg.norm(disp, axis=2) < gate)
    if not len(ii):
        return np.empty((0, 2))
    cand = disp[ii, jj]  # (P, 2)
    moved = a[None, :, :] + cand[:, None, :]  # (P, A, 2)
    nearest = np.min(np.linalg.norm(moved[:, :, None, :] - b[None, None, :, :], axis=3), axis=2)  # (P, A)
    support = np.sum(nearest < tol, axis=1) - 1e-3 * np.linalg.norm(cand, axis=1)
    out = []
    for i in range(len(a)):
        mine = np.flatnonzero(ii == i)
        if len(mine):
            best = mine[np.argmax(support[mine])]
            out.append(a[i] + frac * cand[best])
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


_LINEAR_PREFILTER = 4.0  # of consistent_points: combinations refined when the linear error is within this many limits
_LINEAR_PREFILTER_PX = 10.0  # plus this (px)


def consistent_points(rig: Rig, spots: Mapping[str, np.ndarray], *, max_error_px: float = 2.5
                      ) -> tuple[np.ndarray, np.ndarray, list[str]] | None:
    """The 3-D points that one spot of every camera in ``spots`` agrees on, or None.

    Every combination of one spot per camera is triangulated; those reprojecting within
    ``max_error_px`` are kept, the best-fitting first, each spot used by one point at most.

    Parameters
    ----------
    rig : Rig
    spots : dict of camera name -> ndarray of shape (K_c, 2)
        Distorted pixels, all at one instant.
    max_error_px : float, keyword-only

    Returns
    -------
    (points, used, cameras) or None
        ``points`` ndarray of shape (P, 3) in mm, ``used`` ndarray of shape (P, C): each point's spot
        index per camera, ``cameras`` the C camera names; None with fewer than two cameras' spots or
        too many combinations.
    """
    cams = [c for c in rig.names if c in spots and len(spots[c])]
    if len(cams) < 2:
        return None
    grids = np.meshgrid(*[np.arange(len(spots[c])) for c in cams], indexing="ij")
    idx = np.stack([g.ravel() for g in grids], axis=1)  # (N, C) one spot per camera
    if len(idx) > 200_000:
        return None
    sub_rig = Rig({c: rig.cameras[c] for c in cams})
    # The linear solution first, for every combination: one whose linear error is many times the limit cannot
    # come within it (Gauss-Newton lowers a consistent point's error by a fraction of a pixel), so only the
    # few near ones are refined (of 25 spots per camera, 15,625 combinations, a few dozen near).
    _, err0 = triangulate_nview(sub_rig, {c: spots[c][idx[:, i]] for i, c in enumerate(cams)},
                                reject_outliers=False, refine_iterations=0)[:2]
    idx = idx[np.isfinite(err0) & (err0 < _LINEAR_PREFILTER * max_error_px + _LINEAR_PREFILTER_PX)]
    xy = {c: spots[c][idx[:, i]] for i, c in enumerate(cams)}
    xyz, err = triangulate_nview(sub_rig, xy, reject_outliers=False)[:2]
    ok = np.flatnonzero(np.isfinite(err) & (err < max_error_px))
    # A spot belongs to at most one 3-D point: keep the best-fitting points first.
    taken: list[set[int]] = [set() for _ in cams]
    keep = []
    for i in ok[np.argsort(err[ok])]:
        if all(idx[i, c] not in taken[c] for c in range(len(cams))):
            keep.append(i)
            for c in range(len(cams)):
                taken[c].add(idx[i, c])
    return xyz[keep], idx[keep], cams


def triangle_candidates(rig: Rig, spots: Mapping[str, np.ndarray], model_mm: np.ndarray, *,
                        max_error_px: float = 2.5, tol_mm: float | None = None) -> tuple[dict, float] | None:
    """The marker triangle among the spots of every camera, or None.

    Parameters
    ----------
    rig : Rig
    spots : dict of camera name -> ndarray of shape (K_c, 2)
        Distorted pixels, all at one instant.
    model_mm : ndarray of shape (M, 3)
        The markers' static-shot positions (any rigid placement).
    max_error_px : float, keyword-only
    tol_mm : float, keyword-only
        Largest RMS mismatch of the distances between markers; default 6 % of their mean (>= 6 mm).

    Returns
    -------
    (xy, rms_mm) or None
        ``xy`` dict of camera name -> ndarray of shape (M, 2) in model order, ``rms_mm`` the RMS
        distance mismatch in mm.
    """
    found = consistent_points(rig, spots, max_error_px=max_error_px)
    if found is None or len(found[0]) < model_mm.shape[0]:
        return None
    pts, used, cams = found
    m = model_mm.shape[0]
    d_model = np.linalg.norm(model_mm[:, None] - model_mm[None], axis=2)
    pairs = list(itertools.combinations(range(m), 2))
    scale = float(np.mean([d_model[a, b] for a, b in pairs]))
    tol = tol_mm if tol_mm is not None else max(6.0, 0.06 * scale)
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    best: tuple[float, tuple[int, ...] | None] = (np.inf, None)
    for perm in itertools.permutations(range(len(pts)), m):
        e = np.array([d[perm[a], perm[b]] - d_model[a, b] for a, b in pairs])
        rms = float(np.sqrt(np.mean(e ** 2)))
        if rms < best[0]:
            best = (rms, perm)
    if best[1] is None or best[0] > tol:
        return None
    chosen = used[list(best[1])]
    return {c: spots[c][chosen[:, i]] for i, c in enumerate(cams)}, best[0]


def find_markers_multiview(rig: Rig, frame_at: Callable[[str, int], np.ndarray | None],
                           offsets: Mapping[str, float], models_mm: list[np.ndarray], *, first: int, last: int,
                           step: int = 2, clip: str = "motion", max_spots: int = 25,
                           frame_position: Callable[[str, int], float] | None = None) -> tuple[int, dict]:
    """The first instant where every camera sees the marker triangle, and the markers' positions there.

    The instant is a reference-camera frame in [first, last) (every ``step``-th) where the spots of
    every camera hold the triangle of one of ``models_mm`` (:func:`triangle_candidates`).
    ``frame_at(camera, index)`` returns that camera's grey frame or None past its end; ``offsets``
    maps camera -> frames later the same instant appears in it (reference camera 0). A variable-rate
    clip (phones) needs ``frame_position(camera, k)``: the (fractional) frame of that camera at the
    instant of reference frame k, NaN outside the clip; it replaces ``k + offsets[camera]``.
    Positions are returned at each camera's nearest whole frame (``frames``), snapped to the spots
    seen there.

    Parameters
    ----------
    rig : Rig
    frame_at : callable (camera, index) -> ndarray of shape (H, W) or None
    offsets : dict of camera name -> float
    models_mm : list of ndarray of shape (M, 3)
        Candidate marker layouts (static-shot positions).
    first, last, step : int, keyword-only
    clip : str, keyword-only
        Named in the error.
    max_spots : int, keyword-only
    frame_position : callable (camera, k) -> float, keyword-only

    Returns
    -------
    (instant, found)
        ``found``: {"xy": {camera: ndarray of shape (M, 2)}, "frames": {camera: int}, "model": index
        into ``models_mm``, "rms_mm": float}.

    Raises
    ------
    DetectionError
        No such instant in [first, last).
    """
    cams = rig.names
    for k in range(first, last, step):
        spots = {}
        nearest = {}
        for c in cams:
            t = frame_position(c, k) if frame_position is not None else k + offsets.get(c, 0.0)
            if not np.isfinite(t) or t < 0:
                break
            f0 = int(np.floor(t))
            a, b = frame_at(c, f0), frame_at(c, f0 + 1)
            if a is None:
                break
            spots[c] = _spots_at((a, b), t - f0, max_spots)
            nearest[c] = f0 if (t - f0 < 0.5 or b is None) else f0 + 1
        else:
            best = None
            for i, model in enumerate(models_mm):
                found = triangle_candidates(rig, spots, model)
                if found is not None and (best is None or found[1] < best[2]):
                    best = (i, found[0], found[1])
            if best is not None:
                xy = {}
                for c, pts in best[1].items():
                    frame = frame_at(c, nearest[c])
                    assert frame is not None  # nearest[c] is a frame read above
                    here = bright_spots(frame, max_spots=max_spots)
                    if len(here):
                        d = np.linalg.norm(pts[:, None] - here[None], axis=2)
                        j = np.argmin(d, axis=1)
                        close = d[np.arange(len(pts)), j] < 0.05 * frame.shape[1]
                        pts = np.where(close[:, None], here[j], pts)
                    xy[c] = pts
                return k, {"xy": xy, "frames": nearest, "model": best[0], "rms_mm": best[2]}
    raise DetectionError(f"the {clip} clip: no instant where all cameras see the three horse markers with "
                         "the layout of the static shot (markers hidden, out of view, or the static shot "
                         "wrong)")


def camera_down(rig: Rig) -> np.ndarray:
    """The cameras' mean image-down direction in rig coordinates, a unit vector of shape (3,).

    Gravity's direction for cameras standing roughly level: a guess, used to recognise a plumb line,
    never as gravity itself.
    """
    down = np.mean([cam.R[1] for cam in rig.cameras.values()], axis=0)
    return down / np.linalg.norm(down)


def tilt_from_down_deg(rig: Rig, d: np.ndarray) -> np.ndarray:
    """Angle in degrees between line directions and the cameras' image-down direction.

    Parameters
    ----------
    rig : Rig
    d : ndarray of shape (..., 3)
        Line directions in rig coordinates (any length).

    Returns
    -------
    ndarray of shape (...,)
        Angle to :func:`camera_down`, either way along the line (0-90 degrees).
    """
    d = np.asarray(d, dtype=np.float64)
    length = np.linalg.norm(d, axis=-1)
    return np.degrees(np.arccos(np.clip(np.abs(d @ camera_down(rig)) / np.maximum(length, 1e-9), 0.0, 1.0)))


def _point_brightness(peaks: Mapping[str, np.ndarray], used: np.ndarray, cams: list[str]) -> np.ndarray:
    """Each consistent point's spot peak, averaged over the cameras (:func:`consistent_points`)."""
    return np.mean([peaks[c][used[:, k]] for k, c in enumerate(cams)], axis=0)


def plumb_candidates(rig: Rig, spots: Mapping[str, np.ndarray], peaks: Mapping[str, np.ndarray] | None = None, *,
                     max_tilt_deg: float = 25.0, length_mm: tuple[float, float] = (100.0, 5000.0),
                     max_error_px: float = 2.5) -> tuple[dict, float, np.ndarray] | None:
    """The plumb line's two markers among the spots of the cameras in ``spots``, or None.

    Glints on a wall or fence can pass for a plumb marker in one camera (a single view has nothing
    but brightness and a vertical pair to go by). Seen by every camera, a plumb line is two 3-D points
    one above the other: pairs of consistent points 0.1-5 m apart within ``max_tilt_deg`` of the
    cameras' image-down direction (cameras stand roughly level) are candidates. The string itself
    gives consistent points along the same vertical, faint ones: with ``peaks`` (each spot's
    brightness, :func:`bright_spots`) a pair loses 10 degrees' worth per its weaker point's shortfall
    from the brightest point (retro-reflective markers outshine a string).

    Parameters
    ----------
    rig : Rig
    spots : dict of camera name -> ndarray of shape (K_c, 2)
        Distorted pixels of one still instant.
    peaks : dict of camera name -> ndarray of shape (K_c,), optional
    max_tilt_deg : float, keyword-only
    length_mm : (float, float), keyword-only
    max_error_px : float, keyword-only

    Returns
    -------
    (xy, score, points_mm) or None
        ``xy`` dict of camera name -> ndarray of shape (2, 2), upper marker first; the score (the tilt
        from image-down in degrees plus the brightness penalty); the two points, ndarray of shape
        (2, 3) in mm.
    """
    found = consistent_points(rig, spots, max_error_px=max_error_px)
    if found is None or len(found[0]) < 2:
        return None
    pts, used, cams = found
    down = camera_down(rig)
    i, j = np.triu_indices(len(pts), 1)
    d = pts[j] - pts[i]
    length = np.linalg.norm(d, axis=1)
    tilt = tilt_from_down_deg(rig, d)
    ok = (length >= length_mm[0]) & (length <= length_mm[1]) & (tilt <= max_tilt_deg)
    if not ok.any():
        return None
    score = tilt.copy()
    if peaks is not None:
        brightness = _point_brightness(peaks, used, cams)
        score += 10.0 * (1.0 - np.minimum(brightness[i], brightness[j]) / brightness.max())
    best = np.flatnonzero(ok)[np.argmin(score[ok])]
    pair = [i[best], j[best]]
    if pts[pair[0]] @ down > pts[pair[1]] @ down:
        pair = pair[::-1]  # the upper marker first, as the tracker labels a vertical pair
    return {c: spots[c][used[pair, k]] for k, c in enumerate(cams)}, float(score[best]), pts[pair]


def _bright_at(gray: np.ndarray, xy: np.ndarray, *, radius_px: int = 3, min_contrast: float = 12.0) -> bool:
    """Whether a marker-like bright spot is within ``radius_px`` of each of the points ``xy`` (K, 2).

    A spot: the brightest pixel there stands ``min_contrast`` grey levels above the median of a ring
    6-10 px out. Points outside the image have none.
    """
    h, w = gray.shape
    yy, xx = np.mgrid[-10:11, -10:11]
    r = np.hypot(xx, yy)
    for x, y in np.asarray(xy, dtype=np.float64):
        if not (np.isfinite(x) and np.isfinite(y)):
            return False
        cx, cy = int(round(x)), int(round(y))
        if not (10 <= cx < w - 10 and 10 <= cy < h - 10):
            return False
        patch = gray[cy - 10:cy + 11, cx - 10:cx + 11].astype(np.float64)
        if patch[r <= radius_px].max() - np.median(patch[(r >= 6) & (r <= 10)]) < min_contrast:
            return False
    return True


def static_marker_candidates(rig: Rig, spots: Mapping[str, np.ndarray], peaks: Mapping[str, np.ndarray],
                             n_markers: int, *, max_extent_mm: float = 2000.0, min_gap_mm: float = 30.0,
                             max_error_px: float = 2.5, ambiguity: float = 0.5
                             ) -> tuple[dict, float, np.ndarray] | None:
    """The standing horse's ``n_markers`` markers among the spots of the cameras in ``spots``, or None.

    One camera sees wall and fence glints as bright as the markers, and one behind the horse in its
    image can pass for a marker there. Seen by every camera the markers are 3-D points on one horse:
    sets of ``n_markers`` consistent points within ``max_extent_mm`` of each other (and at least
    ``min_gap_mm`` apart) are candidates. A set loses 10 points per its dimmest point's shortfall from
    the brightest consistent point and 5 per the spread of its log brightness (retro-reflective
    markers look alike), and 2 per e-fold of its extent over 0.3 m (a horse's markers stand close).
    Two different sets scoring within ``ambiguity`` of each other leave the choice to each camera
    (None).

    Parameters
    ----------
    rig : Rig
    spots : dict of camera name -> ndarray of shape (K_c, 2)
        Distorted pixels of one still instant.
    peaks : dict of camera name -> ndarray of shape (K_c,)
        Each spot's brightness (:func:`bright_spots`).
    n_markers : int
    max_extent_mm, min_gap_mm, max_error_px, ambiguity : float, keyword-only

    Returns
    -------
    (xy, score, points_mm) or None
        ``xy`` dict of camera name -> ndarray of shape (n, 2), left to right in the first camera; the
        score; the points, ndarray of shape (n, 3) in mm.
    """
    found = consistent_points(rig, spots, max_error_px=max_error_px)
    if found is None or len(found[0]) < n_markers:
        return None
    pts, used, cams = found
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    brightness = _point_brightness(peaks, used, cams)
    log_b = np.log(np.maximum(brightness, 1e-9))
    scored = _scored_sets(d, brightness, log_b, n_markers, max_extent_mm, min_gap_mm)
    if scored is None or not len(scored[0]) or len(scored[0]) > 20_000:
        return None
    score, combos = scored
    if len(score) > 1 and score[1] - score[0] < ambiguity:
        return None
    combo = combos[0].tolist()
    combo = [combo[i] for i in np.argsort(spots[cams[0]][used[combo, 0], 0])]  # left to right, as the tracker labels
    return {c: spots[c][used[combo, k]] for k, c in enumerate(cams)}, float(score[0]), pts[combo]


def _scored_sets(d: np.ndarray, brightness: np.ndarray, log_b: np.ndarray, n_markers: int, max_extent_mm: float,
                 min_gap_mm: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Every admissible set of ``n_markers`` points scored as :func:`static_marker_candidates` scores them.

    Returns the scores (K,) and the sets (K, n_markers), best first (ties by the sets' order), all sets at
    once; None for too many sets.
    """
    n = len(d)
    if math.comb(n, n_markers) > 2_000_000:
        return None
    combos = np.array(list(itertools.combinations(range(n), n_markers)), dtype=np.int64).reshape(-1, n_markers)
    sub = d[combos[:, :, None], combos[:, None, :]]  # (K, n, n)
    iu = np.triu_indices(n_markers, 1)
    ok = np.all(sub <= max_extent_mm, axis=(1, 2)) & (sub[:, iu[0], iu[1]].min(axis=1) >= min_gap_mm)
    combos, sub = combos[ok], sub[ok]
    score = (10.0 * (1.0 - brightness[combos].min(axis=1) / brightness.max())
             + 5.0 * np.std(log_b[combos], axis=1)
             + 2.0 * np.log(np.maximum(sub.max(axis=(1, 2)), 300.0) / 300.0))
    order = np.lexsort(tuple(combos[:, k] for k in range(n_markers - 1, -1, -1)) + (score,))
    return score[order], combos[order]


def _find_still_multiview(rig: Rig, frames: Mapping[str, np.ndarray], candidates: Callable, *, max_spots: int,
                          split_lines: bool) -> tuple[dict, float, np.ndarray] | None:
    """The best of ``candidates(rig, spots, peaks)`` over all cameras' spots and every two cameras'.

    Two cameras agree on spurious points easily (any spots on matching epipolar lines), so a
    two-camera candidate counts only where the third camera shows a bright spot at each of its points
    or cannot see them (outside its image). One seen by all cameras wins unless a two-camera one
    scores more than 1 better.
    """
    frames = {c: g for c, g in frames.items() if c in rig.cameras}
    found_spots = {c: bright_spots(g, max_spots=max_spots, return_peaks=True, split_lines=split_lines)
                   for c, g in frames.items()}
    spots = {c: xy for c, (xy, _) in found_spots.items()}
    peaks = {c: p for c, (_, p) in found_spots.items()}
    everyone = candidates(rig, spots, peaks)
    pairs = []
    if len(spots) >= 3:
        for two in itertools.combinations(spots, 2):
            found = candidates(rig, {c: spots[c] for c in two}, peaks)
            if found is None:
                continue
            others = [c for c in frames if c not in two]
            if all(not in_image(rig, c, found[2]) or _bright_at(frames[c], rig.cameras[c].project(found[2]))
                   for c in others):
                pairs.append(found)
    best_pair = min(pairs, key=lambda p: p[1]) if pairs else None
    if everyone is not None and (best_pair is None or everyone[1] <= best_pair[1] + 1.0):
        return everyone
    return best_pair


def find_plumb_multiview(rig: Rig, frames: Mapping[str, np.ndarray], *, max_spots: int = 25
                         ) -> tuple[dict, float, np.ndarray] | None:
    """The plumb line's markers in the still frames ``frames`` {camera: grey frame (H, W)}, or None.

    Candidates (:func:`plumb_candidates`) come from all cameras' spots and from every two cameras'
    (a plumb line hung at the end of the arena may be outside one camera's view, or a marker against
    the bright sky too faint for the spot search there): :func:`_find_still_multiview`.

    Returns
    -------
    (xy, score, points_mm) or None
        ``xy`` dict of camera name -> ndarray of shape (2, 2) (upper marker first) for the cameras
        whose spots it was found among, its score, and the two points, ndarray of shape (2, 3) in mm.
    """
    return _find_still_multiview(rig, frames, plumb_candidates, max_spots=max_spots, split_lines=True)


def find_static_multiview(rig: Rig, frames: Mapping[str, np.ndarray], n_markers: int, *, max_spots: int = 25
                          ) -> tuple[dict, float, np.ndarray] | None:
    """The standing horse's markers in the still frames ``frames`` {camera: grey frame (H, W)}, or None.

    Candidates (:func:`static_marker_candidates`) come from all cameras or two and the third's check
    (:func:`_find_still_multiview`).

    Returns
    -------
    (xy, score, points_mm) or None
        ``xy`` dict of camera name -> ndarray of shape (n, 2) (left to right) for the cameras whose
        spots they were found among, the score, and the points, ndarray of shape (n, 3) in mm.
    """
    return _find_still_multiview(rig, frames, functools.partial(static_marker_candidates, n_markers=n_markers),
                                 max_spots=max_spots, split_lines=False)


def in_image(rig: Rig, camera: str, points_mm: np.ndarray) -> bool:
    """Whether every point of ``points_mm`` (N, 3), rig mm, is in front of the camera and inside its image."""
    cam = rig.cameras[camera]
    depth = (np.asarray(points_mm) @ np.asarray(cam.R).T + cam.t_mm)[:, 2]
    xy = cam.project(points_mm)
    w, h = cam.image_size
    return bool(np.all(depth > 0) and np.all((xy >= 0) & (xy < (w, h))))


class SequentialFrames:
    """Random access to frames of forward-only streams, keeping the last few decoded frames.

    ``open_stream(camera, start)`` returns an iterator of (index, grey frame); asking for an earlier
    frame than those kept reopens the stream.
    """

    def __init__(self, open_stream: Callable, keep: int = 4):
        self.open_stream = open_stream
        self.keep = keep
        self._iters: dict = {}
        self._cache: dict[str, dict[int, np.ndarray]] = {}
        self._ended: dict[str, int] = {}

    def __call__(self, camera: str, index: int) -> np.ndarray | None:
        """The camera's grey frame ``index`` (H, W), or None before the clip or past its end."""
        if index < 0:
            return None
        cache = self._cache.setdefault(camera, {})
        if index in cache:
            return cache[index]
        if camera in self._ended and index >= self._ended[camera]:
            return None
        it = self._iters.get(camera)
        if it is None or (cache and index < min(cache)):
            it = self._iters[camera] = iter(self.open_stream(camera, max(0, index - 1)))
            cache.clear()
        for i, frame in it:
            cache[i] = frame.copy()
            for old in [j for j in cache if j < i - self.keep]:
                del cache[old]
            if i >= index:
                break
        else:
            self._ended[camera] = max(cache) + 1 if cache else index
        return cache.get(index)

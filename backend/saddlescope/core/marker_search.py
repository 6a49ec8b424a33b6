"""Finding the horse markers among look-alikes with all cameras at once.

A ridden horse enters the view after the clip starts, and the arena holds bright look-alikes
(reflections, light patches, lamps) that one camera cannot tell from markers. Three calibrated cameras
can: a marker is a 3-D point seen consistently by every camera, and the three horse markers form the
triangle measured in the static shot. This module finds the first instant of a clip where such a
triangle is seen and returns each camera's image positions of markers 1-3 there, so the tracker of
thesis 4.5 starts from the right blobs instead of asking the user for labels.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping

import cv2
import numpy as np

from saddlescope.core.errors import DetectionError
from saddlescope.core.triangulation import triangulate_nview
from saddlescope.core.types import Rig


def bright_spots(gray: np.ndarray, *, max_spots: int = 40, radius_px: int | None = None,
                 min_contrast: float = 25.0) -> np.ndarray:
    """Centres (K, 2) of small bright spots, the most contrasted first.

    A white top-hat keeps what is brighter than its surroundings within ``radius_px`` (markers,
    glints) and drops large bright areas (sky, white boards); centroids are weighted by the top-hat.
    """
    h, w = gray.shape
    r = int(radius_px or max(4, round(w / 110)))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    tophat = cv2.morphologyEx(gray, cv2.MORPH_TOPHAT, kernel)
    thr = max(min_contrast, float(np.percentile(tophat, 99.5)))
    n, labels, stats, _ = cv2.connectedComponentsWithStats((tophat > thr).astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.empty((0, 2))
    area = stats[1:, cv2.CC_STAT_AREA]
    keep = np.flatnonzero(area <= (2 * r + 1) ** 2) + 1
    spots, peaks = [], []
    for i in keep:
        x, y, bw, bh = stats[i, :4]
        patch = tophat[y:y + bh, x:x + bw].astype(np.float64) * (labels[y:y + bh, x:x + bw] == i)
        total = patch.sum()
        if total <= 0:
            continue
        yy, xx = np.mgrid[y:y + bh, x:x + bw]
        spots.append(((xx * patch).sum() / total, (yy * patch).sum() / total))
        peaks.append(patch.max())
    if not spots:
        return np.empty((0, 2))
    order = np.argsort(peaks)[::-1][:max_spots]
    return np.asarray(spots, dtype=np.float64)[order]


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


def triangle_candidates(rig: Rig, spots: Mapping[str, np.ndarray], model_mm: np.ndarray, *,
                        max_error_px: float = 2.5, tol_mm: float | None = None) -> tuple[dict, float] | None:
    """The marker triangle among the spots of every camera, or None.

    Parameters
    ----------
    spots : dict camera -> ndarray (K_c, 2) distorted px, all at one instant
    model_mm : ndarray of shape (M, 3), the markers' static-shot positions (any rigid placement)

    Returns
    -------
    ({camera: ndarray (M, 2)} in model order, RMS distance mismatch in mm) or None.
    """
    cams = [c for c in rig.names if c in spots and len(spots[c])]
    if len(cams) < 2:
        return None
    grids = np.meshgrid(*[np.arange(len(spots[c])) for c in cams], indexing="ij")
    idx = np.stack([g.ravel() for g in grids], axis=1)  # (N, C) one spot per camera
    if len(idx) > 200_000:
        return None
    xy = {c: spots[c][idx[:, i]] for i, c in enumerate(cams)}
    xyz, err = triangulate_nview(Rig({c: rig.cameras[c] for c in cams}), xy, reject_outliers=False)[:2]
    ok = np.isfinite(err) & (err < max_error_px)
    if ok.sum() < model_mm.shape[0]:
        return None
    pts, used = xyz[ok], idx[ok]
    # A spot belongs to at most one 3-D point: keep the best-fitting points first.
    order = np.argsort(err[ok])
    taken = [set() for _ in cams]
    keep = []
    for i in order:
        if all(used[i, c] not in taken[c] for c in range(len(cams))):
            keep.append(i)
            for c in range(len(cams)):
                taken[c].add(used[i, c])
    pts, used = pts[keep], used[keep]
    m = model_mm.shape[0]
    d_model = np.linalg.norm(model_mm[:, None] - model_mm[None], axis=2)
    pairs = list(itertools.combinations(range(m), 2))
    scale = float(np.mean([d_model[a, b] for a, b in pairs]))
    tol = tol_mm if tol_mm is not None else max(6.0, 0.06 * scale)
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    best = (np.inf, None)
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
    """First instant (reference-camera frame) in [first, last) where every camera sees the marker
    triangle of one of ``models_mm``, and each camera's marker positions there.

    ``frame_at(camera, index)`` returns that camera's grey frame or None past its end; ``offsets``
    maps camera -> frames later the same instant appears in it (reference camera 0). A variable-rate
    clip (phones) needs ``frame_position(camera, k)``: the (fractional) frame of that camera at the
    instant of reference frame k, NaN outside the clip; it replaces ``k + offsets[camera]``.
    Positions are returned at each camera's nearest whole frame (``frames``), snapped to the spots
    seen there.

    Returns (instant, {"xy": {camera: (M, 2)}, "frames": {camera: int}, "model": index, "rms_mm"}).
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
                    here = bright_spots(frame_at(c, nearest[c]), max_spots=max_spots)
                    if len(here):
                        d = np.linalg.norm(pts[:, None] - here[None], axis=2)
                        j = np.argmin(d, axis=1)
                        close = d[np.arange(len(pts)), j] < 0.05 * frame_at(c, nearest[c]).shape[1]
                        pts = np.where(close[:, None], here[j], pts)
                    xy[c] = pts
                return k, {"xy": xy, "frames": nearest, "model": best[0], "rms_mm": best[2]}
    raise DetectionError(f"the {clip} clip: no instant where all cameras see the three horse markers with "
                         "the layout of the static shot (markers hidden, out of view, or the static shot "
                         "wrong)")


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

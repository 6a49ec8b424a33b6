"""The free-fall ball's candidates: every camera's small bright spots and their 2-D tracks (thesis 8.3).

One camera cannot tell a ball in flight from a glint on the wall behind it, a lamp or another moving
bright thing, so every bright spot of every frame is kept (:func:`detect_spots`), linked into short
2-D tracks (:func:`link_spots`), and the tracks that stand still are dropped (:func:`moving_tracks`);
:mod:`.freefall` then finds the one that all cameras agree on.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import cv2
import numpy as np

from saddlescope.core.types import ImageTracks

__all__ = ["Spots", "bright_spots", "detect_spots", "link_spots", "moving_tracks"]

Spots = Mapping[int, np.ndarray]  # clip frame index -> (K, 2) spot centres, distorted px


def bright_spots(gray: np.ndarray, *, max_spots: int = 40, min_contrast: float = 25.0,
                 sigmas_px: tuple[float, ...] = (1.5, 2.5, 4.0)) -> np.ndarray:
    """Centres (K, 2) of small bright spots (a ball, glints), the most contrasted first.

    A spot curves down both ways; an edge, a stripe or a line only one way. So the candidates are the
    local maxima of the weaker of the two principal curvatures of the image smoothed at a few scales
    (scale-normalised Hessian, ``sigmas_px`` on frames up to 800 px wide; a wider frame is first shrunk
    to that), and each is measured on the full frame by :func:`_half_max_centroid`. A top-hat (as
    :func:`saddlescope.core.detection.search.bright_spots`) keeps whatever is narrower than its element:
    between the planks of a wall the background itself is a bright stripe, which joined a ball passing
    over it into one blob too big to be a spot.

    Parameters
    ----------
    gray : ndarray of shape (H, W)
        Grey frame.
    max_spots : int, keyword-only
    min_contrast : float, keyword-only
        Least height of a spot above its surroundings, grey levels.
    sigmas_px : tuple of float, keyword-only
        Smoothing scales of the curvature search.

    Returns
    -------
    ndarray of shape (K, 2)
        Spot centres in pixels, K <= ``max_spots``.
    """
    h, w = gray.shape
    f = max(1, w // 800)
    small = cv2.resize(gray, (w // f, h // f), interpolation=cv2.INTER_AREA) if f > 1 else gray
    g0 = small.astype(np.float32)
    strength = np.zeros_like(g0)
    scale = np.zeros_like(g0)
    for s in sigmas_px:
        g = cv2.GaussianBlur(g0, (0, 0), s)
        dxx = cv2.Sobel(g, cv2.CV_32F, 2, 0, ksize=3)
        dyy = cv2.Sobel(g, cv2.CV_32F, 0, 2, ksize=3)
        dxy = cv2.Sobel(g, cv2.CV_32F, 1, 1, ksize=3)
        # minus the larger Hessian eigenvalue, times sigma^2 (the 3x3 Sobel kernels sum to 4)
        root = cv2.magnitude(cv2.subtract(dxx, dyy), cv2.multiply(dxy, 2.0))  # type: ignore[call-overload]  # cv2's stubs lack the scalar form
        weak = cv2.addWeighted(cv2.add(dxx, dyy), -0.125 * s * s, root, -0.125 * s * s, 0)
        better = weak > strength
        np.copyto(strength, weak, where=better)
        scale[better] = s
    peaks = (strength >= cv2.dilate(strength, np.ones((5, 5), np.uint8))) & (strength > 0.1 * min_contrast)
    ys, xs = np.nonzero(peaks)
    order = np.argsort(strength[ys, xs])[::-1][:3 * max_spots]
    spots, contrast = [], []
    for i in order:
        centre = (xs[i] * f + (f - 1) / 2.0, ys[i] * f + (f - 1) / 2.0)
        found = _half_max_centroid(gray, centre, max(2.0, 1.5 * f * scale[ys[i], xs[i]]))
        if found is not None and found[1] >= min_contrast:
            spots.append(found[0])
            contrast.append(found[1])
    keep = np.argsort(contrast)[::-1][:max_spots]
    return np.asarray(spots, dtype=np.float64).reshape(-1, 2)[keep]


def _half_max_centroid(gray: np.ndarray, centre_xy: tuple[float, float],
                       radius_px: float) -> tuple[tuple[float, float], float] | None:
    """Centroid and contrast of the spot whose brightest pixel lies within ``radius_px`` of ``centre_xy``.

    The background is the median of a ring about twice the spot's radius out; the pixels brighter than
    half-way between it and the spot's brightest pixel (and than most of the ring), connected to that
    pixel, weigh by how much they exceed that level. A symmetric spot gives its centre whatever lies
    under the ring (a stripe, an edge), as long as it stays below half the spot's height.
    """
    h, w = gray.shape
    half = int(np.ceil(2.0 * radius_px)) + 2
    cx, cy = int(round(centre_xy[0])), int(round(centre_xy[1]))
    x0, y0 = max(0, cx - half), max(0, cy - half)
    x1, y1 = min(w, cx + half + 1), min(h, cy + half + 1)
    win = gray[y0:y1, x0:x1].astype(np.float64)
    if win.shape[0] < 5 or win.shape[1] < 5:
        return None
    r = int(np.ceil(radius_px))
    yy, xx = np.mgrid[y0:y1, x0:x1]
    near = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
    py, px = np.unravel_index(np.argmax(np.where(near, win, -np.inf)), win.shape)
    ring = np.concatenate([win[0], win[-1], win[1:-1, 0], win[1:-1, -1]])
    background = float(np.median(ring))
    top = float(win[py, px])
    if top <= background:
        return None
    # half-way up, and clear of the brightest quarter of the ring's own height above it: a spot in
    # front of an edge to a bright area (the sky above a wall) must not take that area's pixels
    ring_high = float(np.percentile(ring, 95))
    level = max(background + 0.5 * (top - background), ring_high + 0.25 * (top - ring_high))
    _, labels = cv2.connectedComponents((win > level).astype(np.uint8), connectivity=8)
    weights = np.where(labels == labels[py, px], win - level, 0.0)
    total = weights.sum()
    return ((float((xx * weights).sum() / total), float((yy * weights).sum() / total)), top - background)


def detect_spots(frames: Iterable[tuple[int, np.ndarray]], *, max_spots: int = 40) -> dict[int, np.ndarray]:
    """Small bright spots of every frame (:func:`bright_spots`).

    Parameters
    ----------
    frames : iterable of (int, ndarray of shape (H, W))
        Frame index and grey frame.
    max_spots : int, keyword-only

    Returns
    -------
    dict of int -> ndarray of shape (K, 2)
        Spot centres per frame index, the most contrasted first.
    """
    return {int(index): bright_spots(gray, max_spots=max_spots) for index, gray in frames}


class _Track:
    """A spot followed from frame to frame."""

    def __init__(self, frame: int, xy: np.ndarray):
        self.frames = [frame]
        self.xy = [xy]

    def predict(self, frame: int) -> np.ndarray:
        """Constant acceleration through the last three points (constant velocity through two)."""
        f = np.asarray(self.frames[-3:], dtype=np.float64) - self.frames[-1]
        p = np.asarray(self.xy[-3:])
        if f.size == 1:
            last: np.ndarray = p[-1]
            return last
        coef = np.polyfit(f, p, deg=min(2, f.size - 1))
        dt = frame - self.frames[-1]
        return np.array([np.polyval(coef[:, 0], dt), np.polyval(coef[:, 1], dt)])

    def as_image_tracks(self, camera: str) -> ImageTracks:
        frames = np.arange(self.frames[0], self.frames[-1] + 1)
        xy = np.full((frames.size, 1, 2), np.nan)
        xy[np.asarray(self.frames) - frames[0], 0] = self.xy
        return ImageTracks(camera=camera, xy_px=xy, frame_index=frames)


def link_spots(spots: Spots, *, camera: str = "", first_step_px: float = 40.0, gate_px: float = 6.0,
               max_gap: int = 2, min_frames: int = 4) -> list[ImageTracks]:
    """Link every frame's spots into tracks.

    A track predicts its next position from its last three (constant acceleration: a ball in flight)
    and takes a spot within ``gate_px`` of it; a track of one spot takes any spot within
    ``first_step_px`` (its speed is unknown). Pairs are assigned closest first, so a still glint keeps
    its own spot when a ball passes it. A track missing for more than ``max_gap`` frames ends.

    Parameters
    ----------
    spots : dict of int -> ndarray of shape (K, 2)
        Spot centres per clip frame (:func:`detect_spots`).
    camera : str, keyword-only
        Named in the tracks.
    first_step_px, gate_px : float, keyword-only
    max_gap, min_frames : int, keyword-only

    Returns
    -------
    list of ImageTracks
        ``xy_px`` of shape (F, 1, 2) over each track's frames (NaN in its gaps), for the tracks seen on
        at least ``min_frames`` frames.
    """
    active: list[_Track] = []
    done: list[_Track] = []
    for index in sorted(spots):
        xy = np.asarray(spots[index], dtype=np.float64).reshape(-1, 2)
        pairs = []
        if len(xy):
            for i, tr in enumerate(active):
                d = np.linalg.norm(xy - tr.predict(index), axis=1)
                limit = first_step_px if len(tr.frames) == 1 else gate_px
                pairs += [(float(d[j]), i, int(j)) for j in np.flatnonzero(d < limit)]
        taken_track, taken_spot = set(), set()
        for _, i, j in sorted(pairs):
            if i in taken_track or j in taken_spot:
                continue
            active[i].frames.append(index)
            active[i].xy.append(xy[j])
            taken_track.add(i)
            taken_spot.add(j)
        going: list[_Track] = []
        for tr in active:
            (going if index - tr.frames[-1] <= max_gap else done).append(tr)
        active = going + [_Track(index, xy[j]) for j in range(len(xy)) if j not in taken_spot]
    done += active
    return [tr.as_image_tracks(camera) for tr in done if len(tr.frames) >= min_frames]


def moving_tracks(tracks: Iterable[ImageTracks], *, min_travel_px: float = 8.0,
                  max_tracks: int = 12) -> list[ImageTracks]:
    """The tracks whose spot travels at least ``min_travel_px`` (a still glint does not).

    The longest path first, at most ``max_tracks``; each as given (``xy_px`` of shape (F, 1, 2)).
    """
    out = []
    for tr in tracks:
        xy = tr.xy_px[:, 0]
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        extent = float(np.linalg.norm(xy.max(axis=0) - xy.min(axis=0))) if len(xy) else 0.0
        if extent >= min_travel_px:
            out.append((extent, tr))
    out.sort(key=lambda e: -e[0])
    return [tr for _, tr in out[:max_tracks]]

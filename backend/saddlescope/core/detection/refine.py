"""Sub-pixel marker centroids: intensity weighted, over a local background (thesis 4.5.2).

The weights are grey minus a local background from a grey opening, so the step of a saddle pad's
edge or a thin line across the marker does not pull the centroid; < 0.01 px on clean discs. Each blob
is refined on its own patch of the whole image, so a centroid does not depend on the window it was
labelled in: the tracker's windowed centroids equal a whole-frame search's.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__: list[str] = []

_SQUARES: dict[int, np.ndarray] = {}


def _square(side: int) -> np.ndarray:
    """A ``side`` x ``side`` square structuring element (cached)."""
    kernel = _SQUARES.get(side)
    if kernel is None:
        kernel = _SQUARES[side] = np.ones((side, side), np.uint8)
    return kernel


def _above(gray: np.ndarray, threshold: float) -> np.ndarray:
    """1 where ``gray`` > ``threshold``, else 0 (uint8): the pixels blobs are labelled from (eq. 4.5)."""
    if gray.dtype == np.uint8:
        return cv2.threshold(gray, min(float(threshold), 255.0), 1, cv2.THRESH_BINARY)[1]
    return (gray > threshold).view(np.uint8)


def _below_or_at(gray: np.ndarray, threshold: float) -> np.ndarray:
    """1 - :func:`_above`: the free pixels, outside every blob."""
    if gray.dtype == np.uint8:
        return cv2.threshold(gray, min(float(threshold), 255.0), 1, cv2.THRESH_BINARY_INV)[1]
    return (gray <= threshold).view(np.uint8)


def _refine(gray: np.ndarray, labels: np.ndarray, ids: np.ndarray, boxes: np.ndarray, pad_px: int,
            threshold: float, origin: tuple[int, int] = (0, 0), ring_gap_px: int = 2) -> np.ndarray:
    """Intensity-weighted centroids of components ``ids`` of a labelled window of ``gray``.

    Weights are grey minus the local background inside each component's bounding box dilated by
    ``pad_px`` (more for big blobs, which are blurred over more pixels), with the pixels of other
    blobs (above ``threshold``) left out; the faint rim below threshold counts too, which removes the
    bias a hard threshold gives on a blurred disc. The background is a grey opening with a square wider
    than the blob (:func:`_opened`), which keeps a slope or an edge under the blob; the level the top-hat
    keeps on pure noise is read on the free (below threshold) border pixels of a box ``ring_gap_px``
    further out, far enough that the blob's own blur does not raise it, and subtracted.

    Each blob's patch is cut from the whole image, not from the window: a blob labelled in a small
    window (tracking) gets the same centroid as in a whole-frame search.

    Parameters
    ----------
    gray : ndarray of shape (H, W)
        The whole grey image; the patches may reach beyond the window.
    labels : ndarray of shape (h, w), uint16 or int32
        Component labels of the window whose top-left pixel is ``origin`` (x0, y0) in ``gray``.
    ids : ndarray of shape (K,), int
    boxes : ndarray of shape (K, 4), int
        Bounding boxes (x, y, w, h) in window pixels, as ``cv2.connectedComponentsWithStats`` gives them.
    pad_px : int
    threshold : float
        The level the window was labelled at.

    Returns
    -------
    ndarray of shape (K, 4)
        (x, y, peak grey level, background grey level under the centroid), x and y in image pixels.
    """
    K = int(ids.size)
    out = np.empty((K, 4))
    H, W = gray.shape
    ox, oy = int(origin[0]), int(origin[1])
    for k, (bx, by, w, h) in enumerate(np.asarray(boxes, dtype=np.int64).tolist()):
        x, y = bx + ox, by + oy  # the box in image pixels
        pad = pad_px + int(0.15 * max(w, h))
        side = (max(w, h) + 2 * pad + 1) | 1  # the opening's square (odd): wider than the blob, blur too
        g = pad + ring_gap_px                 # the ring where the background level is read
        G = g + side                          # the patch: the opening needs a square's width around the ring
        X0, Y0, X1, Y1 = max(x - G, 0), max(y - G, 0), min(x + w + G, W), min(y + h + G, H)
        grey = gray[Y0:Y1, X0:X1]
        patch = grey.astype(np.float32)
        own = np.zeros(patch.shape, np.uint8)
        own[y - Y0:y - Y0 + h, x - X0:x - X0 + w] = labels[by:by + h, bx:bx + w] == ids[k]
        free = _below_or_at(grey, threshold)
        opened = _opened(patch, side)
        top = patch - opened
        # The top-hat of pure noise is positive: remove its level, measured on the free ring (an empty
        # ring: cv2.mean gives 0).
        ring = np.zeros(patch.shape, np.uint8)
        cv2.rectangle(ring, (max(x - g, 0) - X0, max(y - g, 0) - Y0),
                      (min(x + w + g, W) - 1 - X0, min(y + h + g, H) - 1 - Y0), 1, 1)
        floor = np.float32(cv2.mean(top, mask=ring & free)[0])
        # Weights only near the blob: a thin bright line through the marker, such as a plumb line,
        # survives the opening and must not pull the centroid along itself.
        keep = cv2.dilate(own, _square(2 * pad + 1)) & (own | free)
        wts = cv2.threshold(top - floor, 0.0, 0.0, cv2.THRESH_TOZERO)[1]  # max(top - floor, 0)
        wts *= keep
        m = cv2.moments(wts)
        if m["m00"] > 0:
            out[k, 0], out[k, 1] = X0 + m["m10"] / m["m00"], Y0 + m["m01"] / m["m00"]
        else:
            out[k, 0], out[k, 1] = x + (w - 1) / 2, y + (h - 1) / 2
        out[k, 2] = cv2.minMaxLoc(patch, mask=own)[1]
        out[k, 3] = cv2.mean(opened, mask=own)[0]
    return out


def _opened(patch: np.ndarray, side: int) -> np.ndarray:
    """The background of a patch: a grey opening with a square of ``side`` px."""
    # A square wider than the blob (white top-hat) erases the blob and keeps whatever is larger - a
    # flat or sloping background, and the step of an edge the marker sits on (saddle pad against the
    # horse), where a fitted plane would pull the centroid. A small closing first fills thin dark lines
    # (a stripe on the wall behind a plumb marker), which the marker hides: left in, they would count
    # the marker twice along the line.
    closed = cv2.morphologyEx(patch, cv2.MORPH_CLOSE, _square(5))
    return cv2.morphologyEx(closed, cv2.MORPH_OPEN, _square(side))

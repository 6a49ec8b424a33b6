"""Sub-pixel marker centroids: intensity weighted, over a local background (thesis 4.5.2).

The weights are grey minus a local background from a grey opening, so the step of a saddle pad's
edge or a thin line across the marker does not pull the centroid; < 0.01 px on clean discs. All blobs
of one detection pass are refined at once, as one stack of equally sized patches.
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


def _refine(win: np.ndarray, labels: np.ndarray, ids: np.ndarray, boxes: np.ndarray, pad_px: int,
            ring_gap_px: int = 2) -> np.ndarray:
    """Intensity-weighted centroids of components ``ids`` of a labelled window, all at once.

    Weights are grey minus the local background inside each component's bounding box dilated by
    ``pad_px`` (more for big blobs, which are blurred over more pixels), with the pixels of other
    components left out; the faint rim below threshold counts too, which removes the bias a hard
    threshold gives on a blurred disc. The background is a grey opening with a square wider than the
    blob (:func:`_opened`), which keeps a slope or an edge under the blob; the level the top-hat keeps
    on pure noise is read on the free (unlabelled) border pixels of a box ``ring_gap_px`` further out,
    far enough that the blob's own blur does not raise it, and subtracted. The blobs are processed as
    one stack of equally sized patches (a few numpy calls per frame instead of a few per blob).

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
    x, y, w, h = (boxes[:, j].astype(np.int64) for j in range(4))
    pad = pad_px + (0.15 * np.maximum(w, h)).astype(np.int64)
    side = (np.maximum(w, h) + 2 * pad + 1) | 1  # the opening's square (odd): wider than the blob, blur too
    g = pad + ring_gap_px                 # the ring where the background level is read
    G = g + side                          # the patch: the opening needs a square's width around the ring
    xs, ys, patch, lab, valid = _patch_stack(win, labels, (x, y, w, h), G)
    ring = _ring(xs, ys, (x, y, w, h), g, win.shape) & (valid & (lab == 0))
    opened = _opened(patch, side)
    top = patch - opened
    # The top-hat of pure noise is positive: remove its level, measured on the free ring.
    n = ring.sum(axis=(1, 2))
    floor = np.where(n > 0, np.where(ring, top, 0.0).sum(axis=(1, 2)) / np.maximum(n, 1), 0.0)
    own = lab == ids[:, None, None]
    keep = _near(own, pad) & valid & (own | (lab == 0))
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


def _patch_stack(win: np.ndarray, labels: np.ndarray, box, G: np.ndarray):
    """Equally sized patches around each box (x, y, w, h) grown by ``G`` (K,) px, cut at the window.

    Returns the window columns xs (K, sw) and rows ys (K, sh) of each patch, its grey levels as
    float32 and its labels (K, sh, sw), and which of its pixels lie inside the patch proper (valid).
    """
    x, y, w, h = box
    H, W = win.shape
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
    return xs, ys, patch, lab, valid


def _ring(xs: np.ndarray, ys: np.ndarray, box, g: np.ndarray, shape) -> np.ndarray:
    """The border (K, sh, sw) of each box (x, y, w, h) grown by ``g`` (K,) px, cut at the window."""
    x, y, w, h = box
    H, W = shape
    rx0, ry0 = np.maximum(x - g, 0), np.maximum(y - g, 0)
    rx1, ry1 = np.minimum(x + w + g, W) - 1, np.minimum(y + h + g, H) - 1
    in_x = (xs >= rx0[:, None]) & (xs <= rx1[:, None])
    in_y = (ys >= ry0[:, None]) & (ys <= ry1[:, None])
    return (((xs == rx0[:, None]) | (xs == rx1[:, None])) & in_x)[:, None, :] & in_y[:, :, None] \
        | (((ys == ry0[:, None]) | (ys == ry1[:, None])) & in_y)[:, :, None] & in_x[:, None, :]


def _opened(patch: np.ndarray, side: np.ndarray) -> np.ndarray:
    """The background of each patch (K, sh, sw): a grey opening with a square of ``side`` (K,) px."""
    # A square wider than the blob (white top-hat) erases the blob and keeps whatever is larger - a
    # flat or sloping background, and the step of an edge the marker sits on (saddle pad against the
    # horse), where a fitted plane would pull the centroid. A small closing first fills thin dark lines
    # (a stripe on the wall behind a plumb marker), which the marker hides: left in, they would count
    # the marker twice along the line.
    opened = np.empty_like(patch)
    for k in range(patch.shape[0]):
        closed = cv2.morphologyEx(patch[k], cv2.MORPH_CLOSE, _square(5))
        opened[k] = cv2.morphologyEx(closed, cv2.MORPH_OPEN, _square(int(side[k])))
    return opened


def _near(own: np.ndarray, pad: np.ndarray) -> np.ndarray:
    """Each blob's own pixels (K, sh, sw) grown by its ``pad`` (K,) px: where weights may be."""
    # Weights only near the blob: a thin bright line through the marker, such as a plumb line,
    # survives the opening and must not pull the centroid along itself.
    near = np.empty_like(own)
    own_u8 = own.view(np.uint8)
    for k in range(own.shape[0]):
        near[k] = cv2.dilate(own_u8[k], _square(2 * int(pad[k]) + 1)).view(bool)
    return near

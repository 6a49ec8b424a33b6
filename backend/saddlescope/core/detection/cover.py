"""Partly covered markers (issue 38): a disc half behind a rider's boot, a tail or a lunge line.

A disc something passes in front of shrinks before it vanishes and grows again after: its centroid is
then pulled off the marker's centre, towards the part still seen, by up to the disc's radius. Such a
sample is worse than none: bridged through or fitted, it bends the stride's curve exactly where nothing
else measures it. :func:`partly_covered_samples` recognises them in one camera's tracks:

- its area against its own recent frames: a blob smaller than ``area_share`` of the marker's running
  median over ``window_frames`` frames on either side, while the other markers in the same frame
  keep theirs (a frame that blurs or dims every marker at once is no cover);
- the frames next to a gap inside a track (the disc was going behind something, or coming out).

:func:`drop_partly_covered` sets those samples to gaps (NaN), so that the fits see only whole discs.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from saddlescope.core.types import ImageTracks

__all__ = ["AREA_SHARE", "WINDOW_FRAMES", "drop_partly_covered", "partly_covered_samples"]

# A 30 mm disc is 6-10 px in area at 7.5 m on the thesis rig: its area scatters by 10-20 % from frame to
# frame (threshold and noise); a disc below half its running median is covered (a third of it or more).
AREA_SHARE = 0.5
WINDOW_FRAMES = 12
_NEIGHBOUR_SHARE = 0.85  # the other markers' own area ratios must stay above this (not a frame-wide dip)


def _running_median(area: np.ndarray, half: int) -> np.ndarray:
    """Per sample, the median of the finite areas within ``half`` samples on either side (NaN if none)."""
    n = area.size
    out = np.full(n, np.nan)
    for i in range(n):
        seg = area[max(0, i - half):i + half + 1]
        seg = seg[np.isfinite(seg)]
        if seg.size >= 3:
            out[i] = float(np.median(seg))
    return out


def partly_covered_samples(tracks: ImageTracks, *, area_share: float = AREA_SHARE,
                           window_frames: int = WINDOW_FRAMES, edge_frames: int = 1) -> np.ndarray:
    """Which samples (F, M) bool of one camera's tracks show a partly covered disc.

    Parameters
    ----------
    tracks : ImageTracks
        One camera's tracks; without ``area_px`` only the gaps' edges are judged.
    area_share : float
        A blob smaller than this share of its marker's running median area is covered.
    window_frames : int
        Half-width (frames) of the running median.
    edge_frames : int
        Samples on either side of a gap inside a track counted as partly covered (0: none).
    """
    xy = np.asarray(tracks.xy_px, dtype=np.float64)
    seen = np.all(np.isfinite(xy), axis=-1)
    n_frames, n_markers = seen.shape
    covered = np.zeros((n_frames, n_markers), bool)
    if tracks.area_px is not None and n_frames:
        area = np.where(seen, np.asarray(tracks.area_px, dtype=np.float64), np.nan)
        ratio = np.full_like(area, np.nan)
        for m in range(n_markers):
            with np.errstate(invalid="ignore", divide="ignore"):
                ratio[:, m] = area[:, m] / _running_median(area[:, m], int(window_frames))
        for m in range(n_markers):
            others = np.delete(ratio, m, axis=1)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # a frame where no other marker is seen
                neighbours = np.nanmedian(others, axis=1) if others.shape[1] else np.full(n_frames, np.nan)
            # a dip of this marker alone: the others keep their area (or are not seen to compare)
            alone = ~(neighbours < _NEIGHBOUR_SHARE)
            covered[:, m] |= (ratio[:, m] < area_share) & alone
    if edge_frames > 0:
        covered |= _gap_edges(seen, int(edge_frames))
    return covered & seen


def _gap_edges(seen: np.ndarray, edge_frames: int) -> np.ndarray:
    """Samples within ``edge_frames`` of a gap that has seen samples on both sides (not a track's ends)."""
    n_frames, n_markers = seen.shape
    out = np.zeros_like(seen)
    for m in range(n_markers):
        idx = np.flatnonzero(seen[:, m])
        if idx.size < 2:
            continue
        for a, b in zip(idx[:-1], idx[1:], strict=True):
            if b - a > 1:  # a gap between seen samples a and b
                out[max(a - edge_frames + 1, 0):a + 1, m] = True
                out[b:min(b + edge_frames, n_frames), m] = True
    return out & seen


def drop_partly_covered(tracks: ImageTracks, **options) -> tuple[ImageTracks, int]:
    """The tracks with partly covered samples set to gaps (NaN), and how many were dropped.

    ``options`` are :func:`partly_covered_samples`'s.
    """
    covered = partly_covered_samples(tracks, **options)
    if not covered.any():
        return tracks, 0
    xy = np.where(covered[..., None], np.nan, np.asarray(tracks.xy_px, dtype=np.float64))
    area = None if tracks.area_px is None else np.where(covered, np.nan, np.asarray(tracks.area_px, dtype=np.float64))
    return replace(tracks, xy_px=xy, area_px=area), int(covered.sum())

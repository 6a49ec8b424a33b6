"""Markers detected and followed through one camera's clip: :func:`track_markers` (thesis 4.5).

Search: the first frame on which all markers are visible is searched whole (:mod:`.pattern`); frames
1280 px wide or more are searched shrunk 2x first, then at full resolution only around the pattern that
shows there. Track: later frames only inside a window around the markers' prediction (:mod:`.tracker`),
with no work on the whole frame. A pattern not
followed over its first frames was not the markers, and the search goes on; after a loss the search
resumes every few frames and a re-found pattern keeps the old labels.

- Rides (``moving=True``): only the part of the frame that changed is searched, and spots that stood
  still since the previous frame (glints, lamps) are not markers; a marker row that runs to the edge of
  the image is not taken while the horse enters the view (a look-alike could complete it).
- While tracking only a window around the predicted markers is read, so detection costs little next
  to decoding.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from saddlescope.core.detection.blobs import _bright_spots, _check_gray, _coarse, _moving_roi, _Scene, _scene, _where
from saddlescope.core.detection.pattern import (
    MarkerPattern,
    _default_area_range,
    _default_layout,
    _find_pattern_coarse_first,
)
from saddlescope.core.detection.tracker import _Tracker
from saddlescope.core.errors import DetectionError, InputError
from saddlescope.core.types import ImageTracks

__all__ = ["track_markers"]


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
    window_px = _window_size(window_px, where)
    if not 0 < distance_tol < 1:
        raise InputError(f"{where}distance_tol must be in (0, 1), got {distance_tol}")
    n = int(n_markers)
    run = _ClipRun(_Options(n, camera, clip, where, threshold, area_range_px, window_px, first_frame_xy,
                            layout or _default_layout(n), distance_tol, moving, max_init_frames, confirm_frames,
                            lost_frames, search_every, pad_px))
    for index, gray in frames:
        run.feed(index, gray)
    return run.tracks()


def _window_size(window_px, where: str) -> tuple[int, int] | None:
    """The fixed tracking window (width, height) in px, or None (automatic)."""
    if window_px is None:
        return None
    if np.isscalar(window_px):
        side_px = int(window_px)  # type: ignore[arg-type]  # a number here; np.isscalar's guard also admits str
        window_px = (side_px, side_px)
    else:
        window_px = tuple(int(v) for v in window_px)
    if len(window_px) != 2 or min(window_px) < 3:
        raise InputError(f"{where}window_px must be a size >= 3 px or (width, height), got {window_px}")
    return window_px


@dataclass(frozen=True)
class _Options:
    """The settings of one :func:`track_markers` call (see there); ``where`` names camera and clip."""

    n: int
    camera: str
    clip: str
    where: str
    threshold: float | None
    area_range_px: tuple[float, float] | None
    window_px: tuple[int, int] | None
    first_frame_xy: object
    layout: str
    distance_tol: float
    moving: bool
    max_init_frames: int
    confirm_frames: int
    lost_frames: int
    search_every: int
    pad_px: int


class _ClipRun:
    """One clip through :func:`track_markers`.

    Each frame is searched for the markers, or, once they are found, followed by a :class:`_Tracker`;
    rows of positions and areas (None for a gap) pile up.
    """

    def __init__(self, opt: _Options):
        self.opt = opt
        self.xy_rows: list = []
        self.area_rows: list = []
        self.indices: list[int] = []
        self.tracker: _Tracker | None = None
        self.ever_found = False
        self.confirmed = False  # a pattern followed through its first frames
        self.tracked_from = 0            # row where the current tracker started
        self.since_search = 10 ** 6       # frames since the last search attempt
        self.last_error: DetectionError | None = None
        self.scene: _Scene | None = None
        self.scene_age = 0
        self.previous: np.ndarray | None = None        # moving mode: the previous frame (a copy) ...
        self.previous_coarse: np.ndarray | None = None  # ... and its 8x-shrunk version
        # vectors between markers when they were last tracked
        self.vec_ref: list[list[tuple[float, float]]] | None = None

    def feed(self, index, gray: np.ndarray) -> None:
        """Take the next frame (index, grey frame (H, W)): follow the markers, or search for them."""
        self.indices.append(int(index))
        if self.tracker is not None:
            self._follow(index, gray)
        else:
            self._search(index, gray)

    def _follow(self, index, gray: np.ndarray) -> None:
        """One frame of tracking.

        The tracker is dropped when its pattern was not followed at once (not the markers: its rows
        become gaps) or the markers are lost.
        """
        opt, tracker = self.opt, self.tracker
        assert tracker is not None  # feed() follows only with a tracker
        if gray.shape != (tracker.H, tracker.W):
            raise InputError(f"{opt.where}frame {index} has shape {gray.shape}, earlier frames "
                             f"{(tracker.H, tracker.W)}")
        found, areas = tracker.step(gray)
        self.xy_rows.append(found)
        self.area_rows.append(areas)
        recent = self.xy_rows[self.tracked_from + 1:]
        self.confirmed = self.confirmed or len(recent) > opt.confirm_frames
        if len(recent) <= opt.confirm_frames and sum(any(p is None for p in row) for row in recent) >= 2:
            # Not followed at once: the pattern found was not the markers. Forget it, search again.
            for r in range(self.tracked_from, len(self.xy_rows)):
                self.xy_rows[r] = [None] * opt.n
                self.area_rows[r] = [None] * opt.n
            self.tracker, self.since_search = None, 0
        elif tracker.lost >= opt.lost_frames:
            self.vec_ref = tracker.vec_ref
            self.tracker, self.since_search = None, 0
        if self.tracker is None and opt.moving:
            self.previous, self.previous_coarse = gray.copy(), _coarse(gray)

    def _search(self, index, gray: np.ndarray) -> None:
        """One frame of searching (every few frames only): a gap row, or the pattern found there."""
        opt = self.opt
        _check_gray(gray, opt.camera, opt.clip, index)
        self.xy_rows.append([None] * opt.n)
        self.area_rows.append([None] * opt.n)
        self.since_search += 1
        # A search costs some ten frames of tracking: after a loss look every few frames only, and for
        # a ride (the horse walks in) every other frame.
        every = opt.search_every if self.ever_found else (2 if opt.moving else 1)
        if self.since_search < every:
            return
        self.since_search = 0
        coarse = _coarse(gray)
        if self.scene is None or self.scene_age >= 30 or self.scene.coarse.shape != coarse.shape:
            self.scene, self.scene_age = _scene(gray, opt.threshold), 0
        self.scene_age += 1
        try:
            pattern = self._find(gray, coarse)
        except DetectionError as exc:
            self.last_error = exc
            if opt.moving:
                self.previous, self.previous_coarse = gray.copy(), coarse
            if not self.ever_found and len(self.indices) >= opt.max_init_frames:
                raise DetectionError(f"{opt.where}markers not found on any of the first {len(self.indices)} "
                                     f"frames (last: {exc})") from None
            return
        self._start(pattern, gray.shape)

    def _find(self, gray: np.ndarray, coarse: np.ndarray) -> MarkerPattern:
        """The marker pattern on this frame (:func:`_find_pattern`), or DetectionError."""
        opt = self.opt
        assert self.scene is not None  # feed() made it
        roi = exclude = None
        if opt.moving:
            roi, exclude = self._moving_search_area(gray, coarse)
        # Given positions hold for the first search, and in a still clip until a pattern is
        # followed: a start lost over its first frames is looked for there again, not among glints.
        look_near_start = opt.first_frame_xy is not None and (
            not self.ever_found or (not opt.moving and not self.confirmed))
        pattern = _find_pattern_coarse_first(
            gray, opt.n, threshold=opt.threshold, area_range_px=opt.area_range_px,
            first_frame_xy=opt.first_frame_xy if look_near_start else None, layout=opt.layout, max_candidates=24,
            ambiguity_margin=0.03, exclude_xy=exclude, roi=roi, pad_px=opt.pad_px, where=opt.where, scene=self.scene)
        if opt.moving and not look_near_start and opt.layout == "row" and _row_runs_out_of_view(pattern, gray.shape):
            # The horse is entering (or leaving) the view: a marker of the row may still be outside
            # it, and a look-alike moving with the horse (a D-ring) would stand in for it; the tracker
            # would keep the look-alike once the marker came in (a 120 fps canter: 16 % instead of 6 %).
            raise DetectionError(f"{opt.where}the marker row runs to the edge of the image: a marker may "
                                 "still be outside the view")
        return pattern

    def _moving_search_area(self, gray: np.ndarray, coarse: np.ndarray):
        """For a ride: where to search, and the still spots that are not markers.

        Returns the window (x0, y0, x1, y1) that changed since the previous frame, and the spots (S, 2)
        that were there before.
        """
        opt, scene = self.opt, self.scene
        assert scene is not None  # feed() made it
        if self.previous_coarse is None or self.previous_coarse.shape != coarse.shape:
            raise DetectionError(f"{opt.where}needs a second frame to tell moving markers from still "
                                 "glints")
        roi = _moving_roi(coarse, self.previous_coarse, scene.noise_sigma, gray.shape)
        if roi is None:
            raise DetectionError(f"{opt.where}nothing moves")
        span = opt.area_range_px or _default_area_range(gray.shape)
        assert self.previous is not None  # kept with previous_coarse, checked above
        return roi, _bright_spots(self.previous, scene.levels, span, roi)

    def _start(self, pattern: MarkerPattern, shape: tuple[int, int]) -> None:
        """Follow the pattern found on the last frame (relabelled like the markers before a loss)."""
        opt = self.opt
        if self.vec_ref is not None:
            pattern = _relabel(pattern, self.vec_ref)
        self.ever_found = True
        self.tracker = _Tracker(pattern, threshold_fixed=opt.threshold is not None, window_px=opt.window_px,
                                distance_tol=opt.distance_tol, pad_px=opt.pad_px, shape=shape)
        self.tracked_from = len(self.xy_rows) - 1
        self.xy_rows[-1] = pattern.xy_px.tolist()
        self.area_rows[-1] = pattern.area_px.tolist()

    def tracks(self) -> ImageTracks:
        """The rows of every frame fed as ImageTracks, NaN in the gaps; DetectionError if none found."""
        where, n, indices = self.opt.where, self.opt.n, self.indices
        if not indices:
            raise DetectionError(f"{where}no frames to detect markers in")
        if all(all(p is None for p in row) for row in self.xy_rows):
            raise DetectionError(f"{where}markers not found on any of the {len(indices)} frames "
                                 f"(last: {self.last_error})")
        xy_all = np.full((len(indices), n, 2), np.nan)
        area_all = np.full((len(indices), n), np.nan)
        for f, (row, arow) in enumerate(zip(self.xy_rows, self.area_rows, strict=True)):
            for m in range(n):
                if row[m] is not None:
                    xy_all[f, m] = row[m]
                    area_all[f, m] = arow[m]
        missing = np.isnan(xy_all[..., 0]).sum(axis=0)
        flags = tuple(f"{where}marker {m + 1} missing in {int(k)} of {len(indices)} frames"
                      for m, k in enumerate(missing) if k)
        return ImageTracks(camera=self.opt.camera, xy_px=xy_all, frame_index=np.asarray(indices, dtype=np.int64),
                           area_px=area_all, flags=flags)


def _relabel(pattern: MarkerPattern, vec_ref) -> MarkerPattern:
    """Order a re-found pattern like the markers were before, so labels survive losing them a while.

    The permutation that best keeps the vectors between markers ``vec_ref`` wins.
    """
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
    """Whether the marker row may run on outside the image.

    True when one more marker, the row's widest gap beyond either end, would not be whole in the
    image (a diameter and 2 px from the edge): then the row found may be the part of the markers in
    view, completed by a look-alike.
    """
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

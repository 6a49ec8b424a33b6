"""Video: a checkerboard tracked from frame to frame, searched for only when lost."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from saddlescope.core.calibration.boards import board_type, object_points_mm
from saddlescope.core.calibration.boards.checkerboard import (
    CheckerboardFinder,
    _checkerboard_corners,
    canonical_checkerboard_order,
)
from saddlescope.core.calibration.detection import BoardFinder
from saddlescope.core.calibration.refinement import _as_gray, _rescale, refine_corners_subpixel, unscale_px
from saddlescope.core.calibration.saddles import _grids_from_saddles, _saddle_clusters
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.errors import InputError
from saddlescope.core.types import Board

__all__ = ["BoardTracker", "detect_board_views"]

_TRACK_MAX_MOVE = 0.25  # of a corner's square spacing: moving further it may have slid onto the next one
_TRACK_MAX_FIT_GROWTH = 1.5  # r.m.s. distance of tracked corners from a board homography, over that when found
_MOVING_PX = 1.0  # board motion between frames above which a lost board is not searched for (still < 0.5 px)
_MIN_SQUARE_RATIO = 1.4  # of _square_checks: about 2 at a board's corner, at most 1 on its edge
# A lost board is looked for on the frame shrunk by a whole factor to about this width (block averages: a
# fraction of the cost of a 1000 px search at 1080p, and an exact pixel grid); its corners are then refined
# at full resolution.
COARSE_WIDTH_PX = 640
_FINE_SPACING_PX = 8.0  # squares smaller than this in the shrunk frame: their saddles found again less shrunk
# While the board last seen had squares of at least this in a frame shrunk twice as far (to about half the
# coarse width), a lost board is first looked for there: its saddles are still found (640x480 rides: squares of 4 px
# found as well at half size, at a quarter of the cost); a board come back smaller is looked for less shrunk.
_MIN_COARSE_SQUARE_PX = 2.0


@dataclass(frozen=True)
class _Track:
    corners: np.ndarray  # (N, 2) px in the frame
    scale: float  # the frame was resized by this before cornerSubPix (as when the board was found)
    sign: float  # of _square_checks' ratios: which squares are dark
    fit_rms: float  # px, r.m.s. distance of the corners from a board-to-image homography when found


class BoardTracker:
    """Checkerboard corners through the frames of a video: tracked from frame to frame, searched only when lost.

    A board found in one frame is followed into the next by ``cornerSubPix`` from its previous corners,
    on the frame resized as when it was found (tracked corners are as accurate as detected ones). They
    are kept only if every corner moved less than a quarter of its square, the squares round each corner
    still alternate as on the board (a board shifted by a whole square leaves corners on its edge, which
    the move test cannot see) and they fit a board-to-image homography about as well as when found.

    A lost board is looked for where strong saddle points (x-junctions) cluster in the frame shrunk by a whole
    factor to about ``coarse_width_px`` wide (cheaply first), and only while that region, and the one where the
    board was last seen, are not moving (a moving board is blurred, and only boards held still are used): the
    board's grid is grown over the region's saddle points, looked at again less shrunk where its squares are a
    few pixels, and refined at full resolution (precisely second), else ``findChessboardCornersSB`` searches
    the region. The whole frame is searched every ``search_every``
    frames at most, so that boards the localizer misses are still found. A board found again is also
    tracked back into the frame before.

    Parameters
    ----------
    board : Board of a trackable kind (a checkerboard)
    max_width : int
        As :class:`~saddlescope.core.calibration.detection.BoardFinder`.
    search_every : int
        Frames between whole-frame searches while the board is lost (half a second of video suits).
    coarse_width_px : int
        About the width of the shrunk frame the lost board's saddle points are looked for in.
    """

    def __init__(self, board: Board, *, max_width: int = 1000, search_every: int = 15,
                 coarse_width_px: int = COARSE_WIDTH_PX):
        kind = board_type(board.kind)
        if not kind.trackable:
            raise InputError(f"BoardTracker follows checkerboards; {kind.label} boards are found frame by frame")
        self.board = board
        self.max_width = int(max_width)
        self.search_every = max(1, int(search_every))
        if coarse_width_px < 64:
            raise InputError(f"coarse_width_px {coarse_width_px} is too small to find a board in (at least 64)")
        self.coarse_width_px = int(coarse_width_px)
        self.finder = CheckerboardFinder(board, max_width=max_width, thorough=False)
        self.ids = np.arange(board.inner_corners[0] * board.inner_corners[1])
        self._obj = object_points_mm(board)[:, :2].astype(np.float64)
        self.counts = {"tracked": 0, "tracked_back": 0, "found_from_saddles": 0, "found_near_saddles": 0,
                       "found_whole_frame": 0,
                       "skipped_moving": 0, "skipped_unchanged": 0, "whole_frame_searches": 0, "finer_searches": 0}
        self._failed: list[tuple[int, int, int, int]] = []  # boxes searched in vain in the frame before
        self._last_spacing_px: float | None = None  # median square of the board when last seen

    def views(self, frames: Iterable[tuple[int, np.ndarray]]) -> Iterable[BoardView]:
        """Board views of ``(frame index, grey image of shape (H, W))`` pairs, in frame order (a generator)."""
        track: _Track | None = None
        prev: tuple[int, np.ndarray] | None = None  # the frame before, copied (decoders reuse buffers)
        last_box: tuple[slice, slice] | None = None  # round the board when last seen
        lost_for = 0  # frames since the board was last seen
        since_search = self.search_every  # frames since the board was seen or the whole frame searched
        for index, gray in frames:
            gray = _as_gray(gray)
            found = self._follow(gray, track) if track is not None else None
            if found is not None:
                self.counts["tracked"] += 1
            # motion is measured at full size (a shrunk frame's noise over its weaker gradients overstates it)
            elif (prev is not None and last_box is not None and lost_for < self.search_every
                  and _motion_px(prev[1][last_box], gray[last_box]) > _MOVING_PX):
                self.counts["skipped_moving"] += 1  # the board is being moved away: wait until it is still
            else:
                found, near_moving = self._search_near_saddles(gray, None if prev is None else prev[1])
                if found is None and not near_moving and since_search >= self.search_every:
                    found = self._search_whole(gray)
                    since_search = 0
                if found is not None and prev is not None and lost_for > 0:
                    back = self._follow(prev[1], found)  # the frame before may show it still too
                    if back is not None:
                        self.counts["tracked_back"] += 1
                        yield BoardView(prev[0], back.corners, self.ids.copy())
            if found is not None:
                since_search = lost_for = 0
                last_box = _box_round(found.corners, gray.shape)
                yield BoardView(int(index), found.corners, self.ids.copy())
            else:
                since_search += 1
                lost_for += 1
            track = found
            prev = (int(index), gray.copy())

    def _state(self, gray: np.ndarray, corners: np.ndarray, scale: float) -> _Track:
        self._last_spacing_px = float(np.median(_local_spacing_px(corners, self.board.inner_corners)))
        ratio, _ = _square_checks(gray, corners, self.board.inner_corners)
        return _Track(corners, float(scale), 1.0 if np.median(ratio) >= 0 else -1.0,
                      _homography_rms(self._obj, corners))

    def _follow(self, gray: np.ndarray, track: _Track) -> _Track | None:
        """The tracked board in ``gray``, or None if it is lost."""
        corners, up = track.corners, track.scale
        local = _local_spacing_px(corners, self.board.inner_corners)
        h, w = gray.shape
        pad = local.max() + 4.0  # the cornerSubPix window plus the largest accepted move
        x0, y0 = np.maximum(np.floor(corners.min(axis=0) - pad), 0).astype(int)
        x1, y1 = np.minimum(np.ceil(corners.max(axis=0) + pad), [w, h]).astype(int)
        crop = gray[y0:y1, x0:x1]
        img = crop if up == 1.0 else cv2.resize(crop, None, fx=up, fy=up, interpolation=cv2.INTER_CUBIC)
        refined = refine_corners_subpixel(img, _rescale(corners - [x0, y0], up), self.board, upsampled=up != 1.0)
        new = unscale_px(refined, up) + [x0, y0]
        if np.any(np.linalg.norm(new - corners, axis=1) >= _TRACK_MAX_MOVE * local):
            return None
        ratio, span = _square_checks(gray, new, self.board.inner_corners)
        if np.any(ratio * track.sign < _MIN_SQUARE_RATIO) or np.any(span < 0.25 * np.median(span)):
            return None
        # the board fits a homography about as well as when it was found (lens distortion bends it a little)
        if _homography_rms(self._obj, new) > _TRACK_MAX_FIT_GROWTH * track.fit_rms + 0.05 * np.median(local):
            return None
        return _Track(new, up, track.sign, track.fit_rms)

    def _search_near_saddles(self, gray: np.ndarray, prev: np.ndarray | None) -> tuple[_Track | None, bool]:
        """The board searched for where saddle points cluster; also whether such a region was moving.

        Saddle points are looked for in ``gray`` shrunk by a whole factor (:func:`_coarse_factor`; where that
        finds nothing, by :func:`_shrink_factor`), motion against the frame before (``prev``, None for the
        first frame) at full size.
        """
        failed, self._failed = self._failed, []
        base = _shrink_factor(gray.shape[1], self.coarse_width_px)
        factor = _coarse_factor(gray.shape[1], self.coarse_width_px, self._last_spacing_px)
        found, moving = self._search_shrunk(gray, prev, factor, failed)
        if found is None and factor > base:
            # squares smaller than when last seen (further away) may be lost in the further shrunk frame, and
            # the noise's saddles there found instead (a region of noise looks as if moving)
            self._failed = []
            found, moving = self._search_shrunk(gray, prev, base, failed)
        return found, moving

    def _search_shrunk(self, gray: np.ndarray, prev: np.ndarray | None, factor: int,
                       failed: list[tuple[int, int, int, int]]) -> tuple[_Track | None, bool]:
        """:meth:`_search_near_saddles` with saddle points first looked for on ``gray`` shrunk by ``factor``.

        ``failed``: the boxes searched in vain in the frame before.
        """
        h, w = gray.shape
        small = _shrunk_by(gray, factor)
        moving = False
        clusters, at = _saddle_clusters(small, len(self.ids)), factor
        if not clusters and factor > 1:
            # a far board's squares are a pixel or two in the shrunk frame: look again, shrunk less
            self.counts["finer_searches"] += 1
            at = max(1, int(round(factor / 1.5)))
            clusters = _saddle_clusters(_shrunk_by(gray, at), len(self.ids))
        regions = []  # (box, spacing) where the grid was not grown: searched by SB after every grid was tried
        for cluster in clusters[:2]:
            x0, y0 = np.maximum(np.floor(unscale_px(cluster.box[:2], 1.0 / at)), 0).astype(int)
            x1, y1 = np.minimum(np.ceil(unscale_px(cluster.box[2:], 1.0 / at)), [w, h]).astype(int)
            crop = gray[y0:y1, x0:x1]
            motion = np.inf if prev is None else _motion_px(prev[y0:y1, x0:x1], crop)
            if np.isfinite(motion) and motion > _MOVING_PX:
                moving = True
                self.counts["skipped_moving"] += 1
                continue
            box = (x0, y0, x1, y1)
            if motion < 0.3 and any(_overlap(box, f) > 0.7 for f in failed):
                # the picture the search failed on in the frame before, unchanged: it would fail again
                self._failed.append(box)
                self.counts["skipped_unchanged"] += 1
                continue
            spacing = cluster.spacing * at
            # squares of a few px in the shrunk frame give a grid too rough to grow: look at the saddles of
            # the region again, shrunk less (the region is a small part of the frame)
            grid_cluster, grid_factor, origin = cluster, at, np.zeros(2)
            sub = max(1, int(spacing // _FINE_SPACING_PX))
            if sub < at:
                fine = _saddle_clusters(_shrunk_by(crop, sub), len(self.ids))
                if not fine:  # the board's corners would be saddles here too: no board
                    self._failed.append(box)
                    continue
                grid_cluster, grid_factor, origin = fine[0], sub, np.array([x0, y0], np.float64)
                spacing = fine[0].spacing * sub
            for grid in _grids_from_saddles(grid_cluster, self.board.inner_corners):
                grid = unscale_px(grid, 1.0 / grid_factor) + origin
                if self._looks_like_board(gray, grid):
                    refine = 2.0 if spacing < 6 else 1.0
                    corners = self._refined(crop, grid - [x0, y0], refine) + [x0, y0]
                    if self._looks_like_board(gray, corners):
                        self.counts["found_from_saddles"] += 1
                        return self._state(gray, corners, refine), False
                    break
            if max(x1 - x0, y1 - y0) > 3 * (max(self.board.inner_corners) + 5) * spacing:
                continue  # far larger than a board of such squares: a textured background, not worth SB
            regions.append((box, spacing))
        for (x0, y0, x1, y1), spacing in regions:
            found = self._find_in(gray[y0:y1, x0:x1], spacing)
            if found is not None:
                self.counts["found_near_saddles"] += 1
                return self._state(gray, found[0] + [x0, y0], found[1]), False
            self._failed.append((x0, y0, x1, y1))
        return None, moving

    def _refined(self, crop: np.ndarray, corners: np.ndarray, scale: float) -> np.ndarray:
        """Grid corners in a crop put in canonical order and refined on the crop resized by ``scale``."""
        img = crop if scale == 1.0 else cv2.resize(crop, None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)
        big = canonical_checkerboard_order(img, _rescale(corners, scale), self.board.inner_corners)
        return unscale_px(refine_corners_subpixel(img, big, self.board, upsampled=scale != 1.0), scale)

    def _looks_like_board(self, gray: np.ndarray, corners: np.ndarray) -> bool:
        """Whether the corners (N, 2) px look like the board.

        Every corner an x-junction of squares alternating as on the board (none on its edge), and all
        of them on a plane's perspective image.
        """
        ratio, span = _square_checks(gray, corners, self.board.inner_corners)
        ratio = ratio * np.sign(np.median(ratio))
        if np.any(ratio < _MIN_SQUARE_RATIO) or np.any(span < 0.25 * np.median(span)):
            return False
        local = _local_spacing_px(corners, self.board.inner_corners)
        return _homography_rms(self._obj, corners) < 0.2 * float(np.median(local))

    def _find_in(self, crop: np.ndarray, spacing: float) -> tuple[np.ndarray, float] | None:
        """Board corners in a crop whose squares are about ``spacing`` px, and the scale they were refined at.

        ``findChessboardCornersSB`` fails on squares of a few pixels, costing more than it takes to find a
        board, and also now and then on an upsampled crop: so search the crop upsampled 3x when the squares
        are small, else as it is, then the other way. Corners are refined as :class:`CheckerboardFinder` does
        (on the crop upsampled 2x if it had to be upsampled, else as it is).
        """
        if crop.shape[1] > 1.5 * self.max_width:  # a big board: searched downscaled, refined as it is
            found = self.finder._find_full(crop)
            return None if found is None else (found[0], self.finder.refine_scale)
        scales = (3.0, 2.0) if spacing < 6 else (1.0, 3.0) if spacing < 12 else (1.0, 2.0)
        for up in scales:
            img = crop if up == 1.0 else cv2.resize(crop, None, fx=up, fy=up, interpolation=cv2.INTER_CUBIC)
            # a crop round the board needs no histogram equalisation (without it SB is faster, as reliable)
            corners = _checkerboard_corners(img, self.board, thorough=False, normalize=False)
            if corners is None:
                continue
            refine = 1.0 if up == 1.0 else 2.0
            return self._refined(crop, unscale_px(corners, up), refine), refine
        return None

    def _search_whole(self, gray: np.ndarray) -> _Track | None:
        self.counts["whole_frame_searches"] += 1
        found = self.finder._find_full(gray)
        if found is None:
            return None
        self.counts["found_whole_frame"] += 1
        return self._state(gray, found[0], self.finder.refine_scale)


def _shrink_factor(width_px: int, coarse_width_px: int) -> int:
    """The whole factor that shrinks a frame ``width_px`` wide to about ``coarse_width_px`` (1: not at all)."""
    return max(1, int(round(width_px / coarse_width_px)))


def _coarse_factor(width_px: int, coarse_width_px: int, last_spacing_px: float | None) -> int:
    """The whole factor a lost board's saddle points are first looked for at.

    Shrunk to about ``coarse_width_px`` wide, or twice as far while the squares last seen stay
    ``_MIN_COARSE_SQUARE_PX`` there. Only twice as far or not at all: shrinking less further saves less
    than the searches repeated less shrunk (when the further shrunk frame shows no board, as a moving
    one) cost.
    """
    factor = _shrink_factor(width_px, coarse_width_px)
    if last_spacing_px is not None and last_spacing_px / (2 * factor) >= _MIN_COARSE_SQUARE_PX:
        return 2 * factor
    return factor


def _shrunk_by(gray: np.ndarray, factor: int) -> np.ndarray:
    """The frame (H, W) shrunk by a whole ``factor`` (:func:`_shrink_factor`, :func:`_coarse_factor`).

    Each pixel is the mean of a factor x factor block (the last rows and columns that do not fill a block
    are dropped): pixel i of the shrunk frame is centred on pixel (i + 0.5) * factor - 0.5 of the frame,
    as :func:`~saddlescope.core.calibration.refinement.unscale_px` maps it back.
    """
    if factor == 1:
        return gray
    h, w = gray.shape[0] // factor, gray.shape[1] // factor
    return cv2.resize(gray[:h * factor, :w * factor], (w, h), interpolation=cv2.INTER_AREA)


def _homography_rms(obj_xy: np.ndarray, img_xy: np.ndarray) -> float:
    """R.m.s. distance (px) of ``img_xy`` from the least-squares homography of board (x, y) to them."""
    H, _ = cv2.findHomography(obj_xy, img_xy, 0)
    if H is None:
        return np.inf
    fit = cv2.perspectiveTransform(obj_xy.reshape(-1, 1, 2), H).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum((img_xy - fit) ** 2, axis=1))))


def _local_spacing_px(corners: np.ndarray, inner_corners: tuple[int, int]) -> np.ndarray:
    """Per corner of a full grid, the distance (px) to its nearest neighbour along the grid."""
    cols, rows = inner_corners
    g = corners.reshape(rows, cols, 2)
    d = np.full((rows, cols), np.inf)
    dx = np.linalg.norm(np.diff(g, axis=1), axis=2)
    dy = np.linalg.norm(np.diff(g, axis=0), axis=2)
    d[:, :-1] = np.minimum(d[:, :-1], dx)
    d[:, 1:] = np.minimum(d[:, 1:], dx)
    d[:-1] = np.minimum(d[:-1], dy)
    d[1:] = np.minimum(d[1:], dy)
    return d.ravel()


def _square_checks(gray: np.ndarray, corners: np.ndarray, inner_corners: tuple[int, int]) -> tuple[np.ndarray,
                                                                                                   np.ndarray]:
    """Per corner (N,), a contrast ratio of the four squares round it, and their grey-level range.

    From the grey levels at the centres of the four squares: (one diagonal's sum minus the other's) /
    (their range), its sign alternating along the grid.

    About +-2 everywhere on a board (the sign says which squares are dark); at most 1 where a corner
    lies on the board's edge (two of its "squares" are the margin), as after a shift by a whole square.
    """
    cols, rows = inner_corners
    g = corners.reshape(rows, cols, 2)
    ext = np.empty((rows + 2, cols + 2, 2))
    ext[1:-1, 1:-1] = g
    ext[1:-1, 0], ext[1:-1, -1] = 2 * g[:, 0] - g[:, 1], 2 * g[:, -1] - g[:, -2]
    ext[0], ext[-1] = 2 * ext[1] - ext[2], 2 * ext[-2] - ext[-3]
    centre = 0.25 * (ext[:-1, :-1] + ext[1:, :-1] + ext[:-1, 1:] + ext[1:, 1:])  # (rows + 1, cols + 1, 2)
    v = cv2.remap(gray, centre[..., 0].astype(np.float32), centre[..., 1].astype(np.float32), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_REPLICATE).astype(np.float64)
    four = np.stack([v[:-1, :-1], v[1:, 1:], v[:-1, 1:], v[1:, :-1]])
    span = four.max(axis=0) - four.min(axis=0)
    alt = np.where(np.add.outer(np.arange(rows), np.arange(cols)) % 2 == 0, 1.0, -1.0)
    ratio = alt * (four[0] + four[1] - four[2] - four[3]) / np.maximum(span, 1e-6)
    return ratio.ravel(), span.ravel()


def _box_round(corners: np.ndarray, shape: tuple[int, int]) -> tuple[slice, slice]:
    """Slices of the image round a board's corners, with a margin of half the board's size."""
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    pad = 0.5 * (hi - lo)
    x0, y0 = np.maximum(np.floor(lo - pad), 0).astype(int)
    x1, y1 = np.minimum(np.ceil(hi + pad), [shape[1], shape[0]]).astype(int)
    return slice(y0, y1), slice(x0, x1)


def _overlap(a, b) -> float:
    """Intersection over union of two boxes (x0, y0, x1, y1)."""
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    if w <= 0 or h <= 0:
        return 0.0
    inter = w * h
    return inter / ((a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter)


def _motion_px(before: np.ndarray, after: np.ndarray) -> float:
    """Rough motion (px) of the picture between two crops (H, W).

    The grey-level change over the mean gradient along a random direction (a shift by d changes a
    pixel by about d times that gradient).
    """
    a = cv2.GaussianBlur(before.astype(np.float32), (0, 0), 1.0)
    b = cv2.GaussianBlur(after.astype(np.float32), (0, 0), 1.0)
    gx = cv2.Sobel(b, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(b, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    # E|grad . u| over random unit u is half of E(|gx| + |gy|) for isotropic gradients
    return float(np.mean(np.abs(b - a)) / (0.5 * np.mean(np.abs(gx) + np.abs(gy)) + 1e-6))


def detect_board_views(frames: Iterable[tuple[int, np.ndarray]], board: Board, *,
                       inverted: bool | None = None, max_width: int = 1000,
                       thorough: bool = False, track: bool = True,
                       search_every: int = 15) -> tuple[list[BoardView], tuple[int, int] | None]:
    """Board views in frames.

    Parameters
    ----------
    frames : iterable of (frame index, grey image of shape (H, W))
    board : Board
    track : bool
        Frames are consecutive frames of a video (or every ``step``-th): a checkerboard is tracked from
        frame to frame (:class:`BoardTracker`) instead of searched for in each frame. Not with ``thorough``.
    search_every : int
        While a tracked board is lost, frames between whole-frame searches (about half a second of video).

    Returns
    -------
    views : list of BoardView, in frame order
    image_size : (width, height) of the frames, or None when there were no frames

    Raises
    ------
    InputError
        If the frames do not all have the same size.
    """
    size = None

    def checked():
        nonlocal size
        for index, gray in frames:
            this = (int(gray.shape[1]), int(gray.shape[0]))
            if size is None:
                size = this
            elif this != size:
                raise InputError(f"frame {index} is {this[0]}x{this[1]} px, "
                                 f"earlier frames {size[0]}x{size[1]} px")
            yield index, gray

    if track and not thorough and board_type(board.kind).trackable:
        tracker = BoardTracker(board, max_width=max_width, search_every=search_every)
        return list(tracker.views(checked())), size
    finder = BoardFinder(board, inverted=inverted, max_width=max_width, thorough=thorough)
    views: list[BoardView] = []
    for index, gray in checked():
        found = finder(gray)
        if found is not None:
            views.append(BoardView(int(index), found[0], found[1]))
    return views, size

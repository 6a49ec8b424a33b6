"""The calibration clip checked before anyone rides: where the board went in each camera's image and depth.

A wand calibration's clip is checked the same way (:func:`check_wand_coverage`): where the wand's two ends
went over the image, and the distances its apparent length puts it at.

From the board corners found in a sample of one camera's calibration clip (a few frames a second, not
every frame): a coverage map over the image (a grid counting the views whose corners fell in each
cell), the reach of the board (its corners' extent and hull as shares of the image), the distances the
board was held at (each view's pose from a quick lens fit of the same views), and findings that name,
in words, the thirds of the image the board never reached. A third of the image never reached leaves
the lens model to extrapolate there (the partial-view canters of issue 27): film that part again.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from saddlescope.core.calibration.boards import object_points_mm
from saddlescope.core.findings import Finding
from saddlescope.core.types import Board

__all__ = ["BANDS", "CameraCoverageCheck", "check_camera_coverage", "check_wand_coverage"]

# The image's thirds: (axis, band index) -> name; axis 0 across (x), 1 down (y)
BANDS: dict[tuple[int, int], str] = {
    (0, 0): "left third", (0, 1): "middle band from top to bottom", (0, 2): "right third",
    (1, 0): "upper third", (1, 1): "middle band from side to side", (1, 2): "lower third",
}
_NINTHS = (("top-left", "top", "top-right"), ("left", "centre", "right"), ("bottom-left", "bottom", "bottom-right"))
MIN_VIEWS = 12  # views of the board a camera's lens fit wants at least
MIN_VIEWS_IN_BAND = 2  # one stray detection does not make a third reached
NARROW_DEPTH_RATIO = 1.25  # farthest / nearest view (10th-90th percentile) below this: one distance only


@dataclass(frozen=True)
class CameraCoverageCheck:
    """One camera's calibration clip checked: coverage over the image and depth, reach, findings, verdict."""

    camera: str
    image_size: tuple[int, int]
    frames_sampled: int
    views: int  # sampled frames in which the board was found
    grid: np.ndarray  # (rows, cols) int: views whose corners fell in each cell of the image
    bands_missed: tuple[str, ...]  # names of the thirds no corner reached (see BANDS)
    corners_missed: tuple[str, ...]  # names of the image's ninths no corner reached
    reach_x: tuple[float, float]  # leftmost and rightmost corner, as shares of the image width
    reach_y: tuple[float, float]  # topmost and lowest corner, as shares of the image height
    hull_fraction: float  # the corners' convex hull as a share of the image
    distances_m: np.ndarray  # (views,) the board's distance from the camera in each view (NaN: unknown)
    findings: tuple[Finding, ...] = field(default=())

    @property
    def film_again(self) -> bool:
        """Whether this camera's calibration clip should be filmed again before riding."""
        return any(f.severity == "problem" for f in self.findings)


def _views_per_cell(corners: Sequence[np.ndarray], size: tuple[int, int], shape: tuple[int, int]) -> np.ndarray:
    w, h = size
    rows, cols = shape
    grid = np.zeros(shape, np.int64)
    for pts in corners:
        cx = np.clip((pts[:, 0] * cols / w).astype(int), 0, cols - 1)
        cy = np.clip((pts[:, 1] * rows / h).astype(int), 0, rows - 1)
        hit = np.zeros(shape, bool)
        hit[cy, cx] = True
        grid += hit
    return grid


def _band_views(corners: Sequence[np.ndarray], size: tuple[int, int]) -> np.ndarray:
    """(2, 3) views whose corners reached each third: axis 0 across (x), axis 1 down (y)."""
    out = np.zeros((2, 3), np.int64)
    for pts in corners:
        for axis in (0, 1):
            bands = np.clip((3 * pts[:, axis] / size[axis]).astype(int), 0, 2)
            out[axis, np.unique(bands)] += 1
    return out


def _distances_m(corners: Sequence[np.ndarray], ids: Sequence[np.ndarray], board: Board,
                 size: tuple[int, int]) -> np.ndarray:
    """Each view's board distance (m) from a quick lens fit of these views (a 60 degree guess if it fails)."""
    grid_mm = object_points_mm(board).astype(np.float32)
    usable = [i for i, pts in enumerate(corners) if len(pts) >= 6]
    obj = [grid_mm[np.asarray(ids[i], int)] for i in usable]
    img = [np.asarray(corners[i], np.float32).reshape(-1, 1, 2) for i in usable]
    w, h = size
    K = np.array([[w / (2 * np.tan(np.radians(30))), 0, w / 2], [0, w / (2 * np.tan(np.radians(30))), h / 2],
                  [0, 0, 1]], np.float64)
    dist = np.zeros(5)
    if len(usable) >= 4:
        pick = np.linspace(0, len(usable) - 1, min(len(usable), 25)).round().astype(int)
        flags = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_ZERO_TANGENT_DIST
                 | cv2.CALIB_FIX_K3 | cv2.CALIB_FIX_PRINCIPAL_POINT)
        try:
            _, K_fit, dist_fit, _, _ = cv2.calibrateCamera([obj[i] for i in pick], [img[i] for i in pick],
                                                           (w, h), K.copy(), dist.copy(), flags=flags)
            if np.all(np.isfinite(K_fit)) and 0.2 * w < K_fit[0, 0] < 5 * w:
                K, dist = np.asarray(K_fit, np.float64), np.asarray(dist_fit, np.float64).ravel()
        except cv2.error:
            pass  # too few or degenerate views: the guess stands
    out = np.full(len(corners), np.nan)
    for i, o, p in zip(usable, obj, img, strict=True):
        ok, _, tvec = cv2.solvePnP(o, p, K, dist)
        if ok:
            out[i] = float(np.linalg.norm(tvec)) / 1000.0
    return out


def _joined(names: Sequence[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]


def _findings(camera: str, views: int, frames: int, bands_missed: list[str], corners_missed: list[str],
              distances_m: np.ndarray) -> list[Finding]:
    if views == 0:
        return [Finding("calibration_check.board_not_seen",
                        f"The board was not found in the {camera} camera's calibration clip ({frames} frames "
                        "looked at): film it again.", {"frames": frames})]
    out = []
    if views < MIN_VIEWS:
        out.append(Finding("calibration_check.few_views",
                           f"The board was found in only {views} of the {frames} frames looked at in the {camera} "
                           f"camera's clip (at least {MIN_VIEWS} wanted): film it again, longer and slower.",
                           {"views": views, "frames": frames}))
    if bands_missed:
        out.append(Finding("calibration_check.third_missed",
                           f"The board never reached the {_joined(bands_missed)} of the {camera} camera's view: "
                           "film that part again.", {"bands_missed": len(bands_missed)}))
    elif corners_missed:
        out.append(Finding("calibration_check.corners_missed",
                           f"The board never reached the {_joined(corners_missed)} of the {camera} camera's view; "
                           "the lens there is estimated from its neighbours.", {"ninths_missed": len(corners_missed)}))
    known = distances_m[np.isfinite(distances_m)]
    if len(known) >= 4:
        near, far = np.percentile(known, [10, 90])
        if far / near < NARROW_DEPTH_RATIO:
            out.append(Finding("calibration_check.narrow_depth",
                               f"The board stayed {near:.1f}-{far:.1f} m from the {camera} camera: carry it nearer "
                               "and farther too.", {"near_m": float(near), "far_m": float(far)}))
    if not out:
        out.append(Finding("calibration_check.covered",
                           f"The board reached every part of the {camera} camera's view in {views} views.",
                           {"views": views}))
    return out


def check_camera_coverage(camera: str, sightings: Sequence[tuple[np.ndarray, np.ndarray]], board: Board,
                          image_size: tuple[int, int], *, frames_sampled: int,
                          grid_cols: int = 12) -> CameraCoverageCheck:
    """Check one camera's calibration clip from the board corners found in its sampled frames.

    Parameters
    ----------
    camera : str
        The camera's role, as the sentences name it (left, middle, right).
    sightings : list of (corners_px, ids)
        Per sampled frame where the board was found: corners of shape (N, 2) px and their ids (N,).
    board : Board
    image_size : (w, h) px
    frames_sampled : int
        How many frames were looked at (with or without the board).
    grid_cols : int
        Columns of the coverage map; its rows follow the image's aspect.
    """
    w, h = int(image_size[0]), int(image_size[1])
    corners = [np.asarray(c, np.float64).reshape(-1, 2) for c, _ in sightings]
    ids = [np.asarray(i, np.int64).reshape(-1) for _, i in sightings]
    rows = max(3, round(grid_cols * h / w))
    grid = _views_per_cell(corners, (w, h), (rows, grid_cols))
    band_views = _band_views(corners, (w, h))
    bands_missed = [BANDS[(a, b)] for a in (1, 0) for b in range(3) if band_views[a, b] < MIN_VIEWS_IN_BAND]
    if not corners:
        bands_missed = []  # the board not found at all is said once, not as six thirds
    ninths = _views_per_cell(corners, (w, h), (3, 3))
    corners_missed = [f"{_NINTHS[r][c]} corner" for r, c in ((0, 0), (0, 2), (2, 0), (2, 2)) if ninths[r, c] == 0]
    pts = np.concatenate(corners) if corners else np.zeros((0, 2))
    if len(pts) >= 3:
        hull = cv2.convexHull(pts.astype(np.float32))
        hull_fraction = float(cv2.contourArea(hull)) / (w * h)
        reach_x = (float(pts[:, 0].min() / w), float(pts[:, 0].max() / w))
        reach_y = (float(pts[:, 1].min() / h), float(pts[:, 1].max() / h))
    else:
        hull_fraction, reach_x, reach_y = 0.0, (0.0, 0.0), (0.0, 0.0)
    distances = _distances_m(corners, ids, board, (w, h)) if corners else np.zeros(0)
    findings = _findings(camera, len(corners), frames_sampled, bands_missed, corners_missed if corners else [],
                         distances)
    return CameraCoverageCheck(camera, (w, h), int(frames_sampled), len(corners), grid, tuple(bands_missed),
                               tuple(corners_missed) if corners else (), reach_x, reach_y, hull_fraction,
                               distances, tuple(findings))


MIN_WAND_FRAMES = 40  # sampled frames with both ends seen a camera's wand clip wants at least (a few a second)


def _wand_distances_m(ends: Sequence[np.ndarray], size: tuple[int, int], wand_length_mm: float) -> np.ndarray:
    """Each frame's wand distance (m) from its apparent length and a 60-degree lens: at most that far.

    A wand turned towards the camera looks shorter, so one frame says "no farther than"; the spread of
    many frames still tells a wand kept at one distance from one carried near and far.
    """
    focal_px = size[0] / (2 * np.tan(np.radians(30)))
    length_px = np.array([float(np.linalg.norm(e[1] - e[0])) for e in ends])
    with np.errstate(divide="ignore"):
        return np.where(length_px > 1.0, focal_px * wand_length_mm / 1000.0 / np.maximum(length_px, 1.0), np.nan)


def _wand_findings(camera: str, frames: int, seen: int, bands_missed: list[str], corners_missed: list[str],
                   distances_m: np.ndarray) -> list[Finding]:
    """The wand clip's findings, in the board's words (:func:`_findings`) for the wand's ends."""
    if seen == 0:
        return [Finding("calibration_check.wand_not_seen",
                        f"The wand's two ends were never both seen in the {camera} camera's wand clip ({frames} frames "
                        "looked at): film it again.", {"frames": frames})]
    out = []
    if seen < MIN_WAND_FRAMES:
        out.append(Finding("calibration_check.wand_few_frames",
                           f"The wand's two ends were seen in only {seen} of the {frames} frames looked at in the "
                           f"{camera} camera's clip (at least {MIN_WAND_FRAMES} wanted): film it again, longer.",
                           {"frames_seen": seen, "frames": frames}))
    if bands_missed:
        out.append(Finding("calibration_check.wand_third_missed",
                           f"The wand never reached the {_joined(bands_missed)} of the {camera} camera's view: "
                           "film that part again.", {"bands_missed": len(bands_missed)}))
    elif corners_missed:
        out.append(Finding("calibration_check.wand_corners_missed",
                           f"The wand never reached the {_joined(corners_missed)} of the {camera} camera's view.",
                           {"ninths_missed": len(corners_missed)}))
    known = distances_m[np.isfinite(distances_m)]
    if len(known) >= 4:
        near, far = np.percentile(known, [10, 90])
        if far / near < NARROW_DEPTH_RATIO:
            out.append(Finding("calibration_check.wand_narrow_depth",
                               f"The wand stayed about {near:.1f}-{far:.1f} m from the {camera} camera: wave it "
                               "nearer and farther too.", {"near_m": float(near), "far_m": float(far)}))
    if not out:
        out.append(Finding("calibration_check.wand_covered",
                           f"The wand reached every part of the {camera} camera's view in {seen} frames.",
                           {"frames_seen": seen}))
    return out


def check_wand_coverage(camera: str, ends_px: Sequence[np.ndarray], image_size: tuple[int, int], *,
                        frames_sampled: int, wand_length_mm: float, grid_cols: int = 12) -> CameraCoverageCheck:
    """Check one camera's wand clip from the wand's two ends found in its sampled frames.

    Parameters
    ----------
    ends_px : list of ndarray of shape (2, 2)
        Per sampled frame where both ends were seen, their pixels.
    wand_length_mm : float
        The wand's length (for the distances its apparent length gives).

    Returns
    -------
    CameraCoverageCheck
        As :func:`check_camera_coverage`; ``views`` counts the frames with both ends, ``distances_m`` is
        each such frame's "at most" distance, and the findings are the ``calibration_check.wand_*`` codes.
    """
    w, h = int(image_size[0]), int(image_size[1])
    ends = [np.asarray(e, np.float64).reshape(2, 2) for e in ends_px]
    rows = max(3, round(grid_cols * h / w))
    grid = _views_per_cell(ends, (w, h), (rows, grid_cols))
    band_views = _band_views(ends, (w, h))
    bands_missed = [BANDS[(a, b)] for a in (1, 0) for b in range(3) if band_views[a, b] < MIN_VIEWS_IN_BAND] if ends \
        else []
    ninths = _views_per_cell(ends, (w, h), (3, 3))
    corners_missed = [f"{_NINTHS[r][c]} corner" for r, c in ((0, 0), (0, 2), (2, 0), (2, 2)) if ninths[r, c] == 0] \
        if ends else []
    pts = np.concatenate(ends) if ends else np.zeros((0, 2))
    if len(pts) >= 3:
        hull_fraction = float(cv2.contourArea(cv2.convexHull(pts.astype(np.float32)))) / (w * h)
        reach_x = (float(pts[:, 0].min() / w), float(pts[:, 0].max() / w))
        reach_y = (float(pts[:, 1].min() / h), float(pts[:, 1].max() / h))
    else:
        hull_fraction, reach_x, reach_y = 0.0, (0.0, 0.0), (0.0, 0.0)
    distances = _wand_distances_m(ends, (w, h), wand_length_mm) if ends else np.zeros(0)
    findings = _wand_findings(camera, int(frames_sampled), len(ends), bands_missed, corners_missed, distances)
    return CameraCoverageCheck(camera, (w, h), int(frames_sampled), len(ends), grid, tuple(bands_missed),
                               tuple(corners_missed), reach_x, reach_y, hull_fraction, distances, tuple(findings))

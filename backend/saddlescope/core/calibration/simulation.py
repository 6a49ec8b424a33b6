"""Synthetic board views and rendered board images (tests and ``saddlescope bench``)."""

from __future__ import annotations

import cv2
import numpy as np

from saddlescope.core.calibration.boards import board_type, checkerboard, make_board, object_points_mm
from saddlescope.core.calibration.projection import _UNDISTORT_CRITERIA
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.types import Board, Camera, Rig

__all__ = ["board_texture", "render_board", "simulate_board_views", "thesis_like_views"]


def simulate_board_views(rig: Rig, board: Board, board_rvecs: np.ndarray, board_t_mm: np.ndarray, *,
                         noise_px: float, rng: np.random.Generator) -> dict[str, list[BoardView]]:
    """Project board poses through a rig, with Gaussian pixel noise; keep views fully inside images.

    Parameters
    ----------
    board_rvecs, board_t_mm : ndarray of shape (P, 3)
        Board poses in the rig (reference camera) frame: ``x = R(rvec) @ X_board + t``.

    Returns
    -------
    dict name -> list of BoardView, frame = pose index
    """
    obj = object_points_mm(board)
    out: dict[str, list[BoardView]] = {n: [] for n in rig.cameras}
    ids = np.arange(len(obj))
    for k, (rv, t) in enumerate(zip(np.asarray(board_rvecs), np.asarray(board_t_mm), strict=True)):
        pts = obj @ cv2.Rodrigues(rv)[0].T + t
        for name, cam in rig.cameras.items():
            depth = (pts @ cam.R.T + cam.t_mm)[:, 2]
            if np.any(depth <= 0):
                continue
            xy = cam.project(pts) + rng.normal(0.0, noise_px, (len(obj), 2))
            w, h = cam.image_size
            if np.all((xy[:, 0] >= 1) & (xy[:, 0] <= w - 2) & (xy[:, 1] >= 1) & (xy[:, 1] <= h - 2)):
                out[name].append(BoardView(k, xy, ids))
    return out


def thesis_like_views(n_poses: int = 90, *, rng: np.random.Generator, noise_px: float = 0.1,
                      board: Board | None = None) -> tuple[Rig, Board, dict[str, list[BoardView]],
                                                           dict[str, tuple[int, int]]]:
    """A thesis-like rig (3 cameras, 640x480, f ~ 730 px, 0.23 m apart, scene 7.5 m away) and views.

    The board (default 15 x 8 inner corners of 100 mm, as large as the thesis's 800 x 1500 mm board)
    slides across the scene in six stations and tilts (thesis 8.2: six slides, 15 images each).

    Returns
    -------
    rig (truth), board, views_by_camera, image_sizes
    """
    board = board or make_board(checkerboard.KIND, (15, 8), 100.0)
    size = (640, 480)
    names = ("left", "middle", "right")
    cams = {}
    for i, name in enumerate(names):
        f = 730.0 + rng.normal(0, 5)
        K = np.array([[f, 0, 320 + rng.normal(0, 5)], [0, f * (1 + rng.normal(0, 0.002)),
                                                      240 + rng.normal(0, 5)], [0, 0, 1]])
        dist = np.array([-0.13 + rng.normal(0, 0.005), 0.03 + rng.normal(0, 0.01),
                         rng.normal(0, 0.001), rng.normal(0, 0.001), 0.0])
        # cameras on a line 230 mm apart, turned slightly inwards
        yaw = np.radians(-1.5 * (i - 1))
        R = cv2.Rodrigues(np.array([rng.normal(0, 0.005), yaw, rng.normal(0, 0.005)]))[0]
        centre = np.array([230.0 * i, rng.normal(0, 3), rng.normal(0, 10)])
        cams[name] = Camera(name, K, dist, size, R=R, t_mm=-R @ centre)
    # express relative to the left camera
    R0, t0 = cams["left"].R, cams["left"].t_mm
    rel = {n: Camera(n, c.K, c.dist, size, R=c.R @ R0.T, t_mm=c.t_mm - c.R @ R0.T @ t0)
           for n, c in cams.items()}
    rig = Rig(rel)
    cols, rows = board.inner_corners
    half = np.array([(cols - 1) * board.square_mm / 2, (rows - 1) * board.square_mm / 2, 0.0])
    rvecs, ts = [], []
    stations = np.linspace(-2000, 2000, 6) + 230
    for k in range(n_poses):
        x = stations[k % 6] + rng.uniform(-250, 250)
        centre = np.array([x, rng.uniform(-300, 300), rng.uniform(6800, 8200)])
        tilt = np.radians([rng.uniform(-35, 35), rng.uniform(-35, 35), rng.uniform(-15, 15)])
        R = cv2.Rodrigues(tilt)[0]
        rvecs.append(tilt)
        ts.append(centre - R @ half)
    views = simulate_board_views(rig, board, np.array(rvecs), np.array(ts), noise_px=noise_px, rng=rng)
    return rig, board, views, {n: size for n in names}


def board_texture(board: Board, *, px_per_square: int = 40) -> tuple[np.ndarray, float, np.ndarray]:
    """Image of the board with a one-square white margin (its kind's texture), for printing and rendering.

    Returns
    -------
    texture : ndarray (H, W) uint8
    px_per_mm : float
    origin_px : ndarray (2,), texture pixel of board point (0, 0) (inner corner 0)
    """
    return board_type(board.kind).texture(board, px_per_square=px_per_square)


def render_board(board: Board, camera: Camera, board_rvec: np.ndarray, board_t_mm: np.ndarray, *,
                 background: int = 128, supersample: int = 2, px_per_square: int = 40) -> np.ndarray:
    """Synthetic grey image of the board seen by a camera (with its lens distortion).

    For tests, demos and benchmarks; anti-aliased by rendering ``supersample`` times larger.

    Parameters
    ----------
    board : Board
        Drawn with its kind's texture (:func:`board_texture`).
    camera : Camera
    board_rvec, board_t_mm : ndarray of shape (3,)
        The board pose in the camera's frame: ``x_cam = R(board_rvec) @ X_board + board_t_mm`` (mm).
    background : int
        Grey level round the board.

    Returns
    -------
    ndarray of shape (H, W), uint8, the camera's image size
    """
    tex, px_per_mm, origin = board_texture(board, px_per_square=px_per_square)
    w, h = camera.image_size
    s = int(supersample)
    # undistort a coarse grid and interpolate: the distortion field is smooth, undistortPoints is slow
    step = 8
    gy, gx = np.arange(0, h * s + step, step), np.arange(0, w * s + step, step)
    ys, xs = np.meshgrid(gy, gx, indexing="ij")
    pix = np.column_stack([(xs.ravel() + 0.5) / s - 0.5, (ys.ravel() + 0.5) / s - 0.5])
    coarse = cv2.undistortPoints(pix.reshape(-1, 1, 2), camera.K, camera.dist,
                                 criteria=_UNDISTORT_CRITERIA).reshape(len(gy), len(gx), 2)
    mx, my = np.meshgrid(np.arange(w * s, dtype=np.float32) / step, np.arange(h * s, dtype=np.float32) / step)
    xn = cv2.remap(np.ascontiguousarray(coarse[..., 0], np.float32), mx, my, cv2.INTER_LINEAR)
    yn = cv2.remap(np.ascontiguousarray(coarse[..., 1], np.float32), mx, my, cv2.INTER_LINEAR)
    R = cv2.Rodrigues(np.asarray(board_rvec, np.float64))[0]
    # the board plane maps to normalised image coordinates by H = [r1 r2 t]; invert it per pixel
    Hi = np.linalg.inv(np.column_stack([R[:, 0], R[:, 1], np.asarray(board_t_mm, np.float64)]))
    den = Hi[2, 0] * xn + Hi[2, 1] * yn + Hi[2, 2]
    behind = den <= 0
    den[behind] = 1.0
    u = (Hi[0, 0] * xn + Hi[0, 1] * yn + Hi[0, 2]) / den * px_per_mm + origin[0]
    v = (Hi[1, 0] * xn + Hi[1, 1] * yn + Hi[1, 2]) / den * px_per_mm + origin[1]
    u[behind] = -1e6
    v[behind] = -1e6
    big = cv2.remap(tex, u.astype(np.float32), v.astype(np.float32), cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_CONSTANT, borderValue=int(background))
    return cv2.resize(big, (w, h), interpolation=cv2.INTER_AREA) if s > 1 else big

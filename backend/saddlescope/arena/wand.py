"""A wand calibration set in the arena: a wand waved through the riding volume, close-up board views.

The wand (two 40 mm retro-reflective discs ``length_m`` apart) follows a random smooth path through the
riding volume, turning as a hand turns it; each camera films it (:func:`render_wand_frames`). Each
camera's lens is calibrated from a small board held close to it (:func:`close_up_board_views`: exact
corner projections with pixel noise, as a detector finds them on a sharp close-up board).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from saddlescope.arena.render import (
    CameraView,
    RenderOptions,
    board_patch,
    composite_patch,
    draw_markers,
    finish_frame,
    flash_fraction,
    render_background,
)
from saddlescope.arena.rig import SceneRig, normalized_pixel_grid
from saddlescope.arena.timing import ClipTiming, clip_timing
from saddlescope.core.calibration.simulation import simulate_board_views
from saddlescope.core.calibration.views import BoardView
from saddlescope.core.types import Board, Camera, Rig

__all__ = ["CLOSE_UP_BOARD", "WandPath", "close_up_board_poses", "close_up_board_views", "render_close_up_frames",
           "render_wand_clip", "render_wand_frames", "true_wand_pixels", "wand_clip_timing", "wand_path"]

# an A3 print: 10 x 7 squares of 30 mm
CLOSE_UP_BOARD = Board(kind="checkerboard", inner_corners=(9, 6), square_mm=30.0)


@dataclass(frozen=True)
class WandPath:
    """The wand's two ends (N, 2, 3) in world metres at frames 0..N-1, ``fps`` frames a second."""

    ends_w: np.ndarray
    length_m: float
    fps: float
    marker_diameter_mm: float = 40.0


def wand_path(rig: SceneRig, rng: np.random.Generator, *, n_frames: int = 300, fps: float = 10.0,
              length_m: float = 1.0, track_x_m: tuple[float, float] | None = None) -> WandPath:
    """A random smooth wand path through the riding volume (world metres).

    The centre sweeps the track's length once and back (x), rises and falls between knee and
    above-head height (y, down positive) and moves across the track (z), each with a few slow
    sinusoids; the wand turns slowly about changing axes. ``track_x_m`` (from, to): the wand is walked
    along that stretch of the track instead of the calibration volume's (where the horse will pass
    through every camera's view, not only where the views overlap).
    """
    t = np.arange(n_frames) / fps
    dur = max(t[-1], 1e-6)
    half = np.asarray(rig.volume_half_m, np.float64)
    lo, hi = track_x_m if track_x_m is not None else (-half[0] * 0.95, half[0] * 0.95)
    x = (lo + hi) / 2 - (hi - lo) / 2 * np.cos(2 * np.pi * t / dur)  # one sweep there and back
    y = 0.15 + sum(0.35 / (k + 1) * np.sin(2 * np.pi * (k + 1) * 3 * t / dur + rng.uniform(0, 2 * np.pi))
                   for k in range(2))
    z = sum(0.5 / (k + 1) * np.sin(2 * np.pi * (k + 1) * 2 * t / dur + rng.uniform(0, 2 * np.pi)) for k in range(2))
    centre = np.column_stack([x, y, z])
    az = rng.uniform(0, 2 * np.pi) + 2 * np.pi * 2.5 * t / dur + 0.4 * np.sin(2 * np.pi * 5 * t / dur)
    el = 0.9 * np.sin(2 * np.pi * 4 * t / dur + rng.uniform(0, 2 * np.pi))
    # mostly upright-to-horizontal in the image plane (x-y), tilting out of it by ``el``
    d = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el) * 0.6])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ends = np.stack([centre - d * length_m / 2, centre + d * length_m / 2], axis=1)
    return WandPath(ends, float(length_m), float(fps))


def _view(rig: SceneRig, role: str) -> CameraView:
    cam = rig.cameras[role]
    r_wc, c_w = rig.camera_world_pose(role)
    return CameraView(role, cam, r_wc, -r_wc @ c_w * 1000.0, normalized_pixel_grid(cam))


def true_wand_pixels(rig: SceneRig, path: WandPath, role: str) -> np.ndarray:
    """The ends' true pixels (N, 2, 2) in camera ``role``, NaN where behind it or outside the image."""
    cam = rig.cameras[role]
    pts = rig.world_to_rig_mm(path.ends_w.reshape(-1, 3))
    xy = cam.project(pts)
    depth = (pts @ cam.R.T + cam.t_mm)[:, 2]
    w, h = cam.image_size
    inside = (depth > 0) & (xy[:, 0] >= 3) & (xy[:, 0] <= w - 4) & (xy[:, 1] >= 3) & (xy[:, 1] <= h - 4)
    xy[~inside] = np.nan
    return xy.reshape(-1, 2, 2)


def render_wand_frames(rig: SceneRig, path: WandPath, role: str, *, rng: np.random.Generator,
                       options: RenderOptions | None = None) -> Iterator[tuple[int, np.ndarray]]:
    """Camera ``role``'s wand clip: (frame, grey uint8 (H, W)) for every frame of the path.

    The arena's background without its distractors, the two discs at their true positions (no motion
    blur: a wand waved at 1 m/s moves 2 mm in a 1/500 s exposure), lighting and sensor noise.
    """
    opts = options or RenderOptions(distractors=False, occluder=False, motion_blur=False)
    view = _view(rig, role)
    background = render_background(view, ground_y_m=rig.ground_y_m, wall_z_m=rig.wall_z_m, rng=rng, options=opts)
    xy = true_wand_pixels(rig, path, role)
    cam = rig.cameras[role]
    depth_mm = view.to_camera_mm(path.ends_w)[..., 2]
    radius_px = cam.K[0, 0] * path.marker_diameter_mm / 2 / np.maximum(depth_mm, 1.0)
    for f in range(len(path.ends_w)):
        frame = background.copy()
        draw_markers(frame, xy[f][None], radius_px[f], np.array([245.0, 245.0]), options=opts)
        yield f, finish_frame(frame, gain=1.0, flash=0.0, rng=rng, options=opts)


def close_up_board_poses(camera: Camera, rng: np.random.Generator, *, board: Board = CLOSE_UP_BOARD,
                         n_poses: int = 120) -> tuple[np.ndarray, np.ndarray]:
    """Poses (rvecs (P, 3), t_mm (P, 3), in the camera's frame) of a board held 0.6-1.6 m in front of it.

    The board's centre is spread over the image (10-90 % of each side) and it is tilted by up to 35 degrees.
    """
    obj_centre = np.array([(board.inner_corners[0] - 1) * board.square_mm / 2,
                           (board.inner_corners[1] - 1) * board.square_mm / 2, 0.0])
    w, h = camera.image_size
    rvecs, ts = [], []
    for _ in range(n_poses):
        z = rng.uniform(600.0, 1600.0)
        u, v = rng.uniform(0.1 * w, 0.9 * w), rng.uniform(0.1 * h, 0.9 * h)
        ray = np.array([(u - camera.K[0, 2]) / camera.K[0, 0], (v - camera.K[1, 2]) / camera.K[1, 1], 1.0])
        rv = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), rng.uniform(-0.3, 0.3)])
        rvecs.append(rv)
        ts.append(ray * z - cv2.Rodrigues(rv)[0] @ obj_centre)
    return np.array(rvecs), np.array(ts)


def close_up_board_views(rig: SceneRig, rng: np.random.Generator, *, board: Board = CLOSE_UP_BOARD,
                         n_poses: int = 40, noise_px: float = 0.15) -> dict[str, list[BoardView]]:
    """Each camera's views of a small board held 0.6-1.6 m in front of it (:func:`close_up_board_poses`).

    Returns role -> list of BoardView (frame = pose index); only whole boards inside the image are kept.
    """
    out = {}
    for role, cam in rig.cameras.items():
        alone = Rig({role: Camera(role, cam.K, cam.dist, cam.image_size)})
        rvecs, ts = close_up_board_poses(cam, rng, board=board, n_poses=n_poses * 3)
        views = simulate_board_views(alone, board, rvecs, ts, noise_px=noise_px, rng=rng)[role]
        out[role] = views[:n_poses]
    return out


def wand_clip_timing(path: WandPath, rng: np.random.Generator, *, fps: float) -> ClipTiming:
    """A ride bundle's wand clip timing at ``fps``: the cameras' start offsets, the sync flash, then the path."""
    return clip_timing("wand", rng, fps, len(path.ends_w) / path.fps)


def _ends_at(path: WandPath, t_s: np.ndarray) -> np.ndarray:
    """The wand's ends (T, 2, 3) world m at path instants ``t_s`` (T,): linear between frames, held outside."""
    k = np.clip(np.asarray(t_s, np.float64) * path.fps, 0.0, len(path.ends_w) - 1.0)
    k0 = np.minimum(np.floor(k).astype(int), len(path.ends_w) - 2)
    w = (k - k0)[:, None, None]
    return (1 - w) * path.ends_w[k0] + w * path.ends_w[k0 + 1]


def render_wand_clip(rig: SceneRig, path: WandPath, timing: ClipTiming, role: str, *, rng: np.random.Generator,
                     exposure_s: float = 1 / 500, options: RenderOptions | None = None) -> Iterator[np.ndarray]:
    """Camera ``role``'s wand clip of a ride bundle: grey uint8 frames at ``timing``'s instants, with its flash.

    The wand is held at its first place until the content starts (after the flash), then follows ``path``.
    """
    opts = options or RenderOptions(distractors=False, occluder=False, motion_blur=False)
    view = _view(rig, role)
    background = render_background(view, ground_y_m=rig.ground_y_m, wall_z_m=rig.wall_z_m, rng=rng, options=opts)
    times = timing.frame_times(role)
    flash = flash_fraction(times, exposure_s, timing.flash_on_s, timing.flash_off_s, timing.flash_ramp_s)
    ends_w = _ends_at(path, times - timing.content_start_s)
    moved = WandPath(ends_w, path.length_m, path.fps, path.marker_diameter_mm)
    xy = true_wand_pixels(rig, moved, role)
    depth_mm = view.to_camera_mm(ends_w)[..., 2]
    radius_px = rig.cameras[role].K[0, 0] * path.marker_diameter_mm / 2 / np.maximum(depth_mm, 1.0)
    for f in range(len(times)):
        frame = background.copy()
        draw_markers(frame, xy[f][None], radius_px[f], np.array([245.0, 245.0]), options=opts)
        yield finish_frame(frame, gain=1.0, flash=float(flash[f]), rng=rng, options=opts)


def render_close_up_frames(rig: SceneRig, role: str, *, rng: np.random.Generator, board: Board = CLOSE_UP_BOARD,
                           n_poses: int = 30, options: RenderOptions | None = None) -> Iterator[np.ndarray]:
    """Camera ``role``'s close-up clip: one frame per pose of the small board held 0.6-1.6 m in front of it.

    Poses from :func:`close_up_board_poses` whose whole board is in the image; rendered as the arena
    renders its calibration board (:func:`~saddlescope.arena.render.board_patch`).
    """
    opts = options or RenderOptions(distractors=False, occluder=False, motion_blur=False)
    view = _view(rig, role)
    cam = rig.cameras[role]
    background = render_background(view, ground_y_m=rig.ground_y_m, wall_z_m=rig.wall_z_m, rng=rng, options=opts)
    alone = Rig({role: Camera(role, cam.K, cam.dist, cam.image_size)})
    rvecs, ts = close_up_board_poses(cam, rng, board=board, n_poses=n_poses * 3)
    seen = simulate_board_views(alone, board, rvecs, ts, noise_px=0.0, rng=rng)[role]
    for v in seen[:n_poses]:
        r_cb = cv2.Rodrigues(rvecs[v.frame])[0]
        r_bw = view.r_wc.T @ r_cb
        o_w = view.r_wc.T @ (ts[v.frame] - view.t_wc_mm) / 1000.0
        frame = background.copy()
        patch = board_patch(view, [(r_bw, o_w)], square_m=board.square_mm / 1000.0,
                            inner_corners=board.inner_corners, options=opts)
        if patch is not None:
            composite_patch(frame, *patch)
        yield finish_frame(frame, gain=1.0, flash=0.0, rng=rng, options=opts)

"""Where things stand in the synthetic arena: board poses, the standing horse, plumb line, ball, glints.

Every placement is checked against the cameras' views (world metres, distorted pixels): a board
must be wholly inside the images it is seen in and not too oblique, markers must be inside every
image with a margin. Draws come from the generator handed in, in a fixed order, so a seed gives
the same arena every time.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

from saddlescope.arena.content import BallContent, BoardContent, HorseContent
from saddlescope.arena.gait import GaitModel
from saddlescope.arena.render import CameraView, RenderOptions, draw_markers
from saddlescope.arena.rig import SceneRig
from saddlescope.core.errors import InputError

__all__ = [
    "add_static_glints",
    "board_distance_poses",
    "board_origin",
    "board_pose_ok",
    "board_rotation",
    "out_of_view",
    "place_ball",
    "place_in_view",
    "place_standing_horse",
    "sample_board_poses",
    "visible_everywhere",
    "visible_in",
]


def visible_everywhere(views: dict[str, CameraView], pts_w: np.ndarray, margin_px: float = 10.0) -> np.ndarray:
    """Where every point is inside every image with a margin.

    Parameters
    ----------
    views : dict of str to CameraView
    pts_w : ndarray of shape (T, M, 3)
        World points (m) at T instants.
    margin_px : float

    Returns
    -------
    ndarray of bool, shape (T,)
    """
    ok = np.ones(pts_w.shape[0], bool)
    for view in views.values():
        ok &= np.all(view.inside(view.project(pts_w), margin_px), axis=1)
    return ok


def visible_in(views: dict[str, CameraView], pts_w: np.ndarray, min_views: int, margin_px: float = 10.0
               ) -> np.ndarray:
    """Where every point is inside at least ``min_views`` images (the same ones for all points), shape (T,).

    ``pts_w`` (T, M, 3) world points (m); with ``min_views`` = the number of cameras this is
    :func:`visible_everywhere`.
    """
    seen = np.zeros(pts_w.shape[0], int)
    for view in views.values():
        seen += np.all(view.inside(view.project(pts_w), margin_px), axis=1)
    return seen >= int(min_views)


def out_of_view(views: dict[str, CameraView], pts_w: np.ndarray, margin_px: float = 12.0) -> bool:
    """True if any world point ``pts_w`` (N, 3) m is outside any image (with a margin)."""
    return not all(np.all(view.inside(view.project(pts_w), margin_px)) for view in views.values())


def board_pose_ok(views: dict[str, CameraView], board: BoardContent, r_bw: np.ndarray, o_w: np.ndarray, *,
                  min_views: int | None = None) -> bool:
    """Whether a board pose is usable.

    The whole board (with margin) is inside every image (or ``min_views`` of them, wholly outside
    the others) and not too oblique to a camera that sees it. ``r_bw`` (3, 3) board -> world,
    ``o_w`` (3,) its origin in world metres.
    """
    cols, rows = board.inner_corners
    sq = board.square_m
    outline = np.array([[-2, -2], [cols + 1, -2], [cols + 1, rows + 1], [-2, rows + 1]], float) * sq
    pts = o_w + np.column_stack([outline, np.zeros(4)]) @ r_bw.T
    seen = 0
    for view in views.values():
        xy = view.project(pts)
        inside = view.inside(xy, 6.0)
        if not np.all(inside):
            if min_views is None or np.any(inside):
                return False  # a board cut by the image border is no use to anyone
            continue
        normal_c = view.r_wc @ r_bw[:, 2]
        ray = view.to_camera_mm(o_w) / np.linalg.norm(view.to_camera_mm(o_w))
        if abs(normal_c @ ray) < 0.55:  # steeper than ~57 degrees: corners unreadable
            return False
        seen += 1
    return seen >= (len(views) if min_views is None else min_views)


def board_rotation(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Board orientation (3, 3): yaw about world Y, pitch about X, in-plane roll about Z (radians)."""
    return (
        cv2.Rodrigues(np.array([0.0, yaw, 0.0]))[0]
        @ cv2.Rodrigues(np.array([pitch, 0.0, 0.0]))[0]
        @ cv2.Rodrigues(np.array([0.0, 0.0, roll]))[0]
    )


def board_origin(r_bw: np.ndarray, centre_w: np.ndarray, inner: tuple[int, int], sq: float) -> np.ndarray:
    """World origin (3,) m of a board (rotation ``r_bw`` (3, 3)) whose inner corners centre on ``centre_w``."""
    cols, rows = inner
    return centre_w - r_bw @ np.array([(cols - 1) / 2 * sq, (rows - 1) / 2 * sq, 0.0])


def sample_board_poses(
    views,
    board_tmpl: BoardContent,
    rng: np.random.Generator,
    n_poses: int,
    half_m: np.ndarray,
    *,
    per_slide: int = 15,
    edge_share: float = 0.0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Calibration board poses (R_board_to_world (3, 3), origin_world_m (3,)) through the volume.

    Poses are spread through the calibration volume (half-size ``half_m`` (3,) m) in slides along
    the track (thesis 8.2), and ``edge_share`` of them at the edges of the views, seen by one
    camera or more.
    """
    levels = [(y, z) for z in (-0.6, 0.0, 0.6) for y in (-0.55, 0.55)]
    poses = []
    n_edge = int(round(edge_share * n_poses))
    n_poses -= n_edge
    n_slides = max(1, math.ceil(n_poses / per_slide))
    for i in range(n_poses):
        slide, j = divmod(i, per_slide)
        n_in = min(per_slide, n_poses - slide * per_slide)
        y_f, z_f = levels[slide % len(levels)]
        frac = (j + 0.5) / n_in
        if slide % 2:
            frac = 1.0 - frac  # the carrier walks back on the next slide
        for attempt in range(80):
            # first near the planned place on the slide, then anywhere along it, then nearer the centre
            x = (
                (2 * frac - 1) * half_m[0]
                if attempt < 20
                else rng.uniform(-1, 1) * half_m[0] * (1.0 - min(attempt, 60) / 80.0)
            )
            centre = np.array(
                [
                    x + rng.normal(0, 0.08),
                    y_f * half_m[1] + rng.normal(0, 0.06),
                    z_f * half_m[2] + rng.normal(0, 0.05),
                ]
            )
            r_bw = board_rotation(
                np.deg2rad(rng.uniform(-38, 38)),
                np.deg2rad(rng.uniform(-32, 32)),
                np.deg2rad(rng.uniform(-12, 12)),
            )
            o_w = board_origin(r_bw, centre, board_tmpl.inner_corners, board_tmpl.square_m)
            if board_pose_ok(views, board_tmpl, r_bw, o_w):
                poses.append((r_bw, o_w))
                break
        else:
            raise InputError(
                f"could not place calibration board pose {i + 1} inside all three views of the "
                f"{n_slides}-slide volume; the rig's cameras do not overlap enough"
            )
    # What a club is told to do: also carry the board to the edges of each camera's view, where the
    # lens distortion is largest and the horse still passes (seen there by one or two cameras).
    for k in range(n_edge):
        side = -1.0 if k % 2 == 0 else 1.0
        for _attempt in range(200):
            centre = np.array([side * rng.uniform(0.8, 1.9) * half_m[0], rng.uniform(-1.6, 1.6) * half_m[1],
                               rng.uniform(-1, 1) * half_m[2]])
            r_bw = board_rotation(np.deg2rad(rng.uniform(-38, 38)), np.deg2rad(rng.uniform(-32, 32)),
                                  np.deg2rad(rng.uniform(-12, 12)))
            o_w = board_origin(r_bw, centre, board_tmpl.inner_corners, board_tmpl.square_m)
            if board_pose_ok(views, board_tmpl, r_bw, o_w, min_views=1):
                poses.append((r_bw, o_w))
                break
    return poses


def place_in_view(factory: Callable, views: dict[str, CameraView], what: str,
                  candidates=(0.3, -0.3, 0.9, -0.9, 1.5, -1.5, 2.1, -2.1)):
    """The first content ``factory(x)`` over the candidate world x (m) whose markers every camera sees."""
    for x in candidates:
        cand = factory(x)
        if not out_of_view(views, cand.markers_w(np.zeros(1))[0]):
            return cand
    raise InputError(f"could not place the {what} where all three cameras see it")


def place_standing_horse(views: dict[str, CameraView], model: GaitModel, m_dir: np.ndarray, ground_y_m: float, *,
                         peaks: np.ndarray, marker_diameter_mm: float, distractors: bool) -> HorseContent:
    """The horse standing still (static clip) where every camera sees markers 1-3 and S.

    ``m_dir`` (3, 3) maps arena -> world; ``peaks`` (4,) are the markers' grey levels.
    """
    for x_try in (0.0, 0.6, -0.6, 1.2, -1.2, 1.8, -1.8):
        cand = HorseContent(
            model,
            m_dir,
            ground_y_m,
            static=True,
            static_x_m=x_try,
            rider=False,
            peaks=peaks,
            marker_diameter_mm=marker_diameter_mm,
            distractors=distractors,
        )
        if not out_of_view(views, cand.markers_w(np.zeros(1))[0]):
            return cand
    raise InputError("could not place the standing horse where all cameras see markers 1-3 and S")


def add_static_glints(views: dict[str, CameraView], rig: SceneRig, rng: np.random.Generator) -> None:
    """Small bright spots on the back wall and fence near marker height (the same in every camera)."""
    n = 10
    pts = np.column_stack([rng.uniform(-6.0, 6.0, n), rng.uniform(-0.2, 0.6, n), np.full(n, rig.wall_z_m - 0.02)])
    diam = rng.uniform(35.0, 70.0, n)
    peak = rng.uniform(225.0, 275.0, n)
    opts = RenderOptions(motion_blur=False)
    for view in views.values():
        xy = view.project(pts)
        r = view.radius_px(pts, diam)
        draw_markers(view.rendered_background(), xy[None], r, peak, options=opts)


def place_ball(views: dict[str, CameraView], top_y_m: float, v_up_m_s: float, release_s: float, flight_s: float,
               rng: np.random.Generator) -> BallContent:
    """The freefall ball (thesis 8.3), thrown from world height ``top_y_m`` (the volume's lower edge).

    Its path during the flight must stay inside every image; the sideways throw speed comes from
    ``rng``.
    """
    vx = float(rng.uniform(0.15, 0.35)) * (1 if rng.random() < 0.5 else -1)

    def ball(x):
        return BallContent(
            p0_w=np.array([x, top_y_m, -0.1]),
            v0_w=np.array([vx, -v_up_m_s, 0.03]),
            release_s=release_s,
            catch_s=release_s + flight_s,
        )

    for x in (0.2, -0.4, 0.8, -1.0, 1.4, -1.6):
        cand = ball(x)
        path = cand.markers_w(np.linspace(release_s, release_s + flight_s, 25))[:, 0]
        if not out_of_view(views, path):
            return cand
    raise InputError("could not place the freefall ball where all three cameras see it")


def board_distance_poses(views: dict[str, CameraView], board_tmpl: BoardContent,
                         rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray]]:
    """Three still board poses seen by all cameras for the board-distance clip (thesis Fig. 8.6)."""
    poses = []
    for centre_x in (-1.5, 0.0, 1.5, -0.7, 0.7, -2.2, 2.2):
        for _ in range(20):
            r_bw = board_rotation(
                np.deg2rad(rng.uniform(-30, 30)),
                np.deg2rad(rng.uniform(-20, 20)),
                np.deg2rad(rng.uniform(-8, 8)),
            )
            centre = np.array([centre_x + rng.normal(0, 0.1), rng.normal(0, 0.08), rng.normal(0, 0.08)])
            o_w = board_origin(r_bw, centre, board_tmpl.inner_corners, board_tmpl.square_m)
            if board_pose_ok(views, board_tmpl, r_bw, o_w):
                poses.append((r_bw, o_w))
                break
        if len(poses) == 3:
            break
    if len(poses) < 3:
        raise InputError("could not place the board-distance board in three poses seen by all cameras")
    return poses

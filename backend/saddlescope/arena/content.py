"""What the synthetic cameras film: the horse and rider, the calibration board, the plumb line, the ball.

Every content object works in world metres (``arena.rig`` frame W) and offers
``markers_w(t)`` (T, M, 3) - the retro-reflective points rendered as blobs (NaN where absent) -
and ``draw(frame, view, t)`` for everything else (dark shapes, the board), drawn before the markers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from saddlescope.arena.gait import MARKER_NAMES, SADDLE_NAME, GaitModel
from saddlescope.arena.render import (
    CameraView,
    RenderOptions,
    board_patch,
    composite_patch,
    fill_polygons,
)
from saddlescope.core.types import CLIP_KINDS, Board

__all__ = [
    "ALL_CLIPS",
    "BOARD",
    "DISTANCE_POINTS",
    "EXTRA_CLIPS",
    "GRAVITY_M_S2",
    "BallContent",
    "BoardContent",
    "ClipContent",
    "HorseContent",
    "PlumbContent",
]

GRAVITY_M_S2 = 9.81
EXTRA_CLIPS: tuple[str, ...] = ("freefall", "board_distance")
ALL_CLIPS: tuple[str, ...] = CLIP_KINDS + EXTRA_CLIPS
BOARD = Board(kind="checkerboard", inner_corners=(12, 11), square_mm=50.0)
DISTANCE_POINTS = {"A": (0, 0), "B": (10, 0), "C": (0, 10), "D": (10, 10)}  # inner-corner (col, row)

# Horse side silhouette in body coordinates (x forward, y down, metres, a 1.65 m horse), origin at
# the saddle seat. Drawn in the plane z = side * 0.25.
_TRUNK = np.array(
    [
        [-0.95, 0.10],
        [-0.75, -0.02],
        [-0.40, 0.03],
        [-0.10, 0.05],
        [0.25, 0.0],
        [0.45, -0.09],
        [0.62, -0.16],
        [1.05, -0.78],
        [1.20, -0.80],
        [1.50, -0.36],
        [1.46, -0.22],
        [1.15, -0.40],
        [0.95, -0.30],
        [0.88, 0.18],
        [0.75, 0.46],
        [0.40, 0.63],
        [-0.20, 0.66],
        [-0.70, 0.56],
        [-0.98, 0.36],
    ]
)
_TAIL = np.array([[-0.93, 0.08], [-1.12, 0.45], [-1.10, 0.95], [-0.99, 0.88], [-0.96, 0.30]])
_PAD = np.array([[-0.52, -0.02], [0.36, -0.04], [0.34, 0.19], [-0.50, 0.10]])
_SADDLE = np.array(
    [
        [-0.46, -0.24],
        [-0.38, -0.22],
        [-0.30, -0.12],
        [0.05, -0.10],
        [0.22, -0.20],
        [0.28, -0.12],
        [0.22, 0.12],
        [0.0, 0.13],
        [-0.06, 0.05],
        [-0.46, 0.04],
    ]
)
_RIDER = {  # polygon, value, z factor
    "torso": (np.array([[-0.20, -0.06], [0.08, -0.08], [0.12, -0.70], [-0.12, -0.74]]), 70.0),
    "arm": (np.array([[0.02, -0.68], [0.10, -0.66], [0.38, -0.30], [0.33, -0.26]]), 62.0),
    "head": (
        np.array(
            [
                [np.cos(a) * 0.11, -0.86 + np.sin(a) * 0.12]
                for a in np.linspace(0, 2 * np.pi, 14, endpoint=False)
            ]
        ),
        24.0,
    ),
    "thigh": (np.array([[-0.10, -0.10], [0.05, -0.12], [0.26, 0.26], [0.12, 0.31]]), 185.0),
    "shin": (np.array([[0.12, 0.26], [0.25, 0.27], [0.16, 0.60], [0.05, 0.58]]), 24.0),
    "boot": (np.array([[0.04, 0.56], [0.18, 0.55], [0.30, 0.64], [0.05, 0.66]]), 20.0),
}
# legs: body x of the top, z factor (near/far), phase offset (fraction of the stride) per gait
_LEG_PHASES = {
    "walk": (0.0, 0.25, 0.5, 0.75),
    "sitting_trot": (0.0, 0.5, 0.5, 0.0),
    "rising_trot": (0.0, 0.5, 0.5, 0.0),
    "canter": (0.0, 0.3, 0.3, 0.55),
}


# The rider's boot over the rear marker (RenderOptions.boot_share): a dark blob 16 cm long, 12 cm tall,
# 45 cm out from the body's midline (nearer the cameras than the markers, 27 cm), resting 30 cm below
# the rear marker; it swings up over it once a stride.
BOOT_RADIUS_M = 0.06
BOOT_REST_M = 0.30
BOOT_DEPTH_M = 0.45
BOOT_PHASE = 0.3
MAX_BOOT_SHARE = 2.0 * (BOOT_RADIUS_M + 0.015) / BOOT_REST_M * 0.5  # the whole swing within one stride


def _hash01(*vals: float) -> float:
    """A repeatable pseudo-random number in [0, 1) from numbers (no RNG state)."""
    return float((np.sin(np.dot(vals, [12.9898, 78.233, 37.719][: len(vals)])) * 43758.5453) % 1.0)


@dataclass
class HorseContent:
    """The horse (standing or ridden) with markers 1-3 and the saddle point S.

    model : GaitModel in the arena frame; m_dir (3, 3) maps arena -> world; static_x_m is the arena
    x where the horse stands when ``static``; the rider hides S when ``rider``.
    """

    model: GaitModel
    m_dir: np.ndarray
    ground_y_m: float
    static: bool = False
    static_x_m: float = 0.0
    rider: bool = True
    peaks: np.ndarray = field(default_factory=lambda: np.array([265.0, 262.0, 268.0, 260.0]))
    marker_diameter_mm: float = 30.0
    distractors: bool = True
    boot_share: float = 0.0  # share of every stride the rider's boot covers the rear marker (issue 38)

    @property
    def marker_names(self) -> tuple[str, ...]:
        """Markers 1-3 and the saddle point S, in the order of :meth:`markers_w`."""
        return MARKER_NAMES + (SADDLE_NAME,)

    @property
    def rendered(self) -> np.ndarray:
        """Which markers are drawn, shape (4,) bool: the rider hides S during the ride."""
        return np.array([True, True, True, not self.rider])

    @property
    def diameters_mm(self) -> np.ndarray:
        """Marker diameters, shape (4,) mm."""
        return np.full(4, self.marker_diameter_mm)

    def pose_arena(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body rotation (T, 3, 3) and origin (T, 3) m in the arena frame at instants ``t`` (T,) s."""
        t = np.atleast_1d(t)
        if self.static:
            return np.broadcast_to(np.eye(3), (len(t), 3, 3)), np.tile(
                [self.static_x_m, 0.0, 0.0], (len(t), 1)
            )
        return self.model.rotation(t)[0], self.model.origin(t)

    def markers_arena(self, t: np.ndarray, *, skin: bool = True) -> np.ndarray:
        """Markers 1-3 and S in the arena frame (T, 4, 3) m at instants ``t`` (T,) s (skin motion only while moving)."""
        t = np.atleast_1d(t)
        if self.static:
            pts = np.stack([self.model.body_points_m[n] for n in self.marker_names])
            return np.broadcast_to(pts + np.array([self.static_x_m, 0.0, 0.0]), (len(t), 4, 3)).copy()
        return self.model.marker_positions(t, skin=skin)

    def markers_w(self, t: np.ndarray) -> np.ndarray:
        """Markers 1-3 and S in world metres (T, 4, 3) at instants ``t`` (T,) s."""
        return self.markers_arena(t) @ self.m_dir.T

    def _body_to_world(self, pts_body: np.ndarray, rot: np.ndarray, org: np.ndarray) -> np.ndarray:
        """Body points (N, 3) m -> world metres (N, 3), for the body pose ``rot`` (3, 3), ``org`` (3,)."""
        return (org + pts_body @ rot.T) @ self.m_dir.T

    def glints(self, view: CameraView, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Moving look-alikes near the markers: a stirrup flash and a saddle D-ring.

        Returns
        -------
        tuple of ndarray or None
            World positions (2, 3) m, diameters (2,) mm and peak grey levels (2,) DN; None for the
            standing horse or without distractors.
        """
        if not self.distractors or self.static:
            return None
        s = self.model.camera_side
        rot, org = self.pose_arena(np.array([t]))
        pts = np.array([[0.17, 0.63, s * 0.42], [-0.02, 0.17, s * 0.3]])
        w = self._body_to_world(pts, rot[0], org[0])
        # specular: the stirrup flashes for parts of the stride, differently in each camera
        phase = _hash01(len(view.role), ord(view.role[0]))
        stir = 300.0 * max(0.0, np.sin(2 * np.pi * (self.model.stride_hz * t + phase))) ** 6
        return w, np.array([22.0, 20.0]), np.array([stir, 235.0])

    def boot_offset_m(self, t: np.ndarray) -> np.ndarray:
        """How far (m, down the body) the boot's centre is below the rear marker at instants ``t`` (T,) s.

        The boot rests :data:`BOOT_REST_M` below the rear marker, clear of the marker row, and swings up
        over it once a stride, linearly in and out around the stride phase 0.5, so that the marker is at
        least partly covered for ``boot_share`` of the stride (where the offset is below the boot's
        half-height plus the disc's radius).
        """
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        phase = (self.model.stride_hz * (t - self.model.t_cross_s) + BOOT_PHASE) % 1.0
        reach = BOOT_RADIUS_M + 0.5e-3 * self.marker_diameter_mm
        half = max(self.boot_share, 1e-9) * BOOT_REST_M / (2.0 * reach)  # half the swing, in stride phase
        return BOOT_REST_M * np.minimum(1.0, np.abs(phase - 0.5) / half)

    def boot_covers(self, t: np.ndarray) -> np.ndarray:
        """Which markers (T, 4) bool the boot covers at least partly, seen square-on, at instants ``t`` (T,) s."""
        t = np.atleast_1d(t)
        out = np.zeros((len(t), 4), bool)
        if self.boot_share > 0 and not self.static:
            out[:, 2] = self.boot_offset_m(t) < BOOT_RADIUS_M + 0.5e-3 * self.marker_diameter_mm
        return out

    def draw_front(self, frame: np.ndarray, view: CameraView, t: float) -> None:
        """Draw what passes in front of the markers (the rider's boot) at instant ``t`` into ``frame``."""
        if self.boot_share <= 0 or self.static or not self.rider:
            return
        rot, org = self.pose_arena(np.array([t]))
        m3 = self.model.body_points_m[MARKER_NAMES[2]]
        centre = np.array([m3[0], m3[1] + float(self.boot_offset_m(np.array([t]))[0]),
                           self.model.camera_side * BOOT_DEPTH_M])
        ang = np.linspace(0, 2 * np.pi, 20, endpoint=False)
        # wider along the body than tall: it never reaches the next marker, 17-23 cm ahead
        blob = centre + np.column_stack([1.3 * BOOT_RADIUS_M * np.cos(ang), BOOT_RADIUS_M * np.sin(ang),
                                         np.zeros_like(ang)])
        fill_polygons(frame, [view.project(self._body_to_world(blob, rot[0], org[0]))], [22.0])

    def draw(self, frame: np.ndarray, view: CameraView, t: float) -> None:
        """Draw the horse, saddle pad, saddle and rider at instant ``t`` into ``frame`` (H, W) float32."""
        s = self.model.camera_side
        k = self.model.horse_height_m / 1.65
        rot, org = self.pose_arena(np.array([t]))
        rot, org = rot[0], org[0]
        polys, vals = [], []

        def body(poly2d: np.ndarray, zf: float, dy: float = 0.0) -> np.ndarray:
            p = np.column_stack([poly2d[:, 0] * k, poly2d[:, 1] * k + dy, np.full(len(poly2d), s * zf)])
            return self._body_to_world(p, rot, org)

        legs = self._legs(t, rot, org, k)
        for near, quad in legs:
            if not near:
                polys.append(quad)
                vals.append(36.0)
        polys += [body(_TAIL, 0.2), body(_TRUNK, 0.25)]
        vals += [30.0, 58.0]
        for near, quad in legs:
            if near:
                polys.append(quad)
                vals.append(48.0)
        if self.distractors:  # the white saddle pad: a large bright look-alike region near the markers
            polys.append(body(_PAD, 0.32))
            vals.append(215.0)
        polys.append(body(_SADDLE, 0.33))
        vals.append(36.0)
        if self.rider:
            rise = 0.0
            if self.model.gait == "rising_trot":
                rise = -0.09 * max(0.0, np.sin(2 * np.pi * self.model.stride_hz * t))
            for name, (poly, val) in _RIDER.items():
                polys.append(body(poly, 0.42, dy=rise if name in ("torso", "arm", "head") else 0.0))
                vals.append(val)
        sizes = [len(p) for p in polys]
        px = view.project(np.concatenate(polys))
        fill_polygons(frame, np.split(px, np.cumsum(sizes)[:-1]), vals)

    def _legs(self, t: float, rot: np.ndarray, org: np.ndarray, k: float) -> list[tuple[bool, np.ndarray]]:
        """The four legs as (near side, world quadrilateral (4, 3) m), swinging with the stride."""
        s = self.model.camera_side
        phases = _LEG_PHASES[self.model.gait]
        out = []
        for (x_top, near), ph in zip(
            ((0.62, True), (0.52, False), (-0.66, True), (-0.76, False)), phases, strict=True
        ):
            top_body = np.array([x_top * k, 0.5 * k, s * (0.22 if near else -0.18)])
            top = org + rot @ top_body
            swing = 0.0 if self.static else 0.35 * np.sin(2 * np.pi * (self.model.stride_hz * t + ph))
            length = self.ground_y_m - top[1]
            hoof = np.array([top[0] + length * np.sin(swing), self.ground_y_m, top[2]])
            quad = np.array(
                [top + [-0.07 * k, 0, 0], top + [0.07 * k, 0, 0], hoof + [0.045, 0, 0], hoof + [-0.045, 0, 0]]
            )
            out.append((near, quad @ self.m_dir.T))
        return out


@dataclass
class PlumbContent:
    """A plumb line with two markers hanging at world (x, z); gravity gives its direction."""

    x_m: float
    z_m: float
    y_markers_m: tuple[float, float] = (-0.35, 0.35)
    peaks: np.ndarray = field(default_factory=lambda: np.array([262.0, 266.0]))
    marker_diameter_mm: float = 30.0
    marker_names: tuple[str, ...] = ("plumb_top", "plumb_bottom")

    @property
    def rendered(self) -> np.ndarray:
        """Both markers are drawn, shape (2,) bool."""
        return np.array([True, True])

    @property
    def diameters_mm(self) -> np.ndarray:
        """Marker diameters, shape (2,) mm."""
        return np.full(2, self.marker_diameter_mm)

    def markers_w(self, t: np.ndarray) -> np.ndarray:
        """The two hanging markers in world metres (T, 2, 3) at instants ``t`` (T,) s."""
        t = np.atleast_1d(t)
        pts = np.array([[self.x_m, y, self.z_m] for y in self.y_markers_m])
        return np.broadcast_to(pts, (len(t), 2, 3)).copy()

    def glints(self, view: CameraView, t: float):
        """No look-alikes near the plumb line: None."""
        return None

    def draw(self, frame: np.ndarray, view: CameraView, t: float) -> None:
        """Draw the string and the bob into ``frame`` (H, W) float32."""
        top = np.array([self.x_m, -1.3, self.z_m])
        bob = np.array([self.x_m, self.y_markers_m[1] + 0.25, self.z_m])
        ends = view.project(np.stack([top, bob]))
        if not np.all(np.isfinite(ends)):
            return
        # a thin string: blend a 1-px anti-aliased line at partial opacity
        layer = np.zeros_like(frame)
        p = np.round(ends * 16).astype(np.int32)
        cv2.line(layer, tuple(p[0]), tuple(p[1]), 1.0, 1, cv2.LINE_AA, 4)
        frame += 0.45 * layer * (175.0 - frame)
        # the bob: a dark cone
        cone = np.array([bob + [-0.03, -0.04, 0], bob + [0.03, -0.04, 0], bob + [0, 0.06, 0]])
        fill_polygons(frame, [view.project(cone)], [30.0])


@dataclass
class BallContent:
    """A reflective ball (thesis 8.3) held still, thrown up at release_s and caught at catch_s."""

    p0_w: np.ndarray
    v0_w: np.ndarray
    release_s: float
    catch_s: float
    diameter_mm: float = 65.0
    peaks: np.ndarray = field(default_factory=lambda: np.array([262.0]))
    marker_names: tuple[str, ...] = ("ball",)

    @property
    def rendered(self) -> np.ndarray:
        """The ball is drawn, shape (1,) bool."""
        return np.array([True])

    @property
    def diameters_mm(self) -> np.ndarray:
        """The ball's diameter, shape (1,) mm."""
        return np.array([self.diameter_mm])

    def markers_w(self, t: np.ndarray) -> np.ndarray:
        """The ball's centre in world metres (T, 1, 3) at instants ``t`` (T,) s (still before and after the flight)."""
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        tau = np.clip(t, self.release_s, self.catch_s) - self.release_s
        g = np.array([0.0, GRAVITY_M_S2, 0.0])  # world y is down
        p = self.p0_w + np.outer(tau, self.v0_w) + 0.5 * np.outer(tau**2, g)
        return p[:, None, :]

    def glints(self, view: CameraView, t: float):
        """No look-alikes near the ball: None."""
        return None

    def draw(self, frame: np.ndarray, view: CameraView, t: float) -> None:
        """Draw the hand that holds the ball before the throw and after the catch into ``frame`` (H, W)."""
        if t < self.release_s or t > self.catch_s:
            # a hand (dark blob) holds the ball before the throw and after the catch
            p = self.markers_w(np.array([t]))[0, 0] + np.array([0.0, 0.06, 0.0])
            ang = np.linspace(0, 2 * np.pi, 10, endpoint=False)
            hand = p + np.column_stack([0.06 * np.cos(ang), 0.05 * np.sin(ang), np.zeros(10)])
            fill_polygons(frame, [view.project(hand)], [60.0])


@dataclass
class BoardContent:
    """A checkerboard carried through poses: each held still for hold_s, then moved for move_s.

    poses : list of (R_board_to_world (3, 3), origin_world_m (3,)); the first pose is held before
    start_s and the last one after the sequence.
    """

    poses: list[tuple[np.ndarray, np.ndarray]]
    start_s: float
    hold_s: float
    move_s: float
    square_m: float
    inner_corners: tuple[int, int]
    marker_names: tuple[str, ...] = ()

    @property
    def rendered(self) -> np.ndarray:
        """No markers, shape (0,) bool."""
        return np.zeros(0, bool)

    @property
    def diameters_mm(self) -> np.ndarray:
        """No markers, shape (0,)."""
        return np.zeros(0)

    peaks = np.zeros(0)

    def markers_w(self, t: np.ndarray) -> np.ndarray:
        """No markers: shape (T, 0, 3) for instants ``t`` (T,)."""
        return np.zeros((len(np.atleast_1d(t)), 0, 3))

    def glints(self, view: CameraView, t: float):
        """No look-alikes near the board: None."""
        return None

    @property
    def period_s(self) -> float:
        """One pose's hold plus the move to the next (s)."""
        return self.hold_s + self.move_s

    def pose_at(self, t: float) -> tuple[np.ndarray, np.ndarray, bool]:
        """Pose at instant ``t`` (s): R_board_to_world (3, 3), origin_world_m (3,) and whether it is still."""
        x = (t - self.start_s) / self.period_s
        j = int(np.floor(x))
        if j < 0:
            r, o = self.poses[0]
            return r, o, True
        if j >= len(self.poses) - 1:
            r, o = self.poses[-1]
            return r, o, True
        frac = (x - j) * self.period_s
        r0, o0 = self.poses[j]
        if frac <= self.hold_s:
            return r0, o0, True
        r1, o1 = self.poses[j + 1]
        a = (frac - self.hold_s) / self.move_s
        a = a * a * (3 - 2 * a)  # smoothstep: the board starts and stops gently
        rel = cv2.Rodrigues(r1 @ r0.T)[0].ravel()
        r = cv2.Rodrigues(rel * a)[0] @ r0
        return r, o0 + a * (o1 - o0), False

    def pose_index(self, t: float) -> int:
        """Index of the pose held at t (the last pose before it while moving)."""
        x = (t - self.start_s) / self.period_s
        return int(np.clip(np.floor(x), 0, len(self.poses) - 1))

    def draw_samples(
        self,
        frame: np.ndarray,
        view: CameraView,
        t_samples: np.ndarray,
        options: RenderOptions,
        cache: dict | None = None,
    ) -> None:
        """Draw the board blurred over the exposure instants ``t_samples`` (S,) s into ``frame`` (H, W).

        ``cache`` reuses the patch of a still pose.
        """
        if len(t_samples) > 3:  # three instants are plenty for a board in motion
            t_samples = np.asarray(t_samples)[[0, len(t_samples) // 2, -1]]
        poses = [self.pose_at(float(t))[:2] for t in t_samples]
        # a still board needs one sample (and is the same patch as in the previous frame)
        still = all(np.array_equal(p[1], poses[0][1]) and np.array_equal(p[0], poses[0][0]) for p in poses)
        key = None
        if still:
            poses = poses[:1]
            key = (view.role, poses[0][0].tobytes(), poses[0][1].tobytes())
        if cache is not None and key is not None and key in cache:
            res = cache[key]
        else:
            res = board_patch(
                view, poses, square_m=self.square_m, inner_corners=self.inner_corners, options=options
            )
            if cache is not None and key is not None:
                cache.clear()  # keep only the last still pose
                cache[key] = res
        if res is not None:
            composite_patch(frame, *res)

    def draw(self, frame: np.ndarray, view: CameraView, t: float) -> None:
        """Draw the board as it stands at instant ``t`` into ``frame`` (H, W) (no motion blur)."""
        self.draw_samples(frame, view, np.array([t]), RenderOptions())

    def corners_w(self, r_bw: np.ndarray, o_w: np.ndarray) -> np.ndarray:
        """Inner corners in world metres, (cols*rows, 3), row-major like Board.object_points_mm.

        ``r_bw`` (3, 3) maps board -> world; ``o_w`` (3,) is the board origin in world metres.
        """
        cols, rows = self.inner_corners
        grid = np.zeros((rows * cols, 3))
        grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * self.square_m
        return o_w + grid @ r_bw.T


# What one clip shows: the horse (motion, static), the plumb line, the thrown ball or a board.
ClipContent = HorseContent | PlumbContent | BallContent | BoardContent

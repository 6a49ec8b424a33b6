"""Camera rigs of the synthetic arena: the thesis's three close cameras and a wide converging rig.

Frames: the world (arena) frame W has X along the track (to the right in the images), Y down
(gravity) and Z away from the cameras, in metres, origin on the track line at the saddle's rest
height abreast of the middle camera. The rig frame is the left camera's (mm), as in
``core.types``: ``x_rig_mm = R_world_to_rig @ (1000 X_W) + t_world_to_rig_mm``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.types import CAMERA_ROLES, Camera

__all__ = ["RIGS", "SceneRig", "make_rig", "normalized_pixel_grid", "thesis_rig", "wide_partial_rig", "wide_rig"]

RIGS: tuple[str, ...] = ("thesis", "wide", "wide_partial")


def _rotvec(rx: float, ry: float, rz: float) -> np.ndarray:
    """Rotation matrix (3, 3) of the rotation vector (rx, ry, rz) rad."""
    return cv2.Rodrigues(np.array([rx, ry, rz], dtype=np.float64))[0]


def _look_at(center_w: np.ndarray, target_w: np.ndarray, *, roll_rad: float = 0.0) -> np.ndarray:
    """World -> camera rotation (3, 3) of a camera at center looking at target, image y down."""
    z = target_w - center_w
    z = z / np.linalg.norm(z)
    x = np.cross(np.array([0.0, 1.0, 0.0]), z)  # world Y is down, so Y x Z points right
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    r = np.stack([x, y, z])
    return _rotvec(0.0, 0.0, roll_rad) @ r


@dataclass(frozen=True)
class SceneRig:
    """Cameras of one synthetic setup and where they stand in the arena.

    cameras : role -> Camera (rig frame = left camera, mm); R_world_to_rig (3, 3) and
    t_world_to_rig_mm (3,) map world metres*1000 to rig mm; fps, exposure_s; ground_y_m and
    wall_z_m place the arena floor and back wall; volume_half_m (3,) is the half-size of the
    calibration volume (X, Y, Z) around the world origin.
    """

    name: str
    cameras: dict[str, Camera]
    R_world_to_rig: np.ndarray
    t_world_to_rig_mm: np.ndarray
    fps: float
    exposure_s: float
    ground_y_m: float
    wall_z_m: float
    volume_half_m: np.ndarray
    marker_diameter_mm: float = 30.0
    # cameras that must see every marker for the truth's analysis window: 3 = all (the horse crosses
    # the common view), 2 = any two (side cameras see only part of the crossing)
    window_min_views: int = 3

    def world_to_rig_mm(self, x_world_m: np.ndarray) -> np.ndarray:
        """World points (..., 3) m -> rig points (..., 3) mm."""
        x = np.asarray(x_world_m, dtype=np.float64) * 1000.0
        return x @ self.R_world_to_rig.T + self.t_world_to_rig_mm

    def camera_world_pose(self, role: str) -> tuple[np.ndarray, np.ndarray]:
        """World -> camera rotation (3, 3) and camera centre in world metres (3,)."""
        cam = self.cameras[role]
        r_wc = cam.R @ self.R_world_to_rig
        # x_cam = R (R_wr X + t_wr) + t = r_wc X + (R t_wr + t)
        t_wc = cam.R @ self.t_world_to_rig_mm + cam.t_mm
        return r_wc, -r_wc.T @ t_wc / 1000.0

    @property
    def gravity_rig(self) -> np.ndarray:
        """Unit gravity direction (down) in rig coordinates, (3,)."""
        return self.R_world_to_rig[:, 1].copy()


def _scaled(cam: Camera, size: tuple[int, int] | None) -> Camera:
    """The same camera at another resolution: K scales with the image, distortion stays."""
    if size is None:
        return cam
    w, h = int(size[0]), int(size[1])
    if w < 64 or h < 48 or w % 2 or h % 2:
        raise InputError(
            f"image size {w}x{h} must be even and at least 64x48 (H.264 yuv420p needs even sizes)"
        )
    sx, sy = w / cam.image_size[0], h / cam.image_size[1]
    k = np.diag([sx, sy, 1.0]) @ cam.K
    return Camera(cam.name, k, cam.dist.copy(), (w, h), cam.R.copy(), cam.t_mm.copy())


def _assemble(
    name: str,
    poses_w: dict[str, tuple[np.ndarray, np.ndarray]],
    intr: dict[str, tuple],
    size: tuple[int, int] | None,
    **kw,
) -> SceneRig:
    """Cameras from world poses (R_wc, centre m) and intrinsics (K, dist, size), left = rig frame."""
    r_wl, c_l = poses_w["left"]
    cams = {}
    for role in CAMERA_ROLES:
        r_wc, c_c = poses_w[role]
        k, dist, native = intr[role]
        r_rel = r_wc @ r_wl.T
        t_rel_mm = r_wc @ (c_l - c_c) * 1000.0
        if role == "left":
            r_rel, t_rel_mm = np.eye(3), np.zeros(3)
        cams[role] = _scaled(Camera(role, k, dist, native, r_rel, t_rel_mm), size)
    return SceneRig(
        name=name, cameras=cams, R_world_to_rig=r_wl, t_world_to_rig_mm=-r_wl @ c_l * 1000.0, **kw
    )


def thesis_rig(
    rng: np.random.Generator, *, size: tuple[int, int] | None = None, fps: float | None = None
) -> SceneRig:
    """Three parallel-ish cameras 0.22-0.24 m apart, 7.5 m from the track (thesis 8.1, Tables 8.1-8.4).

    Intrinsics are the thesis's averaged values with small per-seed changes; the middle camera is
    tilted by a degree or two so that gravity is not exactly image y.
    """
    # Tables 8.1-8.3 (averaged over the two stereo calibrations of each camera); k3 = 0 as in Bouguet
    base = {
        "left": ([726.7, 725.3], [327.9, 234.6], [-0.1291, 0.0226, -0.0012, 0.0023, 0.0]),
        "middle": ([735.9, 734.5], [315.7, 231.2], [-0.1364, 0.0077, -0.0014, 0.0018, 0.0]),
        "right": ([719.9, 718.1], [309.6, 229.5], [-0.1360, 0.0537, -0.0024, -0.0002, 0.0]),
    }
    intr = {}
    for role in CAMERA_ROLES:
        f, c, d = base[role]
        df = rng.normal(0.0, 2.0)
        k = np.array(
            [
                [f[0] + df, 0.0, c[0] + rng.normal(0.0, 1.5)],
                [0.0, f[1] + df, c[1] + rng.normal(0.0, 1.5)],
                [0.0, 0.0, 1.0],
            ]
        )
        dist = np.array(d) * np.array([1 + rng.normal(0, 0.03), 1 + rng.normal(0, 0.05), 1, 1, 1])
        intr[role] = (k, dist, (640, 480))
    # middle camera: 7.5 m in front of the track, lens ~0.15-0.25 m below the saddle, tilted slightly
    pitch, roll = np.deg2rad(rng.uniform(-2.0, 2.0)), np.deg2rad(rng.uniform(-1.2, 1.2))
    r_wm = _rotvec(0.0, 0.0, roll) @ _rotvec(pitch, 0.0, 0.0)
    c_m = np.array([0.0, rng.uniform(0.15, 0.25), -7.5 + rng.normal(0.0, 0.05)])
    # Table 8.4: x_M = R_ML x_L + t_ML, x_R = R_RL x_L + t_RL (mm); rotation vectors read off the matrices
    r_ml = _rotvec(0.0107, 0.0208, -0.0045) @ _rotvec(*rng.normal(0.0, 0.0015, 3))
    t_ml = np.array([-238.06, -4.26, -13.06]) + rng.normal(0.0, 2.0, 3)
    r_rl = _rotvec(0.0109, 0.0782, -0.0359) @ _rotvec(*rng.normal(0.0, 0.0015, 3))
    t_rl = np.array([-446.97, -3.85, 10.57]) + rng.normal(0.0, 2.0, 3)
    r_wl = r_ml.T @ r_wm
    c_l = c_m + r_wm.T @ t_ml / 1000.0
    r_wr = r_rl @ r_wl
    c_r = c_l - r_wr.T @ t_rl / 1000.0
    poses = {"left": (r_wl, c_l), "middle": (r_wm, c_m), "right": (r_wr, c_r)}
    return _assemble(
        "thesis",
        poses,
        intr,
        size,
        fps=float(fps or 30.0),
        exposure_s=1.0 / 250.0,
        ground_y_m=1.45,
        wall_z_m=6.0,
        volume_half_m=np.array([3.0, 0.35, 0.25]),
    )


def wide_rig(
    rng: np.random.Generator, *, size: tuple[int, int] | None = None, fps: float | None = None
) -> SceneRig:
    """What we recommend to a club: cameras ~2.5 m apart converging on the track, 1920x1080 at 60 fps."""
    intr = {}
    for role in CAMERA_ROLES:
        f = 1450.0 + rng.normal(0.0, 15.0)
        k = np.array([[f, 0.0, 960.0 + rng.normal(0, 6)], [0.0, f, 540.0 + rng.normal(0, 6)], [0, 0, 1.0]])
        dist = np.array(
            [
                -0.09 + rng.normal(0, 0.01),
                0.08 + rng.normal(0, 0.01),
                rng.normal(0, 3e-4),
                rng.normal(0, 3e-4),
                -0.02 + rng.normal(0, 0.005),
            ]
        )
        intr[role] = (k, dist, (1920, 1080))
    target = np.array([0.0, 0.15, 0.0])
    poses = {}
    for role, x in zip(CAMERA_ROLES, (-2.5, 0.0, 2.5), strict=True):
        c = np.array([x + rng.normal(0, 0.05), rng.uniform(0.05, 0.25), -8.0 + abs(x) * 0.15])
        aim = target + np.array([rng.normal(0, 0.2), rng.normal(0, 0.05), 0.0])
        poses[role] = (_look_at(c, aim, roll_rad=np.deg2rad(rng.uniform(-1.0, 1.0))), c)
    return _assemble(
        "wide",
        poses,
        intr,
        size,
        fps=float(fps or 60.0),
        exposure_s=1.0 / 500.0,
        ground_y_m=1.45,
        wall_z_m=6.0,
        volume_half_m=np.array([3.5, 0.45, 0.4]),
    )


def wide_partial_rig(
    rng: np.random.Generator, *, size: tuple[int, int] | None = None, fps: float | None = None
) -> SceneRig:
    """A club's wide rig that nobody tuned (issue 27): 1280x720 at 50 fps, cameras 1.8 m apart at ~6 m.

    The middle camera sees the whole crossing; each side camera, nearer or farther and higher or lower
    than the middle one, about two thirds of it (the three see only the middle third together). Wider
    lenses than the "wide" rig's, with strong barrel distortion that the markers meet near the image
    corners, where a board carried through the common view never went.
    """
    intr = {}
    # left nearer and lower, right farther and higher: different heights and distances
    layout = {"left": (-1.8, 5.5, 0.35), "middle": (0.0, 6.0, 0.15), "right": (1.8, 6.6, -0.1)}
    for role in CAMERA_ROLES:
        f = {"left": 1080.0, "middle": 900.0, "right": 1160.0}[role] + rng.normal(0.0, 10.0)
        k = np.array([[f, 0.0, 640.0 + rng.normal(0, 5)], [0.0, f, 360.0 + rng.normal(0, 5)], [0, 0, 1.0]])
        dist = np.array(
            [
                -0.22 + rng.normal(0, 0.01),
                0.06 + rng.normal(0, 0.005),
                rng.normal(0, 5e-4),
                rng.normal(0, 5e-4),
                0.0,  # k3 = 0 keeps r (1 + k1 r^2 + k2 r^4) monotonic at any angle: nothing folds into view
            ]
        )
        intr[role] = (k, dist, (1280, 720))
    poses = {}
    for role in CAMERA_ROLES:
        x, dist_m, y = layout[role]
        c = np.array([x + rng.normal(0, 0.05), y + rng.normal(0, 0.03), -dist_m + rng.normal(0, 0.05)])
        # side cameras turned in hardly at all (0-2 degrees), so they miss the far third of the crossing
        aim_x = x - np.sign(x) * dist_m * np.tan(np.deg2rad(rng.uniform(0.0, 2.0)))
        aim = np.array([aim_x, 0.15 + rng.normal(0, 0.05), 0.0])
        poses[role] = (_look_at(c, aim, roll_rad=np.deg2rad(rng.uniform(-1.5, 1.5))), c)
    return _assemble(
        "wide_partial",
        poses,
        intr,
        size,
        fps=float(fps or 50.0),
        exposure_s=1.0 / 500.0,
        ground_y_m=1.45,
        wall_z_m=6.0,
        volume_half_m=np.array([1.6, 0.4, 0.35]),
        marker_diameter_mm=50.0,
        window_min_views=2,
    )


def make_rig(
    name: str, rng: np.random.Generator, *, size: tuple[int, int] | None = None, fps: float | None = None
) -> SceneRig:
    """The rig called ``name`` ("thesis", "wide" or "wide_partial")."""
    if fps is not None and not (1.0 <= float(fps) <= 1000.0):
        raise InputError(f"frame rate {fps} fps is outside 1-1000 fps")
    if name == "thesis":
        return thesis_rig(rng, size=size, fps=fps)
    if name == "wide":
        return wide_rig(rng, size=size, fps=fps)
    if name == "wide_partial":
        return wide_partial_rig(rng, size=size, fps=fps)
    raise InputError(f"unknown rig {name!r}; expected one of {', '.join(RIGS)}")


def normalized_pixel_grid(camera: Camera, *, step: int | None = None) -> np.ndarray:
    """Undistorted normalised coordinates (x/z, y/z) of every pixel centre, shape (H, W, 2) float32.

    Exact (iterative) undistortion on a grid every ``step`` pixels, bilinear in between: the map is
    smooth, so the error stays below 0.001 px (step 2 up to 1000 px wide, else 4) at a tenth of the cost.
    """
    w, h = camera.image_size
    step = int(step or (2 if w <= 1000 else 4))
    xs = np.arange(0, w - 1 + step, step, dtype=np.float64)
    ys = np.arange(0, h - 1 + step, step, dtype=np.float64)
    u, v = np.meshgrid(xs, ys)
    pts = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    und = cv2.undistortPoints(
        pts, camera.K, camera.dist, criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    )
    coarse = und.reshape(len(ys), len(xs), 2).astype(np.float32)
    if step == 1:
        return coarse[:h, :w].copy()
    # pixel / step is a multiple of 1/32, so remap's fixed-point weights are exact here
    mx, my = np.meshgrid(np.arange(w, dtype=np.float32) / step, np.arange(h, dtype=np.float32) / step)
    return cv2.remap(coarse, mx, my, cv2.INTER_LINEAR)

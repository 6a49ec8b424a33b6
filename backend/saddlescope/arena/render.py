"""Frame rendering of the synthetic arena: background, dark shapes, marker blobs, boards, flash, noise.

Frames are grey images in [0, 255] (float32 while drawing, uint8 at the end). Only the marker
blobs and the calibration board need sub-pixel accuracy: they are drawn from closed-form radial
profiles / the exact board plane, supersampled per pixel. Everything else uses cv2 drawing with
sub-pixel vertices. Each camera's static layers (textured arena, distractors, vignetting, the
foreground pole) are rendered once in a :class:`CameraView`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.special import erfc

from saddlescope.core.types import Camera

__all__ = [
    "CameraView",
    "Pole",
    "RenderOptions",
    "board_patch",
    "composite_foreground",
    "composite_patch",
    "draw_markers",
    "fill_polygons",
    "finish_frame",
    "flash_fraction",
    "marker_coverage",
    "noise_bank",
    "noise_texture",
    "render_background",
    "render_pole",
]


@dataclass(frozen=True)
class RenderOptions:
    """What the renderer adds on top of the exact geometry (switch parts off for geometry tests)."""

    noise_sigma: float = 2.0  # DN, Gaussian read noise
    shot_noise: float = 0.12  # DN per sqrt(DN)
    motion_blur: bool = True  # integrate blur_samples positions over the exposure
    blur_samples: int = 5
    distractors: bool = True  # glints, light patches, stirrup reflection, white saddle pad
    occluder: bool = True  # a foreground pole that hides markers in one camera at a time
    lighting_drift: bool = True
    textured_background: bool = True
    psf_sigma_px: float = 0.6  # lens blur of marker edges and the board
    marker_halo: float = 0.12  # faint glow around retro-reflective markers (fraction of the peak)
    markers: bool = True  # False renders the scene without its markers (for difference images)
    supersample: int = 3
    # skin sliding of markers 1-3, one of arena.gait.SKIN_MODELS: "stride_locked" (as a real
    # flank), "noise" (small random sliding only) or "none" (markers fixed to the saddle body)
    skin_motion: str = "stride_locked"
    # markers 1-3's layout on the flank, one of arena.gait.MARKER_LAYOUTS: "thesis" (a shallow V)
    # or "triangle" (the middle marker about 10 cm below the others, as the README recommends)
    marker_layout: str = "thesis"
    # the middle and right cameras record at a variable frame rate, as phones do (jittered frame
    # intervals, dropped frames; the clips carry each frame's timestamp)
    variable_frame_rate: bool = False
    # a sync lamp flashes at the start of every clip; False films a ride without one (the cameras are
    # then synchronised from the markers' own motion, with the same unknown sub-frame offsets)
    flash: bool = True
    # --- the field's nuisances (issue 38), all off by default: the demo ride is unchanged ---
    # a rider's boot, a dark blob in front of the rear marker (marker 3) for this share of every
    # stride, phase-locked to the stride; it slides over the disc, so the disc is partly covered as
    # it comes and goes (0: no boot)
    boot_share: float = 0.0
    # a phone's rolling shutter: row y of a frame is exposed at the frame's instant + y / H * readout
    # (0: a global shutter); rendered per band of rows, each at its own instant
    readout_s: float = 0.0
    rolling_bands: int = 16  # row bands the rolling shutter is rendered in
    # the H.264 constant rate factor the bundle's clips are written with (18 near-transparent, 28 a
    # phone's visibly lossy compression)
    crf: int = 20
    # a saddle vertical harmonic of the stride at this order (k) beyond the gait's four, with its
    # acceleration this share of the vertical acceleration's r.m.s. (0: none); e.g. a trot with
    # energy at its 6th harmonic (8-9 Hz, where W_b weighs most)
    high_harmonic: int = 6
    high_harmonic_share: float = 0.0
    # passes of the horse in front of the cameras in the one motion clip (a club's ride round the arena's
    # track): it crosses the view, leaves it for a few seconds and comes back, same direction, its stride
    # running on and its speed a little different each time (1: the one crossing of the demo ride)
    passes: int = 1

    def nuisances(self) -> dict:
        """The field nuisances this ride was filmed with (for its truth.json)."""
        return {"boot_share": self.boot_share, "readout_s": self.readout_s, "crf": self.crf,
                "high_harmonic": self.high_harmonic if self.high_harmonic_share > 0 else None,
                "high_harmonic_share": self.high_harmonic_share, "passes": self.passes}


@dataclass(frozen=True)
class Pole:
    """A vertical striped pole standing on the ground (world metres): a jump stand in the foreground."""

    x_m: float
    z_m: float
    width_m: float
    top_y_m: float
    ground_y_m: float


class CameraView:
    """One camera's projection helpers and pre-rendered static layers.

    camera : Camera in rig coordinates; r_wc (3, 3), t_wc_mm (3,) map world metres*1000 to this
    camera; norm_grid (H, W, 2) undistorted normalised coordinates of every pixel.
    """

    def __init__(
        self, role: str, camera: Camera, r_wc: np.ndarray, t_wc_mm: np.ndarray, norm_grid: np.ndarray
    ):
        self.role = role
        self.camera = camera
        self.r_wc = np.asarray(r_wc, dtype=np.float64)
        self.t_wc_mm = np.asarray(t_wc_mm, dtype=np.float64)
        self.rvec = cv2.Rodrigues(self.r_wc)[0].ravel()
        self.norm_grid = norm_grid
        self.size = camera.image_size
        self.background: np.ndarray | None = None
        self.fg_box: tuple[int, int, int, int] | None = None  # x0, y0, x1, y1
        self.fg_alpha: np.ndarray | None = None
        self.fg_value: np.ndarray | None = None

    def rendered_background(self) -> np.ndarray:
        """The pre-rendered static background (H, W); the scene paints it when it builds the views."""
        if self.background is None:
            raise RuntimeError(f"the {self.role} camera's background is not rendered yet (build the scene first)")
        return self.background

    @property
    def center_w(self) -> np.ndarray:
        """The camera centre in world metres, shape (3,)."""
        return -self.r_wc.T @ self.t_wc_mm / 1000.0

    def to_camera_mm(self, x_w_m: np.ndarray) -> np.ndarray:
        """World metres (..., 3) -> this camera's coordinates in mm (..., 3)."""
        return np.asarray(x_w_m, dtype=np.float64) * 1000.0 @ self.r_wc.T + self.t_wc_mm

    def project(self, x_w_m: np.ndarray) -> np.ndarray:
        """World metres (..., 3) -> distorted pixels (..., 2); NaN behind the camera or for NaN input."""
        pts = np.asarray(x_w_m, dtype=np.float64)
        shape = pts.shape[:-1]
        flat = pts.reshape(-1, 3)
        out = np.full((flat.shape[0], 2), np.nan)
        z = self.to_camera_mm(flat)[:, 2]
        ok = np.all(np.isfinite(flat), axis=1) & (z > 100.0)
        if ok.any():
            img, _ = cv2.projectPoints(
                flat[ok] * 1000.0, self.rvec, self.t_wc_mm, self.camera.K, self.camera.dist
            )
            out[ok] = img.reshape(-1, 2)
        return out.reshape(*shape, 2)

    def radius_px(self, x_w_m: np.ndarray, diameter_mm: np.ndarray | float) -> np.ndarray:
        """Image radius (px), shape (...), of spheres of the given diameter (mm) at world points (..., 3) m."""
        z = self.to_camera_mm(x_w_m)[..., 2]
        f = 0.5 * (self.camera.K[0, 0] + self.camera.K[1, 1])
        return 0.5 * f * np.asarray(diameter_mm, dtype=np.float64) / np.maximum(z, 1.0)

    def inside(self, xy_px: np.ndarray, margin_px: float) -> np.ndarray:
        """True where pixels (..., 2) lie at least margin_px inside the image."""
        w, h = self.size
        x, y = xy_px[..., 0], xy_px[..., 1]
        with np.errstate(invalid="ignore"):
            return (
                (x >= margin_px - 0.5)
                & (x <= w - 0.5 - margin_px)
                & (y >= margin_px - 0.5)
                & (y <= h - 0.5 - margin_px)
            )

    def fg_covers(self, xy_px: np.ndarray, radius_px: np.ndarray) -> np.ndarray:
        """True where a disc of radius_px + 1 around xy_px (..., 2) touches the foreground pole."""
        out = np.zeros(xy_px.shape[:-1], dtype=bool)
        if self.fg_alpha is None or self.fg_box is None:
            return out
        x0, y0, x1, y1 = self.fg_box
        ys, xs = np.nonzero(self.fg_alpha > 0.02)
        if xs.size == 0:
            return out
        # the pole is a vertical band: per row its covered x-range is enough
        lo = np.full(y1 - y0, np.inf)
        hi = np.full(y1 - y0, -np.inf)
        np.minimum.at(lo, ys, xs + x0)
        np.maximum.at(hi, ys, xs + x0)
        flat_xy = xy_px.reshape(-1, 2)
        flat_r = np.broadcast_to(radius_px, xy_px.shape[:-1]).reshape(-1) + 1.0
        res = out.reshape(-1)
        for i, ((x, y), r) in enumerate(zip(flat_xy, flat_r, strict=True)):
            if not np.isfinite(x):
                continue
            r0, r1 = int(np.floor(y - r)) - y0, int(np.ceil(y + r)) - y0 + 1
            r0, r1 = max(r0, 0), min(r1, y1 - y0)
            if r0 >= r1:
                continue
            if np.any((lo[r0:r1] <= x + r) & (hi[r0:r1] >= x - r)):
                res[i] = True
        return res.reshape(out.shape)


# --- textures and static layers --------------------------------------------------------------------
def noise_texture(rng: np.random.Generator, size: int = 512, *, octaves: int = 5) -> np.ndarray:
    """Tileable value noise of shape (size, size), float32, zero mean, unit-ish std."""
    tex = np.zeros((size, size), np.float32)
    amp = 1.0
    for o in range(octaves):
        n = 4 * 2**o
        base = rng.standard_normal((n, n)).astype(np.float32)
        tiled = np.tile(base, (3, 3))
        up = cv2.resize(tiled, (3 * size, 3 * size), interpolation=cv2.INTER_CUBIC)[
            size : 2 * size, size : 2 * size
        ]
        tex += amp * up
        amp *= 0.55
    return (tex - tex.mean()) / (tex.std() + 1e-9)


def render_background(
    view: CameraView, *, ground_y_m: float, wall_z_m: float, rng: np.random.Generator, options: RenderOptions
) -> np.ndarray:
    """The empty arena seen by one camera (H, W) float32: sand floor, plank wall, sky, vignetting."""
    w, h = view.size
    if not options.textured_background:
        return np.full((h, w), 120.0, np.float32)
    n = view.norm_grid.reshape(-1, 2).astype(np.float64)
    d = np.concatenate([n, np.ones((n.shape[0], 1))], axis=1) @ view.r_wc  # world ray directions
    c = view.center_w
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ground = np.where(d[:, 1] > 1e-9, (ground_y_m - c[1]) / d[:, 1], np.inf)
        t_wall = np.where(d[:, 2] > 1e-9, (wall_z_m - c[2]) / d[:, 2], np.inf)
    wall_top = ground_y_m - 2.4
    hit_wall = t_wall < t_ground
    p_wall = c + d * t_wall[:, None]
    sky = hit_wall & (p_wall[:, 1] < wall_top)
    p_ground = c + d * np.minimum(t_ground, 1e4)[:, None]

    sand = noise_texture(rng, 512)
    wood = noise_texture(rng, 256, octaves=4)
    # texture coordinates: sand 2 cm per texel, wall 1 cm per texel (cv2.remap wraps the tiles)
    u = np.where(hit_wall, p_wall[:, 0] * 100.0, p_ground[:, 0] * 50.0).astype(np.float32)
    v = np.where(hit_wall, p_wall[:, 1] * 100.0, p_ground[:, 2] * 50.0).astype(np.float32)
    s_val = cv2.remap(sand, u.reshape(h, w), v.reshape(h, w), cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    w_val = cv2.remap(
        wood, u.reshape(h, w) * 0.5, v.reshape(h, w) * 4.0, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP
    )
    plank = np.floor((p_wall[:, 1] - wall_top) / 0.18)
    plank_shade = (np.sin(plank * 12.9898) * 43758.5453) % 1.0  # per-plank brightness, repeatable
    gap = ((p_wall[:, 1] - wall_top) % 0.18) < 0.012
    wall = 115.0 + 25.0 * plank_shade + 6.0 * w_val.ravel() - 45.0 * gap
    ground = 150.0 + 12.0 * s_val.ravel()
    img = np.where(hit_wall, wall, ground)
    img = np.where(sky, 205.0 - 40.0 * np.clip(-(p_wall[:, 1] - wall_top) / 6.0, 0, 1), img)
    img = img.reshape(h, w).astype(np.float32)
    if options.distractors:
        # soft light patches on the sand (large, not marker-like)
        patches = cv2.GaussianBlur(np.maximum(sand, 1.6) - 1.6, (0, 0), 4.0)
        pv = cv2.remap(
            patches,
            u.reshape(h, w) * 0.3,
            v.reshape(h, w) * 0.3,
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_WRAP,
        )
        img += np.where(hit_wall.reshape(h, w), 0.0, 60.0 * pv).astype(np.float32)
    yy, xx = np.mgrid[0:h, 0:w]
    r2 = ((xx - w / 2) / (w / 2)) ** 2 + ((yy - h / 2) / (h / 2)) ** 2
    return (img * (1.0 - 0.12 * r2)).astype(np.float32)


def render_pole(view: CameraView, pole: Pole) -> None:
    """Pre-render the foreground pole (alpha and value in its bounding box) into the view."""
    w, h = view.size
    ys = np.linspace(pole.top_y_m, pole.ground_y_m, 40)
    left = np.stack([np.full_like(ys, pole.x_m - pole.width_m / 2), ys, np.full_like(ys, pole.z_m)], 1)
    right = left.copy()
    right[:, 0] += pole.width_m
    pl, pr = view.project(left), view.project(right)
    if not (np.all(np.isfinite(pl)) and np.all(np.isfinite(pr))):
        return
    poly = np.concatenate([pl, pr[::-1]])
    x0, y0 = np.floor(poly.min(0)).astype(int) - 2
    x1, y1 = np.ceil(poly.max(0)).astype(int) + 3
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x0 >= x1 or y0 >= y1:
        return
    alpha = np.zeros((y1 - y0, x1 - x0), np.float32)
    cv2.fillPoly(alpha, [np.round((poly - [x0, y0]) * 16).astype(np.int32)], 1.0, cv2.LINE_AA, 4)
    # red-and-white bands of 0.3 m; value per pixel row from the band at that height
    rows = np.arange(y0, y1) + 0.5
    band_y = np.interp(rows, 0.5 * (pl[:, 1] + pr[:, 1]), ys)
    value = np.where(np.floor((band_y - pole.top_y_m) / 0.3) % 2 == 0, 200.0, 75.0).astype(np.float32)
    # a little cylinder shading across the pole
    xs = np.arange(x0, x1) + 0.5
    xc = np.interp(rows, 0.5 * (pl[:, 1] + pr[:, 1]), 0.5 * (pl[:, 0] + pr[:, 0]))
    half = np.maximum(np.interp(rows, 0.5 * (pl[:, 1] + pr[:, 1]), 0.5 * np.abs(pr[:, 0] - pl[:, 0])), 0.5)
    shade = 1.0 - 0.35 * np.clip(np.abs(xs[None, :] - xc[:, None]) / half[:, None], 0, 1) ** 2
    view.fg_box = (x0, y0, x1, y1)
    view.fg_alpha = alpha
    view.fg_value = (value[:, None] * shade).astype(np.float32)


def composite_foreground(frame: np.ndarray, view: CameraView) -> None:
    """Lay the view's pre-rendered foreground pole over ``frame`` (H, W) float32, in place."""
    if view.fg_alpha is None or view.fg_value is None or view.fg_box is None:
        return
    x0, y0, x1, y1 = view.fg_box
    sub = frame[y0:y1, x0:x1]
    sub += view.fg_alpha * (view.fg_value - sub)


# --- dynamic drawing -------------------------------------------------------------------------------
def fill_polygons(frame: np.ndarray, polygons: list[np.ndarray], values: list[float]) -> None:
    """Draw filled anti-aliased polygons (each (N, 2) px) into ``frame`` (H, W) in order, NaN polygons skipped."""
    for poly, val in zip(polygons, values, strict=True):
        if poly.shape[0] < 3 or not np.all(np.isfinite(poly)):
            continue
        if np.abs(poly).max() > 1e5:
            continue
        cv2.fillPoly(frame, [np.round(poly * 16).astype(np.int32)], float(val), cv2.LINE_AA, 4)


def marker_coverage(
    centres_px: np.ndarray, radius_px: float, *, psf_sigma_px: float, supersample: int, halo: float = 0.12
) -> tuple[np.ndarray, int, int] | None:
    """Coverage (h, w) in [0, 1] of one retro-reflective marker blurred over its exposure samples.

    centres_px : ndarray of shape (S, 2), the marker centre at S instants of the exposure. The radial
    profile is a disc of radius_px blurred by the lens PSF (supersampled per pixel) plus a faint wide
    halo (smooth, sampled at pixel centres); it is radially symmetric, so the intensity-weighted
    centroid of the blob is the mean of the centres.
    Returns (coverage, x0, y0) of the patch's top-left pixel, or None if no centre is finite.
    """
    c = centres_px[np.all(np.isfinite(centres_px), axis=1)]
    if c.size == 0:
        return None
    sig = max(psf_sigma_px, 1e-3)
    halo_r = radius_px + 1.5
    reach = radius_px + 3.5 * sig + 1.0
    if halo > 0:
        reach = max(reach, radius_px + 2.5 * halo_r + 1.0)
    x0, y0 = np.floor(c.min(0) - reach).astype(int)
    x1, y1 = np.ceil(c.max(0) + reach).astype(int) + 1
    # core: supersampled inside its own (smaller) box
    reach_c = radius_px + 3.5 * sig + 1.0
    cx0, cy0 = np.floor(c.min(0) - reach_c).astype(int)
    cx1, cy1 = np.ceil(c.max(0) + reach_c).astype(int) + 1
    ss = max(int(supersample), 1)
    off = (np.arange(ss) + 0.5) / ss - 0.5
    gx = (np.arange(cx0, cx1)[:, None] + off[None, :]).ravel()
    gy = (np.arange(cy0, cy1)[:, None] + off[None, :]).ravel()
    acc = np.zeros((gy.size, gx.size))
    for px, py in c:
        d = np.sqrt((gy[:, None] - py) ** 2 + (gx[None, :] - px) ** 2)
        acc += erfc((d - radius_px) / (np.sqrt(2.0) * sig))
    core_c = acc.reshape(cy1 - cy0, ss, cx1 - cx0, ss).mean(axis=(1, 3)) * (0.5 / len(c))
    cov = np.zeros((y1 - y0, x1 - x0))
    cov[cy0 - y0 : cy1 - y0, cx0 - x0 : cx1 - x0] = core_c
    if halo > 0:
        hx = np.arange(x0, x1, dtype=np.float64)
        hy = np.arange(y0, y1, dtype=np.float64)
        hal = np.zeros_like(cov)
        for px, py in c:
            hal += np.exp(-0.5 * (hy[:, None] - py) ** 2 / halo_r**2) * np.exp(
                -0.5 * (hx[None, :] - px) ** 2 / halo_r**2
            )
        cov = cov + (halo / len(c)) * hal * (1.0 - cov)
    return np.clip(cov, 0.0, 1.0).astype(np.float32), int(x0), int(y0)


def draw_markers(
    frame: np.ndarray,
    centres_px: np.ndarray,
    radii_px: np.ndarray,
    peaks: np.ndarray,
    *,
    options: RenderOptions,
) -> None:
    """Composite markers into ``frame`` (H, W) float32, in place.

    centres_px (S, M, 2) exposure samples, radii_px (M,), peak values (M,) DN.
    """
    h, w = frame.shape
    for m in range(centres_px.shape[1]):
        res = marker_coverage(
            centres_px[:, m],
            float(radii_px[m]),
            psf_sigma_px=options.psf_sigma_px,
            supersample=options.supersample,
            halo=options.marker_halo,
        )
        if res is None:
            continue
        cov, x0, y0 = res
        fx0, fy0 = max(x0, 0), max(y0, 0)
        fx1, fy1 = min(x0 + cov.shape[1], w), min(y0 + cov.shape[0], h)
        if fx0 >= fx1 or fy0 >= fy1:
            continue
        a = cov[fy0 - y0 : fy1 - y0, fx0 - x0 : fx1 - x0]
        sub = frame[fy0:fy1, fx0:fx1]
        sub += a * (float(peaks[m]) - sub)


def board_patch(
    view: CameraView,
    poses: list[tuple[np.ndarray, np.ndarray]],
    *,
    square_m: float,
    inner_corners: tuple[int, int],
    options: RenderOptions,
    white: float = 210.0,
    black: float = 28.0,
) -> tuple[np.ndarray, np.ndarray, int, int] | None:
    """Render a checkerboard (with a one-square white margin) over its exposure poses.

    poses : list of (R_board_to_world (3, 3), origin_world_m (3,)); board coordinates (u, v) m have
    the first inner corner at 0, u along columns, v along rows (as ``Board.object_points_mm``).
    Each pixel is sampled supersample^2 times on the exact plane through the undistorted ray.
    Returns (value, alpha, x0, y0) of the patch, or None when the board is not in view.
    """
    cols, rows = inner_corners
    u_lo, u_hi = -2 * square_m, (cols + 1) * square_m
    v_lo, v_hi = -2 * square_m, (rows + 1) * square_m
    outline = np.array([[u_lo, v_lo], [u_hi, v_lo], [u_hi, v_hi], [u_lo, v_hi]])
    outlines_px = []
    for r_bw, o_w in poses:
        pts = o_w + np.concatenate([outline, np.zeros((4, 1))], 1) @ r_bw.T
        outlines_px.append(view.project(pts))
    pix = np.concatenate(outlines_px)
    if not np.all(np.isfinite(pix)):
        return None
    w, h = view.size
    x0, y0 = np.floor(pix.min(0)).astype(int) - 2
    x1, y1 = np.ceil(pix.max(0)).astype(int) + 3
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x0 >= x1 or y0 >= y1:
        return None
    # a still board is sampled finely (corner accuracy); a moving one is blurred anyway
    ss = max(int(options.supersample) + 1, 2) if len(poses) == 1 else 2
    off = (np.arange(ss) + 0.5) / ss - 0.5
    gx = (np.arange(x0, x1)[:, None] + off[None, :]).ravel().astype(np.float32)
    gy = (np.arange(y0, y1)[:, None] + off[None, :]).ravel().astype(np.float32)
    mx, my = np.meshgrid(gx, gy)
    # undistorted normalised coordinates at sub-pixel positions (the map is smooth: bilinear is exact
    # to ~1e-6 px here)
    nrm = cv2.remap(view.norm_grid, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    nx, ny = nrm[..., 0].astype(np.float64), nrm[..., 1].astype(np.float64)
    val = np.zeros(mx.shape)
    alpha = np.zeros(mx.shape)
    for r_bw, o_w in poses:
        # plane in camera coordinates: X = R_cb [u v 0] + o_c; homography n ~ [r1 r2 o_c] [u v 1]
        r_cb = view.r_wc @ r_bw
        o_c = view.to_camera_mm(o_w) / 1000.0
        hmat = np.column_stack([r_cb[:, 0], r_cb[:, 1], o_c])
        hi = np.linalg.inv(hmat)
        wz = hi[2, 0] * nx + hi[2, 1] * ny + hi[2, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (hi[0, 0] * nx + hi[0, 1] * ny + hi[0, 2]) / wz
            v = (hi[1, 0] * nx + hi[1, 1] * ny + hi[1, 2]) / wz
        front = wz > 0
        inside = front & (u >= u_lo) & (u <= u_hi) & (v >= v_lo) & (v <= v_hi)
        in_grid = (u >= -square_m) & (u < cols * square_m) & (v >= -square_m) & (v < rows * square_m)
        with np.errstate(invalid="ignore"):
            parity = (np.floor(u / square_m) + np.floor(v / square_m)) % 2
        # normal towards the camera dims the board a little when tilted
        normal_c = r_cb[:, 2]
        view_dir = -o_c / np.linalg.norm(o_c)
        shade = 0.75 + 0.25 * abs(float(normal_c @ view_dir))
        pv = np.where(in_grid & (parity == 0), black, white) * shade
        val += np.where(inside, pv, 0.0)
        alpha += inside
    n = float(len(poses))
    alpha_px = alpha.reshape(y1 - y0, ss, x1 - x0, ss).mean(axis=(1, 3)) / n
    val_px = val.reshape(y1 - y0, ss, x1 - x0, ss).mean(axis=(1, 3)) / n
    if options.psf_sigma_px > 0:
        # lens blur of the board and its edge (symmetric, so corner positions do not move)
        val_px = cv2.GaussianBlur(val_px, (0, 0), options.psf_sigma_px)
        alpha_px = cv2.GaussianBlur(alpha_px, (0, 0), options.psf_sigma_px)
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.where(alpha_px > 1e-6, val_px / np.maximum(alpha_px, 1e-6), 0.0)
    return value.astype(np.float32), alpha_px.astype(np.float32), int(x0), int(y0)


def composite_patch(frame: np.ndarray, value: np.ndarray, alpha: np.ndarray, x0: int, y0: int) -> None:
    """Blend a patch ``value`` (h, w) with opacity ``alpha`` (h, w) into ``frame`` (H, W) at column x0, row y0."""
    h, w = value.shape
    sub = frame[y0 : y0 + h, x0 : x0 + w]
    sub += alpha * (value - sub)


def flash_fraction(
    t_mid_s: np.ndarray, exposure_s: float, on_s: float, off_s: float, ramp_s: float
) -> np.ndarray:
    """Mean flash level (0..1) over exposures centred at ``t_mid_s`` (F,) s, shape (F,).

    For a lamp that ramps up over ramp_s from on_s and down over ramp_s from off_s (closed form of
    the trapezoid's integral).
    """

    def integral(t):  # integral of the trapezoid from -inf to t
        def ramp_int(x):  # integral of clip(x / ramp, 0, 1)
            x = np.asarray(x, dtype=np.float64)
            return np.where(x <= 0, 0.0, np.where(x < ramp_s, 0.5 * x**2 / ramp_s, x - 0.5 * ramp_s))

        return ramp_int(t - on_s) - ramp_int(t - off_s)

    t = np.asarray(t_mid_s, dtype=np.float64)
    e = max(float(exposure_s), 1e-6)
    return (integral(t + e / 2) - integral(t - e / 2)) / e


def noise_bank(rng: np.random.Generator, shape: tuple[int, int], *, pad: int = 61) -> np.ndarray:
    """Standard normal noise of shape (H + pad, W + pad), float32, to be cut at random offsets per frame.

    ``shape`` is the frames' (H, W).
    """
    return rng.standard_normal((shape[0] + pad, shape[1] + pad), dtype=np.float32)


_FINISH_BAND_VALUES = 1 << 16  # float32 values per band of rows finished at a time (256 KB)


def finish_frame(
    frame: np.ndarray,
    *,
    gain: float,
    flash: float,
    rng: np.random.Generator,
    options: RenderOptions,
    bank: np.ndarray | None = None,
) -> np.ndarray:
    """Lighting gain, flash, sensor noise, 8-bit quantisation: float (H, W) -> uint8 (H, W).

    The noise is a window of ``bank`` at an offset drawn from ``rng`` (with a random sign): as
    good as fresh Gaussian noise for a detector, at a fraction of the cost. Without a bank it is
    drawn from ``rng``.
    """
    h, w = frame.shape
    noise: np.ndarray | None = None
    negate = False
    if options.noise_sigma > 0 or options.shot_noise > 0:
        if bank is None:
            noise = rng.standard_normal((h, w), dtype=np.float32)
        else:
            dy, dx = rng.integers(0, bank.shape[0] - h + 1), rng.integers(0, bank.shape[1] - w + 1)
            noise = bank[dy : dy + h, dx : dx + w]
            negate = bool(rng.random() < 0.5)
    out = np.empty((h, w), np.uint8)
    # A band of rows at a time, changed in place: a 1080p frame is 8 MB of float32, and a dozen passes over it
    # wait on memory, over a band they stay in the cache (3-5x faster). The same operations in the same order
    # as on the whole frame out of place, so the same values.
    rows = max(1, _FINISH_BAND_VALUES // w)
    for r0 in range(0, h, rows):
        r1 = min(r0 + rows, h)
        img = frame[r0:r1] * np.float32(gain) if gain != 1.0 else np.array(frame[r0:r1], dtype=np.float32)
        if flash > 0:
            img += np.float32(95.0 * flash)
        if noise is not None:
            if options.shot_noise > 0:
                sigma = np.maximum(img, np.float32(0.0))
                np.sqrt(sigma, out=sigma)
                sigma *= np.float32(options.shot_noise)
                sigma += np.float32(options.noise_sigma)
                sigma *= noise[r0:r1]
            else:
                sigma = noise[r0:r1] * np.float32(options.noise_sigma)
            if negate:  # img + (-noise) * sigma, exactly
                img -= sigma
            else:
                img += sigma
        img += np.float32(0.5)
        np.clip(img, 0, 255, out=img)
        np.copyto(out[r0:r1], img, casting="unsafe")  # as astype(np.uint8)
    return out

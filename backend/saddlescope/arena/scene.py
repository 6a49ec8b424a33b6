"""The synthetic riding arena: a complete ride with exact ground truth.

``build_scene`` draws one setup from a seed (camera rig, horse and gait, clip timings, board poses,
plumb, extra validation clips); ``render_clip_frames`` yields a camera's uint8 frames of one clip
before encoding; ``true_marker_pixels`` gives the exact 2-D marker centres; ``build_truth`` writes the
exact answer in the result format (CONTRACTS section 2) plus a ``truth`` section for tests;
``saddle_truth_at`` evaluates the saddle point's exact kinematics at any left-clip times.

Time: every clip has its own clock, the left camera's: left frame k is at t = k / fps. Camera c's
frame k shows the instant t = (k - offset_c) / fps (offset = how many frames later an instant
appears in that camera). Frame instants are exposure midpoints.

Units: world/arena metres and seconds; rig (left camera) millimetres; pixels.

The scene (what a test may rely on):

- Rigs: "thesis" (Tables 8.1-8.4: 640x480, 30 fps, f ~720-737 px, cameras 0.22-0.24 m apart, the
  middle one 7.5 m from the track) and "wide" (1920x1080, 60 fps, cameras 2.5 m apart converging).
- The horse travels along a straight track parallel to the baseline: direction "CW" = to the right
  in the images, "CCW" = to the left (drawn from the seed). Markers 1-3 sit in a shallow V on the
  camera-facing flank, numbered from the front (withers) to the back; S is on the saddle above
  them, visible in the static clip only (the rider hides it during the ride).
- Every clip starts with a lamp flash seen by all cameras: the light ramps up over 2 frame periods,
  stays on 1.5 periods, ramps down over 2; the half-level of the rise is at the same instant in
  every camera (truth ``clips.<kind>.flash_half_rise_s``).
- Calibration: the checkerboard ``BOARD`` (12x11 inner corners, 50 mm squares: 4-5 px at 7.5 m on
  the thesis rig) in ``calibration_poses`` poses through the 6.5 x 0.7 x 0.5 m volume, each held still
  for 3 frame periods and moved in 1 (truth ``calibration_board.still`` marks left frames whose
  matching frames in every camera show the same still pose).
- During the ride a striped pole 2-2.6 m in front of the cameras hides each marker for a few
  frames in one camera at a time; a stirrup flash, a D-ring, the white saddle pad, wall glints and
  sunlit patches are the look-alikes; noise, lighting drift, motion blur over the exposure.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from saddlescope.arena.content import (
    ALL_CLIPS,
    BOARD,
    DISTANCE_POINTS,
    EXTRA_CLIPS,
    GRAVITY_M_S2,
    BallContent,
    BoardContent,
    HorseContent,
    PlumbContent,
)
from saddlescope.arena.gait import (
    GaitModel,
    sample_gait,
    with_t_cross,
)
from saddlescope.arena.render import (
    CameraView,
    Pole,
    RenderOptions,
    composite_foreground,
    draw_markers,
    finish_frame,
    flash_fraction,
    noise_bank,
    render_background,
    render_pole,
)
from saddlescope.arena.rig import SceneRig, make_rig, normalized_pixel_grid
from saddlescope.core.errors import InputError
from saddlescope.core.types import CAMERA_ROLES, GAITS

HOLD_FRAMES, MOVE_FRAMES = 3, 1  # calibration board: still for 3 frame periods, moved in 1
FLASH_RAMP_FRAMES, FLASH_PLATEAU_FRAMES = 2.0, 1.5
MIN_MOTION_S = 3.5
OCCLUDED_CLIPS = ("motion",)  # the jump-stand pole stands in the arena during the ride only


@dataclass(frozen=True)
class ClipTiming:
    """Frame counts, per-camera offsets (frames) and the sync flash of one clip (left-clip seconds)."""

    kind: str
    fps: float
    n_left: int
    offsets: dict[str, float]
    n_frames: dict[str, int]
    flash_on_s: float
    flash_off_s: float
    flash_ramp_s: float
    content_start_s: float
    # per camera, how much later than its even clock each frame was taken (s): a phone's variable
    # frame rate (RenderOptions.variable_frame_rate); empty for even clips
    late_s: dict[str, np.ndarray] = field(default_factory=dict)

    def frame_times(self, role: str) -> np.ndarray:
        """Instants (left-clip seconds) of every frame of camera ``role``, shape (n_frames[role],)."""
        even = (np.arange(self.n_frames[role]) - self.offsets[role]) / self.fps
        return even + self.late_s[role] if role in self.late_s else even

    @property
    def left_times(self) -> np.ndarray:
        return np.arange(self.n_left) / self.fps


@dataclass
class Scene:
    """One synthetic setup. Build it with :func:`build_scene`."""

    seed: int
    gait: str
    direction: str
    rig: SceneRig
    model: GaitModel
    m_dir: np.ndarray  # arena -> world rotation (3, 3)
    views: dict[str, CameraView]
    timings: dict[str, ClipTiming]
    contents: dict[str, object]
    window_start_s: float
    window_periods: int
    pole: Pole | None
    options: RenderOptions
    meta: dict = field(default_factory=dict)
    light_phase: float = 0.0

    @property
    def fps(self) -> float:
        return self.rig.fps

    @property
    def clips(self) -> tuple[str, ...]:
        return tuple(k for k in ALL_CLIPS if k in self.timings)

    @property
    def window_duration_s(self) -> float:
        return self.window_periods * self.model.period_s

    @property
    def window_times(self) -> np.ndarray:
        """Left motion-clip frame instants inside [start, start + duration), shape (N,)."""
        k0 = int(round(self.window_start_s * self.fps))
        n = int(math.ceil(self.window_duration_s * self.fps - 1e-9))
        return (k0 + np.arange(n)) / self.fps

    def arena_to_rig_mm(self, x_arena_m: np.ndarray) -> np.ndarray:
        return self.rig.world_to_rig_mm(np.asarray(x_arena_m) @ self.m_dir.T)

    @property
    def R_arena_to_rig(self) -> np.ndarray:
        return self.rig.R_world_to_rig @ self.m_dir


# --- building ---------------------------------------------------------------------------------------
def _clip_timing(
    kind: str,
    rng: np.random.Generator,
    fps: float,
    content_s: float,
    *,
    total_s: float | None = None,
    min_total_s: float = 0.0,
) -> ClipTiming:
    """Random camera start offsets, a flash after every camera has started, then content_s of content
    (or a clip of exactly total_s, or at least min_total_s)."""
    off_s = rng.uniform(-0.15, 0.35, 2)
    offsets = {"left": 0.0, "middle": float(off_s[0] * fps), "right": float(off_s[1] * fps)}
    last_start = max(0.0, *(-o / fps for o in offsets.values()))
    ramp = FLASH_RAMP_FRAMES / fps
    on = last_start + float(rng.uniform(0.12, 0.22))
    off = on + ramp + FLASH_PLATEAU_FRAMES / fps
    content_start = off + ramp + 0.15
    if total_s is None:
        n_left = int(math.ceil(max(content_start + content_s, min_total_s) * fps - 1e-9))
    else:
        n_left = int(round(total_s * fps))
    n_frames = {"left": n_left}
    for role in ("middle", "right"):
        n_frames[role] = int(math.floor(n_left + offsets[role])) + int(rng.integers(0, 4))
    return ClipTiming(kind, fps, n_left, offsets, n_frames, on, off, ramp, content_start)


VFR_JITTER_FRAMES = 0.2  # a phone's frame intervals wander by this much either way
VFR_DROP_RATE = 0.03  # and it drops this share of frames (a double interval)


def _variable_rate(timing: ClipTiming, rng: np.random.Generator) -> ClipTiming:
    """The middle and right cameras as phones at a variable frame rate: from two frames after the
    sync flash, each frame is late by its jitter plus the frames dropped before it. The left camera
    keeps the even clock that the truth is written on."""
    late = {}
    for role in ("middle", "right"):
        n = timing.n_frames[role]
        k0 = int(math.ceil((timing.flash_off_s + timing.flash_ramp_s) * timing.fps + timing.offsets[role])) + 2
        k = np.arange(n)
        dropped = np.cumsum(rng.random(n) < VFR_DROP_RATE)
        jitter = rng.uniform(-VFR_JITTER_FRAMES, VFR_JITTER_FRAMES, n)
        late[role] = np.where(k >= k0, (dropped - dropped[min(k0, n - 1)] + jitter) / timing.fps, 0.0)
    return replace(timing, late_s=late)


def _make_views(rig: SceneRig) -> dict[str, CameraView]:
    views = {}
    for role, cam in rig.cameras.items():
        r_wc, c_w = rig.camera_world_pose(role)
        views[role] = CameraView(role, cam, r_wc, -r_wc @ c_w * 1000.0, normalized_pixel_grid(cam))
    return views


def _visible_everywhere(views: dict[str, CameraView], pts_w: np.ndarray, margin_px: float = 10.0) -> np.ndarray:
    """pts_w (T, M, 3) -> (T,) True where every point is inside every image with a margin."""
    ok = np.ones(pts_w.shape[0], bool)
    for view in views.values():
        ok &= np.all(view.inside(view.project(pts_w), margin_px), axis=1)
    return ok


def _out_of_view(views: dict[str, CameraView], pts_w: np.ndarray, margin_px: float = 12.0) -> bool:
    """True if any point (N, 3) is outside any image (with a margin)."""
    return not all(np.all(view.inside(view.project(pts_w), margin_px)) for view in views.values())


def _board_ok(views: dict[str, CameraView], board: BoardContent, r_bw: np.ndarray, o_w: np.ndarray, *,
              min_views: int | None = None) -> bool:
    """The whole board (with margin) inside every image (or ``min_views`` of them, wholly outside the
    others) and not too oblique to a camera that sees it."""
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


def _euler(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Board orientation: yaw about world Y, pitch about X, in-plane roll about Z (radians)."""
    return (
        cv2.Rodrigues(np.array([0.0, yaw, 0.0]))[0]
        @ cv2.Rodrigues(np.array([pitch, 0.0, 0.0]))[0]
        @ cv2.Rodrigues(np.array([0.0, 0.0, roll]))[0]
    )


def _board_origin(r_bw: np.ndarray, centre_w: np.ndarray, inner: tuple[int, int], sq: float) -> np.ndarray:
    cols, rows = inner
    return centre_w - r_bw @ np.array([(cols - 1) / 2 * sq, (rows - 1) / 2 * sq, 0.0])


def _sample_board_poses(
    views,
    board_tmpl: BoardContent,
    rng: np.random.Generator,
    n_poses: int,
    half_m: np.ndarray,
    *,
    per_slide: int = 15,
    edge_share: float = 0.0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Poses spread through the calibration volume in slides along the track (thesis 8.2), and
    ``edge_share`` of them at the edges of the views, seen by one camera or more."""
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
            r_bw = _euler(
                np.deg2rad(rng.uniform(-38, 38)),
                np.deg2rad(rng.uniform(-32, 32)),
                np.deg2rad(rng.uniform(-12, 12)),
            )
            o_w = _board_origin(r_bw, centre, board_tmpl.inner_corners, board_tmpl.square_m)
            if _board_ok(views, board_tmpl, r_bw, o_w):
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
            r_bw = _euler(np.deg2rad(rng.uniform(-38, 38)), np.deg2rad(rng.uniform(-32, 32)),
                          np.deg2rad(rng.uniform(-12, 12)))
            o_w = _board_origin(r_bw, centre, board_tmpl.inner_corners, board_tmpl.square_m)
            if _board_ok(views, board_tmpl, r_bw, o_w, min_views=1):
                poses.append((r_bw, o_w))
                break
    return poses


def build_scene(
    *,
    gait: str = "canter",
    seed: int = 0,
    rig: str = "thesis",
    size: tuple[int, int] | None = None,
    fps: float | None = None,
    duration_s: float | None = None,
    calibration_poses: int = 90,
    extras: bool = True,
    options: RenderOptions | None = None,
) -> Scene:
    """Draw one synthetic ride setup, deterministic in all arguments.

    gait : walk, sitting_trot, rising_trot or canter; rig : "thesis" (640x480, 30 fps) or "wide"
    (1920x1080, 60 fps); size (w, h) and fps override the rig's; duration_s is the motion clip's
    length (default: at least 3.5 s and two strides plus margins); calibration_poses board poses
    (thesis: 90); extras adds the freefall and board_distance validation clips.
    """
    if gait not in GAITS:
        raise InputError(f"unknown gait {gait!r}; expected one of {', '.join(GAITS)}")
    if not 1 <= int(calibration_poses) <= 400:
        raise InputError(f"calibration_poses must be 1-400, got {calibration_poses}")
    if duration_s is not None and not (0.5 <= float(duration_s) <= 120.0):
        raise InputError(f"motion duration {duration_s} s is outside 0.5-120 s")
    options = options or RenderOptions()
    ss = np.random.SeedSequence([int(seed), 0x5ADD1E])
    r_rig, r_gait, r_meta, r_time, r_board, r_bg, r_place, r_look = (np.random.default_rng(s) for s in ss.spawn(8))

    srig = make_rig(rig, r_rig, size=size, fps=fps)
    fps_ = srig.fps
    views = _make_views(srig)
    direction = "CW" if r_meta.random() < 0.5 else "CCW"
    m_dir = np.eye(3) if direction == "CW" else np.diag([-1.0, 1.0, -1.0])
    camera_side = -1.0 if direction == "CW" else 1.0  # the arena z of the camera-facing flank
    model = sample_gait(gait, r_gait, camera_side=camera_side, skin_model=options.skin_motion,
                        marker_layout=options.marker_layout)
    period = model.period_s

    # --- clip timings -------------------------------------------------------------------------
    timings = {
        "calibration": _clip_timing(
            "calibration", r_time, fps_, calibration_poses * (HOLD_FRAMES + MOVE_FRAMES) / fps_ + 0.1
        ),
        "plumb": _clip_timing("plumb", r_time, fps_, 1.0),
        "static": _clip_timing("static", r_time, fps_, 1.0),
    }
    timings["motion"] = _clip_timing(
        "motion",
        r_time,
        fps_,
        2 * period + 1.0,
        min_total_s=MIN_MOTION_S,
        total_s=None if duration_s is None else float(duration_s),
    )
    tm = timings["motion"]
    motion_s = tm.n_left / fps_
    usable = (tm.content_start_s, tm.n_left / fps_ - 1.0 / fps_)
    if usable[1] - usable[0] < period:
        raise InputError(
            f"a {motion_s:.2f} s motion clip is too short for one {gait} stride "
            f"({period:.2f} s) after the sync flash; use at least "
            f"{tm.content_start_s + period + 0.1:.1f} s"
        )
    t_cross = 0.5 * (usable[0] + usable[1])
    model = with_t_cross(model, t_cross)
    if options.variable_frame_rate:
        r_vfr = np.random.default_rng(np.random.SeedSequence([int(seed), 0x0F1A5]))
        timings = {k: _variable_rate(tm_k, r_vfr) for k, tm_k in timings.items()}
    start_s, n_periods = _choose_window(views, model, m_dir, tm, usable, fps_)

    # --- the foreground pole: hides the markers in one camera at a time inside the window ---------
    pole = None
    if options.occluder:
        c_mid = views["middle"].center_w
        d_pole = float(r_place.uniform(2.0, 2.6))  # near the cameras: parallax separates their views
        t_occ = start_s + float(r_place.uniform(0.3, 0.7)) * n_periods * period
        m2 = model.marker_positions(np.array([t_occ]))[0, 1] @ m_dir.T
        z_p = c_mid[2] + d_pole
        x_p = c_mid[0] + (m2[0] - c_mid[0]) * (z_p - c_mid[2]) / (m2[2] - c_mid[2])
        pole = Pole(
            x_m=float(x_p),
            z_m=float(z_p),
            width_m=0.07,
            top_y_m=srig.ground_y_m - 2.1,
            ground_y_m=srig.ground_y_m,
        )
    for view in views.values():
        view.background = render_background(
            view, ground_y_m=srig.ground_y_m, wall_z_m=srig.wall_z_m, rng=r_bg, options=options
        )
        if pole is not None:
            render_pole(view, pole)
    if options.distractors:
        _add_static_glints(views, srig, r_bg)

    # --- what each clip films -------------------------------------------------------------------
    diam = srig.marker_diameter_mm
    contents: dict[str, object] = {}
    peaks = r_look.uniform(250.0, 290.0, 4)
    contents["motion"] = HorseContent(
        model,
        m_dir,
        srig.ground_y_m,
        static=False,
        rider=True,
        peaks=peaks,
        marker_diameter_mm=diam,
        distractors=options.distractors,
    )
    static = None
    for x_try in (0.0, 0.6, -0.6, 1.2, -1.2, 1.8, -1.8):
        cand = HorseContent(
            model,
            m_dir,
            srig.ground_y_m,
            static=True,
            static_x_m=x_try,
            rider=False,
            peaks=peaks,
            marker_diameter_mm=diam,
            distractors=options.distractors,
        )
        if not _out_of_view(views, cand.markers_w(np.zeros(1))[0]):
            static = cand
            break
    if static is None:
        raise InputError("could not place the standing horse where all cameras see markers 1-3 and S")
    contents["static"] = static
    contents["plumb"] = _place(
        lambda x: PlumbContent(x_m=x, z_m=0.0, peaks=r_look.uniform(250, 290, 2), marker_diameter_mm=diam),
        views,
        "plumb line",
    )

    board_tmpl = BoardContent(
        [], 0.0, HOLD_FRAMES / fps_, MOVE_FRAMES / fps_, BOARD.square_mm / 1000.0, BOARD.inner_corners
    )
    poses = _sample_board_poses(views, board_tmpl, r_board, int(calibration_poses), srig.volume_half_m,
                                edge_share=0.0 if rig == "thesis" else 1.0 / 3.0)
    contents["calibration"] = BoardContent(
        poses,
        timings["calibration"].content_start_s,
        HOLD_FRAMES / fps_,
        MOVE_FRAMES / fps_,
        BOARD.square_mm / 1000.0,
        BOARD.inner_corners,
    )
    if extras:
        _add_extra_clips(timings, contents, views, srig, r_time, r_place, board_tmpl)

    meta = {
        "horse": {
            "name": f"Synthetic horse {seed}",
            "breed": str(r_meta.choice(["Dutch", "German", "French", "English"])),
            "birth_year": int(r_meta.integers(1998, 2018)),
            "height_m": round(model.horse_height_m, 2),
        },
        "rider": {"name": f"Synthetic rider {int(r_meta.integers(1, 5))}"},
    }
    return Scene(
        seed=int(seed),
        gait=gait,
        direction=direction,
        rig=srig,
        model=model,
        m_dir=m_dir,
        views=views,
        timings=timings,
        contents=contents,
        window_start_s=start_s,
        window_periods=n_periods,
        pole=pole,
        options=options,
        meta=meta,
        light_phase=float(r_look.uniform(0, 2 * np.pi)),
    )


def _choose_window(views, model: GaitModel, m_dir, tm: ClipTiming, usable, fps_: float) -> tuple[float, int]:
    """Window start (a left frame instant) and number of periods (2, else 1) where all markers are seen."""
    t = tm.left_times
    pts = model.marker_positions(t, skin=False)[:, :3] @ m_dir.T
    vis = _visible_everywhere(views, pts) & (t >= usable[0]) & (t <= usable[1])
    k_c = int(np.argmin(np.abs(t - model.t_cross_s)))
    if not vis[k_c]:
        raise InputError(
            "the horse's markers are not visible in all three cameras when it crosses the middle "
            "camera's line of sight; check the rig"
        )
    lo = hi = k_c
    while lo > 0 and vis[lo - 1]:
        lo -= 1
    while hi < len(t) - 1 and vis[hi + 1]:
        hi += 1
    for n_periods in (2, 1):
        n = int(math.ceil(n_periods * model.period_s * fps_ - 1e-9))
        if hi - lo + 1 < n + 2:
            continue
        k0 = int(round((lo + hi - n) / 2))  # centred where all markers are in view
        k0 = min(max(k0, lo + 1), hi - n)
        return k0 / fps_, n_periods
    raise InputError(
        f"the {model.gait} horse crosses the field of view in {(hi - lo) / fps_:.2f} s, less than one "
        f"stride ({model.period_s:.2f} s); use a longer clip or the wide rig"
    )


def _place(factory, views, what: str, candidates=(0.3, -0.3, 0.9, -0.9, 1.5, -1.5, 2.1, -2.1)):
    for x in candidates:
        cand = factory(x)
        if not _out_of_view(views, cand.markers_w(np.zeros(1))[0]):
            return cand
    raise InputError(f"could not place the {what} where all three cameras see it")


def _add_static_glints(views: dict[str, CameraView], rig: SceneRig, rng: np.random.Generator) -> None:
    """Small bright spots on the back wall and fence near marker height (the same in every camera)."""
    n = 10
    pts = np.column_stack([rng.uniform(-6.0, 6.0, n), rng.uniform(-0.2, 0.6, n), np.full(n, rig.wall_z_m - 0.02)])
    diam = rng.uniform(35.0, 70.0, n)
    peak = rng.uniform(225.0, 275.0, n)
    opts = RenderOptions(motion_blur=False)
    for view in views.values():
        xy = view.project(pts)
        r = view.radius_px(pts, diam)
        draw_markers(view.background, xy[None], r, peak, options=opts)


def _add_extra_clips(timings, contents, views, srig: SceneRig, r_time, r_place, board_tmpl: BoardContent) -> None:
    fps_ = srig.fps
    # freefall (thesis 8.3): thrown from the lower edge of the volume, peaks at the upper edge
    rise = 2.0 * srig.volume_half_m[1]
    v_up = math.sqrt(2.0 * GRAVITY_M_S2 * rise)
    flight = 2.0 * v_up / GRAVITY_M_S2
    timings["freefall"] = _clip_timing("freefall", r_time, fps_, 0.3 + flight + 0.3)
    t_rel = timings["freefall"].content_start_s + 0.3
    vx = float(r_place.uniform(0.15, 0.35)) * (1 if r_place.random() < 0.5 else -1)

    def ball(x):
        return BallContent(
            p0_w=np.array([x, srig.volume_half_m[1], -0.1]),
            v0_w=np.array([vx, -v_up, 0.03]),
            release_s=t_rel,
            catch_s=t_rel + flight,
        )

    for x in (0.2, -0.4, 0.8, -1.0, 1.4, -1.6):
        cand = ball(x)
        path = cand.markers_w(np.linspace(t_rel, t_rel + flight, 25))[:, 0]
        if not _out_of_view(views, path):
            contents["freefall"] = cand
            break
    else:
        raise InputError("could not place the freefall ball where all three cameras see it")
    # board distances (thesis Fig. 8.6 / Table 8.5): the board held still in three poses
    hold_s, move_s = 0.6, 0.3
    poses = []
    for centre_x in (-1.5, 0.0, 1.5, -0.7, 0.7, -2.2, 2.2):
        for _ in range(20):
            r_bw = _euler(
                np.deg2rad(r_place.uniform(-30, 30)),
                np.deg2rad(r_place.uniform(-20, 20)),
                np.deg2rad(r_place.uniform(-8, 8)),
            )
            centre = np.array([centre_x + r_place.normal(0, 0.1), r_place.normal(0, 0.08), r_place.normal(0, 0.08)])
            o_w = _board_origin(r_bw, centre, board_tmpl.inner_corners, board_tmpl.square_m)
            if _board_ok(views, board_tmpl, r_bw, o_w):
                poses.append((r_bw, o_w))
                break
        if len(poses) == 3:
            break
    if len(poses) < 3:
        raise InputError("could not place the board-distance board in three poses seen by all cameras")
    timings["board_distance"] = _clip_timing("board_distance", r_time, fps_, 3 * (hold_s + move_s))
    contents["board_distance"] = BoardContent(
        poses,
        timings["board_distance"].content_start_s,
        hold_s,
        move_s,
        board_tmpl.square_m,
        board_tmpl.inner_corners,
    )


# --- rendering --------------------------------------------------------------------------------------
def _exposure_samples(scene: Scene, t: float, options: RenderOptions) -> np.ndarray:
    if not options.motion_blur or options.blur_samples < 2:
        return np.array([t])
    e = scene.rig.exposure_s
    return t + (np.arange(options.blur_samples) / (options.blur_samples - 1) - 0.5) * e


def frame_shape(view: CameraView) -> tuple[int, int]:
    w, h = view.size
    return h, w


def lighting_gain(scene: Scene, role: str, t_s: float) -> float:
    """Slow lighting drift (clouds, auto-exposure), a few per cent."""
    cam_phase = {"left": 0.0, "middle": 1.3, "right": 2.9}.get(role, 0.0)
    return float(
        1.0
        + 0.035 * np.sin(2 * np.pi * t_s / 9.0 + scene.light_phase)
        + 0.008 * np.sin(2 * np.pi * t_s / 3.1 + cam_phase)
    )


def render_clip_frames(
    scene: Scene,
    camera: str,
    kind: str,
    *,
    start: int = 0,
    stop: int | None = None,
    options: RenderOptions | None = None,
) -> Iterator[np.ndarray]:
    """Yield camera ``camera``'s frames ``start..stop-1`` of clip ``kind`` as uint8 arrays (H, W).

    These are the frames before encoding. Each frame's noise comes from its own seeded generator, so
    any sub-range is identical to the same frames of a full render. ``options`` overrides the
    scene's render options (e.g. no noise or blur for geometry tests; the background keeps the
    scene's layers).
    """
    if kind not in scene.timings:
        raise InputError(f"unknown clip {kind!r}; this scene has {', '.join(scene.clips)}")
    if camera not in scene.views:
        raise InputError(f"unknown camera {camera!r}; expected one of {', '.join(CAMERA_ROLES)}")
    opts = options or scene.options
    timing = scene.timings[kind]
    view = scene.views[camera]
    content = scene.contents[kind]
    times = timing.frame_times(camera)
    stop = len(times) if stop is None else min(int(stop), len(times))
    flash = flash_fraction(times, scene.rig.exposure_s, timing.flash_on_s, timing.flash_off_s, timing.flash_ramp_s)
    clip_no, cam_no = ALL_CLIPS.index(kind), CAMERA_ROLES.index(camera)
    rendered = np.asarray(content.rendered, bool)
    bank = noise_bank(np.random.default_rng([scene.seed, 0x5ADD1E, clip_no, cam_no]), frame_shape(view))
    board_cache: dict = {}
    for k in range(int(start), stop):
        t = float(times[k])
        frame = view.background.copy()
        samples = _exposure_samples(scene, t, opts)
        if isinstance(content, BoardContent):
            content.draw_samples(frame, view, samples, opts, cache=board_cache)
        else:
            content.draw(frame, view, t)
        if rendered.any() and opts.markers:
            pts = content.markers_w(samples)[:, rendered]
            xy = view.project(pts)
            radii = view.radius_px(pts[len(samples) // 2], content.diameters_mm[rendered])
            draw_markers(frame, xy, radii, np.asarray(content.peaks)[rendered], options=opts)
        glints = content.glints(view, t) if opts.distractors else None
        if glints is not None:
            g_w, g_d, g_peak = glints
            g_xy = view.project(g_w)
            draw_markers(frame, g_xy[None], view.radius_px(g_w, g_d), g_peak, options=opts)
        if opts.occluder and kind in OCCLUDED_CLIPS:
            composite_foreground(frame, view)
        gain = lighting_gain(scene, camera, t) if opts.lighting_drift else 1.0
        rng = np.random.default_rng([scene.seed, 0x5ADD1E, clip_no, cam_no, k])
        yield finish_frame(frame, gain=gain, flash=float(flash[k]), rng=rng, options=opts, bank=bank)


def true_marker_pixels(scene: Scene, camera: str, kind: str) -> dict:
    """Exact 2-D marker centres of every frame of one camera clip.

    Returns names (M,), xy_px (F, M, 2) - the distorted projection at each frame instant, NaN where the
    marker is not rendered (S during the ride), not wholly inside the image or touched by the pole -,
    visible (F, M), occluded (F, M) (hidden by the pole) and radius_px (F, M).
    """
    timing = scene.timings[kind]
    content = scene.contents[kind]
    view = scene.views[camera]
    times = timing.frame_times(camera)
    pts = content.markers_w(times)
    xy = view.project(pts)
    radius = view.radius_px(pts, content.diameters_mm[None, :]) if pts.shape[1] else np.zeros(pts.shape[:2])
    inside = (
        view.inside(xy, 0.0)
        & view.inside(xy + radius[..., None] + 1.0, 0.0)
        & view.inside(xy - radius[..., None] - 1.0, 0.0)
    )
    if scene.options.occluder and kind in OCCLUDED_CLIPS:
        occluded = view.fg_covers(xy, radius)
    else:
        occluded = np.zeros(xy.shape[:2], bool)
    visible = inside & ~occluded & np.asarray(content.rendered, bool)[None, :]
    out = np.where(visible[..., None], xy, np.nan)
    return {
        "names": tuple(content.marker_names),
        "xy_px": out,
        "visible": visible,
        "occluded": occluded & inside,
        "radius_px": radius,
        "frame_times_s": times,
    }


# the truth lives in its own module; re-exported here as part of the synthetic arena's API
from saddlescope.arena.truth import (  # noqa: E402
    build_truth,
    check_result_structure,
    ride_manifest,
    saddle_truth_at,
)

__all__ = [
    "ALL_CLIPS",
    "BOARD",
    "DISTANCE_POINTS",
    "EXTRA_CLIPS",
    "ClipTiming",
    "RenderOptions",
    "Scene",
    "build_scene",
    "build_truth",
    "check_result_structure",
    "render_clip_frames",
    "ride_manifest",
    "saddle_truth_at",
    "true_marker_pixels",
]

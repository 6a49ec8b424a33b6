"""One synthetic ride setup, drawn from a seed: rig, horse and gait, clip timings, poses, look-alikes.

``build_scene`` draws the setup (camera rig, horse and gait, clip timings, board poses, plumb,
extra validation clips) as a :class:`Scene`; :mod:`saddlescope.arena.clips` films it and
:mod:`saddlescope.arena.truth` writes its exact answer. Clip clocks: see
:mod:`saddlescope.arena.timing`.

Units: world/arena metres and seconds; rig (left camera) millimetres; pixels.

The scene (what a test may rely on):

- Rigs: "thesis" (Tables 8.1-8.4: 640x480, 30 fps, f ~720-737 px, cameras 0.22-0.24 m apart, the
  middle one 7.5 m from the track), "wide" (1920x1080, 60 fps, cameras 2.5 m apart converging) and
  "wide_partial" (1280x720, 50 fps, cameras 1.8 m apart at 5.5-6.6 m and different heights, strong
  barrel distortion; the side cameras see about two thirds of the middle one's crossing, so the
  analysis window needs two cameras, not three).
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
- A ride of several passes (``RenderOptions.passes``, ``build_scene(passes=...)``): the one motion clip
  holds that many crossings, ``PASS_GAP_S`` out of every camera's view between two (the horse going round
  the arena's track), same direction, the stride's phase running on, each pass's speed up to
  ``PASS_SPEED_SHARE`` from the first's (truth ``truth.passes``: crossing instant, speed, span in view).
- During the ride a striped pole 2-2.6 m in front of the cameras hides each marker for a few
  frames in one camera at a time; a stirrup flash, a D-ring, the white saddle pad, wall glints and
  sunlit patches are the look-alikes; noise, lighting drift, motion blur over the exposure.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np

from saddlescope.arena.content import (
    ALL_CLIPS,
    BOARD,
    GRAVITY_M_S2,
    MAX_BOOT_SHARE,
    BoardContent,
    ClipContent,
    HorseContent,
    PlumbContent,
)
from saddlescope.arena.gait import GaitModel, sample_gait, with_high_harmonic, with_t_cross
from saddlescope.arena.placement import (
    add_static_glints,
    board_distance_poses,
    place_ball,
    place_in_view,
    place_standing_horse,
    sample_board_poses,
    visible_in,
)
from saddlescope.arena.render import CameraView, Pole, RenderOptions, render_background, render_pole
from saddlescope.arena.rig import SceneRig, make_rig, normalized_pixel_grid
from saddlescope.arena.timing import ClipTiming, clip_timing, variable_rate
from saddlescope.core.errors import InputError
from saddlescope.core.types import GAITS

__all__ = ["HOLD_FRAMES", "MAX_PASSES", "MIN_MOTION_S", "MOVE_FRAMES", "PASS_GAP_S", "Scene", "build_scene"]

HOLD_FRAMES, MOVE_FRAMES = 3, 1  # calibration board: still for 3 frame periods, moved in 1
MIN_MOTION_S = 3.5
# rides of several passes (RenderOptions.passes): at most this many; the later passes' speeds differ from the
# first's by up to this share; the horse is out of every view this long between two passes
MAX_PASSES = 6
PASS_SPEED_SHARE = 0.05
PASS_GAP_S = 2.0
_Content = TypeVar("_Content", bound=ClipContent)
_HORSE_HALF_LENGTH_M = 1.8  # from the markers to the horse's (or the rider's) furthest part, with margin


@dataclass
class Scene:
    """One synthetic setup. Build it with :func:`build_scene`.

    ``m_dir`` (3, 3) maps arena -> world; ``timings`` and ``contents`` are per clip kind; the
    analysis window starts at the left motion-clip instant ``window_start_s`` and lasts
    ``window_periods`` strides.
    """

    seed: int
    gait: str
    direction: str
    rig: SceneRig
    model: GaitModel
    m_dir: np.ndarray  # arena -> world rotation (3, 3)
    views: dict[str, CameraView]
    timings: dict[str, ClipTiming]
    contents: dict[str, ClipContent]
    window_start_s: float
    window_periods: int
    pole: Pole | None
    options: RenderOptions
    meta: dict = field(default_factory=dict)
    light_phase: float = 0.0

    def content(self, kind: str, of_type: type[_Content]) -> _Content:
        """The content of clip ``kind``, which is an ``of_type`` (motion and static: the horse; freefall: the ball)."""
        content = self.contents[kind]
        if not isinstance(content, of_type):
            raise TypeError(f"the {kind} clip shows a {type(content).__name__}, not a {of_type.__name__}")
        return content

    @property
    def fps(self) -> float:
        """The rig's frame rate (frames per second)."""
        return self.rig.fps

    @property
    def clips(self) -> tuple[str, ...]:
        """The clip kinds of this scene, in :data:`ALL_CLIPS` order."""
        return tuple(k for k in ALL_CLIPS if k in self.timings)

    @property
    def window_duration_s(self) -> float:
        """Length of the analysis window (s), a whole number of strides."""
        return self.window_periods * self.model.period_s

    @property
    def window_times(self) -> np.ndarray:
        """Left motion-clip frame instants inside [start, start + duration), shape (N,)."""
        k0 = int(round(self.window_start_s * self.fps))
        n = int(math.ceil(self.window_duration_s * self.fps - 1e-9))
        return (k0 + np.arange(n)) / self.fps

    def arena_to_rig_mm(self, x_arena_m: np.ndarray) -> np.ndarray:
        """Arena points (..., 3) m -> rig points (..., 3) mm."""
        return self.rig.world_to_rig_mm(np.asarray(x_arena_m) @ self.m_dir.T)

    @property
    def R_arena_to_rig(self) -> np.ndarray:
        """Rotation (3, 3) from the arena frame to the rig frame."""
        return self.rig.R_world_to_rig @ self.m_dir


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
    board_band: float | None = None,
    speed_range_m_s: tuple[float, float] | None = None,
    passes: int | None = None,
) -> Scene:
    """Draw one synthetic ride setup, deterministic in all arguments.

    gait : walk, sitting_trot, rising_trot or canter; rig : "thesis" (640x480, 30 fps) or "wide"
    (1920x1080, 60 fps); size (w, h) and fps override the rig's; duration_s is the motion clip's
    length (default: at least 3.5 s and two strides plus margins); calibration_poses board poses
    (thesis: 90); extras adds the freefall and board_distance validation clips.
    board_band (0-1] carries the calibration board only through that central share of the volume
    along the track, and not to the views' edges (default: the whole volume, and the edges on the
    wide rigs); speed_range_m_s (lo, hi) overrides the gait's speed band (e.g. a canter at 4-6 m/s).
    passes (1-6) overrides ``options.passes``: the horse crosses the view that many times in the one
    motion clip (:func:`_with_passes`); the analysis window of the truth is in the first pass.
    """
    _check_arguments(gait, calibration_poses, duration_s)
    _check_scene_options(board_band, speed_range_m_s)
    options = options or RenderOptions()
    if passes is not None:
        options = replace(options, passes=int(passes))
    _check_nuisances(options)
    ss = np.random.SeedSequence([int(seed), 0x5ADD1E])
    r_rig, r_gait, r_meta, r_time, r_board, r_bg, r_place, r_look = (np.random.default_rng(s) for s in ss.spawn(8))

    srig = make_rig(rig, r_rig, size=size, fps=fps)
    views = _make_views(srig)
    direction, m_dir, model = _draw_horse(gait, r_meta, r_gait, options, speed_range_m_s)
    if options.high_harmonic_share > 0:
        model = with_high_harmonic(model, options.high_harmonic, options.high_harmonic_share,
                                   np.random.default_rng(np.random.SeedSequence([int(seed), 0x4A6])))
    pass_speeds, spacing_s, reach_m = _pass_plan(seed, options.passes, views, model, m_dir)
    timings = _clip_timings(r_time, srig.fps, calibration_poses, model.period_s, duration_s,
                            extra_s=(options.passes - 1) * spacing_s)
    tm = timings["motion"]
    usable = _usable_motion(tm, gait, model.period_s)
    model = with_t_cross(model, 0.5 * (usable[0] + usable[1]))
    if options.passes > 1:
        model = replace(_with_passes(model, pass_speeds, spacing_s, usable), pass_reach_m=reach_m)
    if options.variable_frame_rate:
        r_vfr = np.random.default_rng(np.random.SeedSequence([int(seed), 0x0F1A5]))
        timings = {k: variable_rate(tm_k, r_vfr) for k, tm_k in timings.items()}
    start_s, n_periods = _choose_window(views, model, m_dir, tm, usable, srig.fps, min_views=srig.window_min_views)

    pole = _place_pole(views, model, m_dir, srig, r_place, start_s, n_periods) if options.occluder else None
    _paint_backgrounds(views, srig, pole, r_bg, options)
    contents = _horse_and_plumb(views, srig, model, m_dir, options, r_look)
    board_tmpl, contents["calibration"] = _calibration_board(
        views, srig, rig, board_band, r_board, int(calibration_poses), timings["calibration"].content_start_s)
    if extras:
        _add_extra_clips(timings, contents, views, srig, r_time, r_place, board_tmpl)
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
        meta=_ride_meta(seed, model, r_meta),
        light_phase=float(r_look.uniform(0, 2 * np.pi)),
    )


def _calibration_board(views, srig, rig: str, board_band: float | None, r_board: np.random.Generator,
                       calibration_poses: int, content_start_s: float) -> tuple[BoardContent, BoardContent]:
    """Return the board's template and its calibration clip's poses.

    The board goes through the whole volume (and on wide rigs to the views' edges for a third of the
    poses), or only through `board_band` of it along the track.
    """
    board_tmpl = BoardContent(
        [], 0.0, HOLD_FRAMES / srig.fps, MOVE_FRAMES / srig.fps, BOARD.square_mm / 1000.0, BOARD.inner_corners
    )
    volume_half_m, edge_share = srig.volume_half_m, 0.0 if rig == "thesis" else 1.0 / 3.0
    if board_band is not None:
        volume_half_m, edge_share = volume_half_m * np.array([float(board_band), 1.0, 1.0]), 0.0
    poses = sample_board_poses(views, board_tmpl, r_board, calibration_poses, volume_half_m,
                               edge_share=edge_share)
    calibration = BoardContent(
        poses,
        content_start_s,
        HOLD_FRAMES / srig.fps,
        MOVE_FRAMES / srig.fps,
        BOARD.square_mm / 1000.0,
        BOARD.inner_corners,
    )
    return board_tmpl, calibration


def _check_arguments(gait: str, calibration_poses: int, duration_s: float | None) -> None:
    """Refuse an unknown gait, a calibration pose count outside 1-400 or a clip outside 0.5-120 s."""
    if gait not in GAITS:
        raise InputError(f"unknown gait {gait!r}; expected one of {', '.join(GAITS)}")
    if not 1 <= int(calibration_poses) <= 400:
        raise InputError(f"calibration_poses must be 1-400, got {calibration_poses}")
    if duration_s is not None and not (0.5 <= float(duration_s) <= 120.0):
        raise InputError(f"motion duration {duration_s} s is outside 0.5-120 s")


def _check_scene_options(board_band: float | None, speed_range_m_s: tuple[float, float] | None) -> None:
    """Refuse a board band outside (0, 1] and a speed band that is not 0.5 <= lo <= hi <= 12 m/s."""
    if board_band is not None and not (0.0 < float(board_band) <= 1.0):
        raise InputError(f"board_band must be a share of the volume in (0, 1], got {board_band}")
    if speed_range_m_s is not None:
        lo, hi = (float(v) for v in speed_range_m_s)
        if not 0.5 <= lo <= hi <= 12.0:
            raise InputError(f"speed range must be 0.5 <= low <= high <= 12 m/s, got {speed_range_m_s}")


def _check_nuisances(options: RenderOptions) -> None:
    """Refuse field nuisances outside what the arena models (issue 38)."""
    if not 0.0 <= float(options.boot_share) <= MAX_BOOT_SHARE + 1e-9:
        raise InputError(f"boot_share must be 0-{MAX_BOOT_SHARE:.2f} of the stride, got {options.boot_share}")
    if not 0.0 <= float(options.readout_s) <= 0.040:
        raise InputError(f"a rolling shutter's readout must be 0-40 ms, got {1000 * options.readout_s:g} ms")
    if not 1 <= int(options.rolling_bands) <= 512:
        raise InputError(f"rolling_bands must be 1-512, got {options.rolling_bands}")
    if not 0 <= int(options.crf) <= 51:
        raise InputError(f"crf must be 0-51, got {options.crf}")
    if not 1 <= int(options.passes) <= MAX_PASSES:
        raise InputError(f"passes must be 1-{MAX_PASSES}, got {options.passes}")
    if not 5 <= int(options.high_harmonic) <= 12 or not 0.0 <= float(options.high_harmonic_share) <= 1.0:
        raise InputError("high_harmonic must be 5-12 and high_harmonic_share 0-1, got "
                         f"{options.high_harmonic} and {options.high_harmonic_share}")


def _make_views(rig: SceneRig) -> dict[str, CameraView]:
    """Each camera's projection helpers, by role (backgrounds still to be painted)."""
    views = {}
    for role, cam in rig.cameras.items():
        r_wc, c_w = rig.camera_world_pose(role)
        views[role] = CameraView(role, cam, r_wc, -r_wc @ c_w * 1000.0, normalized_pixel_grid(cam))
    return views


def _draw_horse(gait: str, r_meta: np.random.Generator, r_gait: np.random.Generator,
                options: RenderOptions, speed_range_m_s: tuple[float, float] | None = None
                ) -> tuple[str, np.ndarray, GaitModel]:
    """Direction of travel, the arena -> world rotation (3, 3) and the horse's gait model."""
    direction = "CW" if r_meta.random() < 0.5 else "CCW"
    m_dir = np.eye(3) if direction == "CW" else np.diag([-1.0, 1.0, -1.0])
    camera_side = -1.0 if direction == "CW" else 1.0  # the arena z of the camera-facing flank
    model = sample_gait(gait, r_gait, camera_side=camera_side, skin_model=options.skin_motion,
                        marker_layout=options.marker_layout, speed_range_m_s=speed_range_m_s)
    return direction, m_dir, model


def _clip_timings(r_time: np.random.Generator, fps_: float, calibration_poses: int, period: float,
                  duration_s: float | None, extra_s: float = 0.0) -> dict[str, ClipTiming]:
    """Timings of the four clips of the bundle (calibration, plumb, static, motion; drawn in that order).

    ``extra_s`` lengthens the motion clip (the later passes of a ride of several, unless ``duration_s``).
    """
    timings = {
        "calibration": clip_timing(
            "calibration", r_time, fps_, calibration_poses * (HOLD_FRAMES + MOVE_FRAMES) / fps_ + 0.1
        ),
        "plumb": clip_timing("plumb", r_time, fps_, 1.0),
        "static": clip_timing("static", r_time, fps_, 1.0),
    }
    timings["motion"] = clip_timing(
        "motion",
        r_time,
        fps_,
        2 * period + 1.0 + extra_s,
        min_total_s=MIN_MOTION_S + extra_s,
        total_s=None if duration_s is None else float(duration_s),
    )
    return timings


def _pass_plan(seed: int, n_passes: int, views: dict[str, CameraView], model: GaitModel, m_dir: np.ndarray
               ) -> tuple[tuple[float, ...], float, float]:
    """Each pass's speed (m/s), the time (s) from one crossing to the next and the travel's reach (m).

    For a ride of ``n_passes``; the reach is how far from the crossing the horse is out of every view.

    The first pass keeps the horse's speed, the others differ by up to ``PASS_SPEED_SHARE`` either way;
    crossings are far enough apart that the horse (its markers plus ``_HORSE_HALF_LENGTH_M`` for the
    body, rider and look-alikes) is out of every camera's view for ``PASS_GAP_S`` between two passes.
    """
    if n_passes <= 1:
        return (model.speed_m_s,), 0.0, 0.0
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x9A55]))
    speeds = (model.speed_m_s, *(model.speed_m_s * (1 + rng.uniform(-PASS_SPEED_SHARE, PASS_SPEED_SHARE))
                                 for _ in range(n_passes - 1)))
    # where along the track any camera sees a marker: the horse placed every 5 cm from -15 to 15 m
    probe = with_t_cross(model, 0.0)
    x = np.arange(-15.0, 15.0, 0.05)
    pts = (probe.marker_positions(x / probe.speed_m_s, skin=False)[:, :3]) @ m_dir.T
    seen = x[visible_in(views, pts, 1, margin_px=0.0)]
    half_view_m = float(np.max(np.abs(seen))) + _HORSE_HALF_LENGTH_M if seen.size else 15.0
    # the horse waits at the reach, out of view, until its next pass comes (spacing: PASS_GAP_S out of view)
    return speeds, 2.0 * half_view_m / min(speeds) + PASS_GAP_S, half_view_m


def _with_passes(model: GaitModel, speeds: tuple[float, ...], spacing_s: float,
                 usable: tuple[float, float]) -> GaitModel:
    """The horse crossing ``len(speeds)`` times, ``spacing_s`` apart, the first where the one pass would be.

    The first crossing stays where a one-pass ride has it (the middle of the first ``usable`` span less the
    later passes' time), so the analysis window and the pole fall in the first pass.
    """
    n = len(speeds)
    first = 0.5 * (usable[0] + usable[1]) - 0.5 * (n - 1) * spacing_s
    if first < usable[0]:
        raise InputError(f"the motion clip is too short for {n} passes {spacing_s:.1f} s apart; leave its length "
                         "to the arena")
    crossings = first + spacing_s * np.arange(n)
    return replace(with_t_cross(model, first), passes=tuple(zip(crossings.tolist(), speeds, strict=True)))


def _usable_motion(tm: ClipTiming, gait: str, period: float) -> tuple[float, float]:
    """First and last left motion-clip instants (s) after the sync flash; refuses a clip shorter than a stride."""
    fps_ = tm.fps
    motion_s = tm.n_left / fps_
    usable = (tm.content_start_s, tm.n_left / fps_ - 1.0 / fps_)
    if usable[1] - usable[0] < period:
        raise InputError(
            f"a {motion_s:.2f} s motion clip is too short for one {gait} stride "
            f"({period:.2f} s) after the sync flash; use at least "
            f"{tm.content_start_s + period + 0.1:.1f} s"
        )
    return usable


def _choose_window(views, model: GaitModel, m_dir, tm: ClipTiming, usable, fps_: float, *,
                   min_views: int = 3) -> tuple[float, int]:
    """Window start (a left frame instant) and number of periods (2, else 1) where all markers are seen.

    Seen: by ``min_views`` cameras (3: all; 2: a rig whose side cameras see part of the crossing).
    """
    t = tm.left_times
    pts = model.marker_positions(t, skin=False)[:, :3] @ m_dir.T
    vis = visible_in(views, pts, min_views) & (t >= usable[0]) & (t <= usable[1])
    k_c = int(np.argmin(np.abs(t - model.t_cross_s)))
    if not vis[k_c]:
        raise InputError(
            f"the horse's markers are not visible in {min_views} cameras when it crosses the middle "
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


def _place_pole(views: dict[str, CameraView], model: GaitModel, m_dir: np.ndarray, srig: SceneRig,
                r_place: np.random.Generator, start_s: float, n_periods: int) -> Pole:
    """The foreground pole, standing where it hides marker 2 from the middle camera once in the window.

    Near the cameras, so that parallax separates their views: it hides the markers in one camera at
    a time.
    """
    c_mid = views["middle"].center_w
    d_pole = float(r_place.uniform(2.0, 2.6))  # near the cameras: parallax separates their views
    t_occ = start_s + float(r_place.uniform(0.3, 0.7)) * n_periods * model.period_s
    m2 = model.marker_positions(np.array([t_occ]))[0, 1] @ m_dir.T
    z_p = c_mid[2] + d_pole
    x_p = c_mid[0] + (m2[0] - c_mid[0]) * (z_p - c_mid[2]) / (m2[2] - c_mid[2])
    return Pole(
        x_m=float(x_p),
        z_m=float(z_p),
        width_m=0.07,
        top_y_m=srig.ground_y_m - 2.1,
        ground_y_m=srig.ground_y_m,
    )


def _paint_backgrounds(views: dict[str, CameraView], srig: SceneRig, pole: Pole | None,
                       r_bg: np.random.Generator, options: RenderOptions) -> None:
    """Each camera's static layers: the textured arena, the pole, the wall glints."""
    for view in views.values():
        view.background = render_background(
            view, ground_y_m=srig.ground_y_m, wall_z_m=srig.wall_z_m, rng=r_bg, options=options
        )
        if pole is not None:
            render_pole(view, pole)
    if options.distractors:
        add_static_glints(views, srig, r_bg)


def _horse_and_plumb(views: dict[str, CameraView], srig: SceneRig, model: GaitModel, m_dir: np.ndarray,
                     options: RenderOptions, r_look: np.random.Generator) -> dict[str, ClipContent]:
    """What the motion, static and plumb clips film: the ridden horse, the standing horse, the plumb line."""
    diam = srig.marker_diameter_mm
    contents: dict[str, ClipContent] = {}
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
        boot_share=options.boot_share,
    )
    contents["static"] = place_standing_horse(views, model, m_dir, srig.ground_y_m, peaks=peaks,
                                              marker_diameter_mm=diam, distractors=options.distractors)
    contents["plumb"] = place_in_view(
        lambda x: PlumbContent(x_m=x, z_m=0.0, peaks=r_look.uniform(250, 290, 2), marker_diameter_mm=diam),
        views,
        "plumb line",
    )
    return contents


def _add_extra_clips(timings, contents, views, srig: SceneRig, r_time, r_place, board_tmpl: BoardContent) -> None:
    """The validation clips: a ball in free fall (thesis 8.3) and a board held in three poses (Table 8.5)."""
    fps_ = srig.fps
    # freefall (thesis 8.3): thrown from the lower edge of the volume, peaks at the upper edge
    rise = 2.0 * srig.volume_half_m[1]
    v_up = math.sqrt(2.0 * GRAVITY_M_S2 * rise)
    flight = 2.0 * v_up / GRAVITY_M_S2
    timings["freefall"] = clip_timing("freefall", r_time, fps_, 0.3 + flight + 0.3)
    t_rel = timings["freefall"].content_start_s + 0.3
    contents["freefall"] = place_ball(views, srig.volume_half_m[1], v_up, t_rel, flight, r_place)
    # board distances (thesis Fig. 8.6 / Table 8.5): the board held still in three poses
    hold_s, move_s = 0.6, 0.3
    poses = board_distance_poses(views, board_tmpl, r_place)
    timings["board_distance"] = clip_timing("board_distance", r_time, fps_, 3 * (hold_s + move_s))
    contents["board_distance"] = BoardContent(
        poses,
        timings["board_distance"].content_start_s,
        hold_s,
        move_s,
        board_tmpl.square_m,
        board_tmpl.inner_corners,
    )


def _ride_meta(seed: int, model: GaitModel, r_meta: np.random.Generator) -> dict:
    """The horse's and rider's names and particulars for ride.json."""
    return {
        "horse": {
            "name": f"Synthetic horse {seed}",
            "breed": str(r_meta.choice(["Dutch", "German", "French", "English"])),
            "birth_year": int(r_meta.integers(1998, 2018)),
            "height_m": round(model.horse_height_m, 2),
        },
        "rider": {"name": f"Synthetic rider {int(r_meta.integers(1, 5))}"},
    }

"""Ground truth of a synthetic ride: the exact answer in the result format.

``build_truth(scene)`` returns truth.json (CONTRACTS section 2 plus a ``truth`` section for tests);
``saddle_truth_at(truth, t_s)`` evaluates the saddle point's exact kinematics from truth.json alone.
"""

from __future__ import annotations

import math

import numpy as np

from saddlescope.arena.content import (
    BOARD,
    DISTANCE_POINTS,
    GRAVITY_M_S2,
    BallContent,
    BoardContent,
    HorseContent,
)
from saddlescope.arena.gait import (
    MARKER_NAMES,
    SADDLE_NAME,
    GaitModel,
    acceleration_harmonics,
    saddle_vertical_peak_to_peak,
)
from saddlescope.arena.rig import SceneRig
from saddlescope.arena.scene import Scene
from saddlescope.core.errors import InputError
from saddlescope.core.vibration import ride_indicators

__all__ = ["build_truth", "saddle_truth_at"]


def _nan_to_none(x):
    """``x`` with numpy arrays and scalars as plain lists and numbers, and NaN / inf as None (JSON-ready)."""
    if isinstance(x, dict):
        return {k: _nan_to_none(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_nan_to_none(v) for v in x]
    if isinstance(x, np.ndarray):
        return _nan_to_none(x.tolist())
    if isinstance(x, (float, np.floating)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _motion_frame(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """R_rig_to_motion (3, 3) and origin_mm (3,) = rigid marker 1 at the window's first sample."""
    t0 = scene.window_times[:1]
    m1 = scene.model.point(scene.model.body_points_m["marker1"], t0)[0]
    return scene.R_arena_to_rig.T, scene.arena_to_rig_mm(m1)


def saddle_truth_at(truth: dict, t_s: np.ndarray) -> dict:
    """Exact kinematics of the saddle point S at left motion-clip times, from truth.json alone.

    The frame is the motion reference frame (x travel, y gravity down, z = x cross y) with its
    origin at (rigid) marker 1's position at t_s[0].

    Parameters
    ----------
    truth : dict
        A synthetic ride's truth.json (its ``truth.model`` section).
    t_s : ndarray of shape (T,)
        Left motion-clip seconds.

    Returns
    -------
    dict
        ``t_s`` (T,) and ``position_m``, ``velocity_m_s``, ``acceleration_m_s2``, ``omega_rad_s``,
        ``alpha_rad_s2``, each ndarray of shape (T, 3).
    """
    try:
        model = GaitModel.from_dict(truth["truth"]["model"])
    except (KeyError, TypeError):
        raise InputError("truth has no truth.model section (not a synthetic ride's truth.json)") from None
    t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)):
        raise InputError("t_s must be a non-empty 1-D array of finite times in seconds")
    s = model.body_points_m[SADDLE_NAME]
    origin = model.point(model.body_points_m["marker1"], t[:1])[0]
    omega, alpha = model.angular(t)
    return {
        "t_s": t,
        "position_m": model.point(s, t) - origin,
        "velocity_m_s": model.point(s, t, derivative=1),
        "acceleration_m_s2": model.point(s, t, derivative=2),
        "omega_rad_s": omega,
        "alpha_rad_s2": alpha,
    }


def _indicators(scene: Scene, harmonics: dict[str, tuple[np.ndarray, np.ndarray]], pp_m: float) -> dict:
    """Comfort indicators of the exact saddle-point accelerations over the window (all axes)."""
    f0 = scene.model.stride_hz

    def axis(name: str) -> dict:
        a, p = harmonics[name]
        return {"amplitudes_m_s2": a.tolist(), "phases_rad": p.tolist(), "f0_hz": f0}

    return ride_indicators(
        f0_hz=f0,
        acc_y_amplitudes_m_s2=harmonics["y"][0].tolist(),
        acc_y_phases_rad=harmonics["y"][1].tolist(),
        duration_s=scene.window_duration_s,
        speed_kmh=_ride_speed_m_s(scene.model) * 3.6,
        amplitude_y_m=pp_m,
        stride_frequency_hz=f0,
        acc_x=axis("x"),
        acc_z=axis("z"),
    )


def build_truth(scene: Scene) -> dict:
    """The exact answer in the result format (CONTRACTS section 2) plus a ``truth`` section.

    The saddle and angular arrays hold the window's left motion-clip frames (N, 3); NaN becomes None
    (JSON-ready).
    """
    model = scene.model
    t_win = scene.window_times
    kin = saddle_truth_at({"truth": {"model": model.to_dict()}}, t_win)
    harm = {
        name: acceleration_harmonics(model, model.body_points_m[SADDLE_NAME], axis=i, n_harmonics=40)
        for i, name in enumerate("xyz")
    }
    pp = saddle_vertical_peak_to_peak(model)
    return _nan_to_none(
        {
            "format": "saddlescope.result/1",
            "fps": scene.fps,
            "calibration": _calibration_truth(scene.rig),
            "sync": {kind: dict(tm.offsets) for kind, tm in scene.timings.items()},
            "period_s": model.period_s,
            "window": {
                "start_s": scene.window_start_s,
                "duration_s": scene.window_duration_s,
                "periods": scene.window_periods,
            },
            "saddle": {
                "t_s": kin["t_s"],
                "position_m": kin["position_m"],
                "velocity_m_s": kin["velocity_m_s"],
                "acceleration_m_s2": kin["acceleration_m_s2"],
            },
            "angular": {
                "omega_rad_s": kin["omega_rad_s"],
                "alpha_rad_s2": kin["alpha_rad_s2"],
                "singularity_index": _singularity_index(model, t_win, kin["omega_rad_s"]),
            },
            "indicators": _indicators(scene, harm, pp),
            "quality": {},
            "timings_s": {},
            "truth": _truth_section(scene, harm, pp),
        }
    )


def _calibration_truth(rig: SceneRig) -> dict:
    """The rig's exact cameras (intrinsics, rig-frame extrinsics) in the result's calibration format."""
    cams, extr = {}, {}
    for role, cam in rig.cameras.items():
        cams[role] = {"K": cam.K, "dist": cam.dist, "image_size": list(cam.image_size), "rms_px": 0.0}
        if role != "left":
            extr[role] = {"R": cam.R, "t_mm": cam.t_mm}
    return {"cameras": cams, "extrinsics": extr, "checks": {"board_square_error_mm": 0.0}}


def _singularity_index(model: GaitModel, t_win: np.ndarray, omega: np.ndarray) -> float:
    """Median over the window of |n . omega_hat| for the marker plane's normal n (thesis eq. 6.35).

    t_win (N,) s; omega (N, 3) rad/s.
    """
    b = np.stack([model.body_points_m[n] for n in MARKER_NAMES])
    rot = model.rotation(t_win)[0]
    n_w = rot @ np.cross(b[1] - b[0], b[2] - b[0])
    n_w /= np.linalg.norm(n_w, axis=1, keepdims=True)
    w = omega
    sing = np.abs(np.sum(n_w * w, axis=1)) / np.maximum(np.linalg.norm(w, axis=1), 1e-12)
    return float(np.median(sing))


def _truth_section(scene: Scene, harm: dict[str, tuple[np.ndarray, np.ndarray]], pp: float) -> dict:
    """The ``truth`` section: markers in 3-D, the motion frame, the gait model, clips, boards, extras."""
    rig = scene.rig
    model = scene.model
    amps, phases = harm["y"]
    r_rm, origin_mm = _motion_frame(scene)
    markers_3d, names = _markers_3d(scene)
    truth_sec = {
        "markers_3d_mm": markers_3d,
        "marker_names": names,
        "marker_order": "marker1..3 numbered from the front (withers) to the back; saddle = S",
        "motion_frame": {
            "R_rig_to_motion": r_rm,
            "origin_mm": origin_mm,
            "note": "p_motion_m = R_rig_to_motion @ (p_rig_mm - origin_mm) / 1000",
        },
        "gravity_rig": rig.gravity_rig,
        "model": model.to_dict(),
        "saddle_body_m": model.body_points_m[SADDLE_NAME],
        "saddle_acc_y_harmonics": {
            "f0_hz": model.stride_hz,
            "amplitudes_m_s2": amps,
            "phases_rad": phases,
            "time": "t in left motion-clip seconds",
        },
        "saddle_acc_harmonics": {
            name: {"f0_hz": model.stride_hz, "amplitudes_m_s2": a, "phases_rad": p} for name, (a, p) in harm.items()
        },
        "speed_kmh": _ride_speed_m_s(model) * 3.6,
        "speed_m_s": _ride_speed_m_s(model),
        "stride_frequency_hz": model.stride_hz,
        "amplitude_y_m": pp,
        "direction": scene.direction,
        "clips": _clips_truth(scene, markers_3d),
        "exposure_s": rig.exposure_s,
        "marker_diameter_mm": rig.marker_diameter_mm,
        "rig": rig.name,
        "board": {
            "kind": BOARD.kind,
            "inner_corners": list(BOARD.inner_corners),
            "square_mm": BOARD.square_mm,
        },
        "calibration_board": _board_truth(scene, "calibration"),
    }
    if len(model.passes) > 1:
        truth_sec["passes"] = _passes_truth(scene)
    truth_sec["nuisances"] = nuisances = scene.options.nuisances()
    if scene.options.boot_share > 0:
        t_win = scene.window_times
        covered = scene.content("motion", HorseContent).boot_covers(t_win)[:, 2]
        nuisances["boot"] = {
            "marker": "marker3", "share_of_stride": scene.options.boot_share,
            "window_share_covered": float(covered.mean()),
            "note": "the rear marker is at least partly covered, seen square-on, for this share of every stride"}
    if scene.pole is not None:
        p = scene.pole
        truth_sec["occluder"] = {"kind": "pole", "x_m": p.x_m, "z_m": p.z_m, "width_m": p.width_m}
    if "freefall" in scene.timings:
        truth_sec["freefall"] = _freefall_truth(scene)
    if "board_distance" in scene.timings:
        truth_sec["board_distance"] = _distance_truth(scene)
    return truth_sec


def _ride_speed_m_s(model: GaitModel) -> float:
    """The ride's average speed (m/s) in front of the cameras: the mean of its passes' (each pass counts once)."""
    return float(np.mean([v for _, v in model.passes])) if model.passes else model.speed_m_s


def _passes_truth(scene: Scene) -> list[dict]:
    """Per pass of a ride of several: its crossing instant, speed, and the span its markers are in view.

    In view: seen by the rig's ``window_min_views`` cameras (left-clip seconds, first and last frame). The
    saddle's motion (and so every indicator but the speed) is the same in every pass: the stride runs on.
    """
    from saddlescope.arena.placement import visible_in

    t = scene.timings["motion"].left_times
    pts = scene.model.marker_positions(t, skin=False)[:, :3] @ scene.m_dir.T
    seen = visible_in(scene.views, pts, scene.rig.window_min_views)
    crossings = np.array([c for c, _ in scene.model.passes])
    owner = np.searchsorted(0.5 * (crossings[1:] + crossings[:-1]), t)
    out = []
    for i, (t_cross, speed) in enumerate(scene.model.passes):
        in_view = t[seen & (owner == i)]
        out.append({"t_cross_s": t_cross, "speed_m_s": speed, "speed_kmh": speed * 3.6,
                    "in_view_s": [float(in_view[0]), float(in_view[-1])] if in_view.size else None,
                    "strides_in_view": (float((in_view[-1] - in_view[0]) * scene.model.stride_hz)
                                        if in_view.size else 0.0)})
    return out


def _markers_3d(scene: Scene) -> tuple[dict[str, np.ndarray], dict[str, list[str]]]:
    """Per clip with markers, their exact rig positions (n_left, M, 3) mm at every left frame; names per clip."""
    markers_3d, names = {}, {}
    for kind in scene.clips:
        content = scene.contents[kind]
        names[kind] = list(content.marker_names)
        if names[kind]:
            markers_3d[kind] = scene.rig.world_to_rig_mm(content.markers_w(scene.timings[kind].left_times))
    return markers_3d, names


def _clips_truth(scene: Scene, markers_3d: dict[str, np.ndarray]) -> dict:
    """Per clip: frame counts, the sync flash (left-clip s) and where the markers are in view."""
    clips = {}
    for kind, tm in scene.timings.items():
        clips[kind] = {
            "frames": dict(tm.n_frames),
            "fps": tm.fps,
            "flash_on_s": tm.flash_on_s,
            "flash_off_s": tm.flash_off_s,
            "flash_ramp_s": tm.flash_ramp_s,
            "flash_half_rise_s": tm.flash_on_s + tm.flash_ramp_s / 2,
            "content_start_s": tm.content_start_s,
        }
        if kind in markers_3d:
            clips[kind]["markers_in_view_left_frames"] = _in_view_interval(scene, kind)
    return clips


def _freefall_truth(scene: Scene) -> dict:
    """The thrown ball's exact flight in the rig frame (mm, s) and its left frames in flight."""
    rig = scene.rig
    ball = scene.content("freefall", BallContent)
    return {
        "g_m_s2": GRAVITY_M_S2,
        "release_s": ball.release_s,
        "catch_s": ball.catch_s,
        "diameter_mm": ball.diameter_mm,
        "p0_mm": rig.world_to_rig_mm(ball.p0_w),
        "v0_mm_s": rig.R_world_to_rig @ ball.v0_w * 1000.0,
        "g_mm_s2": rig.gravity_rig * GRAVITY_M_S2 * 1000.0,
        "flight_left_frames": [
            int(math.ceil(ball.release_s * scene.fps)),
            int(math.floor(ball.catch_s * scene.fps)),
        ],
    }


def _in_view_interval(scene: Scene, kind: str) -> list[int] | None:
    """First and last left frames at which every rendered marker is inside every camera's image.

    The pole is ignored; the horse enters and leaves the field of view during a fast ride.
    """
    tm = scene.timings[kind]
    content = scene.contents[kind]
    rendered = np.asarray(content.rendered, np.bool_)
    pts = content.markers_w(tm.left_times)[:, rendered]
    ok = np.ones(tm.n_left, bool)
    for view in scene.views.values():
        ok &= np.all(view.inside(view.project(pts), 4.0), axis=1)
    idx = np.nonzero(ok)[0]
    return [int(idx[0]), int(idx[-1])] if idx.size else None


def _board_truth(scene: Scene, kind: str) -> dict:
    """Board pose (rig frame) at every left frame and whether it stands still in all cameras there."""
    board = scene.content(kind, BoardContent)
    tm = scene.timings[kind]
    r_wr, t_wr = scene.rig.R_world_to_rig, scene.rig.t_world_to_rig_mm
    rs, ts, still, index = [], [], [], []
    for t in tm.left_times:
        r, o, s = board.pose_at(float(t))
        # still in every camera's matching frame (rounded offset) over its exposure
        ok = s
        for role in ("middle", "right"):
            k = round(t * scene.fps + tm.offsets[role])
            tc = (k - tm.offsets[role]) / scene.fps
            ok = ok and board.pose_at(tc)[2] and board.pose_index(tc) == board.pose_index(float(t))
        rs.append(r_wr @ r)
        ts.append(r_wr @ o * 1000.0 + t_wr)
        still.append(bool(ok))
        index.append(board.pose_index(float(t)))
    return {
        "R_board_to_rig": np.array(rs),
        "t_mm": np.array(ts),
        "still": still,
        "pose_index": index,
        "n_poses": len(board.poses),
        "hold_s": board.hold_s,
        "move_s": board.move_s,
        "note": "x_rig_mm = R_board_to_rig @ board_object_point_mm + t_mm (Board.object_points_mm order)",
    }


def _distance_truth(scene: Scene) -> dict:
    """The board-distance clip: the corner points' exact positions (rig mm) per pose and their distances."""
    board = scene.content("board_distance", BoardContent)
    tm = scene.timings["board_distance"]
    cols = board.inner_corners[0]
    poses = []
    for j, (r, o) in enumerate(board.poses):
        corners = scene.rig.world_to_rig_mm(board.corners_w(r, o))
        pts = {name: corners[row * cols + col] for name, (col, row) in DISTANCE_POINTS.items()}
        t0 = board.start_s + j * board.period_s
        frames = [int(math.ceil(t0 * scene.fps)), int(math.floor((t0 + board.hold_s) * scene.fps))]
        if j == 0:
            frames[0] = int(math.ceil(tm.content_start_s * scene.fps))
        poses.append({"points_mm": pts, "still_left_frames": frames})
    names = list(DISTANCE_POINTS)
    dist = {}
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            ca, cb = np.array(DISTANCE_POINTS[a]), np.array(DISTANCE_POINTS[b])
            dist[a + b] = float(np.linalg.norm(ca - cb) * BOARD.square_mm)
    return {
        "points": {k: list(v) for k, v in DISTANCE_POINTS.items()},
        "distances_mm": dist,
        "poses": poses,
        "board": _board_truth(scene, "board_distance"),
        "note": "points are inner corners (col, row) of the checkerboard in ride.json board",
    }

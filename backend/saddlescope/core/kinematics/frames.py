"""The motion reference frame (thesis 5.3, eq. 5.6-5.12).

x = direction of travel (net displacement of a marker over whole periods, eq. 5.6-5.7),
y = gravity, down (from the plumb clip: unit vector from the upper to the lower marker),
corrected to be orthogonal to x (eq. 5.8-5.9), z = x cross y. Origin: the first position of
marker 1 (CONTRACTS section 2). Rig coordinates are in mm, motion coordinates in m.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.findings import Finding

__all__ = [
    "CAMERA_DOWN",
    "MotionFrame",
    "plumb_gravity",
    "travel_velocity",
    "motion_frame",
    "to_motion_frame",
    "vectors_to_motion_frame",
]

# Warn when the measured gravity is further than this from perpendicular to the travel.
_PERPENDICULAR_TOL_DEG = 10.0
# Left-camera image "down" in rig coordinates (OpenCV camera: x right, y down, z forward).
CAMERA_DOWN = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class MotionFrame:
    """A motion reference frame.

    R : ndarray of shape (3, 3)
        Rig -> motion rotation; its rows are the unit axes x, y, z in rig coordinates, so
        ``x_motion = R @ (x_rig - origin_mm)`` (eq. 5.12 with R = R_CM^T).
    origin_mm : ndarray of shape (3,)
        Origin in rig coordinates (mm).
    gravity_source : str
        ``"plumb"``, ``"hint"`` (the caller's down direction, e.g. from the rig) or
        ``"camera_down"`` (the left camera's image y axis: a level camera is assumed).
    warnings : tuple of Finding
        What the frame's construction found (no plumb, plumb far from perpendicular to the travel, ...).
    gravity_raw : ndarray of shape (3,)
        The unit gravity estimate before orthogonalisation, rig coordinates.
    travel_raw : ndarray of shape (3,)
        The unit travel direction (eq. 5.7), rig coordinates.
    angle_travel_gravity_deg : float
        Angle between the raw gravity and the travel (90 ideally).
    diagnostics : dict
        Further numbers (plumb length and its spread, number of plumb frames used).
    """

    R: np.ndarray
    origin_mm: np.ndarray
    gravity_source: str
    warnings: tuple[Finding, ...] = ()
    gravity_raw: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    travel_raw: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    angle_travel_gravity_deg: float = float("nan")
    diagnostics: dict = field(default_factory=dict)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _as_track(x, name: str) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 1:
        x = x[None, :]
    if x.ndim != 2 or x.shape[1] != 3:
        raise InputError(f"{name} must have shape (F, 3) or (3,), got {x.shape}")
    return x


def plumb_gravity(plumb_top_mm, plumb_bottom_mm) -> tuple[np.ndarray, dict]:
    """Unit gravity (down) from the two plumb markers, averaged over frames.

    Parameters
    ----------
    plumb_top_mm, plumb_bottom_mm : ndarray of shape (F, 3) or (3,)
        Upper and lower plumb marker positions (rig mm), NaN in gaps.

    Returns
    -------
    gravity : ndarray of shape (3,)
        Mean of the per-frame unit vectors from top to bottom, normalised.
    diagnostics : dict
        ``plumb_frames``, ``plumb_length_mm`` (median), ``plumb_spread_deg`` (r.m.s. angle of the
        per-frame directions about the mean: the plumb's swing plus noise).
    """
    top = _as_track(plumb_top_mm, "plumb_top_mm")
    bottom = _as_track(plumb_bottom_mm, "plumb_bottom_mm")
    if top.shape != bottom.shape:
        raise InputError(f"plumb_top_mm {top.shape} and plumb_bottom_mm {bottom.shape} differ in shape")
    d = bottom - top
    ok = np.all(np.isfinite(d), axis=1)
    length = np.linalg.norm(d, axis=1)
    ok &= length > 0
    if not ok.any():
        raise KinematicsError("the plumb clip has no frame with both plumb markers found")
    units = d[ok] / length[ok, None]
    g = _unit(units.mean(axis=0))
    cos = np.clip(units @ g, -1.0, 1.0)
    diag = {"plumb_frames": int(ok.sum()), "plumb_length_mm": float(np.median(length[ok])),
            "plumb_spread_deg": float(np.degrees(np.sqrt(np.mean(np.arccos(cos) ** 2))))}
    return g, diag


def travel_velocity(t_s, xyz_mm, *, period_s: float, order: int = 4, reject_sigma: float | None = 5.0,
                    reject_min_mm: float = 3.0) -> np.ndarray:
    """Mean travel velocity of a marker from a line plus a periodic series, per coordinate.

    Eq. 5.7 takes the net displacement over exactly two periods; a window of whole frames is
    rarely exactly that, and the leftover part of the vertical oscillation tilts the x axis
    (0.3 deg for half a frame of a canter). Fitting ``p0 + v t + sum_k (a_k cos k w t +
    b_k sin k w t)`` to each coordinate separates the travel v from the periodic motion for any
    window length.

    Parameters
    ----------
    t_s : ndarray of shape (F,)
        Sample times (s).
    xyz_mm : ndarray of shape (F, 3)
        The marker's track (rig mm), NaN in gaps.
    period_s : float
        Stride period.
    order : int, optional
        Harmonics of the stride fitted alongside (fewer if the window is short).
    reject_sigma, reject_min_mm : optional
        Samples further from a bisquare-reweighted fit than ``reject_sigma`` robust standard
        deviations and ``reject_min_mm`` (a look-alike followed for a few frames) are left out of a
        plain refit (None: keep all, one plain fit).

    Returns
    -------
    velocity_mm_s : ndarray of shape (3,)
        Mean travel velocity (rig mm/s).
    """
    t = np.asarray(t_s, dtype=np.float64)
    track = _as_track(xyz_mm, "xyz_mm")
    if t.shape != (track.shape[0],):
        raise InputError(f"t_s has shape {t.shape} but the track has {track.shape[0]} samples")
    if not np.isfinite(period_s) or period_s <= 0:
        raise InputError(f"period_s must be positive, got {period_s}")
    ok = np.all(np.isfinite(track), axis=1) & np.isfinite(t)
    n = int(ok.sum())
    order = int(max(0, min(order, (n - 3) // 2 - 1)))
    tau = t[ok] - t[ok].mean()
    theta = np.multiply.outer(tau, 2 * np.pi / period_s * np.arange(1, order + 1))
    design = np.column_stack([np.ones_like(tau), tau, np.cos(theta), np.sin(theta)])
    if n < design.shape[1] + 1:
        raise KinematicsError(f"the travel marker has only {n} positions in the window")
    coef, *_ = np.linalg.lstsq(design, track[ok], rcond=None)
    if reject_sigma is not None:
        # the series bends towards wild samples (and copies them a period away), so they are found
        # by bisquare reweighting first, then left out of a plain refit
        w = np.ones(n)
        for _ in range(6):
            miss = np.linalg.norm(track[ok] - design @ coef, axis=1)
            scale = 4.685 * 1.4826 * max(float(np.median(miss)), 1e-9)
            w = np.clip(1.0 - (miss / scale) ** 2, 0.0, None) ** 2
            sw = np.sqrt(w)[:, None]
            coef, *_ = np.linalg.lstsq(design * sw, track[ok] * sw, rcond=None)
        miss = np.linalg.norm(track[ok] - design @ coef, axis=1)
        keep = miss <= max(reject_sigma * 1.4826 * float(np.median(miss)), reject_min_mm)
        if keep.sum() >= max(design.shape[1] + 1, 0.8 * n):
            coef, *_ = np.linalg.lstsq(design[keep], track[ok][keep], rcond=None)
    return coef[1]


def motion_frame(travel_xyz_mm, *, plumb_top_mm=None, plumb_bottom_mm=None, rig_down_hint=None,
                 hint_name: str = "the given down direction",
                 origin_mm=None, t_s=None, period_s: float | None = None) -> MotionFrame:
    """Build the motion reference frame (eq. 5.6-5.10).

    Parameters
    ----------
    travel_xyz_mm : ndarray of shape (F, 3)
        Track (rig mm) of the marker that defines the travel, over whole periods: the direction
        is its net displacement from the first to the last finite sample (eq. 5.7), so pass
        ``xyz[start:stop + 1]`` when the sample one window later exists.
    plumb_top_mm, plumb_bottom_mm : ndarray of shape (F, 3) or (3,), optional
        Plumb markers (rig mm). Without them gravity is the ``rig_down_hint`` or, failing that,
        the left camera's image down direction, with a warning.
    rig_down_hint : ndarray of shape (3,), optional
        An approximate down direction in rig coordinates.
    hint_name : str
        What ``rig_down_hint`` is, for the warning.
    origin_mm : ndarray of shape (3,), optional
        Origin (rig mm); default the first finite sample of ``travel_xyz_mm`` (marker 1's first
        position when marker 1 defines the travel).
    t_s : ndarray of shape (F,), optional
        Sample times of ``travel_xyz_mm``; with ``period_s``, x is the travel velocity of
        :func:`travel_velocity` instead of the net displacement (exact for any window length).
    period_s : float, optional
        Stride period, used with ``t_s``.

    Returns
    -------
    MotionFrame

    Raises
    ------
    KinematicsError
        If the marker does not travel, or gravity is (nearly) parallel to the travel.
    """
    track = _as_track(travel_xyz_mm, "travel_xyz_mm")
    finite = np.flatnonzero(np.all(np.isfinite(track), axis=1))
    if finite.size < 2:
        raise KinematicsError("the travel marker has fewer than two positions in the window")
    u1, diagnostics = _travel_direction(track, finite, t_s, period_s)
    g, source, warnings = _gravity(plumb_top_mm, plumb_bottom_mm, rig_down_hint, hint_name, diagnostics)
    angle = float(np.degrees(np.arccos(np.clip(u1 @ g, -1.0, 1.0))))
    if abs(angle - 90.0) > 80.0:
        raise KinematicsError(f"gravity ({source}) is within {90 - abs(angle - 90):.1f} deg of the travel "
                              "direction; the motion frame is undefined (check the plumb clip)")
    if abs(angle - 90.0) > _PERPENDICULAR_TOL_DEG:
        warnings.append(Finding("gravity.tilted",
                                f"gravity ({source}) is {abs(angle - 90):.1f} deg from perpendicular to the travel: "
                                "the horse was not on level ground, or the plumb or travel marker is wrong",
                                {"off_perpendicular_deg": abs(angle - 90)}))
    u3 = _unit(np.cross(u1, g))  # eq. 5.8
    u2 = np.cross(u3, u1)  # eq. 5.9
    R = np.vstack([u1, u2, u3])  # rows = axes: the transpose of R_CM of eq. 5.10
    origin = track[finite[0]] if origin_mm is None else np.asarray(origin_mm, dtype=np.float64).reshape(3)
    return MotionFrame(R=R, origin_mm=np.array(origin, dtype=np.float64), gravity_source=source,
                       warnings=tuple(warnings), gravity_raw=g, travel_raw=u1,
                       angle_travel_gravity_deg=angle, diagnostics=diagnostics)


def _travel_direction(track: np.ndarray, finite: np.ndarray, t_s, period_s: float | None
                      ) -> tuple[np.ndarray, dict]:
    """Unit travel direction x (rig coordinates) of the track (F, 3), and its diagnostics.

    ``finite`` holds the indices of the track's finite samples. With ``t_s`` and ``period_s`` the
    direction is that of :func:`travel_velocity`, otherwise the net displacement (eq. 5.7).
    """
    displacement = track[finite[-1]] - track[finite[0]]
    distance_mm = float(np.linalg.norm(displacement))
    spread_mm = float(np.max(np.linalg.norm(track[finite] - track[finite[0]], axis=1)))
    if distance_mm < 1e-6 or distance_mm < 0.05 * spread_mm:
        raise KinematicsError(f"the travel marker moved only {distance_mm:.1f} mm over the window; the "
                              "horse must travel to define the motion frame's x axis")
    diagnostics: dict = {"travel_distance_mm": distance_mm}
    if t_s is not None and period_s is not None:
        velocity = travel_velocity(t_s, track, period_s=period_s)
        u1 = velocity / np.linalg.norm(velocity)
        diagnostics.update(travel_method="line_plus_series",
                           travel_speed_mm_s=float(np.linalg.norm(velocity)))
    else:
        u1 = displacement / distance_mm  # eq. 5.7
        diagnostics["travel_method"] = "net_displacement"
    return u1, diagnostics


def _gravity(plumb_top_mm, plumb_bottom_mm, rig_down_hint, hint_name: str, diagnostics: dict
             ) -> tuple[np.ndarray, str, list[Finding]]:
    """Unit gravity (rig coordinates), its source and the warnings it calls for.

    From the plumb markers (their diagnostics are added to ``diagnostics``), else the down hint,
    else the left camera's image down direction.
    """
    warnings: list[Finding] = []
    if plumb_top_mm is not None and plumb_bottom_mm is not None:
        g, plumb_diag = plumb_gravity(plumb_top_mm, plumb_bottom_mm)
        diagnostics.update(plumb_diag)
        source = "plumb"
    elif rig_down_hint is not None:
        g = np.asarray(rig_down_hint, dtype=np.float64).reshape(-1)
        if g.shape != (3,) or not np.all(np.isfinite(g)) or np.linalg.norm(g) == 0:
            raise InputError(f"rig_down_hint must be a non-zero 3-vector, got {rig_down_hint!r}")
        g = _unit(g)
        source = "hint"
        warnings.append(Finding("gravity.from_hint",
                                f"no plumb line: gravity taken as {hint_name} (each degree it is off mixes 1.7 % "
                                "of the horizontal motion into the vertical); film a plumb line for exact vertical "
                                "results"))
    else:
        g = CAMERA_DOWN.copy()
        source = "camera_down"
        warnings.append(Finding("gravity.from_camera",
                                "no plumb clip and no down hint: gravity taken as the left camera's image "
                                "down direction (assumes a level camera); vertical results are approximate"))
    if (plumb_top_mm is None) != (plumb_bottom_mm is None):
        warnings.append(Finding("plumb.one_marker", "only one plumb marker track was given; the plumb was ignored"))
    return g, source, warnings


def to_motion_frame(xyz_mm, frame: MotionFrame) -> np.ndarray:
    """Rig coordinates (mm) -> motion coordinates (m) (eq. 5.12).

    Parameters
    ----------
    xyz_mm : ndarray of shape (..., 3)
        Points in rig coordinates, mm (NaN propagates).
    frame : MotionFrame

    Returns
    -------
    xyz_m : ndarray of shape (..., 3)
        The same points in the motion frame, m.
    """
    xyz = np.asarray(xyz_mm, dtype=np.float64)
    if xyz.shape[-1] != 3:
        raise InputError(f"xyz_mm must have shape (..., 3), got {xyz.shape}")
    return (xyz - frame.origin_mm) @ frame.R.T / 1000.0


def vectors_to_motion_frame(vec_rig, frame: MotionFrame, *, scale: float = 1e-3) -> np.ndarray:
    """Rotate free vectors (directions, velocities) into the motion frame, no origin shift.

    Parameters
    ----------
    vec_rig : ndarray of shape (..., 3)
        Vectors in rig coordinates.
    frame : MotionFrame
        The motion frame.
    scale : float, optional
        Unit factor (default mm -> m).

    Returns
    -------
    ndarray of shape (..., 3)
        ``scale * R @ v`` for each vector.
    """
    v = np.asarray(vec_rig, dtype=np.float64)
    if v.shape[-1] != 3:
        raise InputError(f"vec_rig must have shape (..., 3), got {v.shape}")
    return scale * (v @ frame.R.T)

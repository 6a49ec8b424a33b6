"""The free-fall experiment (thesis 8.3): find the thrown ball with all cameras, then fit its flight.

Finding. One camera cannot tell a ball in flight from a glint on the wall behind it, a lamp or another
moving bright thing: a one-marker tracker per camera may follow a different object in each camera, and
the triangulated "ball" is then nonsense. Three calibrated cameras can tell: the ball is the bright spot
whose tracks in the cameras triangulate to one 3-D point at every instant (small reprojection error)
and whose 3-D track is a parabola with a clear acceleration. Every camera's bright spots
(:func:`~saddlescope.core.validation.spots.detect_spots`) are linked into short 2-D tracks
(:func:`~saddlescope.core.validation.spots.link_spots`); the tracks that stand still are dropped;
:func:`find_falling_ball` tries one moving track per camera (or none) and keeps the
combination seen by the most cameras over the longest flight.

Measuring. A ball passing in front of a glint merges with it for a frame or two, which cuts its 2-D
tracks into pieces and shifts a few centroids. So the flight is measured again from the spots
themselves (:func:`fit_flight`): the parabola found predicts the ball in every camera and frame, the
nearest spot there is taken, and a 3-D parabola ``x(t) = p + v t + a t^2 / 2`` is fitted to all
cameras' spots at once by least squares on the reprojection error, each camera's frames at their own
instants (the sub-frame offsets; no resampling across the throw or the catch). Spots far off the
parabola are dropped and the flight is grown frame by frame while spots still follow it. Compared
with fitting the triangulated track, every camera's pixels weigh alike instead of the poorly
determined depth; on the synthetic rides g came out within 0.2 % instead of 0.8 % (1.6 % on a wide
rig whose ball crossed the wall's top edge, which spoils a few centroids).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping

import numpy as np
from scipy.optimize import least_squares

from saddlescope.core.camera_model import project_points
from saddlescope.core.errors import DetectionError, KinematicsError
from saddlescope.core.triangulation import resample_tracks, triangulate_nview
from saddlescope.core.types import ImageTracks, MarkerTracks, Rig
from saddlescope.core.validation.gravity import G_STANDARD_M_S2, gravity_from_freefall
from saddlescope.core.validation.spots import Spots, link_spots, moving_tracks

__all__ = ["find_falling_ball", "fit_flight", "measure_free_fall"]


def _shift(offsets: Mapping[str, float], reference: str) -> dict[str, float]:
    """Frames camera c's clip is ahead of the reference clip (0 for the reference)."""
    base = float(offsets.get(reference, 0.0))
    return {c: float(o) - base for c, o in offsets.items()} | {reference: 0.0}


def _triangulate(rig: Rig, tracks: Mapping[str, ImageTracks], shift: Mapping[str, float],
                 **kwargs) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Reference frames covering every track and the tracks triangulated there.

    Returns frames (F,), xyz_mm (F, 3), reprojection_error_px (F,), views (F,).
    """
    lo = min(float(t.frame_index[0]) - shift.get(c, 0.0) for c, t in tracks.items())
    hi = max(float(t.frame_index[-1]) - shift.get(c, 0.0) for c, t in tracks.items())
    frames = np.arange(int(np.floor(lo)), int(np.ceil(hi)) + 1)
    xy = {c: resample_tracks(t, frames + shift.get(c, 0.0))[:, 0] for c, t in tracks.items()}
    sub = Rig({c: rig.cameras[c] for c in rig.names if c in xy})
    xyz, err, views = triangulate_nview(sub, xy, **kwargs)
    return frames, xyz, err, views


def find_falling_ball(rig: Rig, tracks_by_camera: Mapping[str, list[ImageTracks]],
                      offsets_frames: Mapping[str, float], fps: float, *, reference: str | None = None,
                      clip: str = "freefall", max_error_px: float = 2.0, min_frames: int = 8,
                      min_acceleration_m_s2: float = 0.25 * G_STANDARD_M_S2) -> tuple[MarkerTracks, dict, dict]:
    """The thrown ball's 3-D track, chosen among every camera's moving spot tracks.

    Every combination of one track per camera (or none; at least two cameras) is triangulated on the
    reference camera's clock. It is the ball if its cameras agree (median reprojection error below
    ``max_error_px`` over at least ``min_frames`` instants seen together) and its 3-D track holds a
    free flight (:func:`saddlescope.core.validation.gravity.gravity_from_freefall`) accelerating at least
    ``min_acceleration_m_s2`` (a falling object, not a still glint or a walking person). The best has
    the most cameras, then the longest flight, then the smallest parabola residual.

    Parameters
    ----------
    rig : Rig
    tracks_by_camera : dict camera -> list of ImageTracks
        Candidates (``xy_px`` of shape (F, 1, 2)), e.g. :func:`~saddlescope.core.validation.spots.moving_tracks`
        of :func:`~saddlescope.core.validation.spots.link_spots`.
    offsets_frames : dict camera -> float
        Camera c's frame ``k + offset[c]`` shows the same instant as the reference camera's frame ``k``
        (plus the reference's own offset).
    reference : str, keyword-only
        Default: the rig's first camera with tracks.

    Returns
    -------
    ball : MarkerTracks
        Named ("ball",), at every reference frame the chosen tracks cover (``t_s = frame / fps``).
    chosen : dict camera -> ImageTracks
    fit : dict
        :func:`gravity_from_freefall` of the ball's triangulated track.

    Raises
    ------
    DetectionError
        Naming the clip and the cameras without a moving spot, or that no combination falls.
    """
    cams = [c for c in rig.names if c in tracks_by_camera]
    reference = reference or (cams[0] if cams else "")
    shift = _shift(offsets_frames, reference)
    empty = [c for c in cams if not tracks_by_camera[c]]
    if len(cams) - len(empty) < 2:
        raise DetectionError(f"the {clip} clip: no moving bright spot (the ball) in the "
                             f"{' and '.join(empty) or 'missing'} camera(s); is the ball thrown in view and lit?")
    best = None
    for pick in itertools.product(*[[None, *tracks_by_camera[c]] for c in cams]):
        combo = {c: t for c, t in zip(cams, pick, strict=True) if t is not None}
        if len(combo) < 2:
            continue
        frames, xyz, err, views = _triangulate(rig, combo, shift, reject_outliers=False)
        together = views == len(combo)
        if together.sum() < min_frames or np.median(err[together]) > max_error_px:
            continue
        pts = np.where((together & (err < max_error_px))[:, None], xyz, np.nan)
        try:
            fit = gravity_from_freefall(frames / fps, pts, min_frames=min_frames,
                                        min_acceleration_m_s2=min_acceleration_m_s2)
        except KinematicsError:
            continue
        score = (len(combo), fit["frames"], -fit["rms_residual_mm"])
        if best is None or score > best[0]:
            best = (score, combo, frames, fit)
    if best is None:
        counts = ", ".join(f"{c} {len(tracks_by_camera[c])}" for c in cams)
        raise DetectionError(f"the {clip} clip: no bright spot moves consistently in two or more cameras along a "
                             f"falling parabola (moving spot tracks per camera: {counts}); check that the ball "
                             "flies freely in view of the cameras, and the calibration and synchronisation")
    _, combo, frames, fit = best
    frames, xyz, err, views = _triangulate(rig, combo, shift)
    ball = MarkerTracks(names=("ball",), t_s=frames / fps, xyz_mm=xyz[:, None], reprojection_error_px=err[:, None],
                        views=views[:, None])
    return ball, dict(combo), fit


def _parabola(params: np.ndarray, t: np.ndarray) -> np.ndarray:
    return params[:3] + np.outer(t, params[3:6]) + 0.5 * np.outer(t ** 2, params[6:9])


def fit_flight(rig: Rig, spots_by_camera: Mapping[str, Spots], offsets_frames: Mapping[str, float], fps: float,
               start: Mapping, *, reference: str | None = None, gate_px: float = 4.0, outlier_sigmas: float = 3.5,
               min_sigma_px: float = 0.1, grow: bool = True, grow_limit_px: float = 1.0,
               max_missed_frames: int = 3) -> dict:
    """Fit the ball's free flight to every camera's spots at once (least squares in pixels).

    Parameters
    ----------
    rig : Rig
    spots_by_camera : dict of camera name -> {clip frame: ndarray of shape (K, 2)}
    offsets_frames : dict of camera name -> float
        As :func:`find_falling_ball`.
    fps : float
    start : mapping
        A first parabola on the reference clock: ``t0_s``, ``p_mm``, ``v_mm_s``, ``a_mm_s2`` (3,) with
        ``x(t) = p + v (t - t0) + a (t - t0)^2 / 2``, and the flight ``first_s``/``last_s`` to start from.
    gate_px : float, keyword-only
        A spot is taken in a frame if it is the nearest to the parabola's projection and within this.
    outlier_sigmas, min_sigma_px : float, keyword-only
        Spots further than ``outlier_sigmas`` robust standard deviations (at least ``min_sigma_px``)
        from the fitted parabola are dropped, and are not taken when the flight grows.
    grow : bool, keyword-only
        Extend the flight frame by frame on both sides while spots follow the parabola (within
        ``grow_limit_px`` or the outlier limit, the larger), across at most ``max_missed_frames`` frames
        in a row where none does.

    Returns
    -------
    dict
        ``g_m_s2`` (|a|), ``g_std_m_s2`` (its standard error), ``error_pct`` (against standard
        gravity), ``direction`` (unit vector of a, rig axes), ``first``/``last`` (reference frames of
        the flight), ``frames`` (reference frames spanned), ``observations`` per camera,
        ``rms_reprojection_px``.

    Raises
    ------
    KinematicsError
        Too few spots follow the parabola to fit it.
    """
    cams = [c for c in rig.names if c in spots_by_camera]
    reference = reference or cams[0]
    shift = _shift(offsets_frames, reference)
    t0 = float(start["t0_s"])
    params = np.concatenate([np.asarray(start[k], dtype=np.float64).ravel() for k in ("p_mm", "v_mm_s", "a_mm_s2")])
    # every spot on the reference clock (s from t0)
    times = {c: np.array([(k - shift.get(c, 0.0)) / fps - t0 for k in sorted(spots_by_camera[c])]) for c in cams}
    frame_spots = {c: [np.asarray(spots_by_camera[c][k], dtype=np.float64).reshape(-1, 2)
                       for k in sorted(spots_by_camera[c])] for c in cams}
    lo, hi = float(start["first_s"]) - t0, float(start["last_s"]) - t0
    flight = _Flight(rig, times, frame_spots, params, gate_px=gate_px, outlier_sigmas=outlier_sigmas,
                     min_sigma_px=min_sigma_px)
    step = 1.0 / fps
    obs = flight.gather(lo - 0.5 * step, hi + 0.5 * step)
    res, r, sigma, obs = flight.drop_outliers(obs)
    if grow:
        reached = _grow(flight, obs, sigma, lo, hi, step, grow_limit_px, max_missed_frames)
        # once more over the whole flight with the final parabola: spots that the first, rougher one
        # dropped (near the throw, when it came from a short stretch) come back
        obs = flight.gather(reached["before"] - 0.5 * step, reached["after"] + 0.5 * step)
        res, r, sigma, obs = flight.drop_outliers(obs)
    return _flight_result(res, obs, t0, fps)


class _Flight:
    """The state of :func:`fit_flight`.

    Every camera's spots on the reference clock (s from t0) and the parabola's parameters so far
    (p, v, a: (9,), mm, mm/s, mm/s^2).
    """

    def __init__(self, rig: Rig, times: Mapping[str, np.ndarray], frame_spots: Mapping[str, list[np.ndarray]],
                 params: np.ndarray, *, gate_px: float, outlier_sigmas: float, min_sigma_px: float):
        self.rig = rig
        self.times = times
        self.frame_spots = frame_spots
        self.params = params
        self.gate_px = gate_px
        self.outlier_sigmas = outlier_sigmas
        self.min_sigma_px = min_sigma_px

    def gather(self, a: float, b: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per camera: its instants in [a, b) with a spot near the parabola, and the nearest spot."""
        out = {}
        for c in self.times:
            idx = np.flatnonzero((self.times[c] >= a) & (self.times[c] < b))
            pred = project_points(self.rig.cameras[c], _parabola(self.params, self.times[c][idx]))
            xy = np.full((idx.size, 2), np.nan)
            for n, (i, p) in enumerate(zip(idx, pred, strict=True)):
                d = np.linalg.norm(self.frame_spots[c][i] - p, axis=1)
                if d.size and d.min() < self.gate_px:
                    xy[n] = self.frame_spots[c][i][np.argmin(d)]
            ok = np.all(np.isfinite(xy), axis=1)
            if ok.any():
                out[c] = (self.times[c][idx][ok], xy[ok])
        return out

    def solve(self, obs):
        """Least squares of the parabola on the observations; (result, residuals (N, 2) px, robust sigma px)."""
        res = least_squares(_residuals, self.params, args=(self.rig, obs),
                            x_scale=np.r_[[100.0] * 3, [1000.0] * 3, [1e4] * 3])
        r = res.fun.reshape(-1, 2)
        sigma = max(self.min_sigma_px, 1.4826 * float(np.median(np.abs(r))))
        return res, r, sigma

    def drop_outliers(self, obs):
        """Fit, drop the spots beyond ``outlier_sigmas``, fit again (up to five times).

        The parameters follow each fit. Returns (result, residuals, sigma, observations kept).
        """
        for _ in range(5):
            if sum(len(t) for t, _ in obs.values()) < 6:
                raise KinematicsError("too few spots of the ball follow its parabola to fit its flight")
            res, r, sigma = self.solve(obs)
            self.params = res.x
            bad = np.linalg.norm(r, axis=1) > self.outlier_sigmas * sigma * np.sqrt(2)
            if not bad.any():
                return res, r, sigma, obs
            keep, n = {}, 0
            for c, (t, xy) in obs.items():
                k = ~bad[n:n + len(t)]
                n += len(t)
                keep[c] = (t[k], xy[k])
            obs = keep
        return res, r, sigma, obs

    def following(self, new, limit: float):
        """The observations ``new`` within ``limit`` px of the parabola's projection, per camera."""
        fits = {}
        for c, (t, xy) in new.items():
            near = np.linalg.norm(project_points(self.rig.cameras[c], _parabola(self.params, t)) - xy, axis=1) < limit
            if near.any():
                fits[c] = (t[near], xy[near])
        return fits


def _residuals(p: np.ndarray, rig: Rig, obs) -> np.ndarray:
    """Reprojection residuals (2 N,) px of the parabola ``p`` (9,) against the observations."""
    return np.concatenate([(project_points(rig.cameras[c], _parabola(p, t)) - xy).ravel()
                           for c, (t, xy) in obs.items()])


def _grow(flight: _Flight, obs, sigma: float, lo: float, hi: float, step: float, grow_limit_px: float,
          max_missed_frames: int) -> dict[str, float]:
    """Extend the flight [lo, hi] (s from t0) frame by frame on both sides while spots follow it.

    The parabola is refitted as they come. Returns the furthest instants where they still did.
    """
    edge = {"before": lo, "after": hi}
    reached = dict(edge)  # the furthest instants where spots still followed the parabola
    misses = {"before": 0, "after": 0}
    while misses:
        for side in list(misses):
            # the next frame's instants beyond the flight so far, in every camera
            sign = -1.0 if side == "before" else 1.0
            edge[side] += sign * step
            new = flight.gather(*sorted((edge[side] - sign * 0.5 * step, edge[side] + sign * 0.5 * step)))
            # at least a pixel: a few spoilt centroids (the ball before an edge) bend the parabola by a
            # fraction of one, while past the throw or the catch the ball is off by its speed
            limit = max(grow_limit_px, flight.outlier_sigmas * sigma * np.sqrt(2))
            fits = flight.following(new, limit)
            if not fits:
                # the throw or the catch, out of view, or a few spots spoilt (the ball before an edge)
                misses[side] += 1
                if misses[side] > max_missed_frames:
                    del misses[side]
                continue
            misses[side] = 0
            reached[side] = edge[side]
            for c, (t, xy) in fits.items():
                t_old, xy_old = obs.get(c, (np.empty(0), np.empty((0, 2))))
                obs[c] = (np.concatenate([t_old, t]), np.concatenate([xy_old, xy]))
            _, _, sigma, obs = flight.drop_outliers(obs)
    return reached


def _flight_result(res, obs, t0: float, fps: float) -> dict:
    """The dict of :func:`fit_flight` from the final least-squares result and observations."""
    # standard error of |a| from the Gauss-Newton covariance
    acc = res.x[6:9]
    g = float(np.linalg.norm(acc))
    dof = max(1, res.fun.size - res.x.size)
    cov = np.linalg.pinv(res.jac.T @ res.jac) * float(res.fun @ res.fun) / dof
    g_std = float(np.sqrt((acc / g) @ cov[6:9, 6:9] @ (acc / g)))
    t_all = np.concatenate([t for t, _ in obs.values()])
    first = int(np.ceil((t_all.min() + t0) * fps - 1e-6))
    last = int(np.floor((t_all.max() + t0) * fps + 1e-6))
    return {"g_m_s2": g / 1000.0, "g_std_m_s2": g_std / 1000.0, "error_pct": 100 * (g / 1000.0 / G_STANDARD_M_S2 - 1),
            "direction": (acc / g).tolist(), "first": first, "last": last, "frames": last - first + 1,
            "observations": {c: int(len(t)) for c, (t, _) in obs.items()},
            "rms_reprojection_px": float(np.sqrt(np.mean(res.fun ** 2) * 2))}


def measure_free_fall(rig: Rig, spots_by_camera: Mapping[str, Spots], offsets_frames: Mapping[str, float],
                      fps: float, *, clip: str = "freefall", reference: str | None = None,
                      min_acceleration_m_s2: float = 0.25 * G_STANDARD_M_S2) -> dict:
    """Gravity from a thrown ball, measured with all cameras.

    :func:`find_falling_ball` among every camera's moving spot tracks, then :func:`fit_flight` on all
    cameras' spots.

    Parameters
    ----------
    rig : Rig
    spots_by_camera : dict of camera name -> {clip frame: ndarray of shape (K, 2)}
        e.g. :func:`~saddlescope.core.validation.spots.detect_spots` of each camera's frames after the
        sync flash.
    offsets_frames : dict of camera name -> float
        As :func:`find_falling_ball`.
    fps : float
    clip : str, keyword-only
        Named in errors.
    reference : str, keyword-only
    min_acceleration_m_s2 : float, keyword-only

    Returns
    -------
    dict
        The dict of :func:`fit_flight`, plus ``g_triangulated_m_s2`` (the parabola fitted to the
        triangulated track of the tracks found, for comparison) and ``cameras``.

    Raises
    ------
    DetectionError
        No falling ball found, or the object followed does not fall.
    """
    cams = [c for c in rig.names if c in spots_by_camera]
    reference = reference or (cams[0] if cams else "")
    tracks = {}
    for c in cams:
        w = float(rig.cameras[c].image_size[0])
        found = link_spots(spots_by_camera[c], camera=c, first_step_px=0.06 * w, gate_px=max(3.0, 0.01 * w))
        tracks[c] = moving_tracks(found, min_travel_px=max(8.0, 0.0125 * w))
    ball, chosen, coarse = find_falling_ball(rig, tracks, offsets_frames, fps, reference=reference, clip=clip,
                                             min_acceleration_m_s2=min_acceleration_m_s2)
    t = ball.t_s[coarse["first"]: coarse["last"] + 1]
    x = ball.xyz_mm[coarse["first"]: coarse["last"] + 1, 0]
    ok = np.all(np.isfinite(x), axis=1)
    t0 = float(t[ok].mean())
    design = np.stack([np.ones(ok.sum()), t[ok] - t0, 0.5 * (t[ok] - t0) ** 2], axis=1)
    coef, *_ = np.linalg.lstsq(design, x[ok], rcond=None)
    start = {"t0_s": t0, "p_mm": coef[0], "v_mm_s": coef[1], "a_mm_s2": coef[2],
             "first_s": float(t[0]), "last_s": float(t[-1])}
    w = min(float(rig.cameras[c].image_size[0]) for c in cams)
    fit = fit_flight(rig, spots_by_camera, offsets_frames, fps, start, reference=reference,
                     gate_px=max(3.0, 0.006 * w))
    if fit["g_m_s2"] < min_acceleration_m_s2:
        raise DetectionError(f"the {clip} clip: the object followed in cameras {', '.join(chosen)} accelerates at "
                             f"only {fit['g_m_s2']:.2f} m/s^2; it is not falling (is the ball thrown in view?)")
    fit["g_triangulated_m_s2"] = coarse["g_m_s2"]
    fit["cameras"] = [c for c in cams if fit["observations"].get(c)]
    return fit

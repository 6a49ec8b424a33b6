"""The free-fall experiment (thesis 8.3): find the thrown ball with all cameras, then fit its flight.

Finding. One camera cannot tell a ball in flight from a glint on the wall behind it, a lamp or another
moving bright thing: a one-marker tracker per camera may follow a different object in each camera, and
the triangulated "ball" is then nonsense. Three calibrated cameras can tell: the ball is the bright spot
whose tracks in the cameras triangulate to one 3-D point at every instant (small reprojection error)
and whose 3-D track is a parabola with a clear acceleration. Every camera's bright spots
(:func:`detect_spots`) are linked into short 2-D tracks (:func:`link_spots`); the tracks that stand
still are dropped; :func:`find_falling_ball` tries one moving track per camera (or none) and keeps the
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
from collections.abc import Iterable, Mapping

import cv2
import numpy as np
from scipy.optimize import least_squares

from saddlescope.core.camera_model import project_points
from saddlescope.core.errors import DetectionError, KinematicsError
from saddlescope.core.triangulation import resample_tracks, triangulate_nview
from saddlescope.core.types import ImageTracks, MarkerTracks, Rig
from saddlescope.core.validation import G_STANDARD_M_S2, gravity_from_freefall

__all__ = ["bright_spots", "detect_spots", "link_spots", "moving_tracks", "find_falling_ball", "fit_flight",
           "measure_free_fall"]

Spots = Mapping[int, np.ndarray]  # clip frame index -> (K, 2) spot centres, distorted px


def bright_spots(gray: np.ndarray, *, max_spots: int = 40, min_contrast: float = 25.0,
                 sigmas_px: tuple[float, ...] = (1.5, 2.5, 4.0)) -> np.ndarray:
    """Centres (K, 2) of small bright spots (a ball, glints), the most contrasted first.

    A spot curves down both ways; an edge, a stripe or a line only one way. So the candidates are the
    local maxima of the weaker of the two principal curvatures of the image smoothed at a few scales
    (scale-normalised Hessian, ``sigmas_px`` on frames up to 800 px wide; a wider frame is first shrunk
    to that), and each is measured on the full frame by :func:`_half_max_centroid`. A top-hat (as
    :func:`saddlescope.core.detection.search.bright_spots`) keeps whatever is narrower than its element:
    between the planks of a wall the background itself is a bright stripe, which joined a ball passing
    over it into one blob too big to be a spot.
    """
    h, w = gray.shape
    f = max(1, w // 800)
    small = cv2.resize(gray, (w // f, h // f), interpolation=cv2.INTER_AREA) if f > 1 else gray
    g0 = small.astype(np.float32)
    strength = np.zeros_like(g0)
    scale = np.zeros_like(g0)
    for s in sigmas_px:
        g = cv2.GaussianBlur(g0, (0, 0), s)
        dxx = cv2.Sobel(g, cv2.CV_32F, 2, 0, ksize=3)
        dyy = cv2.Sobel(g, cv2.CV_32F, 0, 2, ksize=3)
        dxy = cv2.Sobel(g, cv2.CV_32F, 1, 1, ksize=3)
        # minus the larger Hessian eigenvalue, times sigma^2 (the 3x3 Sobel kernels sum to 4)
        root = cv2.magnitude(cv2.subtract(dxx, dyy), cv2.multiply(dxy, 2.0))
        weak = cv2.addWeighted(cv2.add(dxx, dyy), -0.125 * s * s, root, -0.125 * s * s, 0)
        better = weak > strength
        np.copyto(strength, weak, where=better)
        scale[better] = s
    peaks = (strength >= cv2.dilate(strength, np.ones((5, 5), np.uint8))) & (strength > 0.1 * min_contrast)
    ys, xs = np.nonzero(peaks)
    order = np.argsort(strength[ys, xs])[::-1][:3 * max_spots]
    spots, contrast = [], []
    for i in order:
        centre = (xs[i] * f + (f - 1) / 2.0, ys[i] * f + (f - 1) / 2.0)
        found = _half_max_centroid(gray, centre, max(2.0, 1.5 * f * scale[ys[i], xs[i]]))
        if found is not None and found[1] >= min_contrast:
            spots.append(found[0])
            contrast.append(found[1])
    keep = np.argsort(contrast)[::-1][:max_spots]
    return np.asarray(spots, dtype=np.float64).reshape(-1, 2)[keep]


def _half_max_centroid(gray: np.ndarray, centre_xy: tuple[float, float],
                       radius_px: float) -> tuple[tuple[float, float], float] | None:
    """Centroid and contrast of the spot whose brightest pixel lies within ``radius_px`` of ``centre_xy``.

    The background is the median of a ring about twice the spot's radius out; the pixels brighter than
    half-way between it and the spot's brightest pixel (and than most of the ring), connected to that
    pixel, weigh by how much they exceed that level. A symmetric spot gives its centre whatever lies
    under the ring (a stripe, an edge), as long as it stays below half the spot's height.
    """
    h, w = gray.shape
    half = int(np.ceil(2.0 * radius_px)) + 2
    cx, cy = int(round(centre_xy[0])), int(round(centre_xy[1]))
    x0, y0 = max(0, cx - half), max(0, cy - half)
    x1, y1 = min(w, cx + half + 1), min(h, cy + half + 1)
    win = gray[y0:y1, x0:x1].astype(np.float64)
    if win.shape[0] < 5 or win.shape[1] < 5:
        return None
    r = int(np.ceil(radius_px))
    yy, xx = np.mgrid[y0:y1, x0:x1]
    near = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
    py, px = np.unravel_index(np.argmax(np.where(near, win, -np.inf)), win.shape)
    ring = np.concatenate([win[0], win[-1], win[1:-1, 0], win[1:-1, -1]])
    background = float(np.median(ring))
    top = float(win[py, px])
    if top <= background:
        return None
    # half-way up, and clear of the brightest quarter of the ring's own height above it: a spot in
    # front of an edge to a bright area (the sky above a wall) must not take that area's pixels
    ring_high = float(np.percentile(ring, 95))
    level = max(background + 0.5 * (top - background), ring_high + 0.25 * (top - ring_high))
    _, labels = cv2.connectedComponents((win > level).astype(np.uint8), connectivity=8)
    weights = np.where(labels == labels[py, px], win - level, 0.0)
    total = weights.sum()
    return ((float((xx * weights).sum() / total), float((yy * weights).sum() / total)), top - background)


def detect_spots(frames: Iterable[tuple[int, np.ndarray]], *, max_spots: int = 40) -> dict[int, np.ndarray]:
    """Small bright spots of every frame (:func:`bright_spots`).

    Returns {frame index: ndarray (K, 2)}, the most contrasted first.
    """
    return {int(index): bright_spots(gray, max_spots=max_spots) for index, gray in frames}


class _Track:
    """A spot followed from frame to frame."""

    def __init__(self, frame: int, xy: np.ndarray):
        self.frames = [frame]
        self.xy = [xy]

    def predict(self, frame: int) -> np.ndarray:
        """Constant acceleration through the last three points (constant velocity through two)."""
        f = np.asarray(self.frames[-3:], dtype=np.float64) - self.frames[-1]
        p = np.asarray(self.xy[-3:])
        if f.size == 1:
            return p[-1]
        coef = np.polyfit(f, p, deg=min(2, f.size - 1))
        dt = frame - self.frames[-1]
        return np.array([np.polyval(coef[:, 0], dt), np.polyval(coef[:, 1], dt)])

    def as_image_tracks(self, camera: str) -> ImageTracks:
        frames = np.arange(self.frames[0], self.frames[-1] + 1)
        xy = np.full((frames.size, 1, 2), np.nan)
        xy[np.asarray(self.frames) - frames[0], 0] = self.xy
        return ImageTracks(camera=camera, xy_px=xy, frame_index=frames)


def link_spots(spots: Spots, *, camera: str = "", first_step_px: float = 40.0, gate_px: float = 6.0,
               max_gap: int = 2, min_frames: int = 4) -> list[ImageTracks]:
    """Link every frame's spots into tracks.

    A track predicts its next position from its last three (constant acceleration: a ball in flight)
    and takes a spot within ``gate_px`` of it; a track of one spot takes any spot within
    ``first_step_px`` (its speed is unknown). Pairs are assigned closest first, so a still glint keeps
    its own spot when a ball passes it. A track missing for more than ``max_gap`` frames ends.

    Returns
    -------
    list of ImageTracks with ``xy_px`` of shape (F, 1, 2) over each track's frames (NaN in its gaps),
    for the tracks seen on at least ``min_frames`` frames.
    """
    active: list[_Track] = []
    done: list[_Track] = []
    for index in sorted(spots):
        xy = np.asarray(spots[index], dtype=np.float64).reshape(-1, 2)
        pairs = []
        if len(xy):
            for i, tr in enumerate(active):
                d = np.linalg.norm(xy - tr.predict(index), axis=1)
                limit = first_step_px if len(tr.frames) == 1 else gate_px
                pairs += [(float(d[j]), i, int(j)) for j in np.flatnonzero(d < limit)]
        taken_track, taken_spot = set(), set()
        for _, i, j in sorted(pairs):
            if i in taken_track or j in taken_spot:
                continue
            active[i].frames.append(index)
            active[i].xy.append(xy[j])
            taken_track.add(i)
            taken_spot.add(j)
        going = []
        for tr in active:
            (going if index - tr.frames[-1] <= max_gap else done).append(tr)
        active = going + [_Track(index, xy[j]) for j in range(len(xy)) if j not in taken_spot]
    done += active
    return [tr.as_image_tracks(camera) for tr in done if len(tr.frames) >= min_frames]


def moving_tracks(tracks: Iterable[ImageTracks], *, min_travel_px: float = 8.0,
                  max_tracks: int = 12) -> list[ImageTracks]:
    """The tracks whose spot travels at least ``min_travel_px`` (a still glint does not), the longest
    path first, at most ``max_tracks``."""
    out = []
    for tr in tracks:
        xy = tr.xy_px[:, 0]
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        extent = float(np.linalg.norm(xy.max(axis=0) - xy.min(axis=0))) if len(xy) else 0.0
        if extent >= min_travel_px:
            out.append((extent, tr))
    out.sort(key=lambda e: -e[0])
    return [tr for _, tr in out[:max_tracks]]


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
    free flight (:func:`saddlescope.core.validation.gravity_from_freefall`) accelerating at least
    ``min_acceleration_m_s2`` (a falling object, not a still glint or a walking person). The best has
    the most cameras, then the longest flight, then the smallest parabola residual.

    Parameters
    ----------
    tracks_by_camera : dict camera -> list of ImageTracks
        Candidates (``xy_px`` of shape (F, 1, 2)), e.g. :func:`moving_tracks` of :func:`link_spots`.
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
    spots_by_camera : dict camera -> {clip frame: ndarray (K, 2)}
    offsets_frames : dict camera -> float
        As :func:`find_falling_ball`.
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
    dict with ``g_m_s2`` (|a|), ``g_std_m_s2`` (its standard error), ``error_pct`` (against standard
    gravity), ``direction`` (unit vector of a, rig axes), ``first``/``last`` (reference frames of the
    flight), ``frames`` (reference frames spanned), ``observations`` per camera, ``rms_reprojection_px``.
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

    def gather(a: float, b: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per camera: its instants in [a, b) with a spot near the parabola, and the nearest spot."""
        out = {}
        for c in cams:
            idx = np.flatnonzero((times[c] >= a) & (times[c] < b))
            pred = project_points(rig.cameras[c], _parabola(params, times[c][idx]))
            xy = np.full((idx.size, 2), np.nan)
            for n, (i, p) in enumerate(zip(idx, pred, strict=True)):
                d = np.linalg.norm(frame_spots[c][i] - p, axis=1)
                if d.size and d.min() < gate_px:
                    xy[n] = frame_spots[c][i][np.argmin(d)]
            ok = np.all(np.isfinite(xy), axis=1)
            if ok.any():
                out[c] = (times[c][idx][ok], xy[ok])
        return out

    def residuals(p: np.ndarray, obs) -> np.ndarray:
        return np.concatenate([(project_points(rig.cameras[c], _parabola(p, t)) - xy).ravel()
                               for c, (t, xy) in obs.items()])

    def solve(obs):
        res = least_squares(residuals, params, args=(obs,), x_scale=np.r_[[100.0] * 3, [1000.0] * 3, [1e4] * 3])
        r = res.fun.reshape(-1, 2)
        sigma = max(min_sigma_px, 1.4826 * float(np.median(np.abs(r))))
        return res, r, sigma

    def drop_outliers(obs):
        nonlocal params
        for _ in range(5):
            if sum(len(t) for t, _ in obs.values()) < 6:
                raise KinematicsError("too few spots of the ball follow its parabola to fit its flight")
            res, r, sigma = solve(obs)
            params = res.x
            bad = np.linalg.norm(r, axis=1) > outlier_sigmas * sigma * np.sqrt(2)
            if not bad.any():
                return res, r, sigma, obs
            keep, n = {}, 0
            for c, (t, xy) in obs.items():
                k = ~bad[n:n + len(t)]
                n += len(t)
                keep[c] = (t[k], xy[k])
            obs = keep
        return res, r, sigma, obs

    step = 1.0 / fps
    obs = gather(lo - 0.5 * step, hi + 0.5 * step)
    res, r, sigma, obs = drop_outliers(obs)
    edge = {"before": lo, "after": hi}
    reached = dict(edge)  # the furthest instants where spots still followed the parabola
    misses = {"before": 0, "after": 0} if grow else {}
    while misses:
        for side in list(misses):
            # the next frame's instants beyond the flight so far, in every camera
            sign = -1.0 if side == "before" else 1.0
            edge[side] += sign * step
            new = gather(*sorted((edge[side] - sign * 0.5 * step, edge[side] + sign * 0.5 * step)))
            # at least a pixel: a few spoilt centroids (the ball before an edge) bend the parabola by a
            # fraction of one, while past the throw or the catch the ball is off by its speed
            limit = max(grow_limit_px, outlier_sigmas * sigma * np.sqrt(2))
            fits = {}
            for c, (t, xy) in new.items():
                near = np.linalg.norm(project_points(rig.cameras[c], _parabola(params, t)) - xy, axis=1) < limit
                if near.any():
                    fits[c] = (t[near], xy[near])
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
            res, r, sigma, obs = drop_outliers(obs)
    if grow:
        # once more over the whole flight with the final parabola: spots that the first, rougher one
        # dropped (near the throw, when it came from a short stretch) come back
        obs = gather(reached["before"] - 0.5 * step, reached["after"] + 0.5 * step)
        res, r, sigma, obs = drop_outliers(obs)
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
    """Gravity from a thrown ball: :func:`find_falling_ball` among every camera's moving spot tracks,
    then :func:`fit_flight` on all cameras' spots.

    Parameters
    ----------
    spots_by_camera : dict camera -> {clip frame: ndarray (K, 2)}
        e.g. :func:`detect_spots` of each camera's frames after the sync flash.

    Returns
    -------
    The dict of :func:`fit_flight`, plus ``g_triangulated_m_s2`` (the parabola fitted to the
    triangulated track of the tracks found, for comparison) and ``cameras``.
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

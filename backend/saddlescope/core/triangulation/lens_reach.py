"""The lens model where the calibration board never went: its extrapolation limited.

k1, k2 (and k3) are fitted to the board's corners only. Beyond the image radius the board reached,
the radial polynomial is a guess that grows with r^5: on a wide rig whose board was carried through
the middle band of the volume only (arena ``wide_partial`` seed 0, board reaching about 100 of the
middle camera's 320 px), the fitted k2 came out -0.60 against a true +0.07; the model then bent a ray
at the image edge by 120-250 px and folded back on itself at r = 0.87. Two-camera points there were
off by hundreds of millimetres in depth with sub-pixel reprojection errors (two views leave one
redundant equation), and the saddle's weighted r.m.s. came out +86 % on seed 2 (docs/accuracy.md).

Beyond the reach (with ``_REACH_MARGIN``), the radial map r_d(r) is continued from the fitted model's
value at the reach with k1 alone, the lowest-order radial term, which a band of the image does fix
(k2's r^5 term is tiny there), and never folded.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from saddlescope.core.camera_model import undistort_normalized
from saddlescope.core.errors import InputError

__all__ = ["board_reach_px", "reach_by_camera", "reach_radius", "undistort_within_reach"]

# The fitted polynomial is trusted a little beyond the board's last corner: its error grows with
# the r^5 term, small just outside the reach.
_REACH_MARGIN = 1.1
# A slope dr_d/dr flatter than this is no lens (a barrel lens's stays near 0.6-1 over its image).
_MIN_SLOPE = 0.2


def board_reach_px(camera, hull_px) -> float:
    """How far (px from the principal point) the calibration board's corners reached in one camera.

    ``hull_px`` (H, 2): the board coverage's convex hull (:func:`~saddlescope.core.pipeline.setup.
    board_coverage`); the radial lens model is symmetric, so the farthest corner sets the reach.
    """
    hull = np.asarray(hull_px, dtype=np.float64).reshape(-1, 2)
    if hull.size == 0 or not np.all(np.isfinite(hull)):
        raise InputError(f"camera {camera.name!r}: the board coverage hull must be finite (H, 2) pixels")
    return float(np.max(np.linalg.norm(hull - np.asarray(camera.K, dtype=np.float64)[:2, 2], axis=1)))


def _radial(dist: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Distorted radius r_d(r) = r (1 + k1 r^2 + k2 r^4 + k3 r^6) of undistorted normalised radii r."""
    r2 = r * r
    return r * (1 + dist[0] * r2 + dist[1] * r2 * r2 + dist[4] * r2 * r2 * r2)


def _dist5(camera) -> np.ndarray:
    """(k1, k2, p1, p2, k3) of a camera, zero-padded."""
    dist = np.zeros(5)
    d = np.asarray(camera.dist, dtype=np.float64).ravel()
    dist[: min(5, d.size)] = d[:5]
    return dist


def reach_radius(camera, reach_px: float) -> tuple[float, float, float]:
    """The undistorted radius r_t at the reach, its distorted radius rho_t and the slope dr_d/dr there.

    Radii are normalised (pixels over the focal length). Where the model folds before the reach
    (r_d stops growing) the fold's start is taken as the reach. The slope is the continuation's
    (k1 alone, :func:`undistort_within_reach`), at least ``_MIN_SLOPE``.
    """
    K = np.asarray(camera.K, dtype=np.float64)
    dist = _dist5(camera)
    rho_t = _REACH_MARGIN * float(reach_px) / float(np.sqrt(K[0, 0] * K[1, 1]))
    r = np.linspace(0.0, max(3.0, 3.0 * rho_t), 6001)
    rd = _radial(dist, r)
    rising = np.flatnonzero(np.diff(rd) <= 0)
    end = int(rising[0]) if rising.size else r.size - 1
    i = min(int(np.searchsorted(rd[: end + 1], rho_t)), end)
    r_t = float(r[i])
    return r_t, float(rd[i]), float(max(1 + 3 * dist[0] * r_t * r_t, _MIN_SLOPE))


def _continued_radius(rho: np.ndarray, r_t: float, rho_t: float, k1: float) -> np.ndarray:
    """Undistorted radii r >= r_t of distorted radii rho >= rho_t on the continued model.

    Beyond the reach r_d(r) = rho_t + g(r) - g(r_t) with g(r) = r (1 + k1 r^2): the fitted model's value
    at the reach, then k1 alone. A band of the image fixes k1 well but not k2 (whose r^5 term is tiny
    there): on the arena's band-calibrated middle camera the k1 continuation is 3 px off at r = 0.75
    where the fitted polynomial's tangent is 22 px off. Where g' falls to ``_MIN_SLOPE`` (a fold
    beyond the image) the continuation goes on straight.
    """
    def g(r):
        return r * (1 + k1 * r * r)

    r_max = np.sqrt((1 - _MIN_SLOPE) / (-3 * k1)) if k1 < 0 else np.inf
    r_max = max(r_max, r_t)
    target = np.asarray(rho, dtype=np.float64) - rho_t + g(r_t)
    straight = np.isfinite(r_max) & (target > g(r_max))
    r = r_t + (target - g(r_t))  # start, then Newton on the monotonic cubic
    for _ in range(30):
        r = np.clip(r - (g(r) - target) / np.maximum(1 + 3 * k1 * r * r, _MIN_SLOPE), r_t, r_max)
    if np.any(straight):
        r = np.where(straight, r_max + (target - g(r_max)) / _MIN_SLOPE, r)
    return r


def undistort_within_reach(camera, xy_px: np.ndarray, reach_px: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Distorted pixels -> ideal normalised coordinates, the lens model limited to the board's reach.

    Inside the reach (times ``_REACH_MARGIN``) this is :func:`~saddlescope.core.camera_model.
    undistort_normalized`; beyond it the point's radius follows k1 alone from the fitted model's value
    at the reach (continuous there, :func:`_continued_radius`), in the point's own direction.

    Parameters
    ----------
    camera : Camera
    xy_px : ndarray of shape (..., 2)
        Distorted pixels, NaN where not seen.
    reach_px : float or None
        :func:`board_reach_px`; None: the model is used everywhere.

    Returns
    -------
    xy_n : ndarray of shape (..., 2)
        Ideal normalised coordinates.
    beyond : ndarray of shape (...,), bool
        Points beyond the reach (on the continued model).
    """
    pts = np.asarray(xy_px, dtype=np.float64)
    if reach_px is None:
        return undistort_normalized(camera, pts), np.zeros(pts.shape[:-1], dtype=bool)
    K = np.asarray(camera.K, dtype=np.float64)
    r_t, rho_t, _ = reach_radius(camera, reach_px)
    kinv = np.linalg.inv(K)
    obs = pts @ kinv[:2, :2].T + kinv[:2, 2]  # distorted normalised
    rho = np.linalg.norm(obs, axis=-1)
    with np.errstate(invalid="ignore"):
        beyond = np.isfinite(rho) & (rho > rho_t)
    if not beyond.any():
        return undistort_normalized(camera, pts), beyond
    direction = obs[beyond] / rho[beyond][:, None]
    # the exact model at the reach in the point's direction, then the continuation's step outward
    at_reach_px = (direction * rho_t) @ K[:2, :2].T + K[:2, 2]
    edge = undistort_normalized(camera, at_reach_px)
    edge_r = np.maximum(np.linalg.norm(edge, axis=-1, keepdims=True), 1e-12)
    step = _continued_radius(rho[beyond], r_t, rho_t, float(_dist5(camera)[0])) - r_t
    out = undistort_normalized(camera, np.where(beyond[..., None], np.nan, pts))
    out[beyond] = edge + edge / edge_r * step[:, None]
    return out, beyond


def reach_by_camera(rig, coverage: Mapping[str, Mapping] | None) -> dict[str, float]:
    """:func:`board_reach_px` of every camera of ``rig`` with a board coverage hull in ``coverage``."""
    if not coverage:
        return {}
    return {cam: board_reach_px(rig.cameras[cam], cov["hull_px"]) for cam, cov in coverage.items()
            if cam in rig.cameras and cov.get("hull_px")}


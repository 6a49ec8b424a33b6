"""The thesis's triangulation (5.1): each stereo pair on its own, moved into the rig frame, averaged.

Each pair (L-M, L-R, M-R) is triangulated with ``cv2.triangulatePoints`` on undistorted points, the
pair results that live in another camera's frame are moved into the left frame (eq. 5.3-5.4) and
averaged (eq. 5.5). Image points are distorted pixels, NaN where not seen; 3-D points in mm, rig
coordinates.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence

import cv2
import numpy as np

from saddlescope.core.camera_model import project_points, undistort_normalized
from saddlescope.core.errors import InputError, TriangulationError
from saddlescope.core.triangulation.reprojection import _camera, _rms_over, _stack_views
from saddlescope.core.types import Rig

__all__ = ["triangulate_thesis_pairs"]


def _pair_pose(rig: Rig, a: str, b: str, use_pair_extrinsics: bool) -> tuple[np.ndarray, np.ndarray]:
    """Pose of camera b relative to camera a: x_b = R_ba x_a + t_ba (eq. 5.1)."""
    pair = rig.pairs.get(f"{a}-{b}") if use_pair_extrinsics else None
    if pair is not None and "R" in pair and "t_mm" in pair:
        return np.asarray(pair["R"], dtype=np.float64), np.asarray(pair["t_mm"], dtype=np.float64).reshape(3)
    ca, cb = _camera(rig, a), _camera(rig, b)
    Ra, ta = np.asarray(ca.R, dtype=np.float64), np.asarray(ca.t_mm, dtype=np.float64).reshape(3)
    Rb, tb = np.asarray(cb.R, dtype=np.float64), np.asarray(cb.t_mm, dtype=np.float64).reshape(3)
    R_ba = Rb @ Ra.T
    return R_ba, tb - R_ba @ ta


def triangulate_thesis_pairs(rig: Rig, xy_by_camera: Mapping[str, np.ndarray], *,
                             pairs: Sequence[tuple[str, str]] | None = None,
                             use_pair_extrinsics: bool = True):
    """The thesis's triangulation: each stereo pair on its own, moved into the rig frame, averaged.

    For each pair (a, b), ``cv2.triangulatePoints`` on the undistorted pixels gives the point in camera
    a's frame; it is moved into the rig (left camera) frame with x_rig = R_a^-1 (x_a - t_a) (eq. 5.3-5.4)
    and the pair results are averaged (eq. 5.5). Where a point is seen by only some cameras, the
    pairs that see it are averaged.

    Parameters
    ----------
    rig : Rig
        With ``rig.pairs["a-b"] = {"R", "t_mm"}`` (a pair's own stereo calibration) used for the pair's
        relative pose when ``use_pair_extrinsics``; otherwise the relative pose follows from the cameras'
        rig poses.
    xy_by_camera : dict of camera name -> ndarray of shape (..., 2)
        Distorted pixels, NaN where not seen.
    pairs : sequence of (a, b), keyword-only
        Default: every pair of the given cameras in order (L-M, L-R, M-R for a thesis rig).
    use_pair_extrinsics : bool, keyword-only

    Returns
    -------
    xyz_mm : ndarray of shape (..., 3)
    reprojection_error_px : ndarray of shape (...,)
        RMS over the cameras of the pairs used.
    views : ndarray of shape (...,), int
        Number of distinct cameras in the pairs used.
    """
    names, shape, obs = _stack_views(rig, xy_by_camera)
    index = {n: i for i, n in enumerate(names)}
    if pairs is None:
        pairs = list(itertools.combinations(names, 2))
    if not pairs:
        raise TriangulationError("the thesis method needs at least two cameras (one stereo pair)")
    ideal = []
    for name, o in zip(names, obs, strict=True):
        cam = _camera(rig, name)
        xn = undistort_normalized(cam, o)
        K = np.asarray(cam.K, dtype=np.float64)
        ideal.append(xn @ K[:2, :2].T + K[:2, 2])
    P = obs.shape[1]
    total = np.zeros((P, 3))
    count = np.zeros(P)
    used = np.zeros((len(names), P), dtype=bool)
    for a, b in pairs:
        if a not in index or b not in index:
            raise InputError(f"pair {a}-{b}: no image points given for camera {a if a not in index else b!r}")
        ia, ib = index[a], index[b]
        ok = np.all(np.isfinite(ideal[ia]), axis=1) & np.all(np.isfinite(ideal[ib]), axis=1)
        if not ok.any():
            continue
        ca, cb = _camera(rig, a), _camera(rig, b)
        R_ba, t_ba = _pair_pose(rig, a, b, use_pair_extrinsics)
        Pa = np.asarray(ca.K, dtype=np.float64) @ np.hstack([np.eye(3), np.zeros((3, 1))])
        Pb = np.asarray(cb.K, dtype=np.float64) @ np.hstack([R_ba, t_ba[:, None]])
        h = cv2.triangulatePoints(Pa, Pb, ideal[ia][ok].T.copy(), ideal[ib][ok].T.copy())
        x_a = (h[:3] / h[3]).T
        Ra = np.asarray(ca.R, dtype=np.float64)
        ta = np.asarray(ca.t_mm, dtype=np.float64).reshape(3)
        x_rig = (x_a - ta) @ Ra  # eq. 5.3: R^-1 (x - t), R^-1 = R^T
        good = np.all(np.isfinite(x_rig), axis=1)
        rows = np.flatnonzero(ok)[good]
        total[rows] += x_rig[good]
        count[rows] += 1
        used[ia, rows] = True
        used[ib, rows] = True
    with np.errstate(invalid="ignore", divide="ignore"):
        X = total / count[:, None]  # eq. 5.5
    X[count == 0] = np.nan
    err = np.stack([np.linalg.norm(project_points(_camera(rig, n), X) - o, axis=-1)
                    for n, o in zip(names, obs, strict=True)])
    rms = _rms_over(err, used)
    rms[count == 0] = np.nan
    n_used = used.sum(axis=0)
    return X.reshape(shape + (3,)), rms.reshape(shape), n_used.reshape(shape).astype(int)

"""Which marker of each camera is which: labels matched across cameras by triangulation.

Each camera's tracker labels its markers on its own (left to right in its image); the cameras'
labels need not agree. Every tuple of one detection per camera is triangulated and the label
permutations that reproject best are kept.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.triangulation.nview import triangulate_nview
from saddlescope.core.triangulation.reprojection import _camera
from saddlescope.core.types import Rig

__all__ = ["match_markers_across_cameras"]


def match_markers_across_cameras(rig: Rig, xy_by_camera: Mapping[str, np.ndarray], *,
                                 reference: str | None = None, cap_px: float = 50.0,
                                 max_combinations: int = 2_000_000) -> dict[str, np.ndarray]:
    """Which marker of each camera is which marker of the reference camera.

    Brute force over label permutations (M <= 5 markers): every tuple of one detection per camera is
    triangulated once (N-view, no outlier rejection) and costs its RMS reprojection error, capped at
    ``cap_px`` (also the cost of a point behind a camera) so that one bad instant cannot outvote the
    others; the permutations minimising the cost summed over markers and instants win. Ties keep the
    cameras' own labels.

    Parameters
    ----------
    rig : Rig
    xy_by_camera : dict of camera name -> ndarray of shape (M, 2) or (T, M, 2)
        Detections of one instant (or T instants) per camera, in each camera's own label order; NaN
        rows allowed (a marker a camera did not see costs nothing).
    reference : str, keyword-only
        The camera whose labels are kept (default: "left" if given, else the first camera).
    cap_px : float, keyword-only
    max_combinations : int, keyword-only
        Guard against an exhaustive search that would not finish.

    Returns
    -------
    dict of camera name -> ndarray of shape (M,), int
        ``perm`` with ``xy_by_camera[name][..., perm[m], :]`` being reference marker ``m``; the
        identity for the reference camera.
    """
    names = list(xy_by_camera)
    if reference is None:
        reference = "left" if "left" in names else names[0]
    if reference not in names:
        raise InputError(f"reference camera {reference!r} has no image points")
    arrays = _as_instants(xy_by_camera, reference)
    T, M = arrays[reference].shape[:2]
    others = [n for n in names if n != reference]
    if not others:
        return {reference: np.arange(M)}
    n_perm = math.factorial(M) ** len(others)
    if n_perm > max_combinations or T * M ** len(names) > max_combinations:
        raise InputError(f"too many label permutations to try ({n_perm}) for {M} markers in "
                         f"{len(names)} cameras")
    order = [reference] + others
    cost = _tuple_costs(rig, arrays, order, cap_px)
    best = _best_permutations(cost, M, len(others))
    result = {reference: np.arange(M)}
    for n, p in zip(others, best, strict=True):
        result[n] = np.asarray(p, dtype=int)
    return {n: result[n] for n in names}


def _as_instants(xy_by_camera: Mapping[str, np.ndarray], reference: str) -> dict[str, np.ndarray]:
    """Every camera's detections as (T, M, 2) float arrays (one instant becomes T = 1), checked alike."""
    arrays = {n: np.asarray(xy_by_camera[n], dtype=np.float64) for n in xy_by_camera}
    ref = arrays[reference]
    if ref.ndim == 2:
        arrays = {n: a[None] for n, a in arrays.items()}
    T, M = arrays[reference].shape[:2]
    for n, a in arrays.items():
        if a.shape != (T, M, 2):
            raise InputError(f"camera {n!r}: expected marker image points of shape {ref.shape}, got "
                             f"{np.asarray(xy_by_camera[n]).shape}")
    return arrays


def _tuple_costs(rig: Rig, arrays: Mapping[str, np.ndarray], order: Sequence[str], cap_px: float) -> np.ndarray:
    """Cost of every tuple (i_ref, i_1, ..., i_k) of one detection per camera, shape (M,) * C.

    The tuple's RMS reprojection error summed over the instants, each capped at ``cap_px`` (also the
    cost of a point behind a camera).
    """
    M = arrays[order[0]].shape[1]
    # One triangulation of T M^C points.
    grids = np.meshgrid(*[np.arange(M)] * len(order), indexing="ij")
    idx = [g.ravel() for g in grids]
    xy = {n: arrays[n][:, i] for n, i in zip(order, idx, strict=True)}  # (T, M^C, 2)
    X, rms, nviews = triangulate_nview(rig, xy, reject_outliers=False)
    behind = np.zeros(X.shape[:-1], dtype=bool)
    for n in order:
        cam = _camera(rig, n)
        R, t = np.asarray(cam.R, dtype=np.float64), np.asarray(cam.t_mm, dtype=np.float64).reshape(3)
        behind |= (X @ R.T + t)[..., 2] <= 0
    cost = np.where(np.isfinite(rms) & ~behind, np.minimum(rms, cap_px), cap_px)
    # A tuple with a missing detection costs nothing extra: the gap stays a gap either way.
    cost = np.where(nviews < len(order), np.where(np.isfinite(rms) & ~behind, np.minimum(rms, cap_px), 0.0),
                    cost)
    summed: np.ndarray = cost.sum(axis=0).reshape((M,) * len(order))
    return summed


def _best_permutations(cost: np.ndarray, M: int, n_others: int) -> list[np.ndarray]:
    """The permutation (M,) of each other camera's labels minimising the summed tuple ``cost``.

    ``cost`` as :func:`_tuple_costs` gives it; the earliest combination (the identity first) wins ties.
    """
    perms = np.array(list(itertools.permutations(range(M))))  # (M!, M), the identity first
    best_total, best = np.inf, None
    # Sum over m of cost[m, p1[m], p2[m], ...] for every combination of permutations (chunks of the first).
    rest = list(itertools.product(range(len(perms)), repeat=n_others - 1))
    rest_idx = np.array(rest, dtype=int).reshape(len(rest), n_others - 1)
    m = np.arange(M)
    for p1 in range(len(perms)):
        index = [m[None, :].repeat(len(rest), 0), perms[p1][None, :].repeat(len(rest), 0)]
        for k in range(n_others - 1):
            index.append(perms[rest_idx[:, k]])
        totals = cost[tuple(index)].sum(axis=1)
        j = int(np.argmin(totals))
        if totals[j] < best_total - 1e-9:
            best_total = float(totals[j])
            best = [perms[p1]] + [perms[rest_idx[j, k]] for k in range(n_others - 1)]
    assert best is not None  # the costs are finite (capped), so some combination beats inf
    return best

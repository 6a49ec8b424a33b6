"""Similarity of two recordings per marker subset and time window (dissertation chapters 2-4)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.similarity.alignment import DISSERTATION_NW_SCORES, nw_similarity
from saddlescope.core.similarity.chain_code import CODE_STILL, chain_code_3d, default_step
from saddlescope.core.similarity.dtw import dtw_distance_reference
from saddlescope.core.similarity.shape import shape_dissimilarity

__all__ = [
    "trajectory_similarity",
]


def _as_markers(xyz, name: str) -> np.ndarray:
    arr = np.asarray(xyz, dtype=np.float64)
    if arr.ndim == 2:
        arr = arr[:, None, :]
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise InputError(f"{name} must be (N, 3) or (N, M, 3) marker positions, got shape {np.shape(xyz)}")
    if arr.shape[0] < 2:
        raise InputError(f"{name} has {arr.shape[0]} samples; at least 2 are needed")
    if not np.all(np.isfinite(arr)):
        f, mk = np.argwhere(~np.isfinite(arr))[0][:2]
        raise InputError(f"{name} contains NaN or infinite positions (marker {mk}, sample {f}); "
                         "bridge the gaps before comparing trajectories")
    return arr


def _subsets(markers, n_markers: int) -> dict[str, list[int]]:
    if markers is None:
        return {"all": list(range(n_markers))}
    if isinstance(markers, Mapping):
        items = {str(k): list(v) for k, v in markers.items()}
    else:
        items = {"selected": list(markers)}
    for name, idx in items.items():
        if not idx:
            raise InputError(f"marker subset {name!r} is empty")
        for k in idx:
            if not isinstance(k, (int, np.integer)) or not 0 <= int(k) < n_markers:
                raise InputError(f"marker subset {name!r} names marker {k!r}, but the trajectories have "
                                 f"markers 0-{n_markers - 1}")
    return {name: [int(k) for k in idx] for name, idx in items.items()}


def _windows(window, n: int) -> list[tuple[int, int]]:
    if window is None:
        return [(0, n)]
    if isinstance(window, (int, np.integer)):
        size = int(window)
        if size < 2:
            raise InputError(f"a time window needs at least 2 samples, got {size}")
        if size > n:
            raise InputError(f"the time window of {size} samples is longer than the records ({n} samples)")
        return [(s, s + size) for s in range(0, n - size + 1, size)]
    try:
        start, stop = (int(v) for v in window)
    except (TypeError, ValueError) as exc:
        raise InputError(f"window must be None, a length in samples or (start, stop), "
                         f"got {window!r}") from exc
    if not 0 <= start < stop <= n or stop - start < 2:
        raise InputError(f"window ({start}, {stop}) is not a range of at least 2 samples within 0-{n}")
    return [(start, stop)]


def _pair_scores(ca: np.ndarray, cb: np.ndarray, nw_scores, band) -> dict:
    ca = ca[ca != CODE_STILL]
    cb = cb[cb != CODE_STILL]
    if ca.size == 0 or cb.size == 0:
        # A marker that does not move by one grid step: alike only if both are still.
        both = ca.size == 0 and cb.size == 0
        return {"nw_similarity": 1.0 if both else 0.0, "shape_dissimilarity": 0.0 if both else 1.0}
    return {"nw_similarity": nw_similarity(ca, cb, scores=nw_scores, band=band),
            "shape_dissimilarity": shape_dissimilarity(ca, cb)}


def trajectory_similarity(xyz_a, xyz_b, *, markers=None, window=None, step: float | None = None,
                          nw_scores: tuple[float, float, float] = DISSERTATION_NW_SCORES,
                          band: int | None = None,
                          dtw: Callable[[np.ndarray, np.ndarray], float] | None = None) -> dict:
    """Similarity of two recordings per marker subset and per time window (dissertation ch. 2-4).

    Each marker's trajectory in each window is turned into a chain code (one common grid step per
    marker for both recordings), the two chains are compared by Needleman-Wunsch (similarity =
    matches / alignment length, Appendix B.1) and by the shape dissimilarity D' (eq. 6), and the
    raw samples by DTW. Values of a subset are the means over its markers, as in the dissertation.

    Parameters
    ----------
    xyz_a, xyz_b : ndarray of shape (N, 3) or (N, M, 3)
        The two recordings of the same M markers, sampled alike (windows are taken at the same
        sample indices in both; the records may differ in length).
    markers : None, sequence of int or mapping of name -> sequence of int, optional
        Marker subsets ("head", "saddle", ...). Default one subset ``"all"``.
    window : None, int or (start, stop), optional
        None: the whole (common) record. An int: consecutive windows of that many samples.
        (start, stop): one window of sample indices.
    step : float, optional
        Grid cell size for all markers; default per marker :func:`default_step` of both records.
    nw_scores : (match, mismatch, gap), optional
        Needleman-Wunsch scores, default the dissertation's (1, 0, 0).
    band : int, optional
        Needleman-Wunsch band half-width (default :func:`saddlescope.core.similarity.alignment.default_band`).
    dtw : callable (a (n, 3), b (m, 3)) -> float, optional
        DTW distance function; default :func:`dtw_distance_reference` with a window of 10 % of the
        longer series. The services layer passes dtaidistance's C implementation.

    Returns
    -------
    result : dict
        ``step`` (marker -> grid step), ``windows`` (list of dicts with ``start``, ``stop``,
        ``markers`` (marker -> ``chain_length_a``, ``chain_length_b``, ``nw_similarity``,
        ``shape_dissimilarity``, ``shape_similarity`` = 1 - D', ``dtw``) and ``subsets``
        (name -> the means over its markers)), and ``subsets`` (name -> the means over windows).
    """
    a = _as_markers(xyz_a, "recording A")
    b = _as_markers(xyz_b, "recording B")
    if a.shape[1] != b.shape[1]:
        raise InputError(f"recording A has {a.shape[1]} markers but recording B has {b.shape[1]}")
    subsets = _subsets(markers, a.shape[1])
    used = sorted({k for idx in subsets.values() for k in idx})
    windows = _windows(window, min(a.shape[0], b.shape[0]))
    if dtw is None:
        def dtw(x, y):
            return dtw_distance_reference(x, y, window=max(2, int(np.ceil(0.1 * max(len(x), len(y))))))
    if step is not None and (not np.isfinite(step) or step <= 0):
        raise InputError(f"the grid step must be a positive length, got {step}")
    steps = {}
    for k in used:
        try:
            steps[k] = float(step) if step is not None else default_step(a[:, k], b[:, k])
        except InputError as exc:
            raise InputError(f"marker {k}: {exc}") from exc

    keys = ("nw_similarity", "shape_dissimilarity", "shape_similarity", "dtw")
    out_windows: list[dict[str, Any]] = []
    for start, stop in windows:
        per_marker = {}
        for k in used:
            xa, xb = a[start:stop, k], b[start:stop, k]
            ca = chain_code_3d(xa, step=steps[k])
            cb = chain_code_3d(xb, step=steps[k])
            entry: dict[str, float] = {"chain_length_a": int(ca.size), "chain_length_b": int(cb.size)}
            entry.update(_pair_scores(ca, cb, nw_scores, band))
            entry["shape_similarity"] = 1.0 - entry["shape_dissimilarity"]
            entry["dtw"] = float(dtw(xa, xb))
            per_marker[k] = entry
        subset_means = {name: {key: float(np.mean([per_marker[k][key] for k in idx])) for key in keys}
                        for name, idx in subsets.items()}
        out_windows.append({"start": start, "stop": stop, "markers": per_marker, "subsets": subset_means})
    summary = {name: {key: float(np.mean([w["subsets"][name][key] for w in out_windows])) for key in keys}
               for name in subsets}
    return {"step": steps, "windows": out_windows, "subsets": summary}

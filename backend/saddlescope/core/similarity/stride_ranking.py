"""Which strides move most alike: DTW (dtaidistance's C code) and chain codes of one mean stride each.

Rides differ in speed, stride rate and the moment the recording starts, so every track is first
normalised to one stride (:func:`saddlescope.core.similarity.ride_strides`): the travel and the mean
removed, folded on its stride period, averaged over its whole strides, resampled and kept to its first
harmonics. Two normalised strides are then compared by DTW over all cyclic shifts of the second (lower =
alike) or by chain codes on one common grid after aligning their start phases (the dissertation's
Needleman-Wunsch similarity, higher = alike; Bribiesca & Aguilar's D' too). SCIENCE.md stage 13.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import Any

import numpy as np
from dtaidistance import dtw as dtai_dtw
from dtaidistance import dtw_ndim as dtai_dtw_ndim

from saddlescope.core.errors import InputError
from saddlescope.core.similarity.canonical import (
    DEFAULT_HARMONICS,
    DEFAULT_STRIDE_SAMPLES,
    align_phase,
    noise_step,
    ride_strides,
)
from saddlescope.core.similarity.chain_code import DEFAULT_CELLS
from saddlescope.core.similarity.dtw import dtw_distance_reference
from saddlescope.core.similarity.measures import chain_measures

__all__ = ["METHODS", "dtw_distance", "most_similar_rides", "normalise_stride", "stride_distance_dtw",
           "stride_similarity_chaincode"]

METHODS = ("dtw", "chaincode")
# dtaidistance sets dtw_cc to None when its C extension failed to build (try_import_c would print).
_C_AVAILABLE = getattr(dtai_dtw, "dtw_cc", None) is not None


def _series(x, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
    if arr.ndim not in (1, 2) or arr.shape[0] < 1:
        raise InputError(f"{name} must be a (N,) or (N, D) series, got shape {np.shape(x)}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or infinite values")
    return arr


def dtw_distance(a, b, *, window: int | None = None) -> float:
    """DTW distance with dtaidistance's C implementation.

    Parameters
    ----------
    a, b : array_like of shape (n,) or (n, D), (m,) or (m, D)
        Series; D-dimensional samples use ``dtw_ndim`` (squared Euclidean cost per sample pair).
    window : int, optional
        Sakoe-Chiba window in samples (dtaidistance's convention, see
        :func:`saddlescope.core.similarity.dtw_distance_reference`).

    Returns
    -------
    distance : float
        ``sqrt`` of the summed squared differences along the best warping path, in the units of the
        series. Falls back to the numpy reference if the C extension is missing.
    """
    x = _series(a, "a")
    y = _series(b, "b")
    if x.ndim != y.ndim or (x.ndim == 2 and x.shape[1] != y.shape[1]):
        raise InputError(f"series have different dimensions: shapes {x.shape} and {y.shape}")
    if window is not None and window < 1:
        raise InputError(f"window must be at least 1, got {window}")
    if not _C_AVAILABLE:
        return dtw_distance_reference(x, y, window=window)
    if x.ndim == 1:
        return float(dtai_dtw.distance_fast(x, y, window=window))
    return float(dtai_dtw_ndim.distance_fast(x, y, window=window))


def normalise_stride(xyz, *, period_samples: float | None = None, fps: float = 30.0,
                     n_samples: int = DEFAULT_STRIDE_SAMPLES, harmonics: int | None = DEFAULT_HARMONICS,
                     ride: Hashable = "track") -> np.ndarray:
    """The mean stride (n_samples, 3) of a track (N, 3): :func:`saddlescope.core.similarity.ride_strides`.

    The travel and the mean are removed, the track is folded on its stride period (estimated from
    ``fps`` if not given), averaged over its whole strides and kept to ``harmonics`` harmonics; it
    starts at the track's first sample.
    """
    return ride_strides(xyz, period_samples=period_samples, fps=fps, n_samples=n_samples, harmonics=harmonics,
                        ride=ride).mean


def stride_distance_dtw(a, b, *, window: int | None = None) -> tuple[float, int]:
    """Smallest DTW distance between stride ``a`` and the cyclic shifts of stride ``b``.

    Parameters
    ----------
    a, b : ndarray of shape (n, 3)
        Normalised strides (:func:`normalise_stride`), same n.
    window : int, optional
        Sakoe-Chiba window; default 10 % of n.

    Returns
    -------
    distance : float
        In the units of the positions.
    shift : int
        The shift s of ``np.roll(b, -s, axis=0)`` that gives it.
    """
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise InputError(f"strides must have the same shape, got {a.shape} and {b.shape}")
    w = max(2, int(np.ceil(0.1 * a.shape[0]))) if window is None else window
    dists = [dtw_distance(a, np.roll(b, -s, axis=0), window=w) for s in range(b.shape[0])]
    best = int(np.argmin(dists))
    return float(dists[best]), best


def stride_similarity_chaincode(a, b, *, cells: int = DEFAULT_CELLS, sigma_a: float = 0.0, sigma_b: float = 0.0,
                                walk: str = "anchored") -> tuple[float, float, float]:
    """Chain-code similarity of two closed strides (the mean strides of two rides).

    The start of ``b`` is aligned to ``a`` (circular cross-correlation, sub-sample Fourier shift),
    both loops are coded on one grid with a vertex at their common centre, with the step
    ``max(extent / cells, 4 sigma)`` (:func:`saddlescope.core.similarity.noise_step`), over a
    second lap (:func:`saddlescope.core.similarity.closed_loop_chain`).

    Parameters
    ----------
    a, b : ndarray of shape (n, 3)
        Normalised strides (mean zero), same n.
    cells : int, optional
        The larger stride's largest bounding-box side spans at most this many cells.
    sigma_a, sigma_b : float, optional
        Noise left in each stride (:attr:`saddlescope.core.similarity.RideStrides.sigma_mean_m`).
    walk : {"anchored", "nearest"}, optional
        The grid walk.

    Returns
    -------
    similarity : float
        The dissertation's Needleman-Wunsch similarity (matches / alignment length, in [0, 1]).
    shape_dissimilarity : float
        Bribiesca & Aguilar's D'.
    shift : float
        The phase shift (samples) applied to ``b``.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise InputError(f"strides must have the same shape, got {a.shape} and {b.shape}")
    rb, shift = align_phase(a, b)
    step = noise_step([a, rb], [sigma_a, sigma_b], cells=cells)
    res = chain_measures(a, rb, step=step, walk=walk)
    return res["chain_code_nw"], res["shape_dissimilarity"], shift


def most_similar_rides(tracks_by_ride: Mapping[Hashable, np.ndarray], *, method: str = "dtw", top: int = 5,
                       periods: Mapping[Hashable, float] | None = None, fps: float = 30.0,
                       n_samples: int = DEFAULT_STRIDE_SAMPLES,
                       harmonics: int | None = DEFAULT_HARMONICS) -> list[dict]:
    """Ride pairs ranked by how alike their strides move.

    Parameters
    ----------
    tracks_by_ride : mapping of ride id -> ndarray of shape (N, 3)
        One track per ride (e.g. the saddle point in the motion frame, m), at least two rides.
    method : {"dtw", "chaincode"}, optional
        DTW distance over cyclic shifts (lower = alike) or chain-code Needleman-Wunsch similarity
        (higher = alike); see the module docstring.
    top : int, optional
        Number of pairs returned.
    periods : mapping of ride id -> float, optional
        Stride period in samples per ride; rides not listed get an estimated period.
    fps : float, optional
        Sampling rate of the tracks (for the period estimate).
    n_samples : int, optional
        Samples per normalised stride.
    harmonics : int or None, optional
        Harmonics kept per stride (see :func:`normalise_stride`).

    Returns
    -------
    pairs : list of dict
        Most alike first, each with ``rides`` ([id_a, id_b]), ``rank`` (1 = most alike),
        ``method``, ``shift`` (samples of the second stride), and ``distance`` (dtw) or
        ``similarity`` and ``shape_dissimilarity`` (chaincode).
    """
    if method not in METHODS:
        raise InputError(f"unknown similarity method {method!r}; choose one of {', '.join(METHODS)}")
    if not isinstance(tracks_by_ride, Mapping) or len(tracks_by_ride) < 2:
        raise InputError("at least two rides are needed to rank pairs of rides")
    if int(top) < 1:
        raise InputError(f"top must be at least 1, got {top}")
    periods = dict(periods or {})
    strides = {rid: ride_strides(xyz, period_samples=periods.get(rid), fps=fps, n_samples=n_samples,
                                 harmonics=harmonics, ride=rid)
               for rid, xyz in tracks_by_ride.items()}
    ids = list(strides)
    pairs: list[dict[str, Any]] = []
    for p in range(len(ids)):
        for q in range(p + 1, len(ids)):
            sa, sb = strides[ids[p]], strides[ids[q]]
            if method == "dtw":
                dist, dtw_shift = stride_distance_dtw(sa.mean, sb.mean)
                pairs.append({"rides": [ids[p], ids[q]], "method": method, "distance": dist, "shift": dtw_shift})
            else:
                sim, shape, cc_shift = stride_similarity_chaincode(sa.mean, sb.mean, sigma_a=sa.sigma_mean_m,
                                                                   sigma_b=sb.sigma_mean_m)
                pairs.append({"rides": [ids[p], ids[q]], "method": method, "similarity": sim,
                              "shape_dissimilarity": shape, "shift": cc_shift})
    if method == "dtw":
        pairs.sort(key=lambda d: d["distance"])
    else:
        pairs.sort(key=lambda d: (-d["similarity"], d["shape_dissimilarity"]))
    out = pairs[: int(top)]
    for rank, d in enumerate(out, start=1):
        d["rank"] = rank
    return out

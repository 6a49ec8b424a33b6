"""Which rides move most alike: DTW (dtaidistance's C code) and chain codes (SCIENCE.md stage 13).

Rides differ in speed, stride rate and the moment the recording starts, so every track is first
normalised to one stride: the travel (a least-squares straight line per coordinate) and the mean are
removed, the track is folded on its stride period, averaged over its whole strides, resampled to a
fixed number of samples and smoothed to its first harmonics. Two normalised
strides are then compared

- by DTW (``method="dtw"``): the smallest DTW distance over all cyclic shifts of the second stride
  (the start phase is arbitrary), with a Sakoe-Chiba window; units of the positions, lower = alike;
- by chain codes (``method="chaincode"``): the closed stride loops are written as Bribiesca chain
  codes on one common grid centred on the strides, after aligning their start phases by circular
  cross-correlation, and compared by the dissertation's Needleman-Wunsch similarity (matches /
  alignment length); higher = alike. The shape dissimilarity D' of Bribiesca & Aguilar is
  reported too.
"""

from __future__ import annotations

import time
from collections.abc import Hashable, Mapping

import numpy as np
from dtaidistance import dtw as dtai_dtw
from dtaidistance import dtw_ndim as dtai_dtw_ndim

from saddlescope.core.errors import InputError, KinematicsError
from saddlescope.core.kinematics import estimate_period
from saddlescope.core.similarity import (
    DEFAULT_CELLS,
    chain_code_3d,
    default_step,
    dtw_distance_reference,
    nw_similarity,
    shape_dissimilarity,
)

METHODS = ("dtw", "chaincode")
# Samples of one normalised stride.
DEFAULT_STRIDE_SAMPLES = 128
# Harmonics of the stride frequency kept in a normalised stride.
DEFAULT_HARMONICS = 8
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


def _track(xyz, ride) -> np.ndarray:
    arr = np.asarray(xyz, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"ride {ride!r}: the track must be an (N, 3) array of positions, got shape "
                         f"{np.shape(xyz)}")
    if arr.shape[0] < 8:
        raise InputError(f"ride {ride!r}: the track has {arr.shape[0]} samples; at least 8 are needed")
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(arr), axis=1))[0])
        raise InputError(f"ride {ride!r}: the track contains NaN or infinite positions (first at sample "
                         f"{bad}); bridge the gaps before comparing rides")
    return arr


def normalise_stride(xyz, *, period_samples: float | None = None, fps: float = 30.0,
                     n_samples: int = DEFAULT_STRIDE_SAMPLES, harmonics: int | None = DEFAULT_HARMONICS,
                     ride: Hashable = "track") -> np.ndarray:
    """The mean stride of a track, without travel or mean, resampled to ``n_samples``.

    Parameters
    ----------
    xyz : ndarray of shape (N, 3)
        Positions of one marker (or the saddle point) over the ride, sampled at ``fps``.
    period_samples : float, optional
        Stride period in samples; default estimated with
        :func:`saddlescope.core.kinematics.estimate_period` (which needs about two strides).
    fps : float, optional
        Sampling rate, used only to estimate the period.
    n_samples : int, optional
        Samples of the returned stride.
    harmonics : int or None, optional
        Keep only this many harmonics of the stride frequency (a truncated Fourier series, as the
        thesis fits to one period in 5.5): measurement noise would otherwise dominate the chain
        codes, whose grid cells are ~1/50 of the stride's extent. None keeps everything.
    ride : hashable, optional
        Name used in error messages.

    Returns
    -------
    stride : ndarray of shape (n_samples, 3)
        The detrended track folded on the stride period and averaged over all its whole strides,
        sampled at ``k * period / n_samples``, k = 0..n_samples-1 (a closed loop: sample n_samples
        would be sample 0 again), mean zero. It starts at the track's first sample.
    """
    x = _track(xyz, ride)
    n = x.shape[0]
    if n_samples < 8:
        raise InputError(f"n_samples must be at least 8, got {n_samples}")
    idx = np.arange(n, dtype=np.float64)
    # Remove the travel: a least-squares line per coordinate.
    basis = np.column_stack([np.ones(n), idx - idx.mean()])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    x = x - basis @ coef
    if period_samples is None:
        if not np.isfinite(fps) or fps <= 0:
            raise InputError(f"fps must be a positive sampling rate, got {fps}")
        try:
            period_s, _ = estimate_period(idx / fps, x[:, None, :])
        except KinematicsError as exc:
            raise InputError(f"ride {ride!r}: no stride period could be estimated ({exc}); pass "
                             "period_samples") from exc
        period_samples = period_s * fps
    period_samples = float(period_samples)
    if not np.isfinite(period_samples) or period_samples < 4:
        raise InputError(f"ride {ride!r}: the stride period must be at least 4 samples, got {period_samples}")
    if period_samples > n - 1:
        raise InputError(f"ride {ride!r}: the track ({n} samples) is shorter than one stride "
                         f"({period_samples:.1f} samples)")
    if harmonics is not None and not 1 <= harmonics < n_samples // 2:
        raise InputError(f"harmonics must be between 1 and {n_samples // 2 - 1}, got {harmonics}")
    n_strides = int((n - 1) // period_samples)
    tq = (np.arange(n_strides)[:, None] * period_samples
          + np.arange(n_samples)[None, :] * (period_samples / n_samples)).ravel()
    folded = np.column_stack([np.interp(tq, idx, x[:, k]) for k in range(3)])
    stride = folded.reshape(n_strides, n_samples, 3).mean(axis=0)
    if harmonics is not None:
        spec = np.fft.rfft(stride, axis=0)
        spec[harmonics + 1:] = 0.0
        stride = np.fft.irfft(spec, n=n_samples, axis=0)
    return stride - stride.mean(axis=0)


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


def _best_cyclic_shift(a: np.ndarray, b: np.ndarray) -> int:
    """Shift s maximising the circular cross-correlation of a with np.roll(b, -s) (all axes)."""
    spec = np.sum(np.conj(np.fft.rfft(a, axis=0)) * np.fft.rfft(b, axis=0), axis=1)
    return int(np.argmax(np.fft.irfft(spec, n=a.shape[0])))


def stride_similarity_chaincode(a, b, *, cells: int = DEFAULT_CELLS) -> tuple[float, float, int]:
    """Chain-code similarity of two closed strides.

    Both loops are coded on one grid with a vertex at their common centre (the origin of the
    normalised strides), so a different start phase does not move the grid; the start of ``b`` is
    aligned to ``a`` by the circular cross-correlation of the positions first.

    Parameters
    ----------
    a, b : ndarray of shape (n, 3)
        Normalised strides (mean zero), same n.
    cells : int, optional
        Grid: the larger stride's largest bounding-box side spans this many cells.

    Returns
    -------
    similarity : float
        The dissertation's Needleman-Wunsch similarity (matches / alignment length, in [0, 1]).
    shape_dissimilarity : float
        Bribiesca & Aguilar's D'.
    shift : int
        The shift s of ``np.roll(b, -s, axis=0)`` used.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise InputError(f"strides must have the same shape, got {a.shape} and {b.shape}")
    step = default_step(a, b, cells=cells)
    shift = _best_cyclic_shift(a, b)
    rb = np.roll(b, -shift, axis=0)
    origin = np.zeros(3)
    ca = chain_code_3d(np.vstack([a, a[:1]]), step=step, origin=origin)
    cb = chain_code_3d(np.vstack([rb, rb[:1]]), step=step, origin=origin)
    if ca.size == 0 or cb.size == 0:
        same = ca.size == cb.size
        return (1.0 if same else 0.0), (0.0 if same else 1.0), shift
    return float(nw_similarity(ca, cb)), float(shape_dissimilarity(ca, cb)), shift


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
    strides = {rid: normalise_stride(xyz, period_samples=periods.get(rid), fps=fps, n_samples=n_samples,
                                     harmonics=harmonics, ride=rid)
               for rid, xyz in tracks_by_ride.items()}
    ids = list(strides)
    pairs = []
    for p in range(len(ids)):
        for q in range(p + 1, len(ids)):
            a, b = strides[ids[p]], strides[ids[q]]
            if method == "dtw":
                dist, shift = stride_distance_dtw(a, b)
                pairs.append({"rides": [ids[p], ids[q]], "method": method, "distance": dist, "shift": shift})
            else:
                sim, shape, shift = stride_similarity_chaincode(a, b)
                pairs.append({"rides": [ids[p], ids[q]], "method": method, "similarity": sim,
                              "shape_dissimilarity": shape, "shift": shift})
    if method == "dtw":
        pairs.sort(key=lambda d: d["distance"])
    else:
        pairs.sort(key=lambda d: (-d["similarity"], d["shape_dissimilarity"]))
    out = pairs[: int(top)]
    for rank, d in enumerate(out, start=1):
        d["rank"] = rank
    return out


# ----------------------------------------------------------------------------------------------
# the product's interface: analysed rides (result documents) compared and ranked

# Which tracks of a ride are compared: the saddle point S, one horse marker, or all of them.
MARKER_SETS = ("saddle", "M1", "M2", "M3", "all")
# One mean stride (speed and start drop out) or the whole analysed window.
SPANS = ("stride", "window")


def _document_tracks(doc: Mapping, markers: str) -> tuple[list[np.ndarray], float, float]:
    """The tracks (each (N, 3) m, motion frame) of a result document's ``markers`` set, its sample
    rate (Hz) and stride period (s)."""
    if markers not in MARKER_SETS:
        raise InputError(f"unknown marker set {markers!r}; choose one of {', '.join(MARKER_SETS)}")
    try:
        fps, period_s = float(doc["fps"]), float(doc["period_s"])
        if markers == "saddle":
            tracks = [np.asarray(doc["saddle"]["position_m"], dtype=np.float64)]
        else:
            xyz = np.asarray(doc["markers"]["position_m"], dtype=np.float64)
            names = list(doc["markers"].get("names") or ["M1", "M2", "M3"])
            tracks = [xyz[:, k] for k in range(xyz.shape[1])] if markers == "all" else [xyz[:, names.index(markers)]]
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise InputError(f"the result has no usable {markers!r} track ({exc})") from None
    return tracks, fps, period_s


def compare_ride_documents(doc_a: Mapping, doc_b: Mapping, *, markers: str = "saddle",
                           span: str = "stride") -> dict:
    """How alike two analysed rides move (result documents of CONTRACTS section 2).

    Returns ``{"similarity": s in [0, 1] (1 = the same motion; the measure rides are ranked by),
    "measure": its name, "measures": {name: value, ...}, "markers": ..., "span": ...}``.
    """
    if span not in SPANS:
        raise InputError(f"unknown span {span!r}; choose one of {', '.join(SPANS)}")
    tracks_a, fps_a, period_a = _document_tracks(doc_a, markers)
    tracks_b, fps_b, period_b = _document_tracks(doc_b, markers)
    sims, shapes = [], []
    for xa, xb in zip(tracks_a, tracks_b, strict=True):
        a = normalise_stride(xa, period_samples=period_a * fps_a, ride="a")
        b = normalise_stride(xb, period_samples=period_b * fps_b, ride="b")
        sim, shape, _ = stride_similarity_chaincode(a, b)
        sims.append(sim)
        shapes.append(shape)
    similarity = float(np.mean(sims))
    return {"similarity": similarity, "measure": "chain_code_nw",
            "measures": {"chain_code_nw": similarity, "shape_dissimilarity": float(np.mean(shapes))},
            "markers": markers, "span": span}


def rank_rides(query: Mapping, candidates: Mapping[Hashable, Mapping], *, markers: str = "saddle",
               span: str = "stride", top: int = 10) -> list[dict]:
    """The ``top`` candidates most alike ``query`` (result documents), most alike first.

    Each entry is :func:`compare_ride_documents`' answer with ``"ride"`` (the candidate's key) and
    ``"rank"`` (1 = most alike). A candidate that cannot be compared is left out.
    """
    rows = []
    for key, doc in candidates.items():
        try:
            rows.append({"ride": key, **compare_ride_documents(query, doc, markers=markers, span=span)})
        except InputError:
            continue
    rows.sort(key=lambda r: -r["similarity"])
    rows = rows[: max(1, int(top))]
    for rank, row in enumerate(rows, start=1):
        row["rank"] = rank
    return rows


# ----------------------------------------------------------------------------------------------
# benchmarks (called by `saddlescope bench`)


def bench_trajectories(n: int = 10_000, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two seeded, ride-like 3-D trajectories of ``n`` samples (30 closed strides each, m).

    The second has another start phase, a slowly varying stride rate and its own measurement noise.
    """
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 30 * 2 * np.pi, n)
    warp = u + 0.3 * np.sin(u / 7.0)

    def loop(p: np.ndarray) -> np.ndarray:
        return np.column_stack([0.02 * np.cos(p) + 0.005 * np.cos(2 * p), 0.05 * np.sin(2 * p + 0.3),
                                0.015 * np.sin(p)])

    a = loop(u) + rng.normal(0.0, 2e-4, (n, 3))
    b = loop(warp + 0.4) + rng.normal(0.0, 2e-4, (n, 3))
    return a, b


def bench_chaincode_10k() -> float:
    """Seconds for one chain-code similarity of two 10,000-sample trajectories.

    Both chain codes (common default grid, 50 cells over the extent) plus the banded
    Needleman-Wunsch similarity of the two chains.
    """
    a, b = bench_trajectories()
    t0 = time.perf_counter()
    step = default_step(a, b)
    nw_similarity(chain_code_3d(a, step=step), chain_code_3d(b, step=step))
    return time.perf_counter() - t0


def bench_shape_10k() -> float:
    """Seconds for the chain codes plus Bribiesca & Aguilar's shape dissimilarity (10,000 samples)."""
    a, b = bench_trajectories()
    t0 = time.perf_counter()
    step = default_step(a, b)
    shape_dissimilarity(chain_code_3d(a, step=step), chain_code_3d(b, step=step))
    return time.perf_counter() - t0


def bench_dtw_10k() -> float:
    """Seconds for one 3-D DTW distance of two 10,000-sample trajectories (C, window 10 %)."""
    a, b = bench_trajectories()
    t0 = time.perf_counter()
    dtw_distance(a, b, window=1000)
    return time.perf_counter() - t0

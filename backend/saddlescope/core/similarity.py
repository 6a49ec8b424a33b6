"""Motion similarity of marker trajectories (SCIENCE.md stage 13, seed 004).

The dissertation models each marker's trajectory as a 3-D discrete curve on a cubic grid and
writes it as Bribiesca's chain code of *orthogonal direction changes*; two motions are then
compared as strings, by Needleman-Wunsch global alignment and by the shape dissimilarity of
Bribiesca & Aguilar, and, for reference, by dynamic time warping (DTW) of the raw samples.

Chain code (Bribiesca 2000, dissertation 1.4 and Appendix A)
    The trajectory is walked on a grid of cell size ``step``: every time the polyline crosses a
    mid-plane between two grid vertices the walk makes one unit step (+-x, +-y, +-z), in the order
    in which the line crosses the planes (the dissertation's "which plane of the cube the line AB
    intersected"). Each step ``w`` after the first is labelled relative to the current direction
    ``v`` (the previous step) and ``u``, the direction before the last change of axis::

        0  w = v            (no change of direction)
        1  w = u x v
        2  w = u
        3  w = -(u x v)
        4  w = -u
        5  w = -v           (the path returns the way it came; the dissertation's added code)
        6  no step between two samples (the dissertation's "lack of motion" '.', optional)

    Because only relative directions are coded, the chain is invariant under translation and under
    the 24 rotations of the grid (multiples of 90 degrees about the axes). Before the first change of
    axis ``u`` is undefined; the first turn then *defines* it and is coded 2 (the "imaginary"
    reference element of the dissertation). A chain of K unit steps has K - 1 elements.

Needleman-Wunsch
    Banded, row-vectorised dynamic programme (see :func:`needleman_wunsch`).

Shape dissimilarity (Bribiesca & Aguilar 2006 as the dissertation implements it, its eq. 1-6)
    See :func:`shape_dissimilarity`.

The dissertation's own implementation took 41 minutes for one pair of sensors; everything here is
vectorised numpy and takes well under a second for chains of 10,000 elements.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from saddlescope.core.errors import InputError

# Chain elements.
CODE_STRAIGHT = 0
CODE_CROSS = 1
CODE_BACK = 2
CODE_NEG_CROSS = 3
CODE_NEG_BACK = 4
CODE_REVERSAL = 5
CODE_STILL = 6
# Gap symbol of aligned integer sequences.
GAP = -1
# Default grid: the largest side of the trajectory's bounding box spans this many cells.
DEFAULT_CELLS = 50
# The dissertation's Needleman-Wunsch scores (match, mismatch, gap), chapter 3.2.
DISSERTATION_NW_SCORES = (1.0, 0.0, 0.0)

# Unit steps, indexed by direction number: +x, -x, +y, -y, +z, -z.
_DIRS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=np.int64)


def _dir_index(v) -> int:
    v = np.asarray(v, dtype=np.int64)
    hits = np.flatnonzero(np.all(_DIRS == v, axis=1))
    return int(hits[0])


def _neg(d: int) -> int:
    return d ^ 1


def _cross(u: int, v: int) -> int:
    return _dir_index(np.cross(_DIRS[u], _DIRS[v]))


# ----------------------------------------------------------------------------------------------
# validation


def _as_trajectory(xyz, name: str, *, min_samples: int = 2) -> np.ndarray:
    arr = np.asarray(xyz, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must be an (N, 3) array of positions, got shape {arr.shape}")
    if arr.shape[0] < min_samples:
        raise InputError(f"{name} has {arr.shape[0]} samples; at least {min_samples} are needed")
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(arr), axis=1))[0])
        raise InputError(f"{name} contains NaN or infinite positions (first at sample {bad}); "
                         "bridge the gaps before comparing trajectories")
    return arr


def _as_codes(codes, name: str) -> np.ndarray:
    arr = np.asarray(codes)
    if arr.ndim != 1:
        raise InputError(f"{name} must be a 1-D chain code, got shape {arr.shape}")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{name} must hold integer chain elements, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.size and (arr.min() < 0 or arr.max() > CODE_STILL):
        raise InputError(f"{name} holds elements outside 0-{CODE_STILL}: not a chain code")
    return arr


def default_step(*trajectories: np.ndarray, cells: int = DEFAULT_CELLS) -> float:
    """Grid cell size so that the largest bounding-box side of the trajectories spans ``cells``.

    Parameters
    ----------
    *trajectories : ndarray of shape (N, 3)
        One or more trajectories; comparing curves needs one common step, so pass all of them.
    cells : int, optional
        Number of cells along the largest side of the (axis-aligned) bounding box.

    Returns
    -------
    step : float
        ``max_k ptp(xyz_k, axis=0).max() / cells``, in the units of the positions. The axis-aligned
        extent is invariant under the 90-degree rotations under which the chain code itself is.

    Raises
    ------
    InputError
        If no trajectory moves at all.
    """
    if cells < 1:
        raise InputError(f"cells must be a positive number of grid cells, got {cells}")
    extent = max(float(np.ptp(np.asarray(x, dtype=np.float64), axis=0).max()) for x in trajectories)
    if not np.isfinite(extent) or extent <= 0:
        raise InputError("the trajectory does not move: its extent is zero, so no grid step can be chosen")
    return extent / cells


# ----------------------------------------------------------------------------------------------
# chain code


def _origin(xyz: np.ndarray, origin) -> np.ndarray:
    if origin is None:
        return xyz[0]
    if isinstance(origin, str):
        if origin == "mean":
            return xyz.mean(axis=0)
        raise InputError(f"origin must be None, 'mean' or a point (3,), got {origin!r}")
    o = np.asarray(origin, dtype=np.float64)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise InputError(f"origin must be a finite point of shape (3,), got {origin!r}")
    return o


def grid_walk(xyz, *, step: float, origin=None) -> tuple[np.ndarray, np.ndarray]:
    """Unit steps of the 6-connected grid walk that follows a trajectory.

    Each sample is represented by its nearest grid vertex (by default the grid has a vertex at the
    first sample, the dissertation's starting point A). Between two
    samples the straight segment crosses the mid-planes between vertices; each crossing is one unit
    step along that axis, and the steps are ordered by where along the segment they occur, which
    fills diagonal moves axis by axis in the order the line itself takes. Only exact ties (the line
    passing through a cell edge or corner) fall back to the order x, y, z.

    Parameters
    ----------
    xyz : ndarray of shape (N, 3)
        Positions.
    step : float
        Grid cell size, same units as ``xyz``.
    origin : None, "mean" or array_like of shape (3,), optional
        A grid vertex: the first sample (None), the centroid ("mean": the same grid whatever the
        start of a closed curve) or a given point.

    Returns
    -------
    dirs : ndarray of shape (K,), int64
        Direction number of each step (0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z).
    segment : ndarray of shape (K,), int64
        Index ``s`` of the sample interval (s, s + 1) in which each step is made.
    """
    xyz = _as_trajectory(xyz, "trajectory")
    if not np.isfinite(step) or step <= 0:
        raise InputError(f"the grid step must be a positive length, got {step}")
    q = (xyz - _origin(xyz, origin)) / step
    # rint is odd-symmetric (ties to even), so 90-degree rotations map vertices onto vertices exactly.
    lat = np.rint(q).astype(np.int64)
    dl = np.diff(lat, axis=0)
    segs, ts, axes, negs = [], [], [], []
    for axis in range(3):
        cnt = np.abs(dl[:, axis])
        total = int(cnt.sum())
        if total == 0:
            continue
        seg = np.repeat(np.arange(dl.shape[0]), cnt)
        k = np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        sgn = np.sign(dl[seg, axis])
        plane = lat[seg, axis] + sgn * (k + 0.5)
        t = (plane - q[seg, axis]) / (q[seg + 1, axis] - q[seg, axis])
        segs.append(seg)
        ts.append(t)
        axes.append(np.full(total, axis))
        negs.append(sgn < 0)
    if not segs:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    seg = np.concatenate(segs)
    t = np.concatenate(ts)
    axis = np.concatenate(axes)
    neg = np.concatenate(negs)
    order = np.lexsort((axis, t, seg))
    dirs = 2 * axis[order] + neg[order].astype(np.int64)
    return dirs, seg[order]


def codes_from_steps(dirs) -> np.ndarray:
    """Bribiesca chain elements of a sequence of unit steps.

    Parameters
    ----------
    dirs : array_like of shape (K,)
        Direction numbers (0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z) of consecutive unit steps.

    Returns
    -------
    codes : ndarray of shape (max(K - 1, 0),), int8
        Element k describes step k + 1 relative to step k and to the direction before the last
        change of axis (codes 0-5, see the module docstring).
    """
    dirs = np.asarray(dirs, dtype=np.int64)
    if dirs.ndim != 1 or (dirs.size and (dirs.min() < 0 or dirs.max() > 5)):
        raise InputError("steps must be a 1-D array of direction numbers 0-5")
    k = dirs.shape[0]
    if k < 2:
        return np.zeros(0, dtype=np.int8)
    axis = dirs // 2
    idx = np.arange(k)
    run_start = np.maximum.accumulate(np.where(np.r_[True, axis[1:] != axis[:-1]], idx, 0))
    # u: the direction before the current axis run (a reversal keeps u, as in the update rule).
    u_dir = np.where(run_start > 0, dirs[np.maximum(run_start - 1, 0)], -1)
    v = _DIRS[dirs[:-1]]
    w = _DIRS[dirs[1:]]
    u_idx = u_dir[:-1]
    u = _DIRS[np.maximum(u_idx, 0)]
    uxv = np.cross(u, v)
    codes = np.full(k - 1, CODE_BACK, dtype=np.int8)  # also the first turn, whose u is imaginary
    known = u_idx >= 0
    codes[known & np.all(w == uxv, axis=1)] = CODE_CROSS
    codes[known & np.all(w == u, axis=1)] = CODE_BACK
    codes[known & np.all(w == -uxv, axis=1)] = CODE_NEG_CROSS
    codes[known & np.all(w == -u, axis=1)] = CODE_NEG_BACK
    codes[np.all(w == v, axis=1)] = CODE_STRAIGHT
    codes[np.all(w == -v, axis=1)] = CODE_REVERSAL
    return codes


def chain_code_3d(xyz, *, step: float | None = None, origin=None, keep_still: bool = False) -> np.ndarray:
    """Bribiesca's 3-D chain code of orthogonal direction changes of a trajectory.

    Parameters
    ----------
    xyz : ndarray of shape (N, 3)
        Positions of one marker, N >= 2, finite.
    step : float, optional
        Grid cell size in the units of ``xyz``. Default :func:`default_step` (the largest side of
        the bounding box / 50). Two chains are only comparable when made with the same step.
    origin : None, "mean" or array_like of shape (3,), optional
        Where the grid has a vertex: the first sample (default), the centroid or a given point
        (see :func:`grid_walk`).
    keep_still : bool, optional
        Insert :data:`CODE_STILL` (6) for every sample interval with no grid step, making a "timed"
        chain as the dissertation's Appendix A does with '.'. Off by default: the dissertation found
        that lack-of-motion elements inflate similarity and removed them.

    Returns
    -------
    codes : ndarray of shape (L,), int8
        Chain elements 0-5 (and 6 if ``keep_still``); see the module docstring. Invariant under
        translation and under rotations by multiples of 90 degrees about the grid axes.

    Raises
    ------
    InputError
        If ``xyz`` is not (N, 3), has fewer than 2 samples, contains NaN or does not move.
    """
    xyz = _as_trajectory(xyz, "trajectory")
    if step is None:
        step = default_step(xyz)
    dirs, seg = grid_walk(xyz, step=step, origin=origin)
    codes = codes_from_steps(dirs)
    if not keep_still:
        return codes
    n_seg = xyz.shape[0] - 1
    still = np.setdiff1d(np.arange(n_seg), seg)
    # Order elements and still marks by the sample interval they belong to; a still interval comes
    # before the steps of later intervals.
    key = np.concatenate([seg[1:] * 2 + 1, still * 2])
    vals = np.concatenate([codes, np.full(still.shape[0], CODE_STILL, dtype=np.int8)])
    return vals[np.argsort(key, kind="stable")]


def _transition_table() -> np.ndarray:
    """next_state[u, v, code] -> (u', v') of the accumulated direction (dissertation 3.2)."""
    table = np.full((6, 6, 7, 2), -1, dtype=np.int64)
    for u in range(6):
        for v in range(6):
            if u // 2 == v // 2:
                continue
            uxv = _cross(u, v)
            table[u, v, CODE_STRAIGHT] = (u, v)
            table[u, v, CODE_CROSS] = (v, uxv)
            table[u, v, CODE_BACK] = (v, u)
            table[u, v, CODE_NEG_CROSS] = (v, _neg(uxv))
            table[u, v, CODE_NEG_BACK] = (v, _neg(u))
            table[u, v, CODE_REVERSAL] = (u, _neg(v))
            table[u, v, CODE_STILL] = (u, v)
    return table


_TABLE = _transition_table()


def accumulated_directions(codes, *, u0=(0, 1, 0), v0=(1, 0, 0)) -> np.ndarray:
    """Reference directions (u, v) after every prefix of a chain (dissertation 3.2, Fig. 3.8).

    Parameters
    ----------
    codes : array_like of shape (L,)
        Chain elements 0-6.
    u0, v0 : array_like of shape (3,), optional
        The arbitrary, orthogonal starting pair: ``v0`` is the direction of the first step and
        ``u0`` the (imaginary) reference of the first turn.

    Returns
    -------
    state : ndarray of shape (L + 1, 2), int64
        Direction numbers (u, v) before element 0, after element 0, ... ``v`` is the direction of
        the step just taken.
    """
    codes = _as_codes(codes, "chain")
    u, v = _dir_index(u0), _dir_index(v0)
    if u // 2 == v // 2:
        raise InputError("u0 and v0 must be orthogonal unit axis vectors")
    table = _TABLE.tolist()
    out = np.empty((codes.shape[0] + 1, 2), dtype=np.int64)
    out[0] = (u, v)
    for i, c in enumerate(codes.tolist()):
        u, v = table[u][v][c]
        out[i + 1] = (u, v)
    return out


def chain_to_path(codes, *, u0=(0, 1, 0), v0=(1, 0, 0)) -> np.ndarray:
    """Grid vertices of a curve with the given chain code (the inverse of :func:`chain_code_3d`).

    Parameters
    ----------
    codes : array_like of shape (L,)
        Chain elements; still elements (6) are skipped.
    u0, v0 : array_like of shape (3,), optional
        Orientation of the reconstruction: first step along ``v0``, first turn along ``u0``.

    Returns
    -------
    vertices : ndarray of shape (K + 1, 3), int64
        Vertices of the unit-step path, starting at the origin; K = number of non-still elements + 1.
        It is congruent (by a grid rotation) to the walk the chain was made from.
    """
    codes = _as_codes(codes, "chain")
    codes = codes[codes != CODE_STILL]
    state = accumulated_directions(codes, u0=u0, v0=v0)
    steps = _DIRS[state[:, 1]]
    return np.vstack([np.zeros((1, 3), dtype=np.int64), np.cumsum(steps, axis=0)])


# ----------------------------------------------------------------------------------------------
# Needleman-Wunsch


def _as_sequence(seq, name: str) -> tuple[np.ndarray, bool]:
    if isinstance(seq, str):
        return np.array([ord(c) for c in seq], dtype=np.int64), True
    arr = np.asarray(seq)
    if arr.ndim != 1:
        raise InputError(f"{name} must be a 1-D sequence, got shape {arr.shape}")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{name} must hold integer symbols (or be a str), got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.size and arr.min() < 0:
        raise InputError(f"{name} holds negative symbols; -1 is reserved for gaps")
    return arr, False


def default_band(n: int, m: int) -> int:
    """Half-width of the Needleman-Wunsch band: the length difference plus a margin.

    ``|n - m| + max(64, ceil(0.1 * max(n, m)))`` cells around the straight line from (0, 0) to
    (n, m).
    """
    return abs(n - m) + max(64, int(np.ceil(0.1 * max(n, m))))


def _nw_fill(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, match: float,
             mismatch: float, gap: float) -> tuple[float, np.ndarray]:
    """Banded score matrix, row by row; returns the score and the traceback bits per band cell.

    Rows are stored with a one-cell offset (column j at index j + 1) so that index 0 is a permanent
    -infinity and the first column needs no special case.
    """
    n, m = a.shape[0], b.shape[0]
    scale = max(abs(match), abs(mismatch), abs(gap))
    exact = all(float(x).is_integer() for x in (match, mismatch, gap)) and scale * (n + m + 2) < 2 ** 28
    if exact:
        dtype, neg, tol = np.int32, -(2 ** 30), 0.0  # integer scores: exact and twice as fast
    else:
        dtype, neg, tol = np.float64, -np.inf, 1e-9 * max(scale, 1e-300) * (n + m)
    match_, mismatch_, gap_ = (dtype(x) for x in (match, mismatch, gap))
    width = int((hi - lo).max()) + 1
    # Traceback bits: not_diag[i, c] (the cell does not come from the diagonal) and not_up[i, c].
    not_diag = np.ones((n + 1, width), dtype=bool)
    not_up = np.ones((n + 1, width), dtype=bool)
    # Score of aligning each symbol of a against every column (index j: b[j - 1]).
    rows: dict[int, np.ndarray] = {}
    symbols = np.unique(a)
    if symbols.shape[0] <= 64:
        for sym in symbols.tolist():
            rows[sym] = np.r_[dtype(0), np.where(b == sym, match_, mismatch_).astype(dtype)]
    prev = np.full(m + 2, neg, dtype=dtype)
    cur = np.full(m + 2, neg, dtype=dtype)
    prev[1: hi[0] + 2] = gap_ * np.arange(hi[0] + 1, dtype=dtype)
    ramp = gap_ * np.arange(width, dtype=dtype)
    best = np.empty(width, dtype=dtype)
    up = np.empty(width, dtype=dtype)
    diag = np.empty(width, dtype=dtype)
    lo_l, hi_l, a_l = lo.tolist(), hi.tolist(), a.tolist()
    for i in range(1, n + 1):
        l0, h0 = lo_l[i], hi_l[i]
        w = h0 - l0 + 1
        srow = rows.get(a_l[i - 1])
        if srow is None:
            srow = np.r_[dtype(0), np.where(b == a_l[i - 1], match_, mismatch_).astype(dtype)]
        d, u, bst, rw = diag[:w], up[:w], best[:w], ramp[:w]
        np.add(prev[l0: h0 + 1], srow[l0: h0 + 1], out=d)
        np.add(prev[l0 + 1: h0 + 2], gap_, out=u)
        np.maximum(d, u, out=bst)
        np.subtract(bst, rw, out=bst)
        np.maximum.accumulate(bst, out=bst)
        h = cur[l0 + 1: h0 + 2]
        np.add(bst, rw, out=h)  # h[j] = max(best[j], h[j - 1] + gap) in closed form
        if exact:
            np.not_equal(h, d, out=not_diag[i, :w])
            np.not_equal(h, u, out=not_up[i, :w])
        else:
            np.greater(h - d, tol, out=not_diag[i, :w])
            np.greater(h - u, tol, out=not_up[i, :w])
        # Clear what is left of row i - 2 to the left of this band (bands only move right).
        if i >= 2:
            cur[lo_l[i - 2] + 1: l0 + 1] = neg
        prev, cur = cur, prev
    return float(prev[m + 1]), not_diag, not_up


def needleman_wunsch(a, b, *, match: float = 1, mismatch: float = -1, gap: float = -1,
                     band: int | None = None) -> tuple[float, np.ndarray | str, np.ndarray | str]:
    """Global alignment of two sequences (Needleman-Wunsch, linear gap penalty).

    The score matrix is filled row by row inside a band of half-width ``band`` around the straight
    line from (0, 0) to (n, m) (a Sakoe-Chiba band). Each row is one set of numpy operations: the
    diagonal and vertical moves are elementwise, and the chain of horizontal moves
    ``H[j] = max(T[j], H[j - 1] + gap)`` is solved in closed form as
    ``H[j] = gap * j + cummax(T[k] - gap * k)``. Time O(n * band), memory O(n * band) bytes for the
    traceback. The result is exact whenever the optimal alignment stays inside the band, which is
    always the case when ``band >= max(n, m)``.

    Parameters
    ----------
    a, b : array_like of shape (n,), (m,), or str
        Sequences of non-negative integer symbols (chain codes), or two strings.
    match, mismatch, gap : float, optional
        Score of a match, of a mismatch and of each gap (usually <= 0). The dissertation used
        1, 0, 0 (:data:`DISSERTATION_NW_SCORES`).
    band : int, optional
        Half-width of the band in cells; default :func:`default_band`.

    Returns
    -------
    score : float
        The optimal alignment score.
    aligned_a, aligned_b : ndarray of shape (L,) or str
        The aligned sequences, ``GAP`` (-1) or ``'-'`` in the gaps. Ties prefer a diagonal move,
        then a gap in ``b``, then a gap in ``a`` (tracing back from the end).

    Raises
    ------
    InputError
        Empty or non-integer sequences, negative symbols, non-finite scores or a band < 1.
    """
    a_arr, a_str = _as_sequence(a, "a")
    b_arr, b_str = _as_sequence(b, "b")
    n, m = a_arr.shape[0], b_arr.shape[0]
    if n == 0 or m == 0:
        raise InputError(f"cannot align an empty sequence (lengths {n} and {m})")
    if not all(np.isfinite(x) for x in (match, mismatch, gap)):
        raise InputError("match, mismatch and gap scores must be finite numbers")
    r = default_band(n, m) if band is None else int(band)
    if r < 1:
        raise InputError(f"band must be at least 1 cell, got {band}")
    r = max(r, int(np.ceil(m / n)), 1)  # consecutive rows' bands must touch
    centre = np.arange(n + 1) * (m / n)
    lo = np.clip(np.ceil(centre - r).astype(np.int64), 0, m)
    hi = np.clip(np.floor(centre + r).astype(np.int64), 0, m)
    lo[0], hi[-1] = 0, m
    score, not_diag, not_up = _nw_fill(a_arr, b_arr, lo, hi, float(match), float(mismatch), float(gap))

    out_a: list[int] = []
    out_b: list[int] = []
    i, j = n, m
    lo_l = lo.tolist()
    while i > 0 or j > 0:
        if j == 0:
            move = 1
        elif i == 0:
            move = 2
        else:
            c = j - lo_l[i]
            move = 0 if not not_diag[i, c] else (1 if not not_up[i, c] else 2)
        if move == 0:
            out_a.append(int(a_arr[i - 1]))
            out_b.append(int(b_arr[j - 1]))
            i, j = i - 1, j - 1
        elif move == 1:
            out_a.append(int(a_arr[i - 1]))
            out_b.append(GAP)
            i -= 1
        else:
            out_a.append(GAP)
            out_b.append(int(b_arr[j - 1]))
            j -= 1
    al_a = np.array(out_a[::-1], dtype=np.int64)
    al_b = np.array(out_b[::-1], dtype=np.int64)
    if a_str and b_str:
        return score, "".join("-" if c == GAP else chr(c) for c in al_a), \
            "".join("-" if c == GAP else chr(c) for c in al_b)
    return score, al_a, al_b


def alignment_similarity(aligned_a, aligned_b) -> float:
    """Fraction of aligned positions holding the same symbol (dissertation Appendix B.1).

    Identical alignments give 1; otherwise matches / alignment length (gaps count as positions).
    """
    x = np.asarray(list(aligned_a) if isinstance(aligned_a, str) else aligned_a)
    y = np.asarray(list(aligned_b) if isinstance(aligned_b, str) else aligned_b)
    if x.shape != y.shape or x.ndim != 1:
        raise InputError(f"aligned sequences must have the same 1-D shape, got {x.shape} and {y.shape}")
    if x.size == 0:
        raise InputError("empty alignment")
    return float(np.mean(x == y))


def nw_similarity(a, b, *, scores: tuple[float, float, float] = DISSERTATION_NW_SCORES,
                  band: int | None = None) -> float:
    """Needleman-Wunsch similarity of two chain codes as in the dissertation (Appendix B.1).

    Parameters
    ----------
    a, b : array_like of shape (n,), (m,)
        Chain codes.
    scores : (match, mismatch, gap), optional
        Default the dissertation's (1, 0, 0).
    band : int, optional
        Band half-width, see :func:`needleman_wunsch`.

    Returns
    -------
    similarity : float
        Matching positions / alignment length, in [0, 1]; 1 for identical chains.
    """
    _, al_a, al_b = needleman_wunsch(a, b, match=scores[0], mismatch=scores[1], gap=scores[2], band=band)
    return alignment_similarity(al_a, al_b)


# ----------------------------------------------------------------------------------------------
# shape dissimilarity (Bribiesca & Aguilar)


def _kmer_keys(x: np.ndarray, k: int) -> np.ndarray:
    """Integer key of every length-k substring (3 bits per element, k <= 21)."""
    win = np.lib.stride_tricks.sliding_window_view(x, k)
    return win @ (np.int64(8) ** np.arange(k - 1, -1, -1, dtype=np.int64))


def _seed_pairs(a: np.ndarray, b: np.ndarray, k: int, max_pairs: int) -> tuple[np.ndarray, np.ndarray] | None:
    """All (i, j) with a[i:i+k] == b[j:j+k], or None if there are more than ``max_pairs``."""
    ka, kb = _kmer_keys(a, k), _kmer_keys(b, k)
    oa, ob = np.argsort(ka, kind="stable"), np.argsort(kb, kind="stable")
    ua, sa, ca = np.unique(ka[oa], return_index=True, return_counts=True)
    ub, sb, cb = np.unique(kb[ob], return_index=True, return_counts=True)
    _, ia, ib = np.intersect1d(ua, ub, assume_unique=True, return_indices=True)
    total = int(np.sum(ca[ia] * cb[ib]))
    if total > max_pairs:
        return None
    if total == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    # Every A occurrence of a shared k-mer, paired with every B occurrence of it.
    occ_start = np.repeat(sa[ia], ca[ia]) + (np.arange(int(ca[ia].sum()))
                                            - np.repeat(np.cumsum(ca[ia]) - ca[ia], ca[ia]))
    i_occ = oa[occ_start]
    nb = np.repeat(cb[ib], ca[ia])
    b_first = np.repeat(sb[ib], ca[ia])
    i_pair = np.repeat(i_occ, nb)
    offs = np.arange(total) - np.repeat(np.cumsum(nb) - nb, nb)
    j_pair = ob[np.repeat(b_first, nb) + offs]
    return i_pair, j_pair


def maximal_matches(a, b, *, min_length: int = 2, max_pairs: int = 1_000_000
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """All maximal common substrings of two chains ("maximum common couples"), longest first.

    A maximal match (i, j, L) has ``a[i:i+L] == b[j:j+L]`` and cannot be extended left or right.
    They are found from the shared length-k substrings (k-mer seeds, hashed exactly) merged along
    the diagonals ``j - i``; the work is proportional to the number of seed pairs, not to n * m.

    Parameters
    ----------
    a, b : array_like of shape (n,), (m,)
        Chain codes (elements 0-7).
    min_length : int, optional
        Shortest match reported. If the chains are so repetitive that length-``min_length`` seeds
        pair up more than ``max_pairs`` times, the seed length is increased until they do not
        (the shorter matches are then left out); the length used is returned.
    max_pairs : int, optional
        Bound on the seed pairs (memory ~ 50 bytes each).

    Returns
    -------
    i, j, length : ndarray of shape (C,), int64
        Start in ``a``, start in ``b`` and length of each maximal match of length >= k.
    k : int
        The seed (= minimum match) length actually used.

    Raises
    ------
    InputError
        If even 21-element seeds pair up more than ``max_pairs`` times (e.g. two long straight
        lines: use a coarser grid step or compare shorter windows).
    """
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    k = max(1, int(min_length))
    while True:
        if k > min(a.shape[0], b.shape[0]):
            empty = np.zeros(0, dtype=np.int64)
            return empty, empty, empty, k
        pairs = _seed_pairs(a, b, k, max_pairs)
        if pairs is not None:
            break
        if k >= 21:
            raise InputError(f"the chain codes (lengths {a.shape[0]} and {b.shape[0]}) are too repetitive "
                             f"for the shape dissimilarity: 21-element seeds pair up more than {max_pairs} "
                             "times; use a coarser grid step or shorter time windows")
        k = min(21, 2 * k)
    i_pair, j_pair = pairs
    if i_pair.size == 0:
        return i_pair, j_pair, i_pair.copy(), k
    n = a.shape[0]
    key = (j_pair - i_pair + n) * (n + 1) + i_pair
    key.sort()
    diag = key // (n + 1) - n
    i_sorted = key % (n + 1)
    starts = np.flatnonzero(np.r_[True, np.diff(key) != 1])
    run = np.diff(np.r_[starts, key.shape[0]])
    i0 = i_sorted[starts]
    j0 = i0 + diag[starts]
    length = run + k - 1
    order = np.lexsort((j0, i0, -length))
    return i0[order], j0[order], length[order], k


def _preceding_two_nonzero(x: np.ndarray) -> np.ndarray:
    """For each position p of ``[9, 9] + x`` (two imaginary non-zero elements), the index of the
    second non-zero element before p (0 if there is none)."""
    ext = np.r_[9, 9, x]
    nz = np.flatnonzero(ext != 0)
    p = np.arange(ext.shape[0] + 1)
    cnt = np.searchsorted(nz, p, side="left")  # non-zero elements strictly before p
    return np.where(cnt >= 2, nz[np.maximum(cnt - 2, 0)], 0)


def shape_dissimilarity(a, b, *, min_length: int = 2, max_pairs: int = 1_000_000,
                        return_couples: bool = False):
    """Shape dissimilarity D' of two chain codes (Bribiesca & Aguilar, dissertation eq. 1-6).

    1. The maximum common couples (S, T) are found: every maximal common sub-chain P, with S and T
       the prefixes of the chains up to the end of P (as in the dissertation's worked example).
    2. Each couple gets (eq. 1)
       ``d = |L(S) - L(T)| / (max(L(S), L(T)) - 1) + (min(m, n) - L(P)) + Delta(S, T) + |nes - net|``
       (d = 0 when S = T), where Delta is 0 if the accumulated directions (u, v) after S and after
       T agree and 1 otherwise, and nes, net are the numbers of elements before P needed to reach
       two non-zero elements (two imaginary non-zero elements precede each chain); ``d' = d / (m + n)``
       (eq. 2).
    3. Couples are taken in increasing d'; a couple whose P lies inside an already chosen P (in A or
       in B) is dropped (the dissertation's ``setCommonCouples``, which keeps partial overlaps).
    4. ``D = sum d'_j + unmatched`` (eq. 3-5) and ``D' = D / (m + n + 4)`` (eq. 6), where unmatched
       is m + n + 4 minus the elements covered by the chosen P's and their preceding elements. Where
       chosen couples overlap, covered elements are counted once (eq. 4 assumes no overlaps and
       would otherwise count them twice).

    Lack-of-motion elements (6) are removed first, as the dissertation did. Identical chains give 0;
    D' is not clipped (the size term of eq. 1 adds about ``min(m, n) / (m + n)`` per chosen couple,
    so chains broken into very many short common pieces can approach or pass 1).

    Parameters
    ----------
    a, b : array_like of shape (m,), (n,)
        Chain codes.
    min_length : int, optional
        Shortest common sub-chain considered (the worked example uses 2).
    max_pairs : int, optional
        See :func:`maximal_matches`.
    return_couples : bool, optional
        Also return the chosen couples.

    Returns
    -------
    dissimilarity : float
        D' (0 for identical chains).
    couples : list of dict, only if ``return_couples``
        Chosen couples in order: ``i``, ``j`` (starts of P in a and b), ``length``, ``d_prime``,
        ``nes``, ``net``, ``delta``.
    """
    a = _as_codes(a, "a")
    b = _as_codes(b, "b")
    a = a[a != CODE_STILL]
    b = b[b != CODE_STILL]
    m, n = a.shape[0], b.shape[0]
    if m == 0 or n == 0:
        raise InputError(f"cannot compare an empty chain code (lengths {m} and {n}); the trajectory "
                         "does not move by one grid step")
    if m == n and np.array_equal(a, b):
        couple = {"i": 0, "j": 0, "length": m, "d_prime": 0.0, "nes": 2, "net": 2, "delta": 0}
        return (0.0, [couple]) if return_couples else 0.0
    i, j, length, _ = maximal_matches(a, b, min_length=min_length, max_pairs=max_pairs)
    state_a = accumulated_directions(a)
    state_b = accumulated_directions(b)
    ls, lt = i + length, j + length
    disp = np.abs(ls - lt) / np.maximum(np.maximum(ls, lt) - 1, 1)
    size = min(m, n) - length
    delta = np.any(state_a[ls] != state_b[lt], axis=1).astype(np.int64)
    pa, pb = _preceding_two_nonzero(a), _preceding_two_nonzero(b)
    nes = (i + 2) - pa[i + 2]
    net = (j + 2) - pb[j + 2]
    d = disp + size + delta + np.abs(nes - net)  # eq. 1
    d[(i == 0) & (j == 0)] = 0.0  # S = T
    d_prime = d / (m + n)  # eq. 2
    order = np.lexsort((j, i, d_prime))

    # max_end_x[p]: the furthest end of a chosen P that starts at or before p.
    max_end_a = np.full(m + 1, -1, dtype=np.int64)
    max_end_b = np.full(n + 1, -1, dtype=np.int64)
    cover_a = np.zeros(m + 2, dtype=bool)
    cover_b = np.zeros(n + 2, dtype=bool)
    chosen: list[int] = []
    # Most candidates lie inside a couple chosen earlier: drop those a chunk at a time with one
    # vectorised test, and walk through the few survivors one by one.
    chunk = 256
    for c0 in range(0, order.shape[0], chunk):
        block = order[c0: c0 + chunk]
        alive = ((max_end_a[i[block]] < i[block] + length[block])
                 & (max_end_b[j[block]] < j[block] + length[block]))
        for c in block[alive].tolist():
            ia, jb, lc = int(i[c]), int(j[c]), int(length[c])
            if max_end_a[ia] >= ia + lc or max_end_b[jb] >= jb + lc:
                continue  # P lies inside a chosen P
            chosen.append(c)
            np.maximum(max_end_a[ia:], ia + lc, out=max_end_a[ia:])
            np.maximum(max_end_b[jb:], jb + lc, out=max_end_b[jb:])
            cover_a[ia + 2 - int(nes[c]): ia + 2 + lc] = True
            cover_b[jb + 2 - int(net[c]): jb + 2 + lc] = True
    chosen_arr = np.array(chosen, dtype=np.int64)
    similar = float(d_prime[chosen_arr].sum()) if chosen else 0.0  # eq. 3
    unmatched = (m + 2 - int(cover_a.sum())) + (n + 2 - int(cover_b.sum()))  # eq. 4
    dissimilarity = (similar + unmatched) / (m + n + 4)  # eq. 5-6
    if not return_couples:
        return dissimilarity
    couples = [{"i": int(i[c]), "j": int(j[c]), "length": int(length[c]), "d_prime": float(d_prime[c]),
                "nes": int(nes[c]), "net": int(net[c]), "delta": int(delta[c])} for c in chosen]
    return dissimilarity, couples


# ----------------------------------------------------------------------------------------------
# DTW reference


def _as_series(x, name: str) -> np.ndarray:
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] < 1:
        raise InputError(f"{name} must be a (N,) or (N, D) series, got shape {np.shape(x)}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or infinite values")
    return arr


def dtw_distance_reference(a, b, *, window: int | None = None) -> float:
    """Dynamic time warping distance, plain numpy (the reference for tests and small inputs).

    ``DTW^2(i, j) = |a_i - b_j|^2 + min(DTW^2(i-1, j-1), DTW^2(i-1, j), DTW^2(i, j-1))`` (dissertation
    4.1) and the distance is ``sqrt(DTW^2(n, m))``: the same convention and window as
    ``dtaidistance`` (squared Euclidean cost per sample pair, square root of the total). Filled by
    anti-diagonals, O(n m) time (O(n window) with a window) and O(n + m) memory.

    Parameters
    ----------
    a, b : array_like of shape (n,) or (n, D), (m,) or (m, D)
        Series; D-dimensional samples use the squared Euclidean distance.
    window : int, optional
        Sakoe-Chiba window as in dtaidistance: cell (i, j) is allowed when
        ``i - max(0, n - m) - (window - 1) <= j <= i + max(0, m - n) + (window - 1)``.

    Returns
    -------
    distance : float
    """
    x = _as_series(a, "a")
    y = _as_series(b, "b")
    if x.shape[1] != y.shape[1]:
        raise InputError(f"series have different dimensions: {x.shape[1]} and {y.shape[1]}")
    n, m = x.shape[0], y.shape[0]
    if window is None:
        w_lo = w_hi = max(n, m)
    else:
        if window < 1:
            raise InputError(f"window must be at least 1, got {window}")
        w_lo = max(0, n - m) + window - 1
        w_hi = max(0, m - n) + window - 1
    inf = np.inf
    y_rev = y[::-1]  # cells (i, s - i) for increasing i read y backwards: a slice of y_rev
    # Three rotating buffers over anti-diagonals s - 2, s - 1, s; buf[i + 1] holds cell (i, s - i)
    # and index 0 stays infinite so that i - 1 = -1 needs no special case.
    d2, d1, cur = (np.full(n + 2, inf) for _ in range(3))
    ranges = [(0, -1), (0, -1), (0, -1)]  # (i_lo, i_hi) written in d2, d1, cur
    for s in range(n + m - 1):
        # i - w_lo <= s - i <= i + w_hi  and  0 <= s - i <= m - 1
        i_lo = max(0, s - m + 1, -((w_hi - s) // 2))
        i_hi = min(n - 1, s, (s + w_lo) // 2)
        old_lo, old_hi = ranges[2]
        cur[old_lo + 1: old_hi + 2] = inf
        if i_lo <= i_hi:
            diff = x[i_lo: i_hi + 1] - y_rev[m - 1 - s + i_lo: m - s + i_hi]
            cost = np.einsum("ij,ij->i", diff, diff)
            if s == 0:
                cur[1] = cost[0]
            else:
                best = np.minimum(np.minimum(d2[i_lo: i_hi + 1], d1[i_lo: i_hi + 1]), d1[i_lo + 1: i_hi + 2])
                cur[i_lo + 1: i_hi + 2] = cost + best
        ranges = [ranges[1], (i_lo, i_hi), ranges[0]]
        d2, d1, cur = d1, cur, d2
    total = d1[n]
    if not np.isfinite(total):
        raise InputError(f"the DTW window {window} leaves no warping path between lengths {n} and {m}")
    return float(np.sqrt(total))


# ----------------------------------------------------------------------------------------------
# combination per marker subset and time window


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
        Needleman-Wunsch band half-width (default :func:`default_band`).
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
    out_windows = []
    for start, stop in windows:
        per_marker = {}
        for k in used:
            xa, xb = a[start:stop, k], b[start:stop, k]
            ca = chain_code_3d(xa, step=steps[k])
            cb = chain_code_3d(xb, step=steps[k])
            entry = {"chain_length_a": int(ca.size), "chain_length_b": int(cb.size)}
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


__all__: Sequence[str] = (
    "CODE_STRAIGHT", "CODE_CROSS", "CODE_BACK", "CODE_NEG_CROSS", "CODE_NEG_BACK", "CODE_REVERSAL",
    "CODE_STILL", "GAP", "DEFAULT_CELLS", "DISSERTATION_NW_SCORES", "default_step", "grid_walk",
    "codes_from_steps", "chain_code_3d", "accumulated_directions", "chain_to_path", "default_band",
    "needleman_wunsch", "alignment_similarity", "nw_similarity", "maximal_matches", "shape_dissimilarity",
    "dtw_distance_reference", "trajectory_similarity",
)

"""Bribiesca's 3-D chain code of orthogonal direction changes of a trajectory (dissertation 1.4, App. A).

Chain code (Bribiesca 2000, dissertation 1.4 and Appendix A)
    The trajectory is walked on a grid of cell size ``step``. Two walks are offered:

    ``walk="anchored"`` (default, the dissertation's Appendix A)
        The walker sits on a grid vertex (its anchor) and makes one unit step along an axis only
        when the point has moved a *full* step away from the anchor along that axis ("if distance
        between A and B < step size then '.'"). Each axis therefore has one step of hysteresis:
        noise smaller than a step never turns into back-and-forth steps.
    ``walk="nearest"`` (the first implementation, kept for comparison)
        Every sample is snapped to its nearest vertex and a step is made whenever the polyline
        crosses a mid-plane between two vertices; noise of a fraction of a step near a mid-plane
        becomes steps forth and back.

    Steps within one sample interval are ordered by where along the segment they occur (the
    dissertation's "which plane of the cube the line AB intersected"). Exact ties (the line passing
    through a cell edge or corner) are ordered so that the chain, read from the current reference
    directions, is the smallest in lexicographic order; that rule only refers to relative
    directions, so the 24 rotations of the grid give identical chains.

    Each step ``w`` after the first is labelled relative to the current direction ``v`` (the
    previous step) and ``u``, the direction before the last change of axis::

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
"""

from __future__ import annotations

import itertools

import numpy as np

from saddlescope.core.errors import InputError

__all__ = [
    "CODE_STRAIGHT",
    "CODE_CROSS",
    "CODE_BACK",
    "CODE_NEG_CROSS",
    "CODE_NEG_BACK",
    "CODE_REVERSAL",
    "CODE_STILL",
    "DEFAULT_CELLS",
    "default_step",
    "WALKS",
    "grid_walk",
    "codes_from_steps",
    "chain_code_3d",
    "accumulated_directions",
    "chain_to_path",
]

# Chain elements.
CODE_STRAIGHT = 0
CODE_CROSS = 1
CODE_BACK = 2
CODE_NEG_CROSS = 3
CODE_NEG_BACK = 4
CODE_REVERSAL = 5
CODE_STILL = 6
# The grid walks: the dissertation's anchored walk (one step of hysteresis) and nearest-vertex snapping.
WALKS = ("anchored", "nearest")
# Tolerance (in steps) under which two crossings of one sample interval count as simultaneous, and
# a coordinate as lying on a grid plane.
_TIE_TOL = 1e-9
# Default grid: the largest side of the trajectory's bounding box spans this many cells.
DEFAULT_CELLS = 50

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


def _nearest_events(q: np.ndarray) -> tuple[list, list, list, list]:
    """Mid-plane crossings of the nearest-vertex walk: per axis (segment, t, axis, negative)."""
    lat = np.rint(q).astype(np.int64)  # rint is odd-symmetric: rotations map vertices onto vertices
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
        segs.append(seg)
        ts.append((plane - q[seg, axis]) / (q[seg + 1, axis] - q[seg, axis]))
        axes.append(np.full(total, axis))
        negs.append(sgn < 0)
    return segs, ts, axes, negs


def _anchored_events(q: np.ndarray) -> tuple[list, list, list, list]:
    """Full-step crossings of the anchored walk (Appendix A): per axis (segment, t, axis, negative).

    Per axis the anchor ``a`` (a grid coordinate) moves only when the point reaches ``a + 1`` or
    ``a - 1``; after every sample ``a`` lies in ``[floor(q), ceil(q)]`` (one step of hysteresis).
    A segment is straight, so each axis moves monotonically along it and its steps cross the
    planes ``a + 1, a + 2, ...`` (or ``a - 1, ...``) in turn.
    """
    snapped = np.where(np.abs(q - np.rint(q)) < _TIE_TOL, np.rint(q), q)
    lo, hi = np.floor(snapped).astype(np.int64), np.ceil(snapped).astype(np.int64)
    segs, ts, axes, negs = [], [], [], []
    for axis in range(3):
        lo_l, hi_l = lo[:, axis].tolist(), hi[:, axis].tolist()
        anchor = [int(np.rint(snapped[0, axis]))]
        a = anchor[0]
        for k in range(1, q.shape[0]):
            a = min(max(a, lo_l[k]), hi_l[k])  # the play operator: clip the anchor to the cell
            anchor.append(a)
        lat = np.asarray(anchor, dtype=np.int64)
        dl = np.diff(lat)
        cnt = np.abs(dl)
        total = int(cnt.sum())
        if total == 0:
            continue
        seg = np.repeat(np.arange(dl.shape[0]), cnt)
        k = np.arange(total) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        sgn = np.sign(dl[seg])
        plane = lat[seg] + sgn * (k + 1)
        segs.append(seg)
        ts.append((plane - snapped[seg, axis]) / (snapped[seg + 1, axis] - snapped[seg, axis]))
        axes.append(np.full(total, axis))
        negs.append(sgn < 0)
    return segs, ts, axes, negs


def _state(dirs: list[int], end: int) -> list[int]:
    """The steps that set the reference directions after ``dirs[:end]``: [u, v], [v] or []."""
    if end == 0:
        return []
    v = dirs[end - 1]
    for k in range(end - 2, -1, -1):
        if dirs[k] // 2 != v // 2:
            return [dirs[k], v]
    return [v]


def _resolve_ties(dirs: np.ndarray, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Order each group of simultaneous steps so that the chain is lexicographically smallest.

    The chain of a candidate order is read from the reference directions reached before the group
    up to the next group of ties; it depends only on relative directions, so the choice is the same
    for every rotation of the grid. Before the first turn (u still undefined) several orders can
    code alike; they are then told apart by the next groups, resolved in turn.
    """
    same = (seg[1:] == seg[:-1]) & (np.abs(t[1:] - t[:-1]) <= _TIE_TOL)
    if not np.any(same):
        return dirs
    starts = np.flatnonzero(np.r_[True, ~same])
    bounds = np.r_[starts, dirs.shape[0]]
    groups = [(int(s0), int(s1)) for s0, s1 in zip(bounds[:-1], bounds[1:], strict=True) if s1 - s0 > 1]
    out = dirs.tolist()
    _resolve_groups(out, groups, 0, len(groups))
    return np.asarray(out, dtype=np.int64)


def _resolve_groups(out: list[int], groups: list[tuple[int, int]], g0: int, g_stop: int) -> None:
    """Resolve ``groups[g0:g_stop]`` of ``out`` in place, in order (see :func:`_resolve_ties`)."""
    for g in range(g0, min(g_stop, len(groups))):
        s0, s1 = groups[g]
        context = _state(out, s0)
        u_known = len(context) == 2
        horizon = g + 1 if u_known else min(g + 4, len(groups))
        stop = groups[horizon][0] if horizon < len(groups) else len(out)
        best = None
        for perm in itertools.permutations(out[s0:s1]):
            trial = out[: stop] if u_known else list(out)
            trial[s0:s1] = perm
            if not u_known:
                _resolve_groups(trial, groups, g + 1, horizon)
            codes = codes_from_steps(np.array(context + trial[s0:stop], dtype=np.int64))
            key = tuple(codes[max(len(context) - 1, 0):].tolist())
            if best is None or key < best[0]:
                best = (key, perm)
        assert best is not None  # the loop above ran at least once
        out[s0:s1] = list(best[1])


def grid_walk(xyz, *, step: float, origin=None, walk: str = "anchored") -> tuple[np.ndarray, np.ndarray]:
    """Unit steps of the 6-connected grid walk that follows a trajectory.

    The grid has a vertex at ``origin`` (by default the first sample, the dissertation's starting
    point A). ``walk="anchored"`` steps along an axis only when the point is a full step away from
    the current vertex (Appendix A; see the module docstring), ``walk="nearest"`` whenever it
    crosses a mid-plane between vertices. Steps within a sample interval are ordered by where
    along the segment they occur; exact ties are ordered by the relative-direction rule of the
    module docstring, so the walk is the same for the 24 rotations of the grid.

    Parameters
    ----------
    xyz : ndarray of shape (N, 3)
        Positions.
    step : float
        Grid cell size, same units as ``xyz``.
    origin : None, "mean" or array_like of shape (3,), optional
        A grid vertex: the first sample (None), the centroid ("mean": the same grid whatever the
        start of a closed curve) or a given point.
    walk : {"anchored", "nearest"}, optional
        The walk (:data:`WALKS`).

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
    if walk not in WALKS:
        raise InputError(f"unknown grid walk {walk!r}; choose one of {', '.join(WALKS)}")
    q = (xyz - _origin(xyz, origin)) / step
    segs, ts, axes, negs = (_anchored_events if walk == "anchored" else _nearest_events)(q)
    if not segs:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    seg = np.concatenate(segs)
    t = np.concatenate(ts)
    axis = np.concatenate(axes)
    neg = np.concatenate(negs)
    order = np.lexsort((axis, t, seg))
    dirs = 2 * axis[order] + neg[order].astype(np.int64)
    return _resolve_ties(dirs, seg[order], t[order]), seg[order]


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


def chain_code_3d(xyz, *, step: float | None = None, origin=None, keep_still: bool = False,
                  walk: str = "anchored") -> np.ndarray:
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
    walk : {"anchored", "nearest"}, optional
        The grid walk (see :func:`grid_walk`); "anchored" is the dissertation's Appendix A.

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
    dirs, seg = grid_walk(xyz, step=step, origin=origin, walk=walk)
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

"""Chain-code measures of two curves already in one canonical frame (see :mod:`.canonical`).

- :func:`closed_loop_chain`: the chain code of a closed loop (one stride), independent of where
  the loop starts: the anchored walk goes round twice and the second lap is kept, so the walk has
  forgotten its start;
- :func:`chain_measures`: the dissertation's Needleman-Wunsch similarity and Bribiesca & Aguilar's
  D' of two loops (or two open curves) on one common grid step.

Both measures are computed on curves of a fixed length (one stride of ``n`` samples, or a recording
resampled to ``n`` samples), so D' does not grow with the length of the recording.
"""

from __future__ import annotations

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.similarity.alignment import nw_similarity
from saddlescope.core.similarity.chain_code import codes_from_steps, grid_walk
from saddlescope.core.similarity.shape import shape_dissimilarity

__all__ = [
    "closed_loop_chain",
    "chain_measures",
]


def closed_loop_chain(loop, *, step: float, walk: str = "anchored") -> np.ndarray:
    """Chain code of a closed loop, read over its second lap.

    Parameters
    ----------
    loop : ndarray of shape (n, 3)
        One closed loop (sample n would be sample 0 again), e.g. a mean stride, centred on the
        grid's origin (mean zero).
    step : float
        Grid step, units of ``loop``.
    walk : {"anchored", "nearest"}, optional
        The grid walk (:func:`saddlescope.core.similarity.grid_walk`).

    Returns
    -------
    codes : ndarray of shape (L,), int8
        The elements of the steps made during the second lap, coded with the reference directions
        carried over from the first; empty when the loop makes no step (no motion).
    """
    x = np.asarray(loop, dtype=np.float64)
    n = x.shape[0]
    dirs, seg = grid_walk(np.vstack([x, x, x[:1]]), step=step, origin=np.zeros(3), walk=walk)
    first = int(np.searchsorted(seg, n))
    if first >= dirs.shape[0]:
        return np.zeros(0, dtype=np.int8)
    codes = codes_from_steps(dirs)
    return codes[max(first - 1, 0):]


def chain_measures(a, b, *, step: float, closed: bool = True, walk: str = "anchored") -> dict:
    """Needleman-Wunsch similarity and shape dissimilarity D' of two curves on one grid.

    Parameters
    ----------
    a, b : ndarray of shape (n, 3), (m, 3)
        Curves in one canonical frame; closed loops centred on the origin (``closed=True``) or
        open curves, both coded on a grid with a vertex at the mean of ``a``.
    step : float
        The common grid step (:func:`saddlescope.core.similarity.canonical.noise_step`).
    closed : bool, optional
        Loops (coded with :func:`closed_loop_chain`) or open curves.
    walk : {"anchored", "nearest"}, optional
        The grid walk.

    Returns
    -------
    dict
        ``chain_code_nw`` (matches / alignment length, in [0, 1]), ``shape_dissimilarity`` (D',
        0 = same shape), ``chain_length_a``, ``chain_length_b`` and ``moves_a``, ``moves_b``
        (False: the curve makes no step, "no motion"). Two still curves are alike (1, 0); a still
        and a moving curve are not (0, 1).
    """
    if not np.isfinite(step) or step <= 0:
        raise InputError(f"the grid step must be a positive length, got {step}")
    if closed:
        ca, cb = closed_loop_chain(a, step=step, walk=walk), closed_loop_chain(b, step=step, walk=walk)
        moves_a, moves_b = ca.size > 0, cb.size > 0
    else:
        origin = np.asarray(a, dtype=np.float64).mean(axis=0)
        open_a, open_b = (_open_chain(x, step, origin, walk) for x in (a, b))
        moves_a, moves_b = open_a is not None, open_b is not None
        ca = open_a if open_a is not None else np.zeros(0, dtype=np.int8)
        cb = open_b if open_b is not None else np.zeros(0, dtype=np.int8)
    out: dict[str, float | bool] = {"chain_length_a": int(ca.size), "chain_length_b": int(cb.size),
                                    "moves_a": bool(moves_a), "moves_b": bool(moves_b)}
    if ca.size == 0 or cb.size == 0:
        same = (ca.size == 0) == (cb.size == 0) and moves_a == moves_b
        out.update(chain_code_nw=1.0 if same else 0.0, shape_dissimilarity=0.0 if same else 1.0)
        return out
    out.update(chain_code_nw=float(nw_similarity(ca, cb)), shape_dissimilarity=float(shape_dissimilarity(ca, cb)))
    return out


def _open_chain(x, step: float, origin: np.ndarray, walk: str) -> np.ndarray | None:
    """Chain code of an open curve on the common grid; None if it makes no step at all."""
    dirs, _ = grid_walk(x, step=step, origin=origin, walk=walk)
    return codes_from_steps(dirs) if dirs.size else None

"""Needleman-Wunsch global alignment of chain codes and its similarity (dissertation 3.2, App. B.1).

A banded, row-vectorised dynamic programme (see :func:`needleman_wunsch`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from saddlescope.core.errors import InputError

__all__ = [
    "GAP",
    "DISSERTATION_NW_SCORES",
    "default_band",
    "needleman_wunsch",
    "alignment_similarity",
    "nw_similarity",
]

# Gap symbol of aligned integer sequences.
GAP = -1
# The dissertation's Needleman-Wunsch scores (match, mismatch, gap), chapter 3.2.
DISSERTATION_NW_SCORES = (1.0, 0.0, 0.0)


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

    Parameters
    ----------
    n, m : int
        Lengths of the two sequences.

    Returns
    -------
    int
        ``|n - m| + max(64, ceil(0.1 * max(n, m)))`` cells around the straight line from (0, 0)
        to (n, m).
    """
    return abs(n - m) + max(64, int(np.ceil(0.1 * max(n, m))))


def _nw_fill(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, match: float,
             mismatch: float, gap: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Banded score matrix, row by row; returns the score and the traceback bits per band cell.

    Rows are stored with a one-cell offset (column j at index j + 1) so that index 0 is a permanent
    -infinity and the first column needs no special case.
    """
    n, m = a.shape[0], b.shape[0]
    scale = max(abs(match), abs(mismatch), abs(gap))
    exact = all(float(x).is_integer() for x in (match, mismatch, gap)) and scale * (n + m + 2) < 2 ** 28
    dtype: Any  # np.int32 or np.float64: numpy's stubs cannot type arithmetic on either
    neg: float
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
    lo, hi = _band_limits(n, m, band)
    score, not_diag, not_up = _nw_fill(a_arr, b_arr, lo, hi, float(match), float(mismatch), float(gap))
    al_a, al_b = _traceback(a_arr, b_arr, lo, not_diag, not_up)
    if a_str and b_str:
        return score, "".join("-" if c == GAP else chr(c) for c in al_a), \
            "".join("-" if c == GAP else chr(c) for c in al_b)
    return score, al_a, al_b


def _band_limits(n: int, m: int, band: int | None) -> tuple[np.ndarray, np.ndarray]:
    """First and last column (n + 1,) of the band in each row of the score matrix."""
    r = default_band(n, m) if band is None else int(band)
    if r < 1:
        raise InputError(f"band must be at least 1 cell, got {band}")
    r = max(r, int(np.ceil(m / n)), 1)  # consecutive rows' bands must touch
    centre = np.arange(n + 1) * (m / n)
    lo = np.clip(np.ceil(centre - r).astype(np.int64), 0, m)
    hi = np.clip(np.floor(centre + r).astype(np.int64), 0, m)
    lo[0], hi[-1] = 0, m
    return lo, hi


def _traceback(a_arr: np.ndarray, b_arr: np.ndarray, lo: np.ndarray, not_diag: np.ndarray,
               not_up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The aligned sequences, ``GAP`` in the gaps, traced back from the end through the band's bits.

    Ties prefer a diagonal move, then a gap in ``b``, then a gap in ``a``.
    """
    n, m = a_arr.shape[0], b_arr.shape[0]
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
    return np.array(out_a[::-1], dtype=np.int64), np.array(out_b[::-1], dtype=np.int64)


def alignment_similarity(aligned_a, aligned_b) -> float:
    """Fraction of aligned positions holding the same symbol (dissertation Appendix B.1).

    Parameters
    ----------
    aligned_a, aligned_b : ndarray of shape (L,) or str
        The aligned sequences of :func:`needleman_wunsch`.

    Returns
    -------
    float
        Matches / alignment length (gaps count as positions), in [0, 1]; 1 for identical
        alignments.
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

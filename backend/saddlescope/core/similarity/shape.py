"""Shape dissimilarity of two chain codes (Bribiesca & Aguilar 2006 as the dissertation implements it).

The maximal common sub-chains are found from exact k-mer seeds merged along the diagonals
(:func:`maximal_matches`), then scored and chosen as in the dissertation's eq. 1-6
(:func:`shape_dissimilarity`).
"""

from __future__ import annotations

import numpy as np

from saddlescope.core.errors import InputError
from saddlescope.core.similarity.chain_code import CODE_STILL, _as_codes, accumulated_directions

__all__ = [
    "maximal_matches",
    "shape_dissimilarity",
]


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
    """Index of the second non-zero element before each position p of ``[9, 9] + x``.

    The two 9s are the imaginary non-zero elements before every chain; 0 where there is none.
    """
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
    d_prime, nes, net, delta = _couple_scores(a, b, i, j, length)
    order = np.lexsort((j, i, d_prime))
    chosen, cover_a, cover_b = _choose_couples(order, i, j, length, nes, net, m, n)
    chosen_arr = np.array(chosen, dtype=np.int64)
    similar = float(d_prime[chosen_arr].sum()) if chosen else 0.0  # eq. 3
    unmatched = (m + 2 - int(cover_a.sum())) + (n + 2 - int(cover_b.sum()))  # eq. 4
    dissimilarity = (similar + unmatched) / (m + n + 4)  # eq. 5-6
    if not return_couples:
        return dissimilarity
    couples = [{"i": int(i[c]), "j": int(j[c]), "length": int(length[c]), "d_prime": float(d_prime[c]),
                "nes": int(nes[c]), "net": int(net[c]), "delta": int(delta[c])} for c in chosen]
    return dissimilarity, couples


def _couple_scores(a: np.ndarray, b: np.ndarray, i: np.ndarray, j: np.ndarray, length: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The d' (eq. 1-2), nes, net and Delta of each common couple (C,) at i in ``a``, j in ``b``."""
    m, n = a.shape[0], b.shape[0]
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
    return d / (m + n), nes, net, delta  # eq. 2


def _choose_couples(order: np.ndarray, i: np.ndarray, j: np.ndarray, length: np.ndarray, nes: np.ndarray,
                    net: np.ndarray, m: int, n: int) -> tuple[list[int], np.ndarray, np.ndarray]:
    """Couples taken in ``order`` unless their P lies inside an already chosen P (step 3).

    Returns the chosen couples' indices and the elements of ``a`` (m + 2,) and ``b`` (n + 2,), two
    imaginary ones first, that the chosen P's and their preceding elements cover.
    """
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
    return chosen, cover_a, cover_b

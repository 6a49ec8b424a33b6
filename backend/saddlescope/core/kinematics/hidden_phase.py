"""Markers hidden at the same moment of every stride: the stride's unmeasured share, and when to refuse.

A rider's boot, a swishing tail or a lunge line passing over a marker leaves the same part of every stride
unmeasured however many strides are filmed (issue 38): the fits bend freely there. This module measures that
share of the stride's phase, names the marker hidden longest by its place on the horse, and words the refusal
of a ride whose markers were never seen together for a whole stride because one kept hiding.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from saddlescope.core.errors import KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.vibration.weighting import weighting_response

__all__ = ["DELETIONS", "DELETION_KEYS", "UNMEASURED_PHASE_LIMIT", "PhaseDeletionTest", "deletion_masks",
           "harmonic_indicators", "hidden_marker_refusal", "phase_coverage", "phase_deletion_test",
           "unmeasured_phase"]


# A marker hidden at the same moment of every stride (a rider's boot, a tail) leaves that part of the stride
# unmeasured however many strides are filmed: the fits bend freely there. From this share of the stride on,
# the ride says so (kinematics.stride_phase_unmeasured) and its intervals grow with the share
# (core.vibration.intervals, "unmeasured_phase").
UNMEASURED_PHASE_LIMIT = 0.1
_SHARE_WORDS = ((0.1, "a tenth"), (0.125, "an eighth"), (1 / 6, "a sixth"), (0.2, "a fifth"), (0.25, "a quarter"),
                (1 / 3, "a third"), (0.5, "half"))
_POSITION_WORDS = {3: ("front", "middle", "rear"), 2: ("front", "rear")}


def _share_words(share: float) -> str:
    """A share of the stride in words ("a fifth"), the nearest of the common fractions."""
    return min(_SHARE_WORDS, key=lambda sw: abs(sw[0] - share))[1]


def phase_coverage(t_s: np.ndarray, measured: np.ndarray, period_s: float) -> float:
    """The share (0-1) of the stride's phase that the measured samples reach, folded over the strides.

    The stride is cut into as many bins as a stride holds frame intervals (rounded down: every bin then
    holds a sample of a wholly measured stride); a bin counts where any measured sample falls.
    """
    t = np.asarray(t_s, dtype=np.float64)
    if t.size < 2 or not np.isfinite(period_s) or period_s <= 0:
        return 0.0
    return float(_phase_hits(t, measured, period_s)[1].mean())


def _phase_bins(t: np.ndarray, period_s: float) -> tuple[np.ndarray, int]:
    """Each sample's bin of the stride's phase (F,), and the bins a stride holds (one per frame interval)."""
    dt = float(np.median(np.diff(t)))
    n_bins = max(4, int(np.floor(period_s / dt + 1e-9)))
    phase = ((t - t[0]) / period_s) % 1.0
    return np.minimum((phase * n_bins).astype(int), n_bins - 1), n_bins


def _phase_hits(t: np.ndarray, measured: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's phase bin (F,) and whether any measured sample falls in each bin (n_bins,)."""
    bins, n_bins = _phase_bins(t, period_s)
    hit = np.zeros(n_bins, bool)
    hit[bins[np.asarray(measured, bool)]] = True
    return bins, hit


def _marker_positions(along_travel: np.ndarray) -> dict[int, str]:
    """Each marker's place on the horse in words ("front", "middle", "rear").

    ``along_travel`` (M,): each marker's mean position along the direction of travel (NaN: never seen).
    """
    n = along_travel.shape[0]
    order = np.argsort(-np.nan_to_num(along_travel, nan=-np.inf))  # front (farthest along the travel) first
    words = _POSITION_WORDS.get(n, tuple(f"number {i + 1}" for i in range(n)))
    return {int(m): words[rank] for rank, m in enumerate(order)}


def _along_travel(xyz: np.ndarray) -> np.ndarray:
    """Each marker's mean position (M,) along the markers' own direction of travel, ``xyz`` (F, M, 3) any frame."""
    with np.errstate(invalid="ignore"):
        centre = np.nanmean(xyz, axis=1)  # (F, 3): the markers seen at each frame
    ok = np.flatnonzero(np.all(np.isfinite(centre), axis=1))
    travel = centre[ok[-1]] - centre[ok[0]] if ok.size > 1 else np.zeros(3)
    if not np.linalg.norm(travel) > 0:
        return np.full(xyz.shape[1], np.nan)
    with np.errstate(invalid="ignore"):
        return np.nanmean((xyz - centre[:, None, :]) @ (travel / np.linalg.norm(travel)), axis=0)


def hidden_marker_refusal(t_s: np.ndarray, xyz: np.ndarray, run_s: float, period_s: float, *,
                          min_hidden: float = 0.1) -> KinematicsError | None:
    """The refusal of a ride whose markers were seen together for less than a stride because one kept hiding.

    Over the frames from the first to the last where any marker is tracked (``xyz`` (F, M, 3) in the motion
    frame), the share of the frames where the others are seen but one marker is not; from ``min_hidden``
    on, the marker hidden most is named (a rider's boot, a tail): "record a longer ride" would not help.
    None where no marker kept hiding.
    """
    seen = np.all(np.isfinite(xyz), axis=2)  # (F, M)
    anything = np.flatnonzero(seen.any(axis=1))
    if anything.size < 2 or seen.shape[1] < 2:
        return None
    span = seen[anything[0]: anything[-1] + 1]
    others = np.array([np.all(np.delete(span, m, axis=1), axis=1) for m in range(span.shape[1])])  # (M, F')
    hidden = np.array([float(np.mean(~span[others[m], m])) if others[m].any() else 0.0
                       for m in range(span.shape[1])])
    worst = int(np.argmax(hidden))
    if hidden[worst] < min_hidden:
        return None
    name = _marker_positions(_along_travel(xyz))[worst]
    return KinematicsError(
        f"the {name} marker was hidden again and again ({100 * hidden[worst]:.0f} % of the frames where the other "
        f"markers were seen): the markers were seen together for at most {run_s:.2f} s, less than one stride of "
        f"{period_s:.2f} s; place the {name} marker where the rider's leg, the tail or a lunge line does not pass, "
        "and film the ride again")


# The phase-deletion test: what a gap of the hidden part's width costs THIS ride's indicators. The ride's
# own fitted frames are refitted, exactly as the analysis fits them, with as much of the stride left out at
# DELETIONS other moments spread over the measured part (the caller's refit fills the hidden part with the
# analysis's own fit, so each refit has one gap as the analysis had); the spread of the indicators' changes
# is the cost the intervals carry (core.vibration.intervals, FLOORS["unmeasured_phase_deletion_one_gap"]). A fixed
# cost per share was blunt: a fifth of the stride hidden moved the field table's trots and canters by at
# most 4.7 % while it put ±18-24 % on them, and said nothing of the one-stride canter it moved by +88 %.
DELETIONS = 6
DELETION_KEYS = ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "amplitude_y_m")
# below this many strides fitted, most phases are measured once: a deletion removes their only measurement
# and the refit says nothing of one gap's cost (the field table's one-stride boot rides, 1.15-1.23 strides,
# gave median changes of 14-20 % where the boot cost 2-5 %); such rides are marked (docs/accuracy.md)
MIN_STRIDES_TESTED = 1.5
_VDV_GRID = 512


@dataclass(frozen=True)
class PhaseDeletionTest:
    """What leaving out as much of the stride at other moments did to the indicators.

    ``changes``: per key of :data:`DELETION_KEYS`, the relative change of each deletion; ``median_change``:
    the largest over the keys of their median size, ``max_change`` the largest one; ``reason`` says why
    the test could not be done (``tested`` False); ``seconds`` what the refits took.

    The median, not the r.m.s. or the largest: at some phases a second gap and the hidden part together
    leave a stretch of the stride the fits cannot bridge, and one deletion of six moves W_b by 15-117 %
    where the hidden part alone cost 1.4-7 % (exact-marker rides, docs/accuracy.md): that measures two
    gaps, not the one.
    """

    tested: bool
    changes: Mapping[str, tuple[float, ...]] = field(default_factory=dict)
    median_change: float = float("nan")
    max_change: float = float("nan")
    reason: str = ""
    seconds: float = 0.0

    def as_quality(self) -> dict:
        """The test as the result's ``quality["stride_phase_deletion"]`` (JSON: no NaN).

        ``method`` "one_gap": each refit had the hidden part filled by the analysis's own fit and one window
        left out elsewhere; results stored without it were refitted with both gaps (their factor is
        ``FLOORS["unmeasured_phase_deletion"]``, this one's ``FLOORS["unmeasured_phase_deletion_one_gap"]``).
        """
        return {"tested": self.tested, "method": "one_gap", "deletions": len(next(iter(self.changes.values()), ())),
                "median_change": self.median_change if self.tested else None,
                "max_change": self.max_change if self.tested else None, "reason": self.reason,
                "seconds": self.seconds, "changes": {k: list(v) for k, v in self.changes.items()}}


def harmonic_indicators(harm: Mapping) -> dict[str, float]:
    """W_b and W_k r.m.s., the W_b VDV over one stride and the peak-to-peak displacement of a vertical series.

    ``harm``: ``core.saddle.vertical_harmonics``'s ``f0_hz``, ``amplitudes_m_s2``, ``phases_rad`` and
    ``amplitude_y_m``. The VDV is per stride: only its relative changes are read.
    """
    f0 = float(harm["f0_hz"])
    coef = np.asarray(harm["amplitudes_m_s2"], float) * np.exp(1j * np.asarray(harm["phases_rad"], float))
    k = np.arange(1, coef.size + 1)
    out = {}
    for name, key in (("Wb", "acc_y_wb_rms"), ("Wk", "acc_y_wk_rms")):
        weighted = coef * weighting_response(name, f0 * k)
        out[key] = float(np.sqrt(np.sum(np.abs(weighted) ** 2) / 2))
        if name == "Wb":
            theta = np.outer(k, 2 * np.pi * np.arange(_VDV_GRID) / _VDV_GRID)
            a = weighted.real @ np.cos(theta) - weighted.imag @ np.sin(theta)
            out["vdv_y_wb"] = float((np.mean(a ** 4) / f0) ** 0.25)
    out["amplitude_y_m"] = float(harm["amplitude_y_m"])
    return out


def deletion_masks(t_s: np.ndarray, measured: np.ndarray, period_s: float, n_deletions: int = DELETIONS
                   ) -> tuple[list[np.ndarray], str]:
    """Up to ``n_deletions`` windows as wide as the unmeasured part of the stride, at other phases.

    ``measured`` (F,) the fitted frames where every marker was measured. Each window (a mask of the
    fitted frames (F,)) lies wholly in the measured part of the stride, the windows spread over it from
    one edge of the gap to the other. Returns (masks, why none could be placed, or "").
    """
    t = np.asarray(t_s, dtype=np.float64)
    _, hit = _phase_hits(t, measured, period_s)
    n_bins = hit.size
    width = int(n_bins - hit.sum())
    if width == 0:
        return [], ""
    # each window apart from the gap by its own width where the measured part allows: a window touching
    # the gap tests a gap twice as wide, which the fits bridge far worse (a trot's W_b moved by 8 % r.m.s.
    # where the gap itself cost 1 %)
    for margin in (width, width // 2, 0):
        starts = [s for s in range(n_bins) if hit[(s - margin + np.arange(width + 2 * margin)) % n_bins].all()]
        if len(starts) >= 2:
            break
    if len(starts) < 2:
        return [], "the part of the stride that was measured is too short to leave as much out elsewhere"
    chosen = np.unique(np.round(np.linspace(0, len(starts) - 1, min(n_deletions, len(starts)))).astype(int))
    # by the samples' own phase, not their bins: a stride rarely holds a whole number of frames, so the
    # bins drift over the strides and the gap's bins hold fewer than the frames it hid: each window is as
    # wide as the share of the fitted frames left unmeasured, if wider
    phase = ((t - t[0]) / period_s) % 1.0
    wide = max(width / n_bins, float(np.mean(~np.asarray(measured, bool))))
    return [((phase - starts[c] / n_bins) % 1.0) < wide for c in chosen], ""


def phase_deletion_test(t_s: np.ndarray, measured: np.ndarray, period_s: float,
                        refit: Callable[[np.ndarray], Mapping], base: Mapping, *,
                        n_deletions: int = DELETIONS, min_strides: float = MIN_STRIDES_TESTED) -> PhaseDeletionTest:
    """The phase-deletion test of a ride whose fitted frames ``t_s`` (F,) left part of the stride unmeasured.

    ``measured`` (F,): the frames where every marker was measured; ``refit(deleted)`` gives the vertical
    harmonics (``core.saddle.vertical_harmonics``) refitted with the frames ``deleted`` (F,) also left out,
    ``base`` the analysis's own. A refit that fails, or fits that saw fewer than ``min_strides`` strides,
    leave the test undone (``tested`` False, with the reason).
    """
    start = time.perf_counter()
    t = np.asarray(t_s, dtype=np.float64)
    strides = float((t[-1] - t[0] + np.median(np.diff(t))) / period_s)
    if strides < min_strides:
        return PhaseDeletionTest(False, reason=f"the fits saw {strides:.1f} strides, too few to measure what the "
                                 "hidden part costs")
    masks, reason = deletion_masks(t, measured, period_s, n_deletions)
    if not masks:
        return PhaseDeletionTest(False, reason=reason or "no part of the stride was left unmeasured")
    ref = harmonic_indicators(base)
    changes: dict[str, list[float]] = {key: [] for key in DELETION_KEYS}
    for mask in masks:
        try:
            values = harmonic_indicators(refit(mask))
        except (KinematicsError, np.linalg.LinAlgError, ValueError) as exc:
            return PhaseDeletionTest(False, reason=f"the fits could not be redone with more of the stride left out "
                                     f"({exc})", seconds=time.perf_counter() - start)
        for key in DELETION_KEYS:
            changes[key].append(values[key] / ref[key] - 1.0 if ref[key] > 0 else float("nan"))
    arr = np.array([changes[key] for key in DELETION_KEYS])  # (keys, deletions)
    if not np.all(np.isfinite(arr)):
        return PhaseDeletionTest(False, reason="the refitted indicators were not finite",
                                 seconds=time.perf_counter() - start)
    return PhaseDeletionTest(True, {k: tuple(v) for k, v in changes.items()},
                             median_change=float(np.max(np.median(np.abs(arr), axis=1))),
                             max_change=float(np.max(np.abs(arr))), seconds=time.perf_counter() - start)


def unmeasured_phase(t_s: np.ndarray, measured: np.ndarray, xyz_m: np.ndarray, period_s: float,
                     flags: list[Finding], *, refit: Callable[[np.ndarray], Mapping] | None = None,
                     base: Mapping | None = None) -> dict:
    """The share of the stride's phase the fits saw no measurement of, overall and per marker, and its cost.

    ``measured`` (F, M) marks each marker's own measured samples over the fitted frames ``t_s`` (F,);
    ``xyz_m`` (F, M, 3) in the motion frame orders the markers front to rear (x is the travel). The fits
    use the frames where every marker is measured. Where part of the stride was unmeasured and ``refit``
    and ``base`` are given (:func:`phase_deletion_test`), ``deletion`` holds the test
    (:meth:`PhaseDeletionTest.as_quality`; None where it could not be done below
    :data:`UNMEASURED_PHASE_LIMIT`: such a share keeps the fixed cost). From that share on, appends
    ``kinematics.stride_phase_unmeasured`` naming the marker hidden longest with what the test measured,
    or ``kinematics.stride_phase_untested`` where the test could not be done (the ride is then too
    uncertain).
    """
    measured = np.asarray(measured, bool)
    together = np.all(measured, axis=1)
    share = 1.0 - phase_coverage(t_s, together, period_s)
    per_marker = [1.0 - phase_coverage(t_s, measured[:, m], period_s) for m in range(measured.shape[1])]
    with np.errstate(invalid="ignore"):
        position = _marker_positions(np.array([np.nanmean(xyz_m[:, m, 0]) if np.isfinite(xyz_m[:, m, 0]).any()
                                               else np.nan for m in range(measured.shape[1])]))
    out: dict = {"share": share, "per_marker": {position[m]: per_marker[m] for m in range(len(per_marker))}}
    test = None
    if share > 0 and refit is not None and base is not None:
        test = phase_deletion_test(t_s, together, period_s, refit, base)
        out["deletion"] = test.as_quality() if test.tested or share >= UNMEASURED_PHASE_LIMIT else None
    if share >= UNMEASURED_PHASE_LIMIT:
        worst = int(np.argmax(per_marker))
        flags.append(_unmeasured_finding(share, per_marker[worst], position[worst], test))
    return out


def _unmeasured_finding(share: float, hidden: float, name: str, test: PhaseDeletionTest | None) -> Finding:
    """The finding of a stride phase no fitted frame measured, with what the phase-deletion test found."""
    if hidden >= 0.5 * share:
        where = f"the {name} marker was hidden for {_share_words(hidden)} of every stride ({100 * hidden:.0f} %)"
        place = f"place the {name} marker"
    else:
        where = f"the markers were not all seen for {_share_words(share)} of every stride ({100 * share:.0f} %)"
        place = "place the markers"
    values = {"unmeasured_share": share, "hidden_share": hidden, "limit_share": UNMEASURED_PHASE_LIMIT}
    advice = f"{place} where the rider's leg, the tail or a lunge line does not pass"
    if test is None:  # no refit offered (a caller of the fits alone): the share's fixed cost
        return Finding("kinematics.stride_phase_unmeasured",
                       f"{where}: the fits guess the stride's motion there; {advice}", values)
    if not test.tested:
        return Finding("kinematics.stride_phase_untested",
                       f"{where}, and {test.reason}: the fits guess the stride's motion there, so the ride is too "
                       f"uncertain; {advice}", values)
    n = len(test.changes[DELETION_KEYS[0]])
    return Finding("kinematics.stride_phase_unmeasured",
                   f"{where}: leaving as much of the stride out at {n} other moments moved the indicators by "
                   f"a median {100 * test.median_change:.1f} % (at most {100 * test.max_change:.1f} %), which their "
                   f"intervals carry; {advice}",
                   {**values, "deletion_median_change": test.median_change, "deletion_max_change": test.max_change,
                    "deletions": float(n)})

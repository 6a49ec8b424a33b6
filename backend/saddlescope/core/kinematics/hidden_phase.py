"""Markers hidden at the same moment of every stride: the stride's unmeasured share, and when to refuse.

A rider's boot, a swishing tail or a lunge line passing over a marker leaves the same part of every stride
unmeasured however many strides are filmed (issue 38): the fits bend freely there. This module measures that
share of the stride's phase, names the marker hidden longest by its place on the horse, and words the refusal
of a ride whose markers were never seen together for a whole stride because one kept hiding.
"""

from __future__ import annotations

import numpy as np

from saddlescope.core.errors import KinematicsError
from saddlescope.core.findings import Finding

__all__ = ["UNMEASURED_PHASE_LIMIT", "hidden_marker_refusal", "phase_coverage", "unmeasured_phase"]


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
    dt = float(np.median(np.diff(t)))
    n_bins = max(4, int(np.floor(period_s / dt + 1e-9)))
    phase = ((t - t[0]) / period_s) % 1.0
    bins = np.minimum((phase * n_bins).astype(int), n_bins - 1)
    hit = np.zeros(n_bins, bool)
    hit[bins[np.asarray(measured, bool)]] = True
    return float(hit.mean())


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


def unmeasured_phase(t_s: np.ndarray, measured: np.ndarray, xyz_m: np.ndarray, period_s: float,
                     flags: list[Finding]) -> dict:
    """The share of the stride's phase the fits saw no measurement of, overall and per marker.

    ``measured`` (F, M) marks each marker's own measured samples over the fitted frames ``t_s`` (F,);
    ``xyz_m`` (F, M, 3) in the motion frame orders the markers front to rear (x is the travel). The fits
    use the frames where every marker is measured. Appends ``kinematics.stride_phase_unmeasured`` when the
    share reaches :data:`UNMEASURED_PHASE_LIMIT`, naming the marker hidden longest.
    """
    measured = np.asarray(measured, bool)
    share = 1.0 - phase_coverage(t_s, np.all(measured, axis=1), period_s)
    per_marker = [1.0 - phase_coverage(t_s, measured[:, m], period_s) for m in range(measured.shape[1])]
    with np.errstate(invalid="ignore"):
        position = _marker_positions(np.array([np.nanmean(xyz_m[:, m, 0]) if np.isfinite(xyz_m[:, m, 0]).any()
                                               else np.nan for m in range(measured.shape[1])]))
    out = {"share": share, "per_marker": {position[m]: per_marker[m] for m in range(len(per_marker))}}
    if share >= UNMEASURED_PHASE_LIMIT:
        worst = int(np.argmax(per_marker))
        hidden = per_marker[worst]
        if hidden >= 0.5 * share:
            where = (f"the {position[worst]} marker was hidden for {_share_words(hidden)} of every stride "
                     f"({100 * hidden:.0f} %)")
        else:
            where = f"the markers were not all seen for {_share_words(share)} of every stride ({100 * share:.0f} %)"
        flags.append(Finding(
            "kinematics.stride_phase_unmeasured",
            f"{where}: the fits guess the stride's motion there, so the ride is too uncertain; place the "
            f"markers where the rider's leg, the tail or a lunge line does not pass",
            {"unmeasured_share": share, "hidden_share": hidden, "limit_share": UNMEASURED_PHASE_LIMIT}))
    return out

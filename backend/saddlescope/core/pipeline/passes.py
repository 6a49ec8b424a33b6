"""Rides of several passes in front of the cameras: each pass found, analysed, and their strides pooled (issue 38).

A club's natural ride is one long motion clip in which the horse goes round the arena's track and passes the
cameras several times, leaving their view in between. One crossing of a wide rig's common view holds one or
two canter strides; the fits of one stride leave its indicators' random error large. Here:

- :func:`find_passes` cuts the motion clip's 3-D tracks into passes: runs of frames with every marker,
  separated by at least :data:`PASS_GAP_S` without them (a marker lost for a few frames inside a pass is
  bridged by the kinematics, not a new pass);
- :func:`analyse_passes` analyses each pass on its own (its own stride period, window, phase and fits); a
  pass too short to fit is left out with the reason;
- :func:`pool_passes` pools the used passes' strides: the vertical acceleration's harmonics of every pass,
  shifted onto the reference pass's stride phase, are averaged with the passes' strides as weights, and the
  indicators follow from the pooled harmonics; the ride's speed is the mean of the passes' (each pass counts
  once). The intervals' random parts (the fits' noise, the stride frequency's, the speed's) shrink with the
  strides pooled; their systematic parts (calibration scale, skin motion, the harmonics' shape, lens,
  depth) do not: the skin's sliding repeats stride after stride, pass after pass.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields, replace

import numpy as np

from saddlescope.core.errors import KinematicsError
from saddlescope.core.findings import Finding
from saddlescope.core.params import PipelineParams
from saddlescope.core.saddle import SaddleAnalysis, kinematics_indicators
from saddlescope.core.types import MarkerTracks, RidePass, RideResult, VerticalHarmonics
from saddlescope.core.vibration import ride_indicators
from saddlescope.core.vibration.intervals import FLOORS, interval_sources

__all__ = ["PASS_GAP_S", "PassAnalysis", "analyse_passes", "aligned_harmonics", "find_passes", "pass_strides",
           "pool_passes", "pooled_sources", "slice_tracks"]

# Two runs of tracked frames further apart than this are two passes (the horse left the view); a shorter
# loss is a marker hidden inside one pass (a pole, a look-alike), which the kinematics bridges or reports.
PASS_GAP_S = 1.0
_MIN_PASS_FRAMES = 8  # fewer tracked frames are no pass (a look-alike triple for a few frames)
# the per-pass indicators the result's ``passes`` list carries
PASS_INDICATORS: tuple[str, ...] = ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vdv_y_wk", "amplitude_y_m",
                                    "vel_x_avg_kmh", "stride_frequency_hz")


@dataclass(frozen=True)
class PassAnalysis:
    """One pass: its frames [start, stop) of the motion clip, and its kinematics, or why it was left out."""

    span: tuple[int, int]
    kin: SaddleAnalysis | None
    harm: dict | None
    indicators: dict | None
    reason: str | None = None

    @property
    def strides(self) -> int:
        """The whole strides the pass's fits saw (0 when left out)."""
        return pass_strides(self.kin) if self.kin is not None else 0


def find_passes(t_s: np.ndarray, xyz_mm: np.ndarray, *, min_gap_s: float = PASS_GAP_S) -> list[tuple[int, int]]:
    """The passes of a motion clip: [start, stop) frames from a pass's first to its last frame with every marker.

    ``t_s`` (F,) s and ``xyz_mm`` (F, M, 3) with NaN where a marker is not tracked. Two frames with every
    marker more than ``min_gap_s`` apart, with none between, end one pass and start the next.
    """
    t = np.asarray(t_s, dtype=np.float64)
    valid = np.all(np.isfinite(np.asarray(xyz_mm, dtype=np.float64)), axis=(1, 2))
    idx = np.flatnonzero(valid)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(t[idx]) > min_gap_s)
    starts = [int(idx[0])] + [int(idx[b + 1]) for b in breaks]
    stops = [int(idx[b]) + 1 for b in breaks] + [int(idx[-1]) + 1]
    return [(a, b) for a, b in zip(starts, stops, strict=True) if valid[a:b].sum() >= _MIN_PASS_FRAMES]


def slice_tracks(tracks: MarkerTracks, start: int, stop: int) -> MarkerTracks:
    """The tracks' frames [start, stop): every per-frame array cut, whatever the tracks' class."""
    n = len(tracks.t_s)
    cut = {f.name: getattr(tracks, f.name)[start:stop] for f in fields(tracks)
           if isinstance(getattr(tracks, f.name), np.ndarray) and getattr(tracks, f.name).shape[:1] == (n,)}
    return replace(tracks, **cut)


def pass_strides(kin: SaddleAnalysis) -> int:
    """The whole strides the fits of ``kin`` saw (its fitted span over the stride period, at least 1)."""
    dt = float(np.median(np.diff(kin.t_s))) if len(kin.t_s) > 1 else 0.0
    return max(1, int(math.floor((kin.fitted[1] - kin.fitted[0]) * dt / kin.period_s + 1e-6)))


def analyse_passes(tracks: MarkerTracks, spans: Sequence[tuple[int, int]],
                   analyse: Callable[[MarkerTracks], SaddleAnalysis], params: PipelineParams) -> list[PassAnalysis]:
    """Each pass analysed on its own frames by ``analyse`` (the saddle's kinematics), with its indicators.

    A pass whose kinematics fail (too short for a stride, too few frames) is kept with the reason and no
    kinematics. Frame indices (window, fitted span) are shifted back onto the whole clip.
    """
    out = []
    for start, stop in spans:
        try:
            kin = analyse(slice_tracks(tracks, start, stop))
        except KinematicsError as exc:
            out.append(PassAnalysis((start, stop), None, None, None, str(exc)))
            continue
        kin = replace(kin, window=(kin.window[0] + start, kin.window[1] + start),
                      fitted=(kin.fitted[0] + start, kin.fitted[1] + start))
        harm, indicators = kinematics_indicators(kin, params)
        out.append(PassAnalysis((start, stop), kin, harm, indicators))
    return out


def aligned_harmonics(amplitudes: Sequence[np.ndarray], phases: Sequence[np.ndarray], weights: Sequence[float],
                      reference: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The weighted mean of several passes' harmonic series, each shifted onto the reference's stride phase.

    Each pass's series a(t) = sum_k A_k cos(k w t + phi_k) is on its own clock: the shift theta (rad of
    the stride) maximising its correlation with the reference's, phi_k + k theta, puts it on the
    reference's. Harmonics a pass does not have count for the others only.

    Returns (amplitudes (K,), phases (K,) rad, per harmonic the weight that carried it (K,)).
    """
    n_k = max(len(a) for a in amplitudes)
    coef = np.zeros((len(amplitudes), n_k), complex)
    have = np.zeros((len(amplitudes), n_k), bool)
    for i, (a, p) in enumerate(zip(amplitudes, phases, strict=True)):
        coef[i, :len(a)] = np.asarray(a, float) * np.exp(1j * np.asarray(p, float))
        have[i, :len(a)] = True
    k = np.arange(1, n_k + 1)
    theta = np.linspace(0.0, 2 * np.pi, 3600, endpoint=False)
    shift = np.exp(1j * np.outer(theta, k))  # (G, K)
    for i in range(len(amplitudes)):
        if i != reference:
            score = np.real(shift @ (np.conj(coef[reference]) * coef[i]))
            coef[i] = coef[i] * shift[int(np.argmax(score))]
    w = np.asarray(weights, float)[:, None] * have
    pooled = np.sum(w * coef, axis=0) / np.maximum(np.sum(w, axis=0), 1e-12)
    return np.abs(pooled), np.angle(pooled), np.sum(w, axis=0)


def pooled_sources(results: Sequence[RideResult], weights: Sequence[float]) -> dict:
    """The intervals' noise model for the pooled passes, from each pass's own (``interval_sources``).

    Random parts shrink as a weighted mean's: the fits' per-harmonic noise (stride weights), the stride
    frequency's beyond its floor, the speed's fit (a plain mean of the passes). Systematic parts (the common
    gain's: calibration scale, skin, lens, depth, unmeasured phase; the harmonics' shape; the peaks' and
    displacement's floors) are the passes' stride-weighted mean: more strides do not remove them; the hidden
    stride phase's part is the weighted median of the passes that measured it (:func:`_pooled_unmeasured_phase`).
    """
    srcs = [interval_sources(r, depth_anisotropy=r.quality.get("depth_anisotropy")) for r in results]
    w = np.asarray(weights, float)
    w_sum = float(w.sum())

    def mean(values) -> float:
        return float(np.sum(w * np.asarray(values, float)) / w_sum)

    parts = {key: mean([s["gain_parts"][key] for s in srcs]) for key in srcs[0]["gain_parts"]}
    parts["unmeasured_phase"] = _pooled_unmeasured_phase(results, [s["gain_parts"]["unmeasured_phase"] for s in srcs],
                                                         w)
    n_k = max(len(s["harmonic_m_s2"]) for s in srcs)
    var = np.zeros(n_k)
    carried = np.zeros(n_k)
    for w_i, s in zip(w, srcs, strict=True):
        sig = np.asarray(s["harmonic_m_s2"], float)
        var[:sig.size] += (w_i * sig) ** 2
        carried[:sig.size] += w_i
    f0_random = [max(s["f0"] ** 2 - FLOORS["f0"] ** 2, 0.0) for s in srcs]
    speed_sys = [s["gain_parts"]["calibration_scale"] ** 2 + FLOORS["speed"] ** 2
                 + (FLOORS["speed_outside_board"] * s["outside_board_share"] ** 2) ** 2 for s in srcs]
    speed_random = [max(s["speed"] ** 2 - sys, 0.0) for s, sys in zip(srcs, speed_sys, strict=True)]
    n = len(srcs)
    return {
        "gain": float(np.sqrt(sum(v ** 2 for v in parts.values()))), "gain_parts": parts,
        "harmonic_m_s2": np.sqrt(var) / np.maximum(carried, 1e-12),
        "shape": srcs[0]["shape"], "peak": mean([s["peak"] for s in srcs]),
        "displacement": mean([s["displacement"] for s in srcs]),
        "f0": float(np.hypot(np.sqrt(np.sum(w ** 2 * np.asarray(f0_random))) / w_sum, FLOORS["f0"])),
        "speed": float(np.sqrt(np.sum(speed_random) / n ** 2 + np.mean(speed_sys))),
        "depth_anisotropy": srcs[0]["depth_anisotropy"],
        "outside_board_share": mean([s["outside_board_share"] for s in srcs]),
    }


def _pooled_unmeasured_phase(results: Sequence[RideResult], parts: Sequence[float], weights: np.ndarray) -> float:
    """The pooled common gain's part for a stride phase hidden in every pass: the passes' weighted median.

    A boot over a marker hides the same phase in every pass, so each pass whose phase-deletion test was done
    measures the same cost; one pass with one stride in its window can answer 15 times its peers (field ride
    s3219: ±94 % where the passes' W_b agreed within 0.8 %), which a mean hands to the whole ride. Passes whose
    test could not be done do not vote while another pass's was; if none was done, the stride-weighted mean.
    """
    tested = [bool(((r.quality or {}).get("stride_phase_deletion") or {}).get("tested")) for r in results]
    values, w = np.asarray(parts, float), np.asarray(weights, float)
    if not any(tested):
        return float(np.sum(w * values) / np.sum(w))
    values, w = values[np.asarray(tested)], w[np.asarray(tested)]
    order = np.argsort(values)
    values, cumulative = values[order], np.cumsum(w[order])
    i = int(np.searchsorted(cumulative, 0.5 * cumulative[-1]))
    if np.isclose(cumulative[i], 0.5 * cumulative[-1]) and i + 1 < values.size:
        return float(0.5 * (values[i] + values[i + 1]))  # an even split (two passes alike): their mean
    return float(values[i])


def _pooled_indicators(analyses: Sequence[PassAnalysis], reference: int, params: PipelineParams
                       ) -> tuple[dict, VerticalHarmonics]:
    """The ride's indicators from the pooled harmonics, and those harmonics."""
    weights = [a.strides for a in analyses]
    harms = [a.harm for a in analyses if a.harm is not None]
    amps, phases, _ = aligned_harmonics([h["amplitudes_m_s2"] for h in harms], [h["phases_rad"] for h in harms],
                                        weights, reference)
    f0 = float(np.average([h["f0_hz"] for h in harms], weights=weights))
    speed_m_s = float(np.mean([abs(a.kin.fits.average_speed_m_s) for a in analyses if a.kin is not None]))
    amplitude_y = float(np.average([h["amplitude_y_m"] for h in harms], weights=weights))
    indicators = ride_indicators(f0_hz=f0, acc_y_amplitudes_m_s2=amps.tolist(), acc_y_phases_rad=phases.tolist(),
                                 duration_s=params.n_periods / f0, speed_kmh=speed_m_s * 3.6,
                                 amplitude_y_m=amplitude_y, stride_frequency_hz=f0)
    return {k: float(v) for k, v in indicators.items()}, VerticalHarmonics(f0_hz=f0, amplitudes_m_s2=amps,
                                                                            phases_rad=phases)


def _ride_pass(t_s: np.ndarray, a: PassAnalysis, result: RideResult | None) -> RidePass:
    """The result's entry for one pass (``result``: its own assembled result, None when left out)."""
    start, stop = a.span
    where = (float(t_s[start]), float(t_s[stop - 1]), int(start), int(stop - start))
    if a.kin is None or result is None:
        return RidePass(*where, strides=0, speed_m_s=None, stride_frequency_hz=None, indicators={},
                        used=False, reason=a.reason)
    intervals = result.indicators_interval_95 or {}
    return RidePass(*where, strides=a.strides, speed_m_s=abs(float(a.kin.fits.average_speed_m_s)),
                    stride_frequency_hz=1.0 / a.kin.period_s,
                    indicators={k: float(result.indicators[k]) for k in PASS_INDICATORS if k in result.indicators},
                    intervals_95={k: intervals[k] for k in ("acc_y_wb_rms",) if k in intervals})


def strides_words(strides: Sequence[int]) -> str:
    """"2, 2 and 3 strides": the strides per pass in words."""
    s = [str(int(n)) for n in strides]
    listed = s[0] if len(s) == 1 else f"{', '.join(s[:-1])} and {s[-1]}"
    return f"{listed} stride{'' if s == ['1'] else 's'}"


def _pooled_findings(results: Sequence[RideResult], reference: int, analyses: Sequence[PassAnalysis],
                     t_s: np.ndarray, pooled_wb: float, spread: float, n_periods: int) -> list[Finding]:
    """The reference pass's findings, the other passes' of other kinds, and what pooling did."""
    used = [a for a in analyses if a.kin is not None]
    total = sum(a.strides for a in used)
    findings = list(results[reference].findings)
    for i, r in enumerate(results):
        if i != reference:
            findings += [f for f in r.findings if f.code not in {g.code for g in findings}]
    if total >= n_periods:  # the pooled strides are as many as the indicators span: no pass's short crossing matters
        findings = [f for f in findings if f.code != "fit.short_crossing"]
    wb = ", ".join(f"{(a.indicators or {})['acc_y_wb_rms']:.2f}" for a in used)
    if len(used) > 1:  # one pass analysed of several: nothing pooled (passes.dropped says why the others were not)
        findings.append(Finding(
            "passes.pooled",
            f"{len(used)} passes in front of the cameras, {strides_words([a.strides for a in used])} ({total} in "
            f"all), pooled: W_b r.m.s. per pass {wb} m/s², pass-to-pass spread ±{100 * spread:.1f} %, pooled "
            f"{pooled_wb:.2f} m/s²", {"passes": len(used), "strides": total, "wb_rms_spread_fraction": spread}))
    for a in analyses:
        if a.kin is None:
            start, stop = a.span
            findings.append(Finding(
                "passes.dropped",
                f"the pass from {t_s[start]:.2f} s to {t_s[stop - 1]:.2f} s was left out: {a.reason}",
                {"start_s": float(t_s[start]), "end_s": float(t_s[stop - 1])}))
    return findings


def pool_passes(analyses: Sequence[PassAnalysis], results: Sequence[RideResult], t_s: np.ndarray,
                params: PipelineParams, with_intervals: Callable[..., RideResult]) -> RideResult:
    """The ride's result pooling every used pass's strides.

    ``analyses`` every pass (used or left out), ``results`` the used passes' own assembled results in the
    same order, ``t_s`` (F,) the motion clip's times; ``with_intervals(result, sources=...)`` puts the
    intervals on. The series (saddle, markers, window) are those of the pass with the most strides.
    """
    used = [a for a in analyses if a.kin is not None]
    strides = [a.strides for a in used]
    reference = max(range(len(used)), key=lambda i: (strides[i], used[i].span[1] - used[i].span[0]))
    indicators, harmonics = _pooled_indicators(used, reference, params)
    wb = np.array([(a.indicators or {})["acc_y_wb_rms"] for a in used])
    spread = float(np.std(wb, ddof=1) / np.mean(wb)) if len(wb) > 1 else 0.0
    findings = _pooled_findings(results, reference, analyses, t_s, indicators["acc_y_wb_rms"], spread,
                                int(params.n_periods))
    ref = results[reference]
    quality = dict(ref.quality)
    quality["pass_pooling"] = {"used": len(used), "left_out": len(analyses) - len(used), "strides": int(sum(strides)),
                         "reference_pass": int(analyses.index(used[reference])),
                         "spread_fraction": {k: _spread(k, used) for k in ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb",
                                                                           "amplitude_y_m", "vel_x_avg_kmh")}}
    quality["stride_phase_unmeasured_share"] = float(np.average(
        [r.quality.get("stride_phase_unmeasured_share") or 0.0 for r in results], weights=strides))
    lookup = {id(a): r for a, r in zip(used, results, strict=True)}
    pooled = replace(ref, indicators=indicators, vertical_harmonics=harmonics, period_s=1.0 / harmonics.f0_hz,
                     quality=quality, findings=tuple(dict.fromkeys(findings)),
                     passes=tuple(_ride_pass(t_s, a, lookup.get(id(a))) for a in analyses))
    return with_intervals(pooled, sources=pooled_sources(results, strides))


def _spread(key: str, used: Sequence[PassAnalysis]) -> float | None:
    """The passes' spread of one indicator: their standard deviation over their mean (None for one pass)."""
    values = np.array([a.indicators[key] for a in used if a.indicators and key in a.indicators], float)
    if values.size < 2 or not np.all(np.isfinite(values)) or values.mean() == 0:
        return None
    return float(np.std(values, ddof=1) / abs(values.mean()))

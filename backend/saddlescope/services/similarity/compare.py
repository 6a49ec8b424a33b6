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

from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from saddlescope.core.errors import InputError, KinematicsError, MocapFileError
from saddlescope.core.similarity import (
    RecordingSignature,
    RideStrides,
    align_phase,
    align_signatures,
    chain_measures,
    dtw_distance,
    noise_step,
    recording_signature,
    ride_strides,
    stretch_differences,
)
from saddlescope.io.threads import single_threaded_numerics

if TYPE_CHECKING:
    from saddlescope.io.mocap.data import MocapData

# ----------------------------------------------------------------------------------------------
# the product's interface: analysed rides (result documents) compared and ranked

# Which tracks of a ride are compared: the saddle point S, one horse marker, or all of them.
MARKER_SETS = ("saddle", "M1", "M2", "M3", "all")
# One mean stride (speed and start drop out) or the whole analysed window, stride by stride.
SPANS = ("stride", "window")
# Every measure reported, each a similarity in [0, 1] (1 = the same motion) except the dissimilarity.
MEASURES = ("dtw", "chain_code_nw", "shape_similarity", "shape_dissimilarity")
# The measure rides are ranked by (the "similarity" of every answer): chosen from the retrieval
# benchmark of `saddlescope bench` (docs/similarity.md).
RANKING_MEASURE = "dtw"
# Canonical frames.
FRAME_RIDE = "motion+stride_phase"
# Stretches of the stride or cycle (or of the matched recording) the differences are reported over.
DIFFERENCE_STRETCHES = 10
# DTW's Sakoe-Chiba window as a fraction of the samples compared.
DTW_WINDOW_FRACTION = 0.1


@dataclass(frozen=True)
class RideSignature:
    """What a ride contributes to any comparison, computed once per ride (and marker set, span).

    ``tracks`` holds one :class:`saddlescope.core.similarity.RideStrides` per track of the marker set.
    """

    tracks: tuple[RideStrides, ...]
    markers: str
    span: str


def _document_tracks(doc: Mapping, markers: str) -> tuple[list[np.ndarray], float, float]:
    """The tracks of a result document's ``markers`` set, its sample rate (Hz) and stride period (s).

    Each track is (N, 3) m, motion frame.
    """
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


def ride_signature(doc: Mapping, *, markers: str = "saddle", span: str = "stride") -> RideSignature:
    """A result document's tracks of ``markers`` in stride phase (:func:`saddlescope.core.similarity.ride_strides`).

    Compute it once per stored ride and compare signatures (:func:`compare_signatures`) to rank many.
    """
    if span not in SPANS:
        raise InputError(f"unknown span {span!r}; choose one of {', '.join(SPANS)}")
    tracks, fps, period_s = _document_tracks(doc, markers)
    if not np.isfinite(period_s * fps) or period_s <= 0:
        raise InputError(f"the result's stride period {period_s} s is not a usable period")
    return RideSignature(tracks=tuple(ride_strides(x, period_samples=period_s * fps, ride="result")
                                      for x in tracks), markers=markers, span=span)


def _dtw_similarity(a: np.ndarray, b: np.ndarray) -> tuple[float, float, int]:
    """DTW of two curves (n, 3) of one canonical frame: similarity in [0, 1], RMS distance, window.

    ``similarity = 1 - DTW(a, b) / (|a| + |b|)`` with |.| the root of the summed squares about each
    curve's mean: DTW is at most the Euclidean distance of the curves (the window holds the
    diagonal), itself at most |a| + |b|. The distance is reported per sample (RMS).
    """
    window = max(2, int(np.ceil(DTW_WINDOW_FRACTION * max(a.shape[0], b.shape[0]))))
    dist = dtw_distance(a, b, window=window)
    norm = float(np.linalg.norm(a - a.mean(axis=0)) + np.linalg.norm(b - b.mean(axis=0)))
    sim = 1.0 - dist / norm if norm > 0 else 1.0
    return float(np.clip(sim, 0.0, 1.0)), dist / np.sqrt(max(a.shape[0], b.shape[0])), window


def _pair_measures(a: np.ndarray, b: np.ndarray, sigma_a: float, sigma_b: float, *, closed: bool,
                   only: str | None = None) -> dict:
    """Every measure (or ``only`` one) of two curves already in one canonical frame."""
    out: dict = {}
    if only in (None, "dtw"):
        out["dtw"], out["dtw_distance_m"], out["dtw_window"] = _dtw_similarity(a, b)
    if only != "dtw":
        step = noise_step([a, b], [sigma_a, sigma_b])
        res = chain_measures(a, b, step=step, closed=closed)
        out.update(chain_code_nw=res["chain_code_nw"], shape_dissimilarity=res["shape_dissimilarity"],
                   shape_similarity=1.0 - res["shape_dissimilarity"], step_m=step,
                   moves_a=res["moves_a"], moves_b=res["moves_b"])
    return out


def _stride_rows(sa: RideStrides, sb: RideStrides, span: str) -> list[dict]:
    """The measures of one track.

    The chain codes compare every stride of either ride with the other ride's mean stride (phase-aligned) and are
    averaged: a fixed length per comparison, so neither NW nor D' depends on how long the recordings are. DTW
    compares the mean strides (``span= "stride"``) or, like the chain codes, every stride (``span="window"``). The
    grid step is the same for all: ``max(extent / 50, 4 sigma)`` with sigma the larger per-stride noise.
    """
    b_mean, _ = align_phase(sa.mean, sb.mean)
    a_mean, _ = align_phase(sb.mean, sa.mean)
    step = noise_step([sa.mean, sb.mean], [sa.sigma_m, sb.sigma_m])
    row = {"step_m": step, "moves_a": sa.moves, "moves_b": sb.moves}
    dist, _, window = _dtw_similarity(sa.mean, b_mean)
    if not (sa.moves and sb.moves):  # "no motion" is alike only "no motion"
        same = float(sa.moves == sb.moves)
        return [{**row, "dtw": same, "dtw_distance_m": dist, "dtw_window": window, "chain_code_nw": same,
                 "shape_dissimilarity": 1.0 - same, "shape_similarity": same}]
    pairs = [(x, b_mean) for x in sa.strides] + [(a_mean, x) for x in sb.strides]
    chains = [chain_measures(x, y, step=step) for x, y in pairs]
    dtw = [_dtw_similarity(x, y) for x, y in pairs] if span == "window" else [_dtw_similarity(sa.mean, b_mean)]
    shape = float(np.mean([c["shape_dissimilarity"] for c in chains]))
    return [{**row, "dtw": float(np.mean([d[0] for d in dtw])), "dtw_distance_m": float(np.mean([d[1] for d in dtw])),
             "dtw_window": dtw[0][2], "chain_code_nw": float(np.mean([c["chain_code_nw"] for c in chains])),
             "shape_dissimilarity": shape, "shape_similarity": 1.0 - shape}]


def _ranking_value(sa: RideStrides, sb: RideStrides) -> float:
    """The ranking measure alone (DTW of the phase-aligned mean strides)."""
    if not (sa.moves and sb.moves):
        return float(sa.moves == sb.moves)
    b_mean, _ = align_phase(sa.mean, sb.mean)
    return _dtw_similarity(sa.mean, b_mean)[0]


def compare_signatures(sig_a: RideSignature, sig_b: RideSignature, *, only: str | None = None) -> dict:
    """:func:`compare_ride_documents` on precomputed signatures.

    ``only="dtw"`` returns just ``{"similarity": ...}`` of the ranking measure (for ranking many).
    """
    if (sig_a.markers, sig_a.span) != (sig_b.markers, sig_b.span) or len(sig_a.tracks) != len(sig_b.tracks):
        raise InputError("the two rides were prepared for different marker sets or spans")
    pairs = list(zip(sig_a.tracks, sig_b.tracks, strict=True))
    if only is not None:
        if only != RANKING_MEASURE:
            raise InputError(f"only the ranking measure {RANKING_MEASURE!r} can be computed alone")
        return {"similarity": float(np.mean([_ranking_value(sa, sb) for sa, sb in pairs]))}
    rows = [row for sa, sb in pairs for row in _stride_rows(sa, sb, sig_a.span)]
    means_a = np.stack([sa.mean for sa, _ in pairs], axis=1) * 1e3
    means_b = np.stack([align_phase(sa.mean, sb.mean)[0] for sa, sb in pairs], axis=1) * 1e3
    names = ["M1", "M2", "M3"] if sig_a.markers == "all" else [sig_a.markers]
    differences = _differences(means_a, means_b, [r["dtw"] for r in rows], names, "stride phase")
    return _answer(rows, frame=FRAME_RIDE, markers=sig_a.markers, span=sig_a.span,
                   noise_m=(max(t.sigma_m for t in sig_a.tracks), max(t.sigma_m for t in sig_b.tracks)),
                   extra={"differences": differences})


def _answer(rows: list[dict], *, frame: str, markers, span: str, noise_m: tuple[float, float],
            extra: dict | None = None) -> dict:
    """The comparison's answer: the means over ``rows`` of every measure, with frame and step."""
    measures = {k: float(np.mean([r[k] for r in rows])) for k in MEASURES if k in rows[0]}
    step_mm = 1e3 * max(r["step_m"] for r in rows) if "step_m" in rows[0] else None
    details: dict = {}
    if "dtw" in measures:
        details["dtw"] = {"frame": frame, "window_samples": int(rows[0]["dtw_window"]),
                          "distance_mm": 1e3 * float(np.mean([r["dtw_distance_m"] for r in rows]))}
    for k in ("chain_code_nw", "shape_similarity", "shape_dissimilarity"):
        if k in measures:
            details[k] = {"frame": frame, "step_mm": step_mm, "walk": "anchored"}
    ranking = RANKING_MEASURE if RANKING_MEASURE in measures else next(iter(measures))
    out = {"similarity": measures[ranking], "measure": ranking, "measures": measures, "details": details,
           "frame": frame, "step_mm": step_mm, "noise_mm": {"a": 1e3 * noise_m[0], "b": 1e3 * noise_m[1]},
           "markers": markers, "span": span}
    if "moves_a" in rows[0]:
        out["moves"] = {"a": all(r["moves_a"] for r in rows), "b": all(r["moves_b"] for r in rows)}
    out.update(extra or {})
    return out


def compare_ride_documents(doc_a: Mapping, doc_b: Mapping, *, markers: str = "saddle",
                           span: str = "stride") -> dict:
    """How alike two analysed rides move (result documents of CONTRACTS section 2).

    Both are brought into the canonical frame of rides (the motion frame, travel and mean removed,
    every stride resampled to stride phase; the second ride's mean stride aligned in phase to the
    first's), then compared by DTW and by chain codes (anchored walk, noise-based step) of the mean
    strides (``span="stride"``) or of every stride against the other ride's mean stride
    (``span="window"``). Marker sets of several tracks average the measures over the tracks.

    Returns
    -------
    dict
        ``similarity`` in [0, 1] (1 = the same motion; the value of ``measure``, the measure rides
        are ranked by, :data:`RANKING_MEASURE`), ``measure``, ``measures`` ({name: value} for
        :data:`MEASURES`), ``details`` (per measure its ``frame`` and ``step_mm`` or DTW window and
        distance), ``frame``, ``step_mm`` (the grid step of the chain codes), ``noise_mm`` ({a, b}:
        the part of each ride's strides that does not repeat), ``moves`` ({a, b}: False for "no
        motion"), ``markers`` and ``span``.
    """
    if span not in SPANS:
        raise InputError(f"unknown span {span!r}; choose one of {', '.join(SPANS)}")
    return compare_signatures(ride_signature(doc_a, markers=markers, span=span),
                              ride_signature(doc_b, markers=markers, span=span))


def rank_signatures(query: RideSignature, candidates: Mapping[Hashable, RideSignature], *,
                    top: int = 10) -> list[dict]:
    """The ``top`` candidates most alike ``query`` by :data:`RANKING_MEASURE`, most alike first.

    Every candidate is scored by the ranking measure alone; the full comparison (every measure) is
    computed for the ``top`` only. Entries as in :func:`rank_rides`.
    """
    scored = []
    for key, sig in candidates.items():
        try:
            scored.append((compare_signatures(query, sig, only=RANKING_MEASURE)["similarity"], key))
        except InputError:
            continue
    scored.sort(key=lambda r: -r[0])
    rows = []
    for rank, (_, key) in enumerate(scored[: max(1, int(top))], start=1):
        rows.append({"ride": key, **compare_signatures(query, candidates[key]), "rank": rank})
    return rows


def rank_rides(query: Mapping, candidates: Mapping[Hashable, Mapping], *, markers: str = "saddle",
               span: str = "stride", top: int = 10) -> list[dict]:
    """The ``top`` candidates most alike ``query`` (result documents), most alike first.

    Each entry is :func:`compare_ride_documents`' answer with ``"ride"`` (the candidate's key) and
    ``"rank"`` (1 = most alike). A candidate that cannot be compared is left out. Each ride is put
    into stride phase once (:func:`ride_signature`); a caller ranking often against the same stored
    rides can keep their signatures and call :func:`rank_signatures`.
    """
    q = ride_signature(query, markers=markers, span=span)
    sigs = {}
    for key, doc in candidates.items():
        try:
            sigs[key] = ride_signature(doc, markers=markers, span=span)
        except InputError:
            continue
    return rank_signatures(q, sigs, top=top)


def compare_recordings(xyz_a, xyz_b, *, rate_a_hz: float = 100.0, rate_b_hz: float | None = None,
                       labels: list[str] | None = None, up: int | None = None, alignment: str | None = None,
                       notes: tuple[str, ...] = (), only: str | None = None) -> dict:
    """How alike two motion-capture recordings of the same markers move (generic motion, any frame).

    Both are aligned in time and space first (:func:`saddlescope.core.similarity.align_recordings`:
    progression removed; periodic recordings in cycle phase, others by subsequence DTW; B turned and
    moved onto A), then each marker's aligned curves are compared by DTW and by chain codes
    (anchored walk, noise-based step); the measures are the means over the markers.

    Parameters
    ----------
    xyz_a, xyz_b : ndarray of shape (N, M, 3), (K, M, 3)
        The two recordings (mm), gaps bridged, the same markers in the same order.
    rate_a_hz, rate_b_hz : float, optional
        Sampling rates (B's default A's).
    labels : list of str, optional
        Marker names for the answer.
    up : {None, 0, 1, 2}, optional
        The vertical axis: the alignment may then only turn about it.
    alignment : {None, "cycle_phase", "subsequence_dtw"}, optional
        Force one (default: cycle phase where both are periodic).
    notes : tuple of str, optional
        What was left out or matched on the way (labels), passed to the answer.
    only : {None, "dtw"}, optional
        ``"dtw"``: the ranking measure alone (no chain codes), for ranking many.

    Returns
    -------
    dict
        As :func:`compare_ride_documents`, with ``frame`` (the alignment plus "kabsch"),
        ``alignment`` (method, periods, cycles, phase shift, the compared span of each),
        ``kabsch_residual_mm``, ``differences`` (per marker and per stretch, mm), ``notes``, and
        ``markers`` the labels.
    """
    sig_a = recording_signature(xyz_a, rate_a_hz, name="recording A")
    sig_b = recording_signature(xyz_b, rate_a_hz if rate_b_hz is None else rate_b_hz, name="recording B")
    return compare_recording_signatures(sig_a, sig_b, labels=labels, up=up, alignment=alignment, notes=notes,
                                        only=only)


def compare_recording_signatures(sig_a: RecordingSignature, sig_b: RecordingSignature, *,
                                 labels: list[str] | None = None, up: int | None = None,
                                 alignment: str | None = None, notes: tuple[str, ...] = (),
                                 only: str | None = None) -> dict:
    """:func:`compare_recordings` on precomputed signatures (:func:`saddlescope.core.similarity.recording_signature`).

    ``only="dtw"`` returns ``{"similarity", "alignment"}`` of the ranking measure alone: one DTW of
    all markers' aligned curves at once (for ranking many).
    """
    if only is not None and only != RANKING_MEASURE:
        raise InputError(f"only the ranking measure {RANKING_MEASURE!r} can be computed alone")
    aligned = align_signatures(sig_a, sig_b, up=up, alignment=alignment)
    n_markers = aligned.a.shape[1]
    if only is not None:
        flat_a, flat_b = aligned.a.reshape(aligned.a.shape[0], -1), aligned.b.reshape(aligned.b.shape[0], -1)
        return {"similarity": _dtw_similarity(flat_a, flat_b)[0], "alignment": _alignment_summary(aligned)}
    names = list(labels) if labels else [f"marker {k + 1}" for k in range(n_markers)]
    rows = [_pair_measures(aligned.a[:, k] / 1e3, aligned.b[:, k] / 1e3, aligned.sigma_a / 1e3,
                           aligned.sigma_b / 1e3, closed=aligned.closed) for k in range(n_markers)]
    frame = f"{aligned.alignment}+kabsch"
    differences = _differences(aligned.a, aligned.b, [r["dtw"] for r in rows], names,
                               "cycle phase" if aligned.closed else "matched stretch of A")
    extra = {"alignment": _alignment_summary(aligned), "kabsch_residual_mm": aligned.rotation_residual_mm,
             "up": None if up is None else "xyz"[up], "differences": differences, "notes": list(notes)}
    return _answer(rows, frame=frame, markers=names, span="cycle" if aligned.closed else "window",
                   noise_m=(aligned.sigma_a / 1e3, aligned.sigma_b / 1e3), extra=extra)


def _alignment_summary(aligned) -> dict:
    """The answer's ``alignment``: which alignment was used and what it found."""
    out = {"method": aligned.alignment, "span_a_s": [round(v, 4) for v in aligned.span_a_s],
           "span_b_s": [round(v, 4) for v in aligned.span_b_s], "samples": int(aligned.a.shape[0])}
    if aligned.period_s is not None:
        out.update(period_s=list(aligned.period_s), cycles=list(aligned.cycles), phase_shift=aligned.phase_shift)
    return out


def _differences(a_mm: np.ndarray, b_mm: np.ndarray, dtws: list[float], names: list[str], time_base: str) -> dict:
    """Where the motions differ (the dissertation's spatial and temporal analysis).

    Per marker its RMS distance and DTW similarity, per stretch of the time base the RMS distance (mm).
    """
    per_stretch, per_marker = stretch_differences(a_mm, b_mm, DIFFERENCE_STRETCHES)
    overall = np.sqrt(np.mean(per_stretch ** 2, axis=0))
    markers = [{"marker": name, "rms_mm": float(per_marker[k]), "dtw": float(dtws[k]),
                "per_stretch_mm": [float(v) for v in per_stretch[k]]} for k, name in enumerate(names)]
    return {"time_base": time_base, "stretches": DIFFERENCE_STRETCHES, "per_marker": markers,
            "per_stretch_mm": [float(v) for v in overall],
            "most_different_marker": names[int(np.argmax(per_marker))],
            "most_different_stretch": int(np.argmax(overall))}


# A marker seen in fewer than this share of a recording's frames is left out of a comparison.
MIN_SEEN_FRACTION = 0.2


def _seen_span(points: np.ndarray) -> tuple[int, int]:
    """First and last frame where every marker of ``points`` (F, M, 3) is seen."""
    all_seen = np.all(np.isfinite(points), axis=(1, 2))
    idx = np.flatnonzero(all_seen)
    return (int(idx[0]), int(idx[-1])) if idx.size else (0, -1)


def _bridged(points: np.ndarray, labels: list[str], source: str) -> np.ndarray:
    """(F, M, 3) with gaps filled by linear interpolation.

    Call on frames where every marker is seen at both ends.
    """
    out = points.copy()
    idx = np.arange(out.shape[0])
    for m, label in enumerate(labels):
        seen = np.all(np.isfinite(out[:, m]), axis=1)
        if seen.sum() < 2:
            raise InputError(f"{source}: marker {label!r} is missing in almost every frame")
        for k in range(3):
            out[:, m, k] = np.interp(idx, idx[seen], out[seen, m, k])
    return out


def _load_result(path) -> dict:
    import json

    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{path.name} is not a readable result JSON ({exc})") from None
    if not isinstance(doc, dict) or "saddle" not in doc:
        raise InputError(f"{path.name} is not an analysed ride result (no saddle track)")
    return doc


def _matched_recordings(data_a, data_b, markers: list[str] | None, label_map: dict[str, str] | None):
    """Both recordings' positions (mm) for the markers they share, gaps bridged.

    Each is cut to the frames where all of them are seen.
    The labels (A's) and the notes of what was matched or left out.
    """
    from saddlescope.io.mocap.labels import match_labels

    match = match_labels(data_a.labels, data_b.labels, user_map=label_map, wanted=markers)
    notes = []
    if match.by_alias:
        notes.append("matched by marker-set aliases: " + ", ".join(f"{a}={b}" for a, b in match.by_alias))
    if match.unmatched_a and markers:
        raise InputError(f"{data_b.source} has no marker labelled {', '.join(match.unmatched_a)} (nor an "
                         "alias of it); name the pair with --map A=B")
    pairs = []
    for a, b in match.pairs:
        seen = [float(np.mean(np.all(np.isfinite(d.marker(x)), axis=1))) for d, x in ((data_a, a), (data_b, b))]
        if min(seen) < MIN_SEEN_FRACTION:
            where = data_a.source if seen[0] < seen[1] else data_b.source
            notes.append(f"{a} left out: seen in {100 * min(seen):.0f} % of {where}'s frames")
        else:
            pairs.append((a, b))
    if not pairs:
        raise InputError(f"{data_a.source} and {data_b.source} share no marker seen in both (labels "
                         f"{', '.join(data_a.labels[:6])} ... and {', '.join(data_b.labels[:6])} ...); "
                         "name pairs with --map A=B")
    sides = []
    for data, col in ((data_a, 0), (data_b, 1)):
        scale = 1e3 if data.units == "m" else 1.0
        pts = np.stack([data.marker(p[col]) for p in pairs], axis=1) * scale
        first, last = _seen_span(pts)
        if last - first < 8:
            raise InputError(f"{data.source}: the markers {', '.join(p[col] for p in pairs[:6])} are seen "
                             "together in fewer than 8 frames")
        if first > 0 or last < pts.shape[0] - 1:
            notes.append(f"{data.source}: frames {first + data.first_frame}-{last + data.first_frame} compared "
                         "(where every compared marker is seen)")
        sides.append(_bridged(pts[first:last + 1], [p[col] for p in pairs], data.source))
    if match.unmatched_a and not markers:
        more = " ..." if len(match.unmatched_a) > 8 else ""
        notes.append(f"{len(match.unmatched_a)} marker(s) of {data_a.source} without a partner in "
                     f"{data_b.source}: {', '.join(match.unmatched_a[:8])}{more}")
    return sides[0], sides[1], [p[0] for p in pairs], notes


def compare_files(path_a, path_b, *, markers: list[str] | None = None, up: str | None = None,
                  label_map: dict[str, str] | None = None, alignment: str | None = None) -> dict:
    """`saddlescope similar`: two analysed ride results (JSON) or two C3D / TRC recordings.

    Results are compared with :func:`compare_ride_documents` (``markers``: one of
    :data:`MARKER_SETS`, default the saddle point); recordings with :func:`compare_recordings` on the
    markers both files have (``markers``: only these labels of A; labels matched by name, by
    marker-set alias or by ``label_map`` {label in A: label in B}; a marker seen in under 20 % of
    either file's frames left out with a note; ``up``: "x", "y" or "z").
    """
    from pathlib import Path

    from saddlescope.io.mocap import read_mocap

    if up is not None and up not in ("x", "y", "z"):
        raise InputError(f"--up must be x, y or z, got {up!r}")
    path_a, path_b = Path(path_a), Path(path_b)
    is_result = [p.suffix.lower() == ".json" for p in (path_a, path_b)]
    if is_result[0] != is_result[1]:
        raise InputError("compare two analysed results or two motion-capture files, not one of each")
    if is_result[0]:
        a, b = _load_result(path_a), _load_result(path_b)
        chosen = markers[0] if markers else "saddle"
        if markers and len(markers) > 1:
            raise InputError(f"for analysed results --markers names one set of {', '.join(MARKER_SETS)}")
        return compare_ride_documents(a, b, markers=chosen)
    data_a, data_b = read_mocap(path_a), read_mocap(path_b)
    xa, xb, labels, notes = _matched_recordings(data_a, data_b, markers, label_map)
    with single_threaded_numerics():  # small matrices: BLAS threads only queue behind each other
        return compare_recordings(xa, xb, rate_a_hz=data_a.rate_hz, rate_b_hz=data_b.rate_hz, labels=labels,
                                  up=None if up is None else "xyz".index(up), alignment=alignment,
                                  notes=tuple(notes))


def similarity_matrix(paths, *, markers: list[str] | None = None, up: str | None = None,
                      label_map: dict[str, str] | None = None) -> dict:
    """`saddlescope similar` over many recordings: the ranking measure of every pair.

    Each file is read once; each pair is matched (labels, aliases, ``label_map``), aligned in time and
    space and scored by :data:`RANKING_MEASURE` (the full measures are for a pair:
    :func:`compare_files`). A file that cannot be read, or a pair that cannot be compared, gets None
    and a note with the reason.

    Returns
    -------
    dict
        ``files`` (names), ``measure``, ``similarity`` (list of rows, 1 on the diagonal, None where a
        pair cannot be compared), ``alignment`` (per pair the method, same layout) and ``notes``.
    """
    from saddlescope.io.mocap import read_mocap

    if up is not None and up not in ("x", "y", "z"):
        raise InputError(f"--up must be x, y or z, got {up!r}")
    paths = list(paths)
    if len(paths) < 2:
        raise InputError("at least two recordings are needed for a matrix (name files or a folder)")
    data: list[MocapData | None] = []
    notes: list[str] = []
    for path in paths:
        try:
            data.append(read_mocap(path))
        except (InputError, MocapFileError) as exc:
            data.append(None)
            notes.append(str(exc))
    n = len(paths)
    sim = [[1.0 if i == j and data[i] is not None else None for j in range(n)] for i in range(n)]
    how = [[None] * n for _ in range(n)]
    with single_threaded_numerics():
        for i in range(n):
            for j in range(i + 1, n):
                first, second = data[i], data[j]
                if first is None or second is None:
                    continue
                try:
                    xa, xb, labels, _ = _matched_recordings(first, second, markers, label_map)
                    res = compare_recordings(xa, xb, rate_a_hz=first.rate_hz, rate_b_hz=second.rate_hz,
                                             labels=labels, up=None if up is None else "xyz".index(up),
                                             only=RANKING_MEASURE)
                except (InputError, KinematicsError) as exc:
                    notes.append(f"{paths[i].name} - {paths[j].name}: {exc}")
                    continue
                sim[i][j] = sim[j][i] = float(res["similarity"])
                how[i][j] = how[j][i] = res["alignment"]["method"]
    return {"files": [p.name for p in paths], "measure": RANKING_MEASURE, "similarity": sim,
            "alignment": how, "notes": notes}

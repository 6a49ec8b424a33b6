"""Use cases of ride similarity in the product: most-alike rides, a pair, a horse's consistency.

The comparison itself is `saddlescope.services.similarity.compare.compare_ride_documents` (called, never
re-implemented here). Every comparison is cached in the ``similarity_pairs`` table per pair of rides,
marker set and span, with the analysis versions of both rides and the similarity method's version;
a row is used only while all three still hold (and a re-analysed ride's rows are deleted with its
old result). A list that needs comparisons not cached yet is not computed in the web request: the
missing pairs go to the workers as a ``similarity`` job (`saddlescope.services.similarity.jobs`), and
the caller answers 202 with that job.
"""

from __future__ import annotations

import json
import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import InputError
from saddlescope.core.types import GAITS
from saddlescope.db.enums import RideStatus
from saddlescope.db.repositories import (
    AnalysedRide,
    Conflict,
    HorseRepository,
    JobRepository,
    RideRepository,
    SimilarityRepository,
    ordered_pair,
)
from saddlescope.db.session import session_scope
from saddlescope.settings import Settings
from saddlescope.storage import Storage

__all__ = [
    "INLINE_PAIRS", "JOB_KIND", "MAX_JOB_PAIRS", "Lookup", "NotAnalysed", "check_options", "compare_pair",
    "compute_pairs", "horse_consistency", "method_version", "most_alike", "pending_answer",
    "ride_summary", "run_pairs_job", "similarity_payload",
]

JOB_KIND = "similarity"
# A pair view or a horse's consistency computes up to this many missing comparisons in the request.
INLINE_PAIRS = 10
# Most pairs one similarity job takes.
MAX_JOB_PAIRS = 50_000
_DOCS_KEPT = 64  # result documents a job keeps loaded (the query ride of a list stays)


class NotAnalysed(Conflict):
    """A ride that cannot be compared: it has no result (HTTP 409, with the reason)."""


def check_options(markers: str, span: str) -> None:
    """Raise `InputError` naming the field when `markers` or `span` is not one the method knows."""
    from saddlescope.services.similarity.compare import MARKER_SETS, SPANS

    if markers not in MARKER_SETS:
        raise InputError(f"markers: unknown marker set {markers!r}; choose one of {', '.join(MARKER_SETS)}")
    if span not in SPANS:
        raise InputError(f"span: unknown span {span!r}; choose one of {', '.join(SPANS)}")


def method_version(settings: Settings) -> str:
    """The similarity method's version a cached comparison must match.

    ``services.similarity.compare.METHOD_VERSION`` where the method declares one, else the code version (so a
    new deployment recomputes rather than serving a comparison an older method made).
    """
    from saddlescope.services.similarity import compare as similarity

    declared = getattr(similarity, "METHOD_VERSION", None)
    return str(declared)[:100] if declared else f"code {settings.resolved_code_version}"[:100]


def ride_summary(ride: AnalysedRide) -> dict[str, Any]:
    """What a list shows of a ride: id, horse, gait and date."""
    return {"ride_id": ride.ride_id, "horse_id": ride.horse_id, "horse": ride.horse, "gait": ride.gait,
            "ridden_on": ride.ridden_on}


def _not_analysed_reason(session: Session, ride_id: int, club_id: int) -> str:
    ride = RideRepository(session, club_id=club_id).get(ride_id)
    job = JobRepository(session, club_id=club_id).latest_for_ride(ride_id, kind="analyze")
    why = {
        RideStatus.NEW.value: "its clips are not all uploaded",
        RideStatus.READY.value: "it has not been analysed yet",
        RideStatus.PROCESSING.value: "its analysis is still running",
    }.get(ride.status, "it has not been analysed yet")
    if ride.status == RideStatus.FAILED.value and job is not None:
        why = f"its analysis {job.status}" + (f" ({job.error})" if job.error else "")
    return f"ride {ride_id} has no result to compare: {why}"


def _analysed(session: Session, ride_id: int, club_id: int) -> AnalysedRide:
    """The club's ride `ride_id` with its result; `NotFound` (404) or `NotAnalysed` (409)."""
    RideRepository(session, club_id=club_id).get(ride_id)
    found = SimilarityRepository(session, club_id=club_id).analysed(ride_ids=[ride_id])
    if not found:
        raise NotAnalysed(_not_analysed_reason(session, ride_id, club_id))
    return found[0]


def _load(storage: Storage, ride: AnalysedRide) -> dict[str, Any]:
    if not storage.exists(ride.result_key):
        raise NotAnalysed(f"ride {ride.ride_id}'s result file is missing from storage; analyse the ride again")
    return json.loads(storage.read_bytes(ride.result_key))


def _jsonable(value: Any) -> Any:
    """An answer as plain JSON: numpy numbers and arrays as Python ones, NaN and infinities as None."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "tolist"):
        return _jsonable(value.tolist())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return value


def _compare(doc_a: dict, doc_b: dict, markers: str, span: str) -> tuple[float | None, str | None, dict, str | None]:
    """(similarity, measure, answer, error) of two result documents; a refusal becomes the error."""
    from saddlescope.services.similarity.compare import compare_ride_documents

    try:
        answer = _jsonable(compare_ride_documents(doc_a, doc_b, markers=markers, span=span))
    except InputError as exc:
        return None, None, {}, str(exc)
    similarity = answer.get("similarity")
    if not isinstance(similarity, int | float):
        return None, None, answer, "the comparison gave no similarity"
    return min(1.0, max(0.0, float(similarity))), answer.get("measure"), answer, None


def _entry(row, other: AnalysedRide) -> dict[str, Any]:
    answer = dict(row.answer or {})
    return {"ride": ride_summary(other), "similarity": row.similarity, "measure": row.measure,
            "measures": answer.get("measures") or {}}


@dataclass
class Lookup:
    """A list answered from the cache (`answer`), or the pairs still to compare (`missing`)."""

    answer: dict[str, Any] | None
    missing: list[tuple[int, int]] = field(default_factory=list)
    cached: int = 0
    total: int = 0


def most_alike(session: Session, ride_id: int, *, club_id: int, markers: str, span: str, any_gait: bool,
               limit: int, version: str) -> Lookup:
    """The club's rides most alike ride `ride_id` (same gait unless `any_gait`), most alike first.

    Answered only when every pair is cached; otherwise `Lookup.missing` lists the pairs to compute.
    Rides that could not be compared are listed under ``not_comparable`` with the reason.
    """
    check_options(markers, span)
    query = _analysed(session, ride_id, club_id)
    repo = SimilarityRepository(session, club_id=club_id)
    others = [r for r in repo.analysed(gait=None if any_gait else query.gait) if r.ride_id != ride_id]
    versions = {r.ride_id: r.version for r in (*others, query)}
    pairs = [ordered_pair(ride_id, r.ride_id) for r in others]
    cached = repo.cached(pairs, markers=markers, span=span, method_version=version, versions=versions)
    missing = [p for p in pairs if p not in cached]
    if missing:
        return Lookup(None, missing, len(cached), len(pairs))
    rows = [(cached[ordered_pair(ride_id, r.ride_id)], r) for r in others]
    ranked = sorted((x for x in rows if x[0].similarity is not None),
                    key=lambda x: (-(x[0].similarity or 0.0), x[1].ride_id))
    items = [{"rank": rank, **_entry(row, other)} for rank, (row, other) in enumerate(ranked[:limit], start=1)]
    answer = {
        "ride": ride_summary(query), "markers": markers, "span": span, "gait": "any" if any_gait else "same",
        "method_version": version, "candidates": len(others), "items": items,
        "not_comparable": [{"ride": ride_summary(other), "reason": row.error or "not comparable"}
                           for row, other in rows if row.similarity is None],
    }
    return Lookup(answer, [], len(cached), len(pairs))


def _store(session: Session, club_id: int, a: AnalysedRide, b: AnalysedRide, docs: dict[int, dict], markers: str,
           span: str, version: str):
    similarity, measure, answer, error = _compare(docs[a.ride_id], docs[b.ride_id], markers, span)
    return SimilarityRepository(session, club_id=club_id).store(
        club_id=club_id, pair=(a.ride_id, b.ride_id), markers=markers, span=span, versions=(a.version, b.version),
        method_version=version, similarity=similarity, measure=measure, answer=answer, error=error)


def compare_pair(session: Session, storage: Storage, ride_id: int, other_id: int, *, club_id: int, markers: str,
                 span: str, version: str) -> dict[str, Any]:
    """Two rides compared (from the cache, or computed and cached now), with the pair view's paths."""
    from saddlescope.services.similarity.pair_view import pair_paths

    check_options(markers, span)
    for rid in (ride_id, other_id):
        RideRepository(session, club_id=club_id).get(rid)  # 404 before anything else
    if ride_id == other_id:
        raise InputError(f"other_id: choose a ride other than ride {ride_id} to compare it with")
    first, second = (_analysed(session, rid, club_id) for rid in (ride_id, other_id))
    a, b = (first, second) if first.ride_id < second.ride_id else (second, first)
    docs = {r.ride_id: _load(storage, r) for r in (a, b)}
    repo = SimilarityRepository(session, club_id=club_id)
    row = repo.cached([(a.ride_id, b.ride_id)], markers=markers, span=span, method_version=version,
                      versions={a.ride_id: a.version, b.ride_id: b.version}).get((a.ride_id, b.ride_id))
    cached = row is not None
    if row is None:
        row = _store(session, club_id, a, b, docs, markers, span, version)
    return {
        "rides": [ride_summary(first), ride_summary(second)], "markers": markers, "span": span, "cached": cached,
        "similarity": row.similarity, "measure": row.measure, "measures": (row.answer or {}).get("measures") or {},
        "reason": row.error, "comparison": dict(row.answer or {}), "method_version": version,
        "differences": (row.answer or {}).get("differences"),
        "view": pair_paths(docs[first.ride_id], docs[second.ride_id]),
    }


def _consistency_rows(rides: Sequence[AnalysedRide], cached: dict) -> list[dict[str, Any]]:
    rows = []
    for j, ride in enumerate(rides):
        sims = [cached[(rides[i].ride_id, ride.ride_id)].similarity for i in range(j)]
        sims = [s for s in sims if s is not None]
        previous = cached[(rides[j - 1].ride_id, ride.ride_id)].similarity if j else None
        rows.append({"ride": ride_summary(ride), "earlier": j, "vs_previous": previous,
                     "mean_vs_earlier": sum(sims) / len(sims) if sims else None,
                     "min_vs_earlier": min(sims) if sims else None})
    return rows


def horse_consistency(session: Session, storage: Storage, horse_id: int, *, club_id: int, markers: str, span: str,
                      version: str) -> Lookup:
    """Each analysed ride of a horse against its own earlier rides in the same gait (by date, then id).

    Up to `INLINE_PAIRS` missing comparisons are computed at once; more are left in `Lookup.missing`.
    """
    check_options(markers, span)
    horse = HorseRepository(session, club_id=club_id).get(horse_id)
    repo = SimilarityRepository(session, club_id=club_id)
    rides = repo.analysed(horse_id=horse_id)
    by_gait = {g: [r for r in rides if r.gait == g] for g in GAITS if any(r.gait == g for r in rides)}
    pairs = [(rs[i].ride_id, rs[j].ride_id) for rs in by_gait.values() for j in range(len(rs)) for i in range(j)]
    versions = {r.ride_id: r.version for r in rides}
    cached = repo.cached(pairs, markers=markers, span=span, method_version=version, versions=versions)
    missing = [p for p in pairs if p not in cached]
    if len(missing) > INLINE_PAIRS:
        return Lookup(None, missing, len(cached), len(pairs))
    if missing:
        compute_pairs(session, storage, missing, club_id=club_id, markers=markers, span=span, version=version)
        cached = repo.cached(pairs, markers=markers, span=span, method_version=version, versions=versions)
    gaits = []
    for gait, group in by_gait.items():
        rows = _consistency_rows(group, cached)
        means = [r["vs_previous"] for r in rows if r["vs_previous"] is not None]
        gaits.append({"gait": gait, "rides": rows, "mean_vs_previous": sum(means) / len(means) if means else None})
    answer = {"horse_id": horse.id, "horse": horse.name, "markers": markers, "span": span,
              "method_version": version, "gaits": gaits}
    return Lookup(answer, [], len(pairs) - len(missing), len(pairs))


def compute_pairs(session: Session, storage: Storage, pairs: Sequence[tuple[int, int]], *, club_id: int,
                  markers: str, span: str, version: str,
                  report: Callable[[float, str | None], None] | None = None) -> dict[str, int]:
    """Compare and cache `pairs` of the club's analysed rides; returns counts (computed, cached, gone).

    Pairs already cached for the rides' current analyses are skipped; a ride deleted or no longer
    analysed (or of another club) makes its pairs ``gone``. Each comparison is flushed as it is
    stored; the caller commits (a job commits every few pairs, see `run_pairs_job`).
    """
    repo = SimilarityRepository(session, club_id=club_id)
    ordered = sorted({ordered_pair(*p) for p in pairs})
    rides = {r.ride_id: r for r in repo.analysed(ride_ids={i for p in ordered for i in p})}
    versions = {rid: r.version for rid, r in rides.items()}
    live = [p for p in ordered if p[0] in rides and p[1] in rides]
    done = repo.cached(live, markers=markers, span=span, method_version=version, versions=versions)
    todo = [p for p in live if p not in done]
    docs: OrderedDict[int, dict] = OrderedDict()
    for k, (a, b) in enumerate(todo):
        for rid in (a, b):
            if rid not in docs:
                docs[rid] = _load(storage, rides[rid])
            docs.move_to_end(rid)
        while len(docs) > _DOCS_KEPT:
            docs.popitem(last=False)
        _store(session, club_id, rides[a], rides[b], docs, markers, span, version)
        if report is not None:
            report((k + 1) / len(todo), f"{k + 1}/{len(todo)} pairs")
    return {"computed": len(todo), "cached": len(done), "gone": len(ordered) - len(live)}


def similarity_payload(payload: dict[str, Any]) -> dict[str, Any]:
    """A similarity job's payload checked: ``{"markers", "span", "pairs": [[ride, ride], ...]}``."""
    markers, span, pairs = payload.get("markers", "saddle"), payload.get("span", "stride"), payload.get("pairs")
    if not isinstance(markers, str) or not isinstance(span, str):
        raise InputError("similarity payload: markers and span must be strings")
    check_options(markers, span)
    if not isinstance(pairs, list) or not 1 <= len(pairs) <= MAX_JOB_PAIRS:
        raise InputError(f"similarity payload: pairs must be a list of 1 to {MAX_JOB_PAIRS} pairs of ride ids")
    clean = []
    for pair in pairs:
        ok = (isinstance(pair, list | tuple) and len(pair) == 2
              and all(isinstance(i, int) and not isinstance(i, bool) and i >= 1 for i in pair) and pair[0] != pair[1])
        if not ok:
            raise InputError(f"similarity payload: each pair must be two different ride ids, got {pair!r}")
        clean.append(list(ordered_pair(*pair)))
    return {"markers": markers, "span": span, "pairs": sorted(map(list, {tuple(p) for p in clean}))}


def run_pairs_job(sessions: sessionmaker[Session], storage: Storage, payload: dict[str, Any], *, club_id: int | None,
                  version: str, report: Callable[[float, str | None], None]) -> dict[str, int]:
    """The similarity job's work: compute the payload's pairs in batches, committing each batch."""
    if club_id is None:
        raise InputError("a similarity job must belong to a club")
    payload = similarity_payload(payload)
    pairs = [tuple(p) for p in payload["pairs"]]
    totals = {"computed": 0, "cached": 0, "gone": 0}
    batch = 25
    for start in range(0, len(pairs), batch):
        chunk = pairs[start:start + batch]
        with session_scope(sessions) as session:
            counts = compute_pairs(session, storage, chunk, club_id=club_id, markers=payload["markers"],
                                   span=payload["span"], version=version)
        for key, value in counts.items():
            totals[key] += value
        report(min(1.0, (start + len(chunk)) / len(pairs)), f"{start + len(chunk)}/{len(pairs)} pairs")
    return totals


def pending_answer(lookup: Lookup, job: dict[str, Any], **what: Any) -> dict[str, Any]:
    """The 202 answer: what was asked, the job computing the missing pairs, and how many are cached."""
    return {**what, "job": job, "cached": lookup.cached, "pairs": lookup.total, "missing": len(lookup.missing)}


"""Ride similarity: a ride's most-alike rides, two rides compared, a horse's consistency.

Comparisons are cached per pair, marker set, span and analysis version; a list whose comparisons are
not all cached answers 202 with the ``similarity`` job that computes them (poll ``/api/jobs/{id}``,
then ask again).
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, status
from fastapi.encoders import jsonable_encoder
from fastapi.responses import JSONResponse

from saddlescope.api.deps import ClubDep, QueueDep, SessionFactoryDep, SettingsDep, StorageDep
from saddlescope.api.routers.common import ERRORS, Id
from saddlescope.api.schemas import ErrorOut
from saddlescope.api.similarity_schemas import (
    AlikeOut,
    ConsistencyOut,
    GaitScope,
    MarkerSet,
    PairOut,
    PendingOut,
    Span,
)
from saddlescope.services.similarity.club import (
    compare_pair,
    horse_consistency,
    method_version,
    most_alike,
    pending_answer,
)
from saddlescope.services.similarity.jobs import queue_pairs

__all__ = ["router"]

router = APIRouter(tags=["similarity"])

NOT_ANALYSED: dict[int | str, dict[str, Any]] = {
    409: {"model": ErrorOut, "description": "a ride has no result to compare (the reason says why)"}}
PENDING: dict[int | str, dict[str, Any]] = {
    202: {"model": PendingOut, "description": "comparisons queued as a job: poll it, then ask again"},
    503: {"model": ErrorOut, "description": "the job could not be queued"}}
MarkersQuery = Annotated[MarkerSet, Query(description="saddle point S, one horse marker, or all markers")]
SpanQuery = Annotated[Span, Query(description="one mean stride, or the whole analysed window")]


def _pending(club, sessions, queue, lookup, **what) -> JSONResponse:
    club.session.rollback()
    job = queue_pairs(sessions, queue, lookup.missing, club_id=club.club_id, markers=what["markers"],
                      span=what["span"])
    body = PendingOut(**pending_answer(lookup, job, **what))
    return JSONResponse(jsonable_encoder(body), status_code=status.HTTP_202_ACCEPTED)


@router.get("/rides/{ride_id}/similar", response_model=AlikeOut, responses={**ERRORS, **NOT_ANALYSED, **PENDING})
def similar_rides(
    ride_id: Id,
    club: ClubDep,
    settings: SettingsDep,
    sessions: SessionFactoryDep,
    queue: QueueDep,
    markers: MarkersQuery = "saddle",
    span: SpanQuery = "stride",
    gait: Annotated[GaitScope, Query(description="same: rides of the ride's gait; any: every gait")] = "same",
    limit: Annotated[int, Query(ge=1, le=100)] = 10,
):
    """The club's analysed rides whose motion is most alike this ride's, most alike first.

    Served from the cache when every pair is cached; otherwise 202 with the job computing the rest.
    """
    lookup = most_alike(club.session, ride_id, club_id=club.club_id, markers=markers, span=span,
                        any_gait=gait == "any", limit=limit, version=method_version(settings))
    if lookup.answer is None:
        return _pending(club, sessions, queue, lookup, markers=markers, span=span, ride_id=ride_id)
    return lookup.answer


@router.get("/rides/{ride_id}/similar/{other_id}", response_model=PairOut, responses={**ERRORS, **NOT_ANALYSED})
def compare_rides(
    ride_id: Id,
    other_id: Id,
    club: ClubDep,
    settings: SettingsDep,
    storage: StorageDep,
    markers: MarkersQuery = "saddle",
    span: SpanQuery = "stride",
) -> dict:
    """Two rides compared (cached, or computed now), with both saddle-point paths and the aligned strides."""
    answer = compare_pair(club.session, storage, ride_id, other_id, club_id=club.club_id, markers=markers,
                          span=span, version=method_version(settings))
    club.session.commit()  # the comparison is cached
    return answer


@router.get("/horses/{horse_id}/consistency", response_model=ConsistencyOut,
            responses={**ERRORS, **PENDING})
def horse_consistency_route(
    horse_id: Id,
    club: ClubDep,
    settings: SettingsDep,
    storage: StorageDep,
    sessions: SessionFactoryDep,
    queue: QueueDep,
    markers: MarkersQuery = "saddle",
    span: SpanQuery = "stride",
):
    """Each analysed ride of the horse against its own earlier rides, per gait (oldest first).

    A few missing comparisons are computed now; many go to a job (202).
    """
    lookup = horse_consistency(club.session, storage, horse_id, club_id=club.club_id, markers=markers, span=span,
                               version=method_version(settings))
    if lookup.answer is None:
        return _pending(club, sessions, queue, lookup, markers=markers, span=span, horse_id=horse_id)
    club.session.commit()  # comparisons computed now are cached
    return lookup.answer

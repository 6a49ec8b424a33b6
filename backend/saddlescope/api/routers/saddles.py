"""Saddles of the club: the list, one saddle across horses, and one horse's saddles compared."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, Query, Response, status

from saddlescope.api.deps import ClubDep
from saddlescope.api.routers.common import (
    CONFLICT,
    ERRORS,
    Id,
    IndicatorKey,
    Paging,
    changes,
    paging_sorted_by,
    sort_enum,
)
from saddlescope.api.saddle_schemas import (
    HorseSaddlesOut,
    SaddleAcrossHorsesOut,
    SaddleIn,
    SaddleOut,
    SaddleUpdate,
)
from saddlescope.api.schemas import Gait, Page
from saddlescope.db.repositories import Saddle, SaddleRepository
from saddlescope.services.comparisons.saddles import horse_saddles, saddle_across_horses

__all__ = ["SaddleSort", "router"]

router = APIRouter(tags=["saddles"])
SaddleSort = sort_enum("SaddleSort", SaddleRepository.sort_fields)
SaddlePaging = Annotated[Paging, Depends(paging_sorted_by(SaddleSort, "name"))]
# The shared tables typed as FastAPI's `responses` wants them.
_ERRORS: dict[int | str, dict[str, Any]] = {code: dict(spec) for code, spec in ERRORS.items()}
_CONFLICTS: dict[int | str, dict[str, Any]] = {code: dict(spec) for code, spec in {**ERRORS, **CONFLICT}.items()}
Indicators = Annotated[
    list[IndicatorKey] | None,
    Query(max_length=16, description="indicator keys (repeat); default W_b and W_k r.m.s. and VDV"),
]
IncludeUncertain = Annotated[
    bool, Query(description="count rides too uncertain for a decision too (left out and counted otherwise)")
]


def _out(saddle: Saddle, rides: int) -> SaddleOut:
    return SaddleOut.model_validate(saddle).model_copy(update={"rides": rides})


@router.get("/saddles", response_model=Page[SaddleOut], responses=_ERRORS)
def list_saddles(
    club: ClubDep,
    paging: SaddlePaging,
    q: Annotated[str | None, Query(max_length=200, description="name contains")] = None,
) -> dict:
    """The club's saddles with their number of rides; sort by name (default), maker, saddle_type, created_at, id."""
    page = club.saddles.list_page(name_like=q, sort=paging.sort, limit=paging.limit, offset=paging.offset)
    counts = club.saddles.ride_counts([s.id for s in page.items])
    return {"items": [_out(s, counts.get(s.id, 0)) for s in page.items], "total": page.total,
            "limit": page.limit, "offset": page.offset}


@router.post(
    "/saddles", status_code=status.HTTP_201_CREATED, response_model=SaddleOut, responses=_CONFLICTS
)
def create_saddle(body: SaddleIn, club: ClubDep) -> SaddleOut:
    """Add a saddle to the club (409 when the club has one of that name)."""
    club.require("saddle.create")
    return _out(club.saddles.add(**body.model_dump()), 0)


@router.get("/saddles/{saddle_id}", response_model=SaddleOut, responses=_ERRORS)
def read_saddle(saddle_id: Id, club: ClubDep) -> SaddleOut:
    """A saddle of the club."""
    return _out(club.saddles.get(saddle_id), club.saddles.ride_counts([saddle_id]).get(saddle_id, 0))


@router.patch("/saddles/{saddle_id}", response_model=SaddleOut, responses=_CONFLICTS)
def update_saddle(saddle_id: Id, body: SaddleUpdate, club: ClubDep) -> SaddleOut:
    """Change a saddle's details (null clears the maker, type, tree width or notes)."""
    club.require("saddle.create")
    values = changes(body, nullable=("maker", "saddle_type", "tree_width", "notes"))
    if "notes" in values and values["notes"] is None:
        values["notes"] = ""  # cleared notes: none
    saddle = club.saddles.update_fields(saddle_id, **values)
    return _out(saddle, club.saddles.ride_counts([saddle_id]).get(saddle_id, 0))


@router.delete("/saddles/{saddle_id}", status_code=status.HTTP_204_NO_CONTENT, responses=_CONFLICTS)
def delete_saddle(saddle_id: Id, club: ClubDep) -> Response:
    """Delete a saddle no ride uses (admins only; 409 while rides name it)."""
    club.require("saddle.delete")
    club.saddles.delete(saddle_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get("/saddles/{saddle_id}/across-horses", response_model=SaddleAcrossHorsesOut, responses=_ERRORS)
def across_horses(saddle_id: Id, club: ClubDep, gait: Gait | None = None, indicator: Indicators = None,
                  include_uncertain: IncludeUncertain = False) -> dict:
    """The saddle's analysed rides (newest first) and per horse and gait the rides, means and 95 % intervals."""
    keys = [str(k) for k in indicator] if indicator else None
    answer = saddle_across_horses(club.session, saddle_id, club_id=club.club_id, gait=gait, indicators=keys,
                                  include_uncertain=include_uncertain)
    answer["saddle"] = _out(answer["saddle"], answer["rides_total"])
    return answer


@router.get("/horses/{horse_id}/saddles", response_model=HorseSaddlesOut, responses=_ERRORS)
def compare_saddles(horse_id: Id, club: ClubDep, gait: Gait, indicator: Indicators = None,
                    include_uncertain: IncludeUncertain = False) -> dict:
    """The horse's saddles in one gait: per saddle n, mean and 95 % interval; each pair compared (Welch).

    ``differences[].sentence`` says in words whether the difference exceeds the uncertainty (its 95 %
    interval excludes zero); ``method`` says how.
    """
    keys = [str(k) for k in indicator] if indicator else None
    return horse_saddles(club.session, horse_id, club_id=club.club_id, gait=gait, indicators=keys,
                         include_uncertain=include_uncertain)

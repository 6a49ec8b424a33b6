"""Horses of the club, and one horse's indicators across gaits."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Depends, Query, Response, status

from saddlescope.api.deps import AdminClubDep, ClubDep
from saddlescope.api.routers.common import (
    CONFLICT,
    ERRORS,
    Id,
    IndicatorKey,
    Paging,
    changes,
    download,
    page_of,
    paging_sorted_by,
    sort_enum,
)
from saddlescope.api.schemas import HorseComparisonOut, HorseIn, HorseOut, HorseUpdate, Page
from saddlescope.db.repositories import HorseRepository
from saddlescope.services.comparisons.analytics import horse_comparison
from saddlescope.services.results.documents import EXPORT_FORMATS, export_horse

__all__ = ["HorseSort", "router"]

router = APIRouter(prefix="/horses", tags=["horses"])
HorseSort = sort_enum("HorseSort", HorseRepository.sort_fields)
HorsePaging = Annotated[Paging, Depends(paging_sorted_by(HorseSort, "name"))]


@router.get("", response_model=Page[HorseOut], responses=ERRORS)
def list_horses(
    club: ClubDep,
    paging: HorsePaging,
    q: Annotated[str | None, Query(max_length=200, description="name contains")] = None,
) -> dict:
    """The club's horses; sort by name (default), breed, birth_year, height_withers_m, created_at, id."""
    page = club.horses.list_page(name_like=q, sort=paging.sort, limit=paging.limit, offset=paging.offset)
    return page_of(page, HorseOut.model_validate)


@router.post(
    "", status_code=status.HTTP_201_CREATED, response_model=HorseOut, responses={**ERRORS, **CONFLICT}
)
def create_horse(body: HorseIn, club: ClubDep) -> HorseOut:
    """Add a horse to the club (409 when the club has one of that name)."""
    return HorseOut.model_validate(club.horses.add(**body.model_dump()))


@router.get("/{horse_id}", response_model=HorseOut, responses=ERRORS)
def read_horse(horse_id: Id, club: ClubDep) -> HorseOut:
    """A horse of the club."""
    return HorseOut.model_validate(club.horses.get(horse_id))


@router.patch("/{horse_id}", response_model=HorseOut, responses={**ERRORS, **CONFLICT})
def update_horse(horse_id: Id, body: HorseUpdate, club: ClubDep) -> HorseOut:
    """Change a horse's details (a null breed, birth_year or height clears it)."""
    values = changes(body, nullable=("breed", "birth_year", "height_withers_m"))
    return HorseOut.model_validate(club.horses.update_fields(horse_id, **values))


@router.delete("/{horse_id}", status_code=status.HTTP_204_NO_CONTENT, responses={**ERRORS, **CONFLICT})
def delete_horse(horse_id: Id, club: AdminClubDep) -> Response:
    """Delete a horse without rides (admins only; 409 while rides use it)."""
    club.horses.delete(horse_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get("/{horse_id}/comparison", response_model=HorseComparisonOut, responses=ERRORS)
def compare_gaits(
    horse_id: Id,
    club: ClubDep,
    indicator: Annotated[
        list[IndicatorKey] | None,
        Query(max_length=64, description="indicator keys (repeat); default the eight comfort indicators"),
    ] = None,
    include_uncertain: Annotated[
        bool, Query(description="average rides too uncertain for a decision too (left out and counted otherwise)")
    ] = False,
) -> dict:
    """One horse's indicators across gaits (thesis Figs 8.29-8.32): n, mean, std, min, max per gait."""
    keys = [str(key) for key in indicator] if indicator else None
    return horse_comparison(club.session, horse_id, club_id=club.club_id, indicators=keys,
                            include_uncertain=include_uncertain)


@router.get("/{horse_id}/export", responses={**ERRORS, 200: {"content": {"text/csv": {}, EXPORT_FORMATS["xlsx"]: {}}}})
def export_horse_rides(
    horse_id: Id,
    club: ClubDep,
    format: Annotated[Literal["csv", "xlsx"], Query(description="csv or xlsx")] = "csv",  # noqa: A002
) -> Response:
    """All of the horse's analysed rides, one row per ride, as CSV or xlsx (named columns, units, rounded)."""
    data, name = export_horse(club.session, horse_id, format, club_id=club.club_id)
    return download(data, name, EXPORT_FORMATS[format])

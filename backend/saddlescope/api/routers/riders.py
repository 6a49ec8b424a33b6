"""Riders of the club."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Query, Response, status

from saddlescope.api.deps import AdminClubDep, ClubDep
from saddlescope.api.routers.common import CONFLICT, ERRORS, Id, Paging, changes, page_of, paging_sorted_by, sort_enum
from saddlescope.api.schemas import Page, RiderIn, RiderOut, RiderUpdate
from saddlescope.db.repositories import RiderRepository

__all__ = ["RiderSort", "router"]

router = APIRouter(prefix="/riders", tags=["riders"])
RiderSort = sort_enum("RiderSort", RiderRepository.sort_fields)
RiderPaging = Annotated[Paging, Depends(paging_sorted_by(RiderSort, "name"))]


def _check_user(club, user_id: int | None) -> None:
    """A rider's account must be a user of this club (404 otherwise)."""
    if user_id is not None:
        club.users.get(user_id)


@router.get("", response_model=Page[RiderOut], responses=ERRORS)
def list_riders(
    club: ClubDep,
    paging: RiderPaging,
    q: Annotated[str | None, Query(max_length=200, description="name contains")] = None,
) -> dict:
    """The club's riders; sort by name (default), created_at, id."""
    page = club.riders.list_page(name_like=q, sort=paging.sort, limit=paging.limit, offset=paging.offset)
    return page_of(page, RiderOut.model_validate)


@router.post(
    "", status_code=status.HTTP_201_CREATED, response_model=RiderOut, responses={**ERRORS, **CONFLICT}
)
def create_rider(body: RiderIn, club: ClubDep) -> RiderOut:
    """Add a rider to the club, with their own account if they have one (409 for a name in use)."""
    _check_user(club, body.user_id)
    return RiderOut.model_validate(club.riders.add(name=body.name, user_id=body.user_id, weight_kg=body.weight_kg))


@router.get("/{rider_id}", response_model=RiderOut, responses=ERRORS)
def read_rider(rider_id: Id, club: ClubDep) -> RiderOut:
    """A rider of the club."""
    return RiderOut.model_validate(club.riders.get(rider_id))


@router.patch("/{rider_id}", response_model=RiderOut, responses={**ERRORS, **CONFLICT})
def update_rider(rider_id: Id, body: RiderUpdate, club: ClubDep) -> RiderOut:
    """Rename a rider, change their account (null: none) or their usual weight in kg (null: not recorded)."""
    _check_user(club, body.user_id)
    return RiderOut.model_validate(
        club.riders.update_fields(rider_id, **changes(body, nullable=("user_id", "weight_kg")))
    )


@router.delete("/{rider_id}", status_code=status.HTTP_204_NO_CONTENT, responses={**ERRORS, **CONFLICT})
def delete_rider(rider_id: Id, club: AdminClubDep) -> Response:
    """Delete a rider without rides (admins only; 409 while rides use them)."""
    club.riders.delete(rider_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)

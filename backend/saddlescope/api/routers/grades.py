"""Riders' comfort grades of rides, and their correlation with the indicators."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, Response, status

from saddlescope.api.deps import ClubDep
from saddlescope.api.routers.common import ERRORS, Id, IndicatorKey, PagingDep, QueryId, changes, page_of
from saddlescope.api.schemas import CorrelationOut, Gait, GradeIn, GradeOut, GradeUpdate, Page
from saddlescope.services.comparisons.analytics import grade_correlation_report

__all__ = ["router"]

router = APIRouter(prefix="/grades", tags=["grades"])


@router.get("", response_model=Page[GradeOut], responses=ERRORS)
def list_grades(
    club: ClubDep,
    paging: PagingDep,
    ride_id: QueryId = None,
    rider_id: QueryId = None,
    horse_id: QueryId = None,
    gait: Gait | None = None,
) -> dict:
    """Grades, filtered by ride, rider, horse and gait; sort by grade, created_at, ride_id, rider_id, id."""
    page = club.grades.list_page(
        ride_id=ride_id,
        rider_id=rider_id,
        horse_id=horse_id,
        gait=gait,
        sort=paging.sort,
        limit=paging.limit,
        offset=paging.offset,
    )
    return page_of(page, GradeOut.model_validate)


@router.post("", status_code=status.HTTP_201_CREATED, response_model=GradeOut, responses=ERRORS)
def set_grade(body: GradeIn, club: ClubDep) -> GradeOut:
    """Grade a ride for a rider (1 = very uncomfortable ... 5 = very comfortable).

    Grading the same ride again replaces the earlier grade.
    """
    club.grades.check_references(ride_id=body.ride_id, rider_id=body.rider_id)
    return GradeOut.model_validate(
        club.grades.set_grade(
            ride_id=body.ride_id, rider_id=body.rider_id, grade=body.grade, comment=body.comment
        )
    )


@router.get("/correlation", response_model=CorrelationOut, responses=ERRORS)
def correlation(
    club: ClubDep,
    gait: Gait | None = None,
    indicator: Annotated[
        list[IndicatorKey] | None,
        Query(description="indicator keys (repeat); default the eight comfort indicators"),
    ] = None,
) -> dict:
    """Riders' average grade per horse and gait against the mean indicator (thesis Figs 8.33-8.36).

    Pearson and Spearman coefficients with p values and 95 % intervals, and the points behind them.
    """
    keys = [str(key) for key in indicator] if indicator else None
    return grade_correlation_report(club.session, club_id=club.club_id, gait=gait, indicators=keys)


@router.get("/{grade_id}", response_model=GradeOut, responses=ERRORS)
def read_grade(grade_id: Id, club: ClubDep) -> GradeOut:
    """A grade of the club."""
    return GradeOut.model_validate(club.grades.get(grade_id))


@router.patch("/{grade_id}", response_model=GradeOut, responses=ERRORS)
def update_grade(grade_id: Id, body: GradeUpdate, club: ClubDep) -> GradeOut:
    """Change a grade or its comment."""
    return GradeOut.model_validate(club.grades.update_fields(grade_id, **changes(body)))


@router.delete("/{grade_id}", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
def delete_grade(grade_id: Id, club: ClubDep) -> Response:
    """Delete a grade."""
    club.grades.delete(grade_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)

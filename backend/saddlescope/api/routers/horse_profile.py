"""The horse page's own routes: an indicator's trend with the horse's normal band, and two rides side by side.

The profile, the rides and the gait comparison come from `routers.horses` and `routers.rides`.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query

from saddlescope.api.deps import ClubDep
from saddlescope.api.horse_profile_schemas import PairOut, TrendOut
from saddlescope.api.routers.common import CONFLICT, ERRORS, Id, IndicatorKey
from saddlescope.api.schemas import MAX_ID, Gait
from saddlescope.services.horses.profile import horse_trend, ride_pair

__all__ = ["router"]

router = APIRouter(prefix="/horses", tags=["horses"])

RideQuery = Annotated[int, Query(ge=1, le=MAX_ID, description="a ride id of this horse")]


@router.get("/{horse_id}/trend", response_model=TrendOut, responses=ERRORS)
def trend(
    horse_id: Id,
    club: ClubDep,
    gait: Gait,
    indicator: IndicatorKey = IndicatorKey("acc_y_wb_rms"),
    include_uncertain: Annotated[
        bool, Query(description="show rides too uncertain for a decision too (never in a band)")
    ] = False,
) -> dict:
    """One indicator of the horse in one gait over its analysed rides, oldest first.

    Every ride carries the horse's own normal band of the rides BEFORE it (mean ± 2 SD, once there are
    at least four) and whether it lies outside. Rides too uncertain for a decision are left out (and
    counted) unless ``include_uncertain``; they never enter a band.
    """
    return horse_trend(club.session, horse_id, club_id=club.club_id, gait=gait, indicator=indicator,
                       include_uncertain=include_uncertain)


@router.get("/{horse_id}/ride-pair", response_model=PairOut, responses={**ERRORS, **CONFLICT})
def pair(
    horse_id: Id,
    club: ClubDep,
    a: RideQuery,
    b: RideQuery,
    indicator: Annotated[
        list[IndicatorKey] | None,
        Query(description="indicator keys (repeat); default the main comfort, exposure and gait indicators"),
    ] = None,
) -> dict:
    """Two analysed rides of the horse side by side: each indicator of both and b's % difference from a."""
    return ride_pair(club.session, horse_id, club_id=club.club_id, first_id=a, second_id=b, indicators=indicator)

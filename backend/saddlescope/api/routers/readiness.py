"""Whether a ride can be analysed now, and what is missing (for the upload form and the ride page)."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from saddlescope.api.deps import ClubDep
from saddlescope.api.routers.common import ERRORS, Id
from saddlescope.services.rides.readiness import missing_for_ride

__all__ = ["ReadinessOut", "router"]

router = APIRouter(prefix="/rides", tags=["rides"])


class ReadinessOut(BaseModel):
    """Whether a ride can be analysed now, and every clip or setting it still needs."""

    ready: bool
    missing: list[str] = Field(description="one sentence per missing clip or setting (none: ready)")


@router.get("/{ride_id}/readiness", response_model=ReadinessOut, responses=ERRORS)
def ride_readiness(ride_id: Id, club: ClubDep) -> ReadinessOut:
    """Every clip or setting the ride still needs.

    The same sentences the API gives when it refuses to analyse the ride (422).
    """
    missing = missing_for_ride(club.session, ride_id, club_id=club.club_id)
    return ReadinessOut(ready=not missing, missing=missing)

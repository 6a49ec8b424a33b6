"""Motion-capture files: a C3D or TRC upload analysed as a ride (its source marked in the result)."""

from __future__ import annotations

import datetime as dt
from typing import Annotated

from fastapi import APIRouter, Query, Request, status
from starlette.concurrency import run_in_threadpool

from saddlescope.api.deps import ClubDep, SessionFactoryDep, SettingsDep, StorageDep
from saddlescope.api.rider_weight import check_weight_kg
from saddlescope.api.routers.common import ERRORS
from saddlescope.api.routers.rides import ride_out
from saddlescope.api.schemas import Direction, ErrorOut, Gait, MocapRideOut
from saddlescope.api.streaming import UPLOAD_OPENAPI, stream_upload
from saddlescope.core.errors import InputError
from saddlescope.db.repositories import RideRepository
from saddlescope.db.session import session_scope
from saddlescope.services.analysis.mocap import MocapChoice, store_mocap_ride
from saddlescope.services.results.documents import result_document
from saddlescope.services.uploads.intake import staging_key

__all__ = ["router"]

router = APIRouter(prefix="/mocap", tags=["mocap"])


def _choice(markers: str, point: str | None, offset_mm: str | None, up: str | None, strides: int | None,
            gait: str) -> MocapChoice:
    labels = tuple(s.strip() for s in markers.split(","))
    if len(labels) != 3 or not all(labels):
        raise InputError(f"markers takes the three labels standing for M1, M2, M3, separated by commas; got "
                         f"{markers!r}")
    offset = (0.0, 0.0, 0.0)
    if offset_mm:
        try:
            dx, dy, dz = (float(v) for v in offset_mm.split(","))
        except ValueError:
            raise InputError(f"offset_mm takes three numbers in mm separated by commas, got {offset_mm!r}") from None
        offset = (dx, dy, dz)
    return MocapChoice(labels, point or None, offset, up or None, strides, gait)


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    response_model=MocapRideOut,
    openapi_extra=UPLOAD_OPENAPI,
    responses={**ERRORS, 413: {"model": ErrorOut}},
)
async def upload_mocap(
    request: Request,
    club: ClubDep,
    sessions: SessionFactoryDep,
    storage: StorageDep,
    settings: SettingsDep,
    horse_id: Annotated[int, Query(ge=1, le=2**31 - 1)],
    rider_id: Annotated[int, Query(ge=1, le=2**31 - 1)],
    markers: Annotated[str, Query(max_length=200, description="three labels for M1, M2, M3: A,B,C")],
    gait: Gait = "walk",
    direction: Direction = "CW",
    point: Annotated[str | None, Query(max_length=100, description="the label reported as S")] = None,
    offset_mm: Annotated[str | None, Query(max_length=100, description="without point: S's offsets (mm) "
                                           "from the markers' centroid in their body frame")] = None,
    up: Annotated[str | None, Query(max_length=3, description="the lab's vertical: x, y, z, -x, ...")] = None,
    strides: Annotated[int | None, Query(ge=1, le=20)] = None,
    filename: Annotated[str | None, Query(max_length=255, description="the file's name (raw body)")] = None,
    ridden_on: dt.date | None = None,
    notes: Annotated[str, Query(max_length=2000)] = "",
    saddle_id: Annotated[int | None, Query(ge=1, le=2**31 - 1, description="the club's saddle the horse wore")] = None,
    pad: Annotated[str | None, Query(max_length=200)] = None,
    rider_weight_kg: Annotated[float | None, Query(description="kg, 20-200; default: the rider's weight")] = None,
) -> MocapRideOut:
    """Upload a C3D or TRC file (raw body with `filename`, or multipart `file`) and analyse it as a ride.

    Three of its markers stand for M1-M3 and `point` (or `offset_mm`) for the saddle point. The ride is
    stored analysed, its source marked in its meta and result (`source`); a refused file stores
    nothing and answers 422 with the reason.
    """
    choice = _choice(markers, point, offset_mm, up, strides, gait)
    await run_in_threadpool(club.horses.get, horse_id)
    await run_in_threadpool(club.riders.get, rider_id)
    if saddle_id is not None:
        await run_in_threadpool(club.saddles.get, saddle_id)  # before the bytes: another club's is not found
    try:
        check_weight_kg(rider_weight_kg)
    except ValueError as exc:
        raise InputError(f"rider_weight_kg: {exc}") from None
    club_id = club.club_id
    club.session.rollback()
    staged = await stream_upload(request, storage, staging_key(club_id), max_bytes=settings.max_upload_bytes)
    ride = {"horse_id": horse_id, "rider_id": rider_id, "gait": gait, "direction": direction,
            "ridden_on": ridden_on or dt.datetime.now(dt.UTC).date(), "notes": notes,
            "created_by": club.principal.user_id, "saddle_id": saddle_id, "pad": pad or None,
            "rider_weight_kg": rider_weight_kg}
    ride_id = await run_in_threadpool(
        store_mocap_ride, sessions, storage, staged.key, staged.filename or filename, choice, club_id=club_id,
        ride=ride, code_version=settings.resolved_code_version)
    with session_scope(sessions) as session:
        document = result_document(session, storage, ride_id, club_id=club_id)
        row = RideRepository(session, club_id=club_id).get(ride_id)
        return MocapRideOut(ride=ride_out(row, document["indicators"]), period_s=document["period_s"],
                            indicators=document["indicators"], flags=document["quality"].get("flags", []),
                            source=document["source"])

"""Rides: metadata, clips (one by one or a whole bundle), analysis, result and exports."""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Literal, get_args

from fastapi import APIRouter, Depends, Query, Request, Response, status
from starlette.concurrency import run_in_threadpool

from saddlescope.api.deps import ClubDep, QueueDep, SessionFactoryDep, SettingsDep, StorageDep
from saddlescope.api.routers.clips import UPLOAD_ERRORS, receive_clip
from saddlescope.api.routers.common import (
    ERRORS,
    Id,
    Paging,
    QueryId,
    changes,
    download,
    page_of,
    paging_sorted_by,
    sort_enum,
)
from saddlescope.api.schemas import (
    BundleUploaded,
    CameraRole,
    ClipUploaded,
    ErrorOut,
    Gait,
    JobOut,
    Page,
    RecordingOut,
    ResultOut,
    RideDetail,
    RideIn,
    RideOut,
    RideUpdate,
)
from saddlescope.api.streaming import UPLOAD_OPENAPI, stream_upload
from saddlescope.core.errors import InputError
from saddlescope.core.types import CAMERA_ROLES
from saddlescope.core.vibration import COMFORT_INDICATORS
from saddlescope.db.enums import RIDE_STATUSES
from saddlescope.db.repositories import Ride, RideFilter, RideRepository
from saddlescope.db.session import session_scope
from saddlescope.services.jobs.lifecycle import get_job, job_as_dict, submit_job
from saddlescope.services.results.documents import EXPORT_FORMATS, export_ride, export_rides, result_view_json
from saddlescope.services.rides.readiness import require_ready
from saddlescope.services.rides.registration import outdated_result_settings, update_ride_details
from saddlescope.services.uploads.intake import (
    ClipOwner,
    accept_bundle,
    remove_upload_files,
    staging_key,
)

__all__ = ["ExportFormat", "RideSort", "RideStatusName", "ride_detail", "ride_out", "router"]

router = APIRouter(prefix="/rides", tags=["rides"])
RideStatusName = Literal[RIDE_STATUSES]  # type: ignore[valid-type]
# EXPORT_FORMATS' keys spelled out so that the type checker knows them; import fails if the two drift apart.
ExportFormat = Literal["json", "csv", "xlsx", "c3d", "trc"]
if set(get_args(ExportFormat)) != set(EXPORT_FORMATS):
    raise RuntimeError(f"ExportFormat {get_args(ExportFormat)} differs from EXPORT_FORMATS {tuple(EXPORT_FORMATS)}")
RideSort = sort_enum("RideSort", RideRepository.sort_fields)
RidePaging = Annotated[Paging, Depends(paging_sorted_by(RideSort, "-ridden_on"))]


def ride_out(ride: Ride, result_indicators: dict | None = None) -> RideOut:
    """The list view of a ride, with its comfort indicators when `result_indicators` are given."""
    indicators = None
    if result_indicators is not None:
        indicators = {k: result_indicators.get(k) for k in COMFORT_INDICATORS}
    return RideOut(
        id=ride.id,
        horse_id=ride.horse_id,
        horse_name=ride.horse.name,
        rider_id=ride.rider_id,
        rider_name=ride.rider.name,
        rig_id=ride.rig_id,
        gait=ride.gait,
        direction=ride.direction,
        ridden_on=ride.ridden_on,
        status=ride.status,
        notes=ride.notes,
        saddle_id=ride.saddle_id,
        pad=ride.pad,
        rider_weight_kg=ride.rider_weight_kg,
        from_bundle=ride.bundle_key is not None,
        indicators=indicators,
        created_at=ride.created_at,
        created_by=_made_by(ride),
        result_outdated_by=outdated_result_settings(ride),
    )


def _made_by(ride: Ride) -> int | None:
    value = dict(ride.meta or {}).get("_created_by")
    return value if isinstance(value, int) else None


def _indicators(club, ride_ids: list[int]) -> dict[int, dict]:
    return club.results.indicators_for(ride_ids)


def ride_detail(club, ride: Ride) -> RideDetail:
    """A ride with its clips and its latest job (read through the club's repositories)."""
    base = ride_out(ride, _indicators(club, [ride.id]).get(ride.id)).model_dump()
    latest = club.jobs.latest_for_ride(ride.id)
    return RideDetail(
        **base,
        meta={k: v for k, v in dict(ride.meta or {}).items() if not k.startswith("_")},
        recordings=[RecordingOut.model_validate(r) for r in club.recordings.for_ride(ride.id)],
        latest_job_id=latest.id if latest else None,
    )


@router.get("", response_model=Page[RideOut], responses=ERRORS)
def list_rides(
    club: ClubDep,
    paging: RidePaging,
    horse_id: QueryId = None,
    rider_id: QueryId = None,
    rig_id: QueryId = None,
    saddle_id: QueryId = None,
    gait: Gait | None = None,
    status_: Annotated[RideStatusName | None, Query(alias="status")] = None,
    date_from: dt.date | None = None,
    date_to: dt.date | None = None,
) -> dict:
    """The club's rides, filtered by horse, rider, rig, gait, status and date range (ridden_on).

    Sort by ridden_on (default, newest first), created_at, gait, status, horse_id, rider_id, id, or an
    indicator with its own column (acc_y_wb_rms, acc_y_wk_rms, vdv_y_wb, vdv_y_wk, vel_x_avg_kmh,
    amplitude_y_m, stride_frequency_hz; rides without a result come last).
    """
    rides = RideFilter(
        horse_id=horse_id,
        rider_id=rider_id,
        rig_id=rig_id,
        saddle_id=saddle_id,
        gait=gait,
        status=status_,
        date_from=date_from,
        date_to=date_to,
    )
    page = club.rides.list_page(rides, sort=paging.sort, limit=paging.limit, offset=paging.offset)
    indicators = _indicators(club, [r.id for r in page.items])
    return page_of(page, lambda ride: ride_out(ride, indicators.get(ride.id)))


@router.post("", status_code=status.HTTP_201_CREATED, response_model=RideOut, responses=ERRORS)
def create_ride(body: RideIn, club: ClubDep) -> RideOut:
    """Create a ride to upload clips to.

    Its motion clips; static, plumb and calibration come from its rig unless uploaded for the ride.
    """
    meta = body.meta.model_dump(exclude_none=True) if body.meta is not None else {}
    ride = club.rides.add(
        horse_id=body.horse_id,
        rider_id=body.rider_id,
        rig_id=body.rig_id,
        gait=body.gait,
        direction=body.direction,
        ridden_on=body.ridden_on or dt.datetime.now(dt.UTC).date(),
        notes=body.notes,
        meta={**meta, "_created_by": club.principal.user_id},
        saddle_id=body.saddle_id,
        pad=body.pad or None,
        rider_weight_kg=body.rider_weight_kg,
    )
    return ride_out(ride)


@router.get(
    "/export/{fmt}", responses={**ERRORS, 200: {"content": {"text/csv": {}, EXPORT_FORMATS["xlsx"]: {}}}}
)
def export_many(
    fmt: Literal["csv", "xlsx"],
    club: ClubDep,
    horse_id: QueryId = None,
    rider_id: QueryId = None,
    rig_id: QueryId = None,
    gait: Gait | None = None,
    date_from: dt.date | None = None,
    date_to: dt.date | None = None,
) -> Response:
    """Indicators of the club's analysed rides (with the ride list's filters) as CSV or xlsx."""
    rides = RideFilter(
        horse_id=horse_id, rider_id=rider_id, rig_id=rig_id, gait=gait, date_from=date_from, date_to=date_to
    )
    data, name = export_rides(club.session, fmt, club_id=club.club_id, rides=rides)
    return download(data, name, EXPORT_FORMATS[fmt])


@router.post(
    "/bundle",
    status_code=status.HTTP_201_CREATED,
    response_model=BundleUploaded,
    openapi_extra=UPLOAD_OPENAPI,
    responses={**UPLOAD_ERRORS, 409: {"model": ErrorOut, "description": (
        "the same bundle, or its motion clips, already a ride of the club: `ride_id` names it")}},
)
async def upload_bundle(
    request: Request,
    club: ClubDep,
    settings: SettingsDep,
    storage: StorageDep,
    sessions: SessionFactoryDep,
    queue: QueueDep,
    rig_id: QueryId = None,
) -> BundleUploaded:
    """Upload a whole ride bundle as a zip (CONTRACTS section 1): ride.json and the clips.

    The horse and rider are found or created by name; the analysis starts at once. Unsafe zips (``..``
    paths, links, zip bombs), an invalid ride.json (unknown gait or camera, ...) and missing clips are
    refused (422), naming the uploaded file; the same bundle again in the club is 409 naming its ride.
    """
    if rig_id is not None:
        await run_in_threadpool(club.rigs.get, rig_id)
    club_id = club.club_id
    club.session.rollback()
    staged = await stream_upload(
        request, storage, staging_key(club_id, "bundle.zip"), max_bytes=settings.max_upload_bytes
    )
    ride_id, job_id = await run_in_threadpool(
        accept_bundle, sessions, storage, queue, staged.key, club_id=club_id, rig_id=rig_id,
        filename=staged.filename, user_id=club.principal.user_id,
    )
    with session_scope(sessions) as session:
        ride = RideRepository(session, club_id=club_id).get(ride_id)
        return BundleUploaded(ride=ride_out(ride), job_id=job_id)


@router.get("/{ride_id}", response_model=RideDetail, responses=ERRORS)
def read_ride(ride_id: Id, club: ClubDep) -> RideDetail:
    """A ride with its clips, comfort indicators (once analysed) and latest job."""
    return ride_detail(club, club.rides.get(ride_id))


@router.patch("/{ride_id}", response_model=RideOut, responses=ERRORS)
def update_ride(ride_id: Id, body: RideUpdate, club: ClubDep) -> RideOut:
    """Change a ride's details (a null rig_id or ridden_on clears it).

    A changed gait or direction makes the shown result outdated (`result_outdated_by`) until the ride
    is analysed again (POST /api/rides/{id}/analyze).
    """
    values = changes(body, nullable=("rig_id", "ridden_on", "saddle_id", "pad", "rider_weight_kg"))
    ride = update_ride_details(club.session, ride_id, club_id=club.club_id, **values)
    return ride_out(ride, _indicators(club, [ride.id]).get(ride.id))


@router.delete("/{ride_id}", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
def delete_ride(ride_id: Id, club: ClubDep, storage: StorageDep) -> Response:
    """Delete a ride with its clips, jobs, result, grades and uploads (an admin or the ride's maker)."""
    club.require("ride.delete", owner_id=club.rides.creator_of(ride_id))
    uploads = club.uploads.ids_of(ride_id=ride_id)
    club.rides.delete(ride_id)
    club.session.commit()
    storage.delete(f"rides/{ride_id}")
    remove_upload_files(storage, uploads)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get("/{ride_id}/clips", response_model=list[RecordingOut], responses=ERRORS)
def list_ride_clips(ride_id: Id, club: ClubDep) -> list[RecordingOut]:
    """The ride's own clips (its rig's shared clips are listed under the rig)."""
    club.rides.get(ride_id)
    return [RecordingOut.model_validate(r) for r in club.recordings.for_ride(ride_id)]


@router.put(
    "/{ride_id}/clips/{clip_kind}/{camera}",
    response_model=ClipUploaded,
    openapi_extra=UPLOAD_OPENAPI,
    responses={**UPLOAD_ERRORS, 409: {"model": ErrorOut, "description": (
        "this motion clip (the same bytes) is already another ride's: `ride_id` names it")}},
)
async def upload_ride_clip(
    ride_id: Id,
    clip_kind: str,
    camera: CameraRole,
    request: Request,
    club: ClubDep,
    settings: SettingsDep,
    storage: StorageDep,
    sessions: SessionFactoryDep,
    queue: QueueDep,
) -> ClipUploaded:
    """Upload one camera's clip of the ride (usually `motion`; multipart field `file`, or the raw bytes).

    It is probed at once and refused (422, the earlier clip kept) if it does not decode or disagrees with
    the other cameras' clips of the set in frame rate or size. The clip that completes the ride starts
    its analysis.
    """
    await run_in_threadpool(club.rides.get, ride_id)
    return await receive_clip(request, ClipOwner("ride", ride_id, club.club_id), clip_kind, camera, club=club,
                              settings=settings, storage=storage, sessions=sessions, queue=queue)


@router.post(
    "/{ride_id}/analyze",
    status_code=status.HTTP_201_CREATED,
    response_model=JobOut,
    responses={**ERRORS, 503: {"model": ErrorOut}},
)
async def analyze_ride(ride_id: Id, club: ClubDep, sessions: SessionFactoryDep, queue: QueueDep) -> JobOut:
    """(Re)start the ride's analysis (an `analyze` job: probe, assemble, calibrate, analyze).

    A ride that cannot run (a clip or setting missing) is refused (422) naming what is missing.
    """
    await run_in_threadpool(require_ready, club.session, ride_id, club_id=club.club_id)
    club.session.rollback()
    job_id = await run_in_threadpool(
        submit_job, sessions, queue, kind="analyze", ride_id=ride_id, club_id=club.club_id
    )
    with session_scope(sessions) as session:
        return JobOut(**job_as_dict(get_job(session, job_id)))


@router.post(
    "/{ride_id}/calibrate-rig",
    status_code=status.HTTP_201_CREATED,
    response_model=JobOut,
    responses={**ERRORS, 503: {"model": ErrorOut}},
)
async def calibrate_rig_from_ride(ride_id: Id, club: ClubDep, sessions: SessionFactoryDep, queue: QueueDep) -> JobOut:
    """Use this ride's own calibration clips (a bundle's) for its rig: a `calibrate_rig` job replacing the rig's.

    Refused (422) when the ride has no rig or no calibration clip of each camera. Run the ride's analysis
    again once the job is done.
    """
    ride = await run_in_threadpool(club.rides.get, ride_id)
    if ride.rig_id is None:
        raise InputError(f"ride {ride_id} has no rig: choose its rig on the ride page first")
    kinds = {(r.clip_kind, r.camera_role) for r in club.recordings.for_ride(ride_id)}
    missing = [cam for cam in CAMERA_ROLES if ("calibration", cam) not in kinds]
    if missing:
        raise InputError(f"ride {ride_id} has no calibration clip of the {', '.join(missing)} camera"
                         f"{'s' if len(missing) > 1 else ''}, so it cannot calibrate its rig")
    rig_id = ride.rig_id
    club.session.rollback()
    job_id = await run_in_threadpool(
        submit_job, sessions, queue, kind="calibrate_rig", ride_id=ride_id, rig_id=rig_id, club_id=club.club_id
    )
    with session_scope(sessions) as session:
        return JobOut(**job_as_dict(get_job(session, job_id)))


@router.get(
    "/{ride_id}/result", response_model=ResultOut, responses={**ERRORS, 304: {"description": "unchanged"}}
)
def read_result(
    ride_id: Id,
    club: ClubDep,
    storage: StorageDep,
    request: Request,
    max_points: Annotated[int, Query(ge=10, le=100_000)] = 2000,
) -> Response:
    """Indicators (with units), quality flags and the series the dashboard plots.

    The series are decimated to at most `max_points` samples. 404 until the ride is analysed. Sends an
    ETag: with ``If-None-Match`` an unchanged result answers 304 without a body.
    """
    data, etag = result_view_json(club.session, storage, ride_id, club_id=club.club_id, max_points=max_points)
    headers = {"ETag": f'"{etag}"', "Cache-Control": "private, no-cache"}
    if request.headers.get("if-none-match") == headers["ETag"]:
        return Response(status_code=status.HTTP_304_NOT_MODIFIED, headers=headers)
    return Response(data, media_type="application/json", headers=headers)


@router.get(
    "/{ride_id}/export/{fmt}",
    responses={
        **ERRORS,
        200: {
            "content": {
                "application/json": {},
                "text/csv": {},
                EXPORT_FORMATS["xlsx"]: {},
                "application/octet-stream": {},
                "text/plain": {},
            }
        },
    },
)
def export_one(ride_id: Id, fmt: ExportFormat, club: ClubDep, storage: StorageDep) -> Response:
    """Download the ride's result.

    As JSON (CONTRACTS section 2), its indicators as CSV or xlsx, or the 3-D tracks of the markers and
    the saddle point S (motion frame, mm) as C3D or TRC.
    """
    data, name = export_ride(club.session, storage, ride_id, fmt, club_id=club.club_id)
    return download(data, name, EXPORT_FORMATS[fmt])

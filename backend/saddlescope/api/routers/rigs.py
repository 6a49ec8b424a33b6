"""Rigs (a day's three-camera set-up): metadata, their calibration, plumb and static clips, calibration."""

from __future__ import annotations

import datetime as dt
import json
from typing import Annotated, Any, TypedDict

from fastapi import APIRouter, Query, Request, Response, status
from fastapi.responses import HTMLResponse
from starlette.concurrency import run_in_threadpool

from saddlescope.api.deps import AdminClubDep, ClubDep, QueueDep, SessionFactoryDep, SettingsDep, StorageDep
from saddlescope.api.rig_schemas import (
    BoardLayoutOut,
    BoardSizesOut,
    CalibrateIn,
    CalibrationCheckOut,
    CalibrationReportOut,
    SquareAtDistance,
)
from saddlescope.api.routers.clips import UPLOAD_ERRORS, receive_clip
from saddlescope.api.routers.common import CONFLICT, ERRORS, Id, PagingDep, changes, page_of
from saddlescope.api.schemas import (
    CameraRole,
    ClipUploaded,
    ErrorOut,
    JobOut,
    Page,
    RecordingOut,
    RigDetail,
    RigIn,
    RigOut,
    RigUpdate,
)
from saddlescope.api.security_headers import inline_style_hashes, report_csp
from saddlescope.api.streaming import UPLOAD_OPENAPI
from saddlescope.db.repositories import Conflict, NotFound, Rig
from saddlescope.db.session import session_scope
from saddlescope.services.jobs.lifecycle import get_job, job_as_dict, submit_job
from saddlescope.services.rides.registration import refresh_rig_rides_status
from saddlescope.services.rigs.board_print import board_advice, board_print_html, camera_view
from saddlescope.services.rigs.calibration_check import check_storage_key
from saddlescope.services.rigs.calibration_way import CalibrationWay, choose_calibration_way
from saddlescope.services.rigs.views import board_svg, board_words, calibration_words, coverage_words
from saddlescope.services.uploads.intake import (
    ClipOwner,
    remove_upload_files,
)

__all__ = ["rig_out", "router"]

router = APIRouter(prefix="/rigs", tags=["rigs"])


class _RigFields(TypedDict):
    """The fields of `RigOut`, read from a rig row (`RigDetail` adds the calibration)."""

    id: int
    name: str
    recorded_on: dt.date | None
    cameras: dict[str, Any]
    board: dict[str, Any] | None
    board_text: str
    wand_length_m: float | None
    calibrated: bool
    quality: dict[str, Any] | None
    created_at: dt.datetime


def rig_out(rig: Rig, *, detail: bool = False) -> RigOut:
    """The list view of a rig, or (`detail`) the view with its calibration."""
    data: _RigFields = {
        "id": rig.id,
        "name": rig.name,
        "recorded_on": rig.recorded_on,
        "cameras": rig.cameras or {},
        "board": rig.board,
        "board_text": board_words(rig.board),
        "wand_length_m": rig.wand_length_m,
        "calibrated": rig.calibration is not None,
        "quality": rig.quality,
        "created_at": rig.created_at,
    }
    return RigDetail(**data, calibration=rig.calibration) if detail else RigOut(**data)


@router.get("", response_model=Page[RigOut], responses=ERRORS)
def list_rigs(
    club: ClubDep,
    paging: PagingDep,
    q: Annotated[str | None, Query(max_length=200, description="name contains")] = None,
) -> dict:
    """The club's rigs; sort by recorded_on (default, newest first), name, created_at, id."""
    page = club.rigs.list_page(name_like=q, sort=paging.sort, limit=paging.limit, offset=paging.offset)
    return page_of(page, rig_out)


@router.post("", status_code=status.HTTP_201_CREATED, response_model=RigOut, responses=ERRORS)
def create_rig(body: RigIn, club: ClubDep) -> RigOut:
    """A new rig; give its `board` so its calibration clips can be used."""
    data = body.model_dump(exclude_none=True)
    return rig_out(
        club.rigs.add(
            name=data["name"],
            recorded_on=data.get("recorded_on"),
            cameras=data.get("cameras"),
            board=data.get("board"),
            wand_length_m=data.get("wand_length_m"),
        )
    )


@router.get("/{rig_id}", response_model=RigDetail, responses=ERRORS)
def read_rig(rig_id: Id, club: ClubDep) -> RigOut:
    """A rig with its calibration (the result's ``calibration`` object) once calibrated."""
    return rig_out(club.rigs.get(rig_id), detail=True)


@router.patch("/{rig_id}", response_model=RigOut, responses=ERRORS)
def update_rig(rig_id: Id, body: RigUpdate, club: ClubDep) -> RigOut:
    """Change a rig's details (a null recorded_on, board or wand_length_m clears it).

    A new wand length forgets a calibration the wand made (its scale was the old length's).
    """
    values = changes(body, nullable=("recorded_on", "board", "wand_length_m"))
    if "board" in values:
        club.require("rig.change_board")
    if "board" in values and values["board"] is not None:
        values["board"] = {k: v for k, v in values["board"].items() if v is not None}
    _forget_a_wand_calibration(club, rig_id, values.get("wand_length_m", ...))
    return rig_out(club.rigs.update_fields(rig_id, **values))


def _forget_a_wand_calibration(club, rig_id: int, wand_length_m) -> None:
    """A rig calibrated with a wand of another length than `wand_length_m` (... : unchanged) loses it."""
    rig = club.rigs.get(rig_id)
    if wand_length_m is ... or wand_length_m == rig.wand_length_m:
        return
    if rig.calibration and "wand" in rig.calibration:
        club.rigs.clear_calibration(rig_id)
        refresh_rig_rides_status(club.session, rig_id)  # its rides may no longer be complete


@router.delete("/{rig_id}", status_code=status.HTTP_204_NO_CONTENT, responses={**ERRORS, **CONFLICT})
def delete_rig(rig_id: Id, club: AdminClubDep, storage: StorageDep) -> Response:
    """Delete a rig no ride uses, with its clips (admins only; 409 while rides use it)."""
    uploads = club.uploads.ids_of(rig_id=rig_id)
    club.rigs.delete(rig_id)
    club.session.commit()
    storage.delete(f"rigs/{rig_id}")
    remove_upload_files(storage, uploads)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get("/{rig_id}/clips", response_model=list[RecordingOut], responses=ERRORS)
def list_rig_clips(rig_id: Id, club: ClubDep) -> list[RecordingOut]:
    """The rig's clips (calibration, plumb and static; shared by its rides)."""
    club.rigs.get(rig_id)
    return [RecordingOut.model_validate(r) for r in club.recordings.for_rig(rig_id)]


@router.put(
    "/{rig_id}/clips/{clip_kind}/{camera}",
    response_model=ClipUploaded,
    openapi_extra=UPLOAD_OPENAPI,
    responses=UPLOAD_ERRORS,
)
async def upload_rig_clip(
    rig_id: Id,
    clip_kind: str,
    camera: CameraRole,
    request: Request,
    club: ClubDep,
    settings: SettingsDep,
    storage: StorageDep,
    sessions: SessionFactoryDep,
    queue: QueueDep,
) -> ClipUploaded:
    """Upload one camera's calibration, plumb or static clip of the rig (multipart field `file`, or raw bytes).

    It is probed at once; a clip that does not decode, or whose frame rate or size differs from the other
    cameras' clips of the set, is refused (422) and any earlier clip stays. The third calibration clip
    starts the rig's calibration job.
    """
    await run_in_threadpool(club.rigs.get, rig_id)
    return await receive_clip(request, ClipOwner("rig", rig_id, club.club_id), clip_kind, camera, club=club,
                              settings=settings, storage=storage, sessions=sessions, queue=queue)


@router.post(
    "/{rig_id}/calibrate",
    status_code=status.HTTP_201_CREATED,
    response_model=JobOut,
    responses={**ERRORS, 503: {"model": ErrorOut}},
)
async def calibrate_rig(rig_id: Id, club: ClubDep, sessions: SessionFactoryDep, queue: QueueDep,
                        body: CalibrateIn | None = None) -> JobOut:
    """(Re)calibrate the rig (a `calibrate_rig` job): the board walk's three calibration clips, a wand, or both.

    The wand way (issue 35) takes each camera's wand and close-up clips and the rig's wand length
    (``wand_length_m`` here sets it); the board+wand way the calibration clips refined by the wand clips (the
    refinement kept only where it helps). Without ``method``: board+wand when the calibration and wand clips
    and the length are there, else the wand way when its clips and length are, else the board walk. 422 for a
    way with a wand but without its length, 409 for clips or the board missing, in words.
    """
    body = body or CalibrateIn()
    way = await run_in_threadpool(_calibration_way, club, rig_id, body)
    club.session.commit()  # the wand length given with the request, before the job reads the rig
    job_id = await run_in_threadpool(
        submit_job, sessions, queue, kind="calibrate_rig", rig_id=rig_id, club_id=club.club_id,
        payload={"method": way.method} if body.method else None,
    )
    with session_scope(sessions) as session:
        return JobOut(**job_as_dict(get_job(session, job_id)))


def _calibration_way(club, rig_id: int, body: CalibrateIn) -> CalibrationWay:
    """The way the rig's calibration job will take (refused in words when it cannot)."""
    if body.wand_length_m is not None:
        _forget_a_wand_calibration(club, rig_id, body.wand_length_m)
        club.rigs.update_fields(rig_id, wand_length_m=body.wand_length_m)
    rig = club.rigs.get(rig_id)
    return choose_calibration_way(rig, club.recordings.for_rig(rig_id), body.method)


@router.get(
    "/{rig_id}/board.svg",
    response_class=Response,
    responses={**ERRORS, 200: {"content": {"image/svg+xml": {}}, "description": "the board at true scale"}},
)
def rig_board_svg(rig_id: Id, club: ClubDep) -> Response:
    """The rig's calibration board to print: an SVG sized in mm (print at 100 %); 404 without a board."""
    rig = club.rigs.get(rig_id)
    if not rig.board:
        raise NotFound(f"rig {rig_id} ({rig.name}) has no board described yet")
    return Response(board_svg(rig.board), media_type="image/svg+xml",
                    headers={"Content-Disposition": f'inline; filename="rig-{rig_id}-board.svg"'})


def _board_of(club, rig_id: int) -> tuple[Rig, dict[str, Any]]:
    """The rig and its board's description (NotFound without one)."""
    rig = club.rigs.get(rig_id)
    if not rig.board:
        raise NotFound(f"rig {rig_id} ({rig.name}) has no board described yet")
    return rig, rig.board


@router.get("/{rig_id}/board-sizes", response_model=BoardSizesOut, responses=ERRORS)
def rig_board_sizes(rig_id: Id, club: ClubDep) -> BoardSizesOut:
    """The board's printed size in mm, the papers it fits (A4, A3, posters, A4 tiles) and the trade-off.

    Which square each camera distance needs, for the rig's own cameras (calibrated focal length, else its
    clips' width with a phone's 70 degree view, else a 1080p phone); 404 without a board.
    """
    rig, board = _board_of(club, rig_id)
    widths = [r.width for r in club.recordings.for_rig(rig_id) if r.width]
    advice = board_advice(board, camera_view(rig.calibration, widths))
    return BoardSizesOut(
        width_mm=advice.width_mm, height_mm=advice.height_mm, square_mm=advice.square_mm,
        image_width_px=advice.view.image_width_px, hfov_deg=advice.view.hfov_deg,
        camera_source=advice.view.source,  # type: ignore[arg-type]
        min_square_px=advice.min_square_px, reach_m=round(advice.reach_m, 2),
        squares_needed=[SquareAtDistance(distance_m=d, square_mm=round(mm, 1))
                        for d, mm in advice.square_needed_mm.items()],
        layouts=[BoardLayoutOut(layout=lay.layout, label=lay.label, sheets=lay.sheets, fits=lay.fits,
                                landscape=lay.landscape, largest_square_mm=round(lay.largest_square_mm, 1),
                                reach_m=round(lay.reach_m, 2)) for lay in advice.layouts],
        sentences=advice.sentences)


@router.get("/{rig_id}/board-print", response_class=HTMLResponse,
            responses={**ERRORS, 200: {"content": {"text/html": {}}, "description": "the print page"}})
def rig_board_print(
    rig_id: Id,
    club: ClubDep,
    layout: Annotated[str, Query(description="a4, a3, a2, a1, a0 (one sheet) or a4-tiles")] = "a4-tiles",
) -> HTMLResponse:
    """The board as a print page: every sheet at its size in mm (``@page``), a 100 mm ruler on each.

    422 when the board does not fit one sheet of the paper asked for (the answer says the largest square
    that would); 404 without a board.
    """
    rig, board = _board_of(club, rig_id)
    page = board_print_html(board, layout, rig_name=rig.name)
    return HTMLResponse(page, headers={"Cache-Control": "private, no-cache",
                                       "Content-Security-Policy": report_csp(inline_style_hashes(page))})


@router.get("/{rig_id}/calibration-check", response_model=CalibrationCheckOut, responses=ERRORS)
def rig_calibration_check(rig_id: Id, club: ClubDep, storage: StorageDep) -> CalibrationCheckOut:
    """The latest check of the rig's calibration clips: per camera where the board went, and a verdict.

    The check runs by itself on every calibration clip uploaded (a ``check_calibration`` job, a minute or
    two); ``checking`` while one is queued or running.
    """
    club.rigs.get(rig_id)
    checking = club.jobs.active_for(rig_id=rig_id, kind="check_calibration") is not None
    key, wand_key = check_storage_key(rig_id), check_storage_key(rig_id, "wand")
    wand = json.loads(storage.read_bytes(wand_key)) if storage.exists(wand_key) else None
    if not storage.exists(key):
        return CalibrationCheckOut(checked=False, checking=checking, wand=wand, verdict=(
            "Checking the calibration clips\u2026" if checking else
            "Not checked yet: upload a calibration clip and it is checked at once."))
    document = json.loads(storage.read_bytes(key))
    return CalibrationCheckOut(checked=True, checking=checking, wand=wand, **document)


@router.post("/{rig_id}/calibration-check", status_code=status.HTTP_201_CREATED, response_model=JobOut,
             responses={**ERRORS, 503: {"model": ErrorOut}})
async def check_rig_calibration(rig_id: Id, club: ClubDep, sessions: SessionFactoryDep, queue: QueueDep) -> JobOut:
    """Check the rig's calibration clips again (a ``check_calibration`` job); 409 with no clip to check."""
    rig = await run_in_threadpool(club.rigs.get, rig_id)
    kinds = {r.clip_kind for r in await run_in_threadpool(club.recordings.for_rig, rig_id)}
    board_ready = "calibration" in kinds and bool(rig.board)
    wand_ready = "wand" in kinds and rig.wand_length_m is not None
    if not (board_ready or wand_ready):
        raise Conflict(f"rig {rig_id} ({rig.name}) has " + ("no board described" if "calibration" in kinds else
                                                            "no calibration clip") + " to check yet"
                       + ("" if "wand" not in kinds else ", and no wand length for its wand clips"))
    club.session.rollback()
    job_id = await run_in_threadpool(
        submit_job, sessions, queue, kind="check_calibration", rig_id=rig_id, club_id=club.club_id
    )
    with session_scope(sessions) as session:
        return JobOut(**job_as_dict(get_job(session, job_id)))


@router.get("/{rig_id}/calibration-report", response_model=CalibrationReportOut, responses=ERRORS)
def rig_calibration_report(rig_id: Id, club: ClubDep) -> CalibrationReportOut:
    """The calibration in plain words, and per camera where in the image the board has been.

    ``quality``: reprojection px and board square error mm, each with a verdict; ``coverage``: per camera
    the board corners seen, their hull and the parts of the image the board never reached.
    """
    rig = club.rigs.get(rig_id)
    job = club.jobs.active_for(rig_id=rig_id, kind="calibrate_rig")
    return CalibrationReportOut.model_validate(
        {"quality": calibration_words(rig.calibration), "coverage": coverage_words(rig.calibration),
         "calibrating": job is not None}, from_attributes=True)

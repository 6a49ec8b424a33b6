"""Resumable uploads (tus-like) for large phone videos: create, send chunks at offsets, resume, finalise."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Body, Header, Path, Request, Response, status
from pydantic import TypeAdapter
from starlette.concurrency import run_in_threadpool

from saddlescope.api.deps import ClubDep, QueueDep, SessionFactoryDep, SettingsDep, StorageDep
from saddlescope.api.routers.common import ERRORS
from saddlescope.api.schemas import ErrorOut, UploadCreate
from saddlescope.api.streaming import stream_chunk
from saddlescope.api.upload_schemas import (
    BundleChoice,
    BundleFinalisedOut,
    BundleMetaOut,
    ClipFinalisedOut,
    FinalisedOut,
    OffsetConflictOut,
    PartNumbers,
    PartsOut,
    PartUrlsOut,
    UploadCreatedOut,
    UploadOut,
)
from saddlescope.db.enums import UploadStatus
from saddlescope.db.repositories import Upload
from saddlescope.services.uploads.direct import (
    S3_PARTS,
    STREAM,
    is_direct,
    part_urls,
    parts_state,
    start_direct,
    transport_for,
)
from saddlescope.services.uploads.intake import (
    IncompleteUpload,
    bundle_meta,
    commit_chunk,
    create_upload,
    expire_uploads,
    finalise_upload,
    remove_upload_files,
)
from saddlescope.services.uploads.outcome import BundleFinalised, UploadOutcome
from saddlescope.storage import upload_chunk_key

__all__ = ["CHUNK_OPENAPI", "OffsetMismatch", "UploadId", "router"]

router = APIRouter(prefix="/uploads", tags=["uploads"])
UploadId = Annotated[str, Path(pattern=r"^[0-9a-f]{32}$", description="the upload's id")]
CHUNK_OPENAPI = {
    "requestBody": {
        "required": True,
        "content": {"application/offset+octet-stream": {"schema": {"type": "string", "format": "binary"}}},
    }
}


class OffsetMismatch(IncompleteUpload):
    """A chunk's Upload-Offset is not where the upload stands, or the upload takes no more bytes (HTTP 409)."""


def _headers(upload: Upload) -> dict[str, str]:
    return {
        "Upload-Offset": str(upload.offset_bytes),
        "Upload-Length": str(upload.length_bytes),
        "Cache-Control": "no-store",
    }


_PARTS = TypeAdapter(PartsOut)


@router.post(
    "",
    status_code=status.HTTP_201_CREATED,
    response_model=UploadCreatedOut,
    responses={**ERRORS, 413: {"model": ErrorOut}},
)
def create(
    body: UploadCreate, club: ClubDep, settings: SettingsDep, storage: StorageDep, response: Response
) -> UploadCreatedOut:
    """Start a resumable upload of a ride's or rig's clip, or of a ride bundle zip; then send its bytes.

    `transport` says how: ``stream`` (PATCH chunks here) or, on object storage, ``s3-parts`` (PUT parts
    of `part_bytes` straight to the bucket, to URLs from ``POST /uploads/{id}/parts``). An open upload that
    receives nothing for `upload_expiry_s` (24 h by default) is removed with its bytes.
    """
    expire_uploads(club.session, storage, max_age_s=settings.upload_expiry_s)
    upload = create_upload(
        club.session,
        club_id=club.club_id,
        user_id=club.principal.user_id,
        target=body.target,
        length_bytes=body.length_bytes,
        max_bytes=settings.max_upload_bytes,
        ride_id=body.ride_id,
        rig_id=body.rig_id,
        clip_kind=body.clip_kind,
        camera=body.camera,
        filename=body.filename,
    )
    sending = {"transport": STREAM}
    if transport_for(storage, settings) == S3_PARTS:
        sending = start_direct(storage, upload.id, upload.length_bytes)
    response.headers["Location"] = f"/api/uploads/{upload.id}"
    response.headers.update(_headers(upload))
    return UploadCreatedOut.model_validate({**UploadOut.model_validate(upload).model_dump(), **sending})


@router.post("/{upload_id}/parts", response_model=PartUrlsOut, responses={**ERRORS, 409: {"model": ErrorOut}})
def sign_parts(upload_id: UploadId, body: PartNumbers, club: ClubDep, storage: StorageDep) -> PartUrlsOut:
    """Pre-signed URLs to PUT parts `numbers` of a direct upload to (``{"urls": {"1": url}, "expires_s"}``)."""
    urls = part_urls(club.session, storage, upload_id, body.numbers, club_id=club.club_id)
    return PartUrlsOut.model_validate(urls, from_attributes=True)


@router.get("/{upload_id}/parts", response_model=PartsOut, responses=ERRORS)
def read_parts(upload_id: UploadId, club: ClubDep, storage: StorageDep) -> PartsOut:
    """Which parts of a direct upload arrived (resume by sending the others) and the bytes in order."""
    state = parts_state(club.session, storage, upload_id, club_id=club.club_id)
    return _PARTS.validate_python(state, from_attributes=True)


@router.get("/{upload_id}", response_model=UploadOut, responses=ERRORS)
def read(upload_id: UploadId, club: ClubDep, response: Response) -> UploadOut:
    """The upload's state; `offset_bytes` is where to resume."""
    upload = club.uploads.get(upload_id)
    response.headers.update(_headers(upload))
    return UploadOut.model_validate(upload)


@router.head("/{upload_id}", status_code=status.HTTP_200_OK, responses=ERRORS)
def offset(upload_id: UploadId, club: ClubDep) -> Response:
    """The offset to resume from, in the `Upload-Offset` header (and the total in `Upload-Length`)."""
    return Response(status_code=status.HTTP_200_OK, headers=_headers(club.uploads.get(upload_id)))


@router.patch(
    "/{upload_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    openapi_extra=CHUNK_OPENAPI,
    responses={
        **ERRORS,
        409: {"model": OffsetConflictOut, "description": "wrong offset (resume from `offset_bytes`), or not open"},
        413: {"model": ErrorOut},
    },
)
async def append(
    upload_id: UploadId,
    request: Request,
    club: ClubDep,
    storage: StorageDep,
    upload_offset: Annotated[int, Header(alias="Upload-Offset", ge=0, le=2**62)],
    settings: SettingsDep,
) -> Response:
    """Send the next chunk (the raw body) starting at byte `Upload-Offset`.

    `Upload-Offset` must be the upload's current offset; a retried chunk at an earlier offset is accepted
    when it equals the bytes already received there (answering the current offset), else 409 with the
    server's offset (its `Upload-Offset` header and `offset_bytes`). Acknowledged bytes are never rewritten.
    Answers 204 with the new `Upload-Offset`. An expired upload is gone (404).
    """
    await run_in_threadpool(expire_uploads, club.session, storage, max_age_s=settings.upload_expiry_s)
    upload = await run_in_threadpool(club.uploads.get, upload_id)
    if upload.status != UploadStatus.OPEN.value:
        raise OffsetMismatch(f"upload {upload_id} is {upload.status}; it takes no more bytes")
    if upload_offset > upload.offset_bytes:
        raise OffsetMismatch(
            f"Upload-Offset {upload_offset} does not match the upload's offset "
            f"{upload.offset_bytes}; resume from {upload.offset_bytes}",
            offset_bytes=upload.offset_bytes,
        )
    if await run_in_threadpool(is_direct, storage, upload_id):
        raise OffsetMismatch(f"upload {upload_id} is sent to the bucket directly: PUT its parts to the URLs "
                             "from POST /api/uploads/{id}/parts")
    length, staged = upload.length_bytes, upload_chunk_key(upload_id)
    club.session.rollback()  # no transaction open while the bytes arrive
    try:
        size = await stream_chunk(request, storage, staged, offset=upload_offset, limit=length)
        end = await run_in_threadpool(
            commit_chunk, club.session, storage, upload_id, offset=upload_offset, staged_key=staged,
            size=size, club_id=club.club_id,
        )
    finally:
        await run_in_threadpool(storage.delete, staged)
    return Response(
        status_code=status.HTTP_204_NO_CONTENT,
        headers={"Upload-Offset": str(end), "Upload-Length": str(length)},
    )


@router.post(
    "/{upload_id}/finalize",
    response_model=FinalisedOut,
    responses={**ERRORS, 409: {"model": ErrorOut}, 503: {"model": ErrorOut}},
)
async def finalize(
    upload_id: UploadId,
    club: ClubDep,
    storage: StorageDep,
    sessions: SessionFactoryDep,
    queue: QueueDep,
    settings: SettingsDep,
    body: Annotated[BundleChoice | None, Body()] = None,
) -> FinalisedOut:
    """Turn the complete upload into a clip (probed as a direct upload is) or a ride (bundle).

    Starts the processing the new clips allow. Returns ``{"recording_id", "job_id"}`` (with ``missing``:
    what the ride still needs, when no job started) or ``{"ride_id", "job_id"}``. A bundle's ride takes
    the body's horse, rider, gait, direction, date and notes where given. An expired upload is gone (404).
    """
    await run_in_threadpool(expire_uploads, club.session, storage, max_age_s=settings.upload_expiry_s)
    club_id = club.club_id
    club.session.rollback()
    chosen = body.model_dump(exclude_none=True) if body is not None else None
    outcome = await run_in_threadpool(finalise_upload, sessions, storage, queue, upload_id, club_id=club_id,
                                      chosen=chosen)
    return _finalised_out(outcome)


def _finalised_out(outcome: UploadOutcome) -> FinalisedOut:
    if isinstance(outcome, BundleFinalised):
        return BundleFinalisedOut.model_validate(outcome, from_attributes=True)
    return ClipFinalisedOut.model_validate(outcome, from_attributes=True)


@router.get("/{upload_id}/bundle-meta", response_model=BundleMetaOut, responses={**ERRORS, 409: {"model": ErrorOut}})
def read_bundle_meta(upload_id: UploadId, club: ClubDep, storage: StorageDep) -> BundleMetaOut:
    """A complete bundle upload's ride.json, to pre-fill the form before finalising (nothing is created).

    ``horse`` and ``rider`` give the name ride.json uses and the id of the club's horse or rider of that
    name (None: not in the club). 409 until every byte has arrived.
    """
    meta = bundle_meta(club.session, storage, upload_id, club_id=club.club_id)
    return BundleMetaOut.model_validate(meta, from_attributes=True)


@router.delete("/{upload_id}", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
def abandon(upload_id: UploadId, club: ClubDep, storage: StorageDep) -> Response:
    """Abandon an upload and delete its bytes."""
    club.uploads.delete(upload_id)
    club.session.commit()
    remove_upload_files(storage, [upload_id])
    return Response(status_code=status.HTTP_204_NO_CONTENT)

"""Receiving one camera's clip, for rides and rigs alike: stream, probe, store, start processing."""

from __future__ import annotations

from fastapi import Request
from starlette.concurrency import run_in_threadpool

from saddlescope.api.routers.common import ERRORS
from saddlescope.api.schemas import ClipUploaded, ErrorOut, RecordingOut
from saddlescope.api.streaming import stream_upload
from saddlescope.db.repositories import RecordingRepository
from saddlescope.db.session import session_scope
from saddlescope.services.uploads.intake import (
    ClipOwner,
    accept_clip,
    check_clip_slot,
    staging_key,
    start_calibration_check,
    start_processing,
)

__all__ = ["UPLOAD_ERRORS", "receive_clip"]

UPLOAD_ERRORS = {
    **ERRORS,
    413: {"model": ErrorOut, "description": "larger than the upload limit"},
    503: {"model": ErrorOut, "description": "the job queue is unreachable"},
}


async def receive_clip(request: Request, owner: ClipOwner, clip_kind: str, camera: str, *, club, settings,
                       storage, sessions, queue) -> ClipUploaded:
    """Receive one clip of a ride or a rig and start what it completes.

    The body is streamed to staging (the size limit enforced while streaming), then probed and stored in
    the owner's clip slot (refused with the reason, the earlier clip kept).
    """
    check_clip_slot(owner, clip_kind, camera)
    club.session.rollback()  # end the read transaction: the upload may take minutes
    staged = await stream_upload(
        request,
        storage,
        staging_key(owner.club_id, request.headers.get("x-filename")),
        max_bytes=settings.max_upload_bytes,
    )
    recording_id = await run_in_threadpool(
        accept_clip,
        sessions,
        storage,
        owner,
        clip_kind,
        camera,
        staged.key,
        size_bytes=staged.size_bytes,
        sha256=staged.sha256,
        filename=staged.filename,
    )
    await run_in_threadpool(start_calibration_check, sessions, queue, owner, clip_kind)
    job_id = await run_in_threadpool(start_processing, sessions, queue, owner)
    with session_scope(sessions) as session:
        recording = RecordingRepository(session, club_id=owner.club_id).get(recording_id)
        return ClipUploaded(recording=RecordingOut.model_validate(recording), job_id=job_id)

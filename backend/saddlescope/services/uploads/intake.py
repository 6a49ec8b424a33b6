"""Use cases of uploads: accept a clip, a ride bundle or a resumable upload, then start what it allows.

A clip is probed and checked against the other cameras' clips of its set; whatever processing the
new clip makes possible is started.

The bytes arrive elsewhere (the API streams them into storage with `Storage.writer`); these functions
take the *staged* storage key of a complete file. A refused file is deleted and leaves every earlier
clip, recording and ride as it was.
"""

from __future__ import annotations

import datetime as dt
import logging
import re
import secrets
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypedDict

from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import BundleError, InputError, SaddleScopeError, VideoError
from saddlescope.core.types import CAMERA_ROLES, CLIP_KINDS, WAND_CLIP_KINDS
from saddlescope.db.enums import JobStatus, UploadStatus, UploadTarget
from saddlescope.db.models import Recording
from saddlescope.db.repositories import (
    Conflict,
    JobRepository,
    NotFound,
    RecordingRepository,
    RideRepository,
    RigRepository,
    UploadRepository,
)
from saddlescope.db.session import session_scope
from saddlescope.services.jobs.lifecycle import submit_job
from saddlescope.services.jobs.queue import JobQueue, QueueUnavailable
from saddlescope.services.rides.readiness import missing_for_ride
from saddlescope.services.rides.registration import (
    DuplicateClips,
    duplicate_message,
    refresh_ride_status,
    refresh_rig_rides_status,
    register_bundle,
    remove_bundle_ride,
    ride_clip_plan,
)
from saddlescope.services.rigs.calibration_way import choose_calibration_way
from saddlescope.services.uploads.direct import check_parts, is_direct
from saddlescope.services.uploads.outcome import BundleFinalised, ClipFinalised, UploadOutcome, outcome_from_json
from saddlescope.storage import FileStorage, S3Storage, Storage, TooLarge, direct_upload_key, upload_key

if TYPE_CHECKING:
    from saddlescope.io.video import VideoInfo
    from saddlescope.services.uploads.bundle_meta import BundleMeta

__all__ = [
    "BUNDLE_BLOCK_BYTES", "ClipOwner", "FPS_TOLERANCE", "IncompleteUpload", "RIDE_CLIP_KINDS", "RIG_CLIP_KINDS",
    "accept_bundle",
    "accept_clip", "check_clip_slot", "clip_suffix", "commit_chunk", "create_upload", "expire_uploads",
    "FINALISE_WAIT_S", "FinaliseInProgress",
    "bundle_meta", "finalise_upload", "find_owner", "remove_upload_files", "staging_key", "start_calibration_check",
    "start_processing",
    "sweep_abandoned",
]

# A rig's wand way (issue 35): each camera's wand clip and close-up board clip, beside the board walk's.
RIG_CLIP_KINDS = ("calibration", "plumb", "static", *WAND_CLIP_KINDS)
# Clips a rig's calibration is computed from: a new one makes the calibration stale.
_CALIBRATING_KINDS = ("calibration", *WAND_CLIP_KINDS)
RIDE_CLIP_KINDS = CLIP_KINDS
# Frame rates of one clip set may differ by rounding in the container (29.97 written as 30000/1001 ...).
FPS_TOLERANCE = 0.005
log = logging.getLogger(__name__)
_SUFFIX = re.compile(r"^\.[a-z0-9]{1,8}$")


class OwnerColumns(TypedDict):
    """The columns naming a clip's owner: one of the two is set."""

    ride_id: int | None
    rig_id: int | None


@dataclass(frozen=True)
class ClipOwner:
    """A ride or a rig of a club, whose clip `clip_kind` of camera `camera` is being uploaded."""

    kind: str  # "ride" or "rig"
    id: int
    club_id: int

    @property
    def label(self) -> str:
        """The owner in words (``ride 3``)."""
        return f"{self.kind} {self.id}"

    def where(self) -> OwnerColumns:
        """The recording columns naming this owner (``ride_id`` and ``rig_id``)."""
        return (
            {"ride_id": self.id, "rig_id": None}
            if self.kind == "ride"
            else {"ride_id": None, "rig_id": self.id}
        )


def staging_key(club_id: int, filename: str | None = None) -> str:
    """A fresh storage key for bytes still to be checked (``incoming/<club>/<random><suffix>``)."""
    return f"incoming/{club_id}/{secrets.token_hex(12)}{clip_suffix(filename)}"


def clip_suffix(filename: str | None, default: str = "") -> str:
    """The lower-case suffix of an uploaded file's name, when it is a plain one (".mp4"), else `default`."""
    if not filename:
        return default
    suffix = "." + filename.rsplit(".", 1)[-1].lower() if "." in filename else ""
    return suffix if _SUFFIX.match(suffix) else default


def check_clip_slot(owner: ClipOwner, clip_kind: str, camera: str) -> None:
    """The clip kind and camera name must be ones this owner can have."""
    kinds = RIDE_CLIP_KINDS if owner.kind == "ride" else RIG_CLIP_KINDS
    if clip_kind not in kinds:
        raise InputError(f"a {owner.kind} has no {clip_kind!r} clips; it takes {', '.join(kinds)}")
    if camera not in CAMERA_ROLES:
        raise InputError(f"unknown camera {camera!r}; the cameras are {', '.join(CAMERA_ROLES)}")


def find_owner(
    session: Session, *, club_id: int, ride_id: int | None = None, rig_id: int | None = None
) -> ClipOwner:
    """The ride or rig (of this club: `NotFound` otherwise)."""
    if ride_id is not None and rig_id is None:
        RideRepository(session, club_id=club_id).get(ride_id)
        return ClipOwner("ride", ride_id, club_id)
    if rig_id is not None and ride_id is None:
        RigRepository(session, club_id=club_id).get(rig_id)
        return ClipOwner("rig", rig_id, club_id)
    raise InputError("name exactly one of ride_id and rig_id")


def _agreement(owner: ClipOwner, clip_kind: str, camera: str, info, others: list[Recording]) -> None:
    """The cameras of one clip set must share frame rate and frame size (one synchronised recording)."""
    for other in others:
        if other.camera_role == camera or other.fps is None:
            continue
        what = f"{owner.label}: the {clip_kind} clip of the {camera} camera"
        if abs(info.fps - other.fps) > FPS_TOLERANCE * other.fps:
            raise VideoError(
                f"{what} runs at {info.fps:.3f} fps but the {other.camera_role} camera's at "
                f"{other.fps:.3f} fps; the three cameras of a clip set must use the same frame rate"
            )
        if (info.width, info.height) != (other.width, other.height):
            raise VideoError(
                f"{what} is {info.width}x{info.height} px but the {other.camera_role} camera's is "
                f"{other.width}x{other.height} px; the three cameras must record the same size"
            )


def _probe_staged(storage: Storage, owner: ClipOwner, clip_kind: str, camera: str, staged_key: str, *,
                  size_bytes: int, filename: str | None) -> VideoInfo | None:
    """The staged clip's `VideoInfo` (None on object storage, where the worker's probe stage reads it).

    Raises `VideoError` naming the owner, the clip and the user's file (never the staging path) for an
    empty, unreadable or too short clip.
    """
    from saddlescope.io.video import probe_video, too_short_for

    name = filename or "the upload"
    if size_bytes == 0:
        raise VideoError(f"{owner.label}: the {clip_kind} clip of the {camera} camera is an empty file")
    if not isinstance(storage, FileStorage):
        return None  # on object storage the worker's probe stage reads the clip (the API keeps no video bytes)
    path = storage.path(staged_key)
    try:
        info = probe_video(path)
    except VideoError as exc:
        # The staging path means nothing to the user (and says where storage lives): name the file.
        reason = str(exc).replace(str(path), name).removeprefix(f"{name}: ")
        raise VideoError(
            f"{owner.label}: the {clip_kind} clip of the {camera} camera ({name}) is not a usable video: {reason}"
        ) from None
    if short := too_short_for(clip_kind, info):
        raise VideoError(f"{owner.label}: the {clip_kind} clip of the {camera} camera ({name}) is too short: {short}")
    return info


def accept_clip(
    sessions: sessionmaker[Session],
    storage: Storage,
    owner: ClipOwner,
    clip_kind: str,
    camera: str,
    staged_key: str,
    *,
    size_bytes: int,
    sha256: str,
    filename: str | None,
) -> int:
    """Probe a staged clip and, if usable, make it the owner's clip (replacing an earlier one).

    Returns the recording id. Raises `VideoError` (unusable video, or disagreeing with the other cameras
    of its set) or `InputError`; the staged file is deleted either way, earlier clips are untouched.
    """
    try:
        check_clip_slot(owner, clip_kind, camera)
        info = _probe_staged(storage, owner, clip_kind, camera, staged_key, size_bytes=size_bytes, filename=filename)
        final_key = (
            f"{owner.kind}s/{owner.id}/clips/{clip_kind}/{camera}-{sha256[:12]}"
            f"{clip_suffix(filename, '.video')}"
        )
        with session_scope(sessions) as session:
            recordings = RecordingRepository(session, club_id=owner.club_id)
            others = [
                r
                for r in (
                    recordings.for_ride(owner.id) if owner.kind == "ride" else recordings.for_rig(owner.id)
                )
                if r.clip_kind == clip_kind
            ]
            if info is not None:
                _agreement(owner, clip_kind, camera, info, others)
            _refuse_known_clip(recordings, owner, clip_kind, camera, sha256, filename)
            previous = next((r.path for r in others if r.camera_role == camera), None)
            storage.move(staged_key, final_key)
            try:
                row = recordings.put_clip(
                    **owner.where(),
                    club_id=owner.club_id,
                    clip_kind=clip_kind,
                    camera_role=camera,
                    path=final_key,
                    sha256=sha256,
                    size_bytes=size_bytes,
                    **_probed(info),
                    original_filename=filename,
                )
                if owner.kind == "rig" and clip_kind in _CALIBRATING_KINDS:
                    RigRepository(session, club_id=owner.club_id).clear_calibration(owner.id)
                if owner.kind == "ride":
                    refresh_ride_status(session, owner.id)
                else:  # a rig's clip (and its calibration cleared) decides whether its rides are complete
                    refresh_rig_rides_status(session, owner.id)
                recording_id = row.id
                session.commit()
            except BaseException:
                if final_key != previous:
                    storage.delete(final_key)
                raise
    finally:
        storage.delete(staged_key)
    if previous is not None and previous != final_key:
        storage.delete(previous)  # after the commit: a failed upload never loses the earlier clip
    return recording_id


def _refuse_known_clip(recordings: RecordingRepository, owner: ClipOwner, clip_kind: str, camera: str,
                       sha256: str, filename: str | None) -> None:
    """`DuplicateClips` when this motion clip is already a clip of another ride of the club (same bytes).

    Only motion clips: a day's calibration, plumb and static clips are rightly shared by its rides.
    """
    if owner.kind != "ride" or clip_kind != "motion":
        return
    existing = recordings.ride_with_clip([sha256], exclude_ride_id=owner.id)
    if existing is not None:
        what = f"the motion clip of the {camera} camera ({filename or 'the upload'}) was"
        raise DuplicateClips(duplicate_message(what, existing, kept=f"it was not stored with {owner.label}"),
                             existing_ride_id=existing)


def _probed(info) -> dict[str, Any]:
    """A recording's probe columns from `probe_video`'s answer (None: not probed yet, the probe stage will)."""
    names = ("fps", "frame_count", "width", "height", "codec")
    return {name: getattr(info, name) if info is not None else None for name in names}


def start_calibration_check(sessions: sessionmaker[Session], queue: JobQueue, owner: ClipOwner,
                            clip_kind: str) -> int | None:
    """A rig's calibration or wand clip arrived: check where its board or wand went (a ``check_calibration`` job).

    Not when a check is already waiting to start (it will read this clip too); returns its id or None.
    """
    if owner.kind != "rig" or clip_kind not in ("calibration", "wand"):
        return None
    with session_scope(sessions) as session:
        rig = RigRepository(session, club_id=owner.club_id).get(owner.id)
        if not (rig.board if clip_kind == "calibration" else rig.wand_length_m is not None):
            return None  # nothing to look for yet: the rig page asks for the board or the wand's length first
        waiting = JobRepository(session, club_id=owner.club_id).active_for(rig_id=owner.id, kind="check_calibration")
        if waiting is not None and waiting.status == JobStatus.QUEUED:
            return None
    try:
        return submit_job(sessions, queue, kind="check_calibration", club_id=owner.club_id, rig_id=owner.id)
    except QueueUnavailable:
        return None  # the check is a courtesy: the rig page offers "Check the clips" again


def start_processing(sessions: sessionmaker[Session], queue: JobQueue, owner: ClipOwner) -> int | None:
    """Start the job a newly complete set of clips allows; returns its id (None when nothing to start).

    A rig with its three calibration clips, or its wand and close-up clips and wand length (and a board),
    and no calibration: a ``calibrate_rig`` job, also behind one running on the clips it started with (never a
    second one queued). A ride whose clips are complete: an ``analyze`` job, never a second one while one is
    queued or running.
    """
    with session_scope(sessions) as session:
        jobs = JobRepository(session, club_id=owner.club_id)
        recordings = RecordingRepository(session, club_id=owner.club_id)
        if owner.kind == "rig":
            rig = RigRepository(session, club_id=owner.club_id).get(owner.id)
            if rig.calibration:
                return None
            try:  # the board walk's clips, or the wand's with its length (issue 35)
                choose_calibration_way(rig, recordings.for_rig(owner.id))
            except (Conflict, InputError):
                return None  # not complete yet
            active = jobs.active_for(rig_id=owner.id, kind="calibrate_rig")
            if active is not None and active.status != JobStatus.RUNNING.value:
                return None  # queued: it reads the rig's clips when it starts, this one among them
            # None, or one running on the clips it started with (it will not keep its calibration, `run_calibrate_rig`):
            # a job behind it calibrates from the clips as they are now
            kind = "calibrate_rig"
        else:
            ride = RideRepository(session, club_id=owner.club_id).get(owner.id)
            rig = RigRepository(session).find(ride.rig_id) if ride.rig_id is not None else None
            try:
                ride_clip_plan(
                    recordings.for_ride(ride.id),
                    recordings.for_rig(rig.id) if rig else [],
                    rig_calibrated=bool(rig is not None and rig.calibration),
                )
            except (BundleError, InputError):
                return None  # not complete yet
            if missing_for_ride(session, ride.id, club_id=owner.club_id):
                return None  # it would stop at a missing board or a partial clip set: never queue it
            if jobs.active_for(ride_id=ride.id) is not None:
                return None
            kind = "analyze"
    return submit_job(sessions, queue, kind=kind, club_id=owner.club_id, **owner.where())


# A bundle zip in a bucket is read in place by ranged GETs of this size (few requests, bounded memory).
BUNDLE_BLOCK_BYTES = 8 * 1024**2


def accept_bundle(
    sessions: sessionmaker[Session],
    storage: Storage,
    queue: JobQueue,
    staged_key: str,
    *,
    club_id: int,
    rig_id: int | None = None,
    filename: str | None = None,
    user_id: int | None = None,
    chosen: dict[str, Any] | None = None,
    return_to: str | None = None,
) -> tuple[int, int]:
    """Register a staged ride bundle zip as a ride of the club and start its analysis; (ride id, job id).

    `saddlescope.io.bundle.open_bundle` refuses unsafe zips (``..`` paths, links, bombs), a missing or
    invalid ride.json (unknown gait, camera roles, ...) and missing clips, as a `BundleError` naming the
    user's file (`filename`), not the staging file. The same bundle (same sha256) uploaded again in the
    club is a `Conflict` naming the ride it already is. `chosen`: what the user chose at upload
    (horse_id, rider_id, gait, direction, ridden_on, notes), winning over the bundle's ride.json.

    When the job queue refuses the analysis (`QueueUnavailable`, HTTP 503) the ride is taken back with its
    files and the horse and rider it added: a 503 leaves no ride without an analysis, and sending the same
    bundle again is no conflict. The zip then goes back to `return_to` (a resumable upload's key: finalising
    again needs no new upload); without it, or on any other refusal, the staged zip is deleted.
    """
    shown = filename or "the bundle"
    give_back = False
    try:
        sha256 = storage.sha256(staged_key)
        with session_scope(sessions) as session:
            if rig_id is not None:
                RigRepository(session, club_id=club_id).get(rig_id)
            existing = RideRepository(session, club_id=club_id).with_bundle_sha256(sha256)
        if existing is not None:
            raise DuplicateClips(duplicate_message(f"{shown}: this bundle (the same content) was", existing),
                                 existing_ride_id=existing)
        ride_id = _register_staged(sessions, storage, staged_key, shown, club_id=club_id, rig_id=rig_id,
                                   chosen=chosen)
        try:
            with session_scope(sessions) as session:
                RideRepository(session, club_id=club_id).note(ride_id, _bundle_sha256=sha256, _created_by=user_id)
            job_id = submit_job(sessions, queue, kind="analyze", ride_id=ride_id, club_id=club_id)
        except BaseException as exc:
            remove_bundle_ride(sessions, storage, ride_id)
            if not isinstance(exc, QueueUnavailable):
                raise
            give_back = return_to is not None
            again = "your upload is kept: finalise it again" if give_back else "send the bundle again"
            raise QueueUnavailable(f"{shown}: {exc}; no ride was made from it, {again} in a moment") from None
    finally:
        if give_back and return_to is not None:
            storage.move(staged_key, return_to)
        else:
            storage.delete(staged_key)
    return ride_id, job_id


def _register_staged(sessions: sessionmaker[Session], storage: Storage, staged_key: str, shown: str,
                     **options: Any) -> int:
    """`register_bundle` of the staged zip; errors name the user's file (`shown`), not the staging key."""
    if not isinstance(storage, FileStorage):
        # Read in place by ranges and copied member by member: no byte of it on this machine's disk.
        with storage.open_seekable(staged_key, block_bytes=BUNDLE_BLOCK_BYTES) as stream:
            return register_bundle(sessions, storage, stream, name=shown, **options)
    path = storage.path(staged_key)
    try:
        return register_bundle(sessions, storage, path, **options)
    except BundleError as exc:
        raise BundleError(str(exc).replace(str(path), shown).replace(path.name, shown)) from None


# --- resumable uploads --------------------------------------------------------------------------------


def create_upload(
    session: Session,
    *,
    club_id: int,
    user_id: int | None,
    target: str,
    length_bytes: int,
    max_bytes: int,
    ride_id: int | None = None,
    rig_id: int | None = None,
    clip_kind: str | None = None,
    camera: str | None = None,
    filename: str | None = None,
):
    """A new resumable upload (not committed); checks its target exists in the club and its size."""
    if target not in {t.value for t in UploadTarget}:
        raise InputError(f"target must be one of {', '.join(t.value for t in UploadTarget)}, got {target!r}")
    if length_bytes > max_bytes:
        raise TooLarge(
            f"{filename or 'the upload'}: {length_bytes} bytes is larger than the upload limit of "
            f"{max_bytes} bytes"
        )
    if target == UploadTarget.BUNDLE:
        if ride_id is not None or clip_kind is not None or camera is not None:
            raise InputError("a bundle upload names no ride, clip kind or camera (ride.json says it all)")
        if rig_id is not None:
            RigRepository(session, club_id=club_id).get(rig_id)
    else:
        owner = find_owner(
            session,
            club_id=club_id,
            ride_id=ride_id if target == UploadTarget.RIDE_CLIP else None,
            rig_id=rig_id if target == UploadTarget.RIG_CLIP else None,
        )
        if clip_kind is None or camera is None:
            raise InputError(f"a {target} upload needs clip_kind and camera")
        check_clip_slot(owner, clip_kind, camera)
    return UploadRepository(session, club_id=club_id).add(
        id_=secrets.token_hex(16),
        user_id=user_id,
        target=target,
        ride_id=ride_id,
        rig_id=rig_id,
        clip_kind=clip_kind,
        camera_role=camera,
        filename=filename,
        length_bytes=length_bytes,
    )


# A finalise finding another one at work waits this long for its outcome, then answers 409 (ask again).
FINALISE_WAIT_S = 60.0
_FINALISE_POLL_S = 0.1


@dataclass(frozen=True)
class _ClaimedUpload:
    """What finalising needs of an upload this request claimed (its row now says ``finalising``)."""

    target: str
    ride_id: int | None
    rig_id: int | None
    user_id: int | None
    clip_kind: str | None
    camera: str | None
    filename: str | None
    length_bytes: int
    offset_bytes: int
    direct: bool


def _claim_or_outcome(sessions: sessionmaker[Session], storage: Storage, upload_id: str, *,
                      club_id: int) -> _ClaimedUpload | UploadOutcome:
    """Claim the open upload for this request, or the outcome of the request that finalised it.

    The "still open" check and the claim are one conditional UPDATE (`UploadRepository.claim`), so of
    concurrent finalises exactly one moves the bytes; the others wait for its outcome and answer it.
    """
    deadline = time.monotonic() + FINALISE_WAIT_S
    while True:
        with session_scope(sessions) as session:
            uploads = UploadRepository(session, club_id=club_id)
            upload = uploads.get(upload_id)
            if upload.status == UploadStatus.FINALISED.value:
                return outcome_from_json(upload.outcome)  # finalised already (a retry): the same answer
            if upload.status == UploadStatus.FAILED.value:
                raise InputError(f"upload {upload_id} was refused when it was finalised: {upload.error}")
            if upload.status == UploadStatus.OPEN.value:
                direct = is_direct(storage, upload_id)
                if not direct and upload.offset_bytes != upload.length_bytes:
                    raise IncompleteUpload(f"upload {upload_id} has {upload.offset_bytes} of its "
                                           f"{upload.length_bytes} bytes; send the rest first")
                claimed = _ClaimedUpload(upload.target, upload.ride_id, upload.rig_id, upload.user_id,
                                         upload.clip_kind, upload.camera_role, upload.filename,
                                         upload.length_bytes, upload.offset_bytes, direct)
                if uploads.claim(upload_id):
                    session.commit()
                    return claimed
        if time.monotonic() >= deadline:
            raise FinaliseInProgress(f"upload {upload_id} is being finalised by an earlier request; ask again "
                                     "in a moment (GET /api/uploads/{id} shows its outcome)")
        time.sleep(_FINALISE_POLL_S)


def _end_claim(sessions: sessionmaker[Session], upload_id: str, *, club_id: int, reopen_at: int | None = None,
               error: str | None = None) -> None:
    """Give the claimed upload back open at byte `reopen_at`, or mark it failed with `error`."""
    try:
        with session_scope(sessions) as session:
            uploads = UploadRepository(session, club_id=club_id)
            if reopen_at is not None:
                uploads.reopen(upload_id, offset_bytes=reopen_at)
            else:
                uploads.close(upload_id, status=UploadStatus.FAILED, error=error)
            session.commit()
    except Exception:  # the database is away: the first error is the one to answer; the sweep ends the claim
        log.exception("upload %s: could not end its finalising", upload_id)


def finalise_upload(
    sessions: sessionmaker[Session], storage: Storage, queue: JobQueue, upload_id: str, *, club_id: int,
    chosen: dict[str, Any] | None = None,
) -> UploadOutcome:
    """Turn a complete resumable upload into a recording (and maybe a job) or a ride; returns the outcome.

    `chosen` (a bundle only): the ride's details chosen at upload, over the bundle's ride.json.
    A refused file marks the upload failed with the reason (and the error is raised again); a bundle whose
    analysis the job queue refuses leaves no ride, and its upload open and complete, to be finalised again.
    Idempotent: a finalise of a finalised upload answers its outcome; concurrent ones wait for the one that
    claimed it and answer its outcome (or 409 `FinaliseInProgress` if it takes over `FINALISE_WAIT_S`).
    """
    claimed = _claim_or_outcome(sessions, storage, upload_id, club_id=club_id)
    if not isinstance(claimed, _ClaimedUpload):
        return claimed
    target, rig_id, size = claimed.target, claimed.rig_id, claimed.length_bytes
    staged = staging_key(club_id, claimed.filename)
    try:
        chosen = dict(chosen or {})
        if target == UploadTarget.BUNDLE and chosen.get("rig_id") is not None:
            rig_id = chosen.pop("rig_id")  # the rig chosen in the form when the ride was confirmed
            with session_scope(sessions) as session:
                RigRepository(session, club_id=club_id).get(rig_id)  # before the bytes move: a 404 keeps them
        chosen.pop("rig_id", None)
        if claimed.direct:  # the client sent the parts to the bucket: join them (409 naming the missing ones)
            check_parts(storage, upload_id, size)
            storage.move(direct_upload_key(upload_id), staged)
        else:
            storage.seal(upload_key(upload_id), staged)
    except BaseException:
        _end_claim(sessions, upload_id, club_id=club_id, reopen_at=claimed.offset_bytes)  # bytes not used yet
        raise
    try:
        outcome = _finalise_staged(sessions, storage, queue, upload_id, claimed, staged, club_id=club_id,
                                   rig_id=rig_id, chosen=chosen)
    except QueueUnavailable as exc:
        # A bundle's zip went back to the upload's key, whole (`accept_bundle`): the upload is open again,
        # complete, to be finalised again once the queue answers (a direct one now as a streamed one).
        again = size if target == UploadTarget.BUNDLE else None
        _end_claim(sessions, upload_id, club_id=club_id, reopen_at=again, error=str(exc))
        raise
    except (SaddleScopeError, Conflict, NotFound) as exc:
        _end_claim(sessions, upload_id, club_id=club_id, error=str(exc))
        raise
    except BaseException:
        _end_claim(sessions, upload_id, club_id=club_id,
                   error="finalising stopped on a server error; upload the file again")
        raise
    with session_scope(sessions) as session:
        UploadRepository(session, club_id=club_id).close(
            upload_id, status=UploadStatus.FINALISED, outcome=outcome.as_json()
        )
    return outcome


def _finalise_staged(sessions: sessionmaker[Session], storage: Storage, queue: JobQueue, upload_id: str,
                     claimed: _ClaimedUpload, staged: str, *, club_id: int, rig_id: int | None,
                     chosen: dict[str, Any]) -> UploadOutcome:
    """The clip or ride a claimed upload's staged bytes make; the upload's outcome."""
    if claimed.target == UploadTarget.BUNDLE:
        new_ride, job_id = accept_bundle(sessions, storage, queue, staged, club_id=club_id, rig_id=rig_id,
                                         filename=claimed.filename, user_id=claimed.user_id, chosen=chosen,
                                         return_to=upload_key(upload_id))
        return BundleFinalised(ride_id=new_ride, job_id=job_id)
    ride_clip = claimed.target == UploadTarget.RIDE_CLIP
    owner_id = claimed.ride_id if ride_clip else rig_id
    if owner_id is None or claimed.clip_kind is None or claimed.camera is None:  # create_upload sets them
        raise InputError(f"upload {upload_id} is a clip without its {'ride' if ride_clip else 'rig'}, clip kind "
                         "or camera")
    owner = ClipOwner("ride" if ride_clip else "rig", owner_id, club_id)
    return _finalise_clip(sessions, storage, queue, owner, claimed.clip_kind, claimed.camera, staged,
                          size=claimed.length_bytes, filename=claimed.filename)


def _finalise_clip(sessions: sessionmaker[Session], storage: Storage, queue: JobQueue, owner: ClipOwner,
                   clip_kind: str, camera: str, staged: str, *, size: int, filename: str | None) -> ClipFinalised:
    """`accept_clip` of a finalised upload's staged clip, then the processing it allows; the upload's outcome."""
    recording_id = accept_clip(sessions, storage, owner, clip_kind, camera, staged, size_bytes=size,
                               sha256=storage.sha256(staged), filename=filename)
    start_calibration_check(sessions, queue, owner, clip_kind)
    job_id = start_processing(sessions, queue, owner)
    if owner.kind != "ride" or job_id is not None:
        return ClipFinalised(recording_id=recording_id, job_id=job_id)
    with session_scope(sessions) as session:
        # Said with the clip, so the page never reports "queued" for a ride that cannot run.
        missing = missing_for_ride(session, owner.id, club_id=owner.club_id)
    return ClipFinalised(recording_id=recording_id, job_id=None, missing=tuple(missing))


def bundle_meta(session: Session, storage: Storage, upload_id: str, *, club_id: int) -> BundleMeta:
    """What a complete, not yet finalised bundle upload's ride.json says, to pre-fill the upload form.

    Only ride.json is read (the whole bundle is checked when it is finalised). The horse and rider are
    matched by name among the club's (``id`` None when the club has no such horse or rider yet).
    """
    from saddlescope.services.uploads.bundle_meta import read_bundle_meta

    uploads = UploadRepository(session, club_id=club_id)
    upload = uploads.get(upload_id)
    if upload.target != UploadTarget.BUNDLE:
        raise InputError(f"upload {upload_id} is a clip, not a ride bundle")
    if upload.status == UploadStatus.OPEN.value and is_direct(storage, upload_id):
        # Parts of an unfinished multipart upload cannot be read: join them (409 naming any missing) into
        # the upload's own key. From then on it is an upload whose bytes all arrived, finalised as a streamed one.
        check_parts(storage, upload_id, upload.length_bytes)
        storage.move(direct_upload_key(upload_id), upload_key(upload_id))
        uploads.advance(upload_id, from_offset=upload.offset_bytes, to_offset=upload.length_bytes)
        session.commit()
        upload = uploads.get(upload_id)
    if upload.status != UploadStatus.OPEN.value or upload.offset_bytes != upload.length_bytes:
        raise IncompleteUpload(f"upload {upload_id} is not a complete open upload "
                               f"({upload.offset_bytes} of {upload.length_bytes} bytes, {upload.status})")
    with storage.open_seekable(upload_key(upload_id)) as zip_stream:  # only ride.json is read, by ranges
        return read_bundle_meta(session, zip_stream, club_id=club_id, shown=upload.filename or "the bundle")


class IncompleteUpload(InputError):
    """A resumable upload is finalised before all its bytes arrived, or a chunk is not where it stands (HTTP 409).

    `offset_bytes`: where the upload stands, when the client is to resume there (a chunk at the wrong offset); the
    409 says it in its ``Upload-Offset`` header and ``offset_bytes``.
    """

    def __init__(self, message: str, *, offset_bytes: int | None = None) -> None:
        super().__init__(message)
        self.offset_bytes = offset_bytes


class FinaliseInProgress(IncompleteUpload):
    """Another request is finalising the upload and has not finished yet (HTTP 409; ask again)."""

    retry_after_s = 5


@contextmanager
def _upload_locked(session: Session, storage: Storage, upload_id: str, *, club_id: int | None) -> Iterator[None]:
    """Hold the upload against other chunks.

    A file lock on this host's disk, the row's lock in the database otherwise (API replicas on several hosts share
    only the database and the bucket).
    """
    if isinstance(storage, FileStorage):  # `local`: keys are files on this machine
        with storage.locked(upload_key(upload_id)):
            session.rollback()  # read the offset as it is now, under the lock
            yield
        return
    session.rollback()
    UploadRepository(session, club_id=club_id).lock(upload_id)  # until this transaction ends
    try:
        yield
    finally:
        if session.in_transaction():
            session.rollback()  # refused: let the next chunk in


def commit_chunk(session: Session, storage: Storage, upload_id: str, *, offset: int, staged_key: str,
                 size: int, club_id: int | None = None) -> int:
    """Add a PATCH's `size` bytes (stored under `staged_key`) meant for byte `offset`; returns the new offset.

    Bytes already acknowledged are never rewritten: where the chunk overlaps them (a retried PATCH) it
    must equal them byte for byte, else `IncompleteUpload` (409) names the server's offset. Only the part
    past the current offset is appended, and the offset moves in the same locked step.
    """
    key = upload_key(upload_id)
    with _upload_locked(session, storage, upload_id, club_id=club_id):
        uploads = UploadRepository(session, club_id=club_id)
        upload = uploads.get(upload_id)
        current = upload.offset_bytes
        if upload.status != UploadStatus.OPEN.value:
            raise IncompleteUpload(f"upload {upload_id} is {upload.status}; it takes no more bytes")
        if offset > current:
            raise IncompleteUpload(f"Upload-Offset {offset} is past the upload's offset {current}; "
                                   f"resume from {current}", offset_bytes=current)
        overlap = min(offset + size, current) - offset
        if overlap > 0 and not storage.same_bytes(key, offset, staged_key, overlap):
            raise IncompleteUpload(
                f"the chunk at Upload-Offset {offset} differs from the bytes already received there; "
                f"acknowledged bytes are never rewritten: the upload is at offset {current}, resume from {current}",
                offset_bytes=current,
            )
        if offset + size <= current:
            return current  # a retry of bytes already here: nothing to do
        storage.append_from(key, current, staged_key, overlap)
        if not uploads.advance(upload_id, from_offset=current, to_offset=offset + size):
            raise IncompleteUpload(f"upload {upload_id} moved on meanwhile; ask for its offset")
        session.commit()
        return offset + size


def remove_upload_files(storage: Storage, upload_ids: list[str]) -> None:
    """Delete the bytes of uploads: their collected file and any chunk still being checked."""
    for upload_id in upload_ids:
        storage.delete(upload_key(upload_id))
        if isinstance(storage, S3Storage):  # a direct upload's parts, and its object if it was joined
            storage.abort_direct(direct_upload_key(upload_id))
            storage.delete(direct_upload_key(upload_id))
    if upload_ids and storage.exists("uploads"):
        prefixes = tuple(f"uploads/{upload_id}.chunk-" for upload_id in upload_ids)
        for key in list(storage.iter_keys("uploads")):
            if key.startswith(prefixes):
                storage.delete(key)


def sweep_abandoned(sessions: sessionmaker[Session], storage: Storage, *, max_age_s: float) -> dict[str, int]:
    """Remove what was left behind for `max_age_s`.

    Open uploads nothing arrived for (with their bytes), staged files of a request that never finished (`incoming/`,
    an API process killed mid-upload), and partial writes (a store's multipart uploads given up, a folder's
    temporary files). Returns the counts.

    Run by every worker once per `sweep_interval_s` and by `saddlescope sweep`; safe to run anywhere, at
    once, repeatedly: an upload still receiving bytes is younger than the limit and kept.
    """
    with session_scope(sessions) as session:
        expired = expire_uploads(session, storage, max_age_s=max_age_s)
    staged = storage.stale_keys("incoming", older_than_s=max_age_s)
    for key in staged:
        storage.delete(key)
    partial = storage.sweep_partial_writes(older_than_s=max_age_s)
    return {"expired uploads": len(expired), "staged files": len(staged), "partial writes": partial}


def expire_uploads(session: Session, storage: Storage, *, max_age_s: float,
                   now: dt.datetime | None = None) -> list[str]:
    """Remove open uploads (of every club) that received nothing for `max_age_s`, with their files.

    Commits `session`. Returns the ids removed.
    """
    before = (now or dt.datetime.now(dt.UTC)) - dt.timedelta(seconds=max_age_s)
    uploads = UploadRepository(session)
    expired = uploads.open_since_before(before)
    uploads.delete_ids(expired)
    session.commit()
    remove_upload_files(storage, expired)
    return expired

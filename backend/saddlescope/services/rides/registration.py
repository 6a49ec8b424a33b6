"""Rides: registering one from a bundle, which clips make it complete, and its status.

A ride's status is derived, never set: `refresh_ride_status` reads the ride's clips, its latest
analysis job and its result, and stores what `ride_status` makes of them. Whatever changes one of
those (a clip stored, a job created, started, finished, cancelled or queued again) calls it.
"""

from __future__ import annotations

import datetime as dt
import hashlib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, BinaryIO

from sqlalchemy import delete, exists, select
from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import BundleError
from saddlescope.core.types import CAMERA_ROLES, CLIP_KINDS
from saddlescope.db.enums import JobStatus, RideStatus, SaddleType
from saddlescope.db.models import Horse, Rider, Saddle
from saddlescope.db.repositories import (
    ClubRepository,
    Conflict,
    HorseRepository,
    JobRepository,
    RecordingRepository,
    ResultRepository,
    Ride,
    RideRepository,
    RiderRepository,
    RigRepository,
    SaddleRepository,
)
from saddlescope.db.session import session_scope
from saddlescope.io.bundle import RideBundle, ZipMember, open_bundle, open_zip_stream, zip_bundle_files
from saddlescope.storage import Storage, ride_bundle_key, sha256_file, tree_digest

__all__ = [
    "ANALYSIS_JOB_KIND",
    "DuplicateClips",
    "duplicate_message",
    "RESULT_SETTINGS",
    "analysed_settings",
    "outdated_result_settings",
    "note_analysed_settings",
    "update_ride_details",
    "complete_clip_sets",
    "refresh_ride_status",
    "refresh_rig_rides_status",
    "register_bundle",
    "remove_bundle_ride",
    "ride_clip_plan",
    "ride_status",
]

# The job kind whose outcome is the ride's analysis (its status shows that job's).
ANALYSIS_JOB_KIND = "analyze"

# The ride's details the pipeline reads (ride.json): the gait guides the fit of the strides and both
# are written into the result. Horse, rider, date and notes only label the result.
RESULT_SETTINGS = ("gait", "direction")
_ANALYSED_AS = "_analysed_as"  # meta key: the RESULT_SETTINGS the current result was computed with


def analysed_settings(ride: Ride) -> dict[str, str]:
    """The ride's RESULT_SETTINGS now, as its next analysis will read them."""
    return {name: getattr(ride, name) for name in RESULT_SETTINGS}


def outdated_result_settings(ride: Ride) -> list[str]:
    """The settings changed since the ride's result was computed (empty: the result is current)."""
    analysed = dict(ride.meta or {}).get(_ANALYSED_AS) or {}
    return [name for name in RESULT_SETTINGS
            if name in analysed and analysed[name] != getattr(ride, name)]


def update_ride_details(session: Session, ride_id: int, *, club_id: int | None, **values) -> Ride:
    """Change a ride's details; if it has a result, remember what that result was computed with."""
    rides = RideRepository(session, club_id=club_id)
    ride = rides.get(ride_id)
    meta = dict(ride.meta or {})
    if _ANALYSED_AS not in meta and ResultRepository(session).for_ride(ride_id) is not None:
        rides.note(ride_id, **{_ANALYSED_AS: analysed_settings(ride)})
    return rides.update_fields(ride_id, **values)


def note_analysed_settings(session: Session, ride_id: int, settings: dict[str, str]) -> None:
    """Record the settings a new result was computed with (the analyze stage, after storing it)."""
    RideRepository(session).note(ride_id, **{_ANALYSED_AS: dict(settings)})


def complete_clip_sets(recordings: Iterable) -> dict[str, dict[str, str]]:
    """Clip kind -> camera -> storage key, for the kinds recorded by all three cameras."""
    by_kind: dict[str, dict[str, str]] = {}
    for r in recordings:
        by_kind.setdefault(r.clip_kind, {})[r.camera_role] = r.path
    return {kind: cams for kind, cams in by_kind.items() if set(CAMERA_ROLES) <= set(cams)}


def ride_clip_plan(ride_recordings: Iterable, rig_recordings: Iterable, *,
                   rig_calibrated: bool) -> dict[str, dict[str, str]]:
    """Which stored clip each camera of each kind comes from: the ride's own, else its rig's.

    Raises `BundleError` naming what is missing (motion and static are required, and calibration
    clips unless the rig is calibrated already).
    """
    own, shared = complete_clip_sets(ride_recordings), complete_clip_sets(rig_recordings)
    plan = {kind: own.get(kind) or shared.get(kind) for kind in CLIP_KINDS}
    missing = [kind for kind in ("static", "motion") if not plan[kind]]
    if not plan["calibration"] and not rig_calibrated:
        missing.insert(0, "calibration")
    if missing:
        raise BundleError(f"the clips of {' and '.join(missing)} are not all uploaded (each needs the left, "
                          "middle and right cameras)")
    return {kind: cams for kind, cams in plan.items() if cams}


def ride_status(*, clips_complete: bool, analysis: str | None, analysed: bool) -> RideStatus:
    """The status a ride shows.

    Parameters
    ----------
    clips_complete : bool
        Every clip the analysis needs is stored (the ride's own, or its rig's shared ones).
    analysis : str or None
        Status of the ride's latest analysis job (None: never analysed).
    analysed : bool
        The ride has a stored result (of an earlier analysis, if the latest one is queued).

    Returns
    -------
    RideStatus
        ``processing`` while its analysis runs, ``failed`` when the latest analysis failed or was
        cancelled, else ``analysed`` once it has a result, ``ready`` with all its clips, ``new``.
    """
    if analysis == JobStatus.RUNNING:
        return RideStatus.PROCESSING
    if analysis in (JobStatus.FAILED, JobStatus.CANCELLED):
        return RideStatus.FAILED
    if analysed:
        return RideStatus.ANALYSED
    return RideStatus.READY if clips_complete else RideStatus.NEW


def _clips_complete(session: Session, ride: Ride) -> bool:
    if ride.bundle_key is not None:
        return True  # a registered bundle was checked whole by `open_bundle`
    recordings = RecordingRepository(session)
    rig = RigRepository(session).find(ride.rig_id) if ride.rig_id is not None else None
    try:
        ride_clip_plan(recordings.for_ride(ride.id), recordings.for_rig(rig.id) if rig else [],
                       rig_calibrated=bool(rig is not None and rig.calibration))
    except BundleError:
        return False
    return True


def refresh_ride_status(session: Session, ride_id: int | None) -> str | None:
    """Derive ride `ride_id`'s status from its clips, latest analysis job and result, and store it.

    The one writer of a ride's status (in `session`'s transaction). Returns the status, or None
    when there is no such ride (or no ride: `ride_id` None).
    """
    rides = RideRepository(session)
    ride = rides.find(ride_id) if ride_id is not None else None
    if ride is None:
        return None
    job = JobRepository(session).latest_for_ride(ride.id, kind=ANALYSIS_JOB_KIND)
    status = ride_status(clips_complete=_clips_complete(session, ride), analysis=job.status if job else None,
                         analysed=ResultRepository(session).for_ride(ride.id) is not None)
    if ride.status != status.value:
        rides.set_status(ride.id, status.value)
    return status.value


def refresh_rig_rides_status(session: Session, rig_id: int | None) -> None:
    """Refresh the status of every ride of rig `rig_id` (its rig's clips and calibration change).

    A rig's clips and calibration decide whether its rides' clips are complete: a ride was left "new" after its
    rig's calibration clips arrived, until something else of the ride changed.
    """
    if rig_id is None:
        return
    for ride_id in RideRepository(session).ids_of_rig(rig_id):
        refresh_ride_status(session, ride_id)


class DuplicateClips(Conflict):
    """The clips uploaded are already a ride of the club (the same content): answered with that ride (409)."""

    def __init__(self, message: str, *, existing_ride_id: int) -> None:
        super().__init__(message)
        self.existing_ride_id = existing_ride_id


def duplicate_message(what: str, existing_ride_id: int, *, kept: str = "no new ride was made") -> str:
    """The sentence a second upload of the same clips answers with (`kept`: what became of the upload)."""
    return (f"{what} already uploaded as ride {existing_ride_id} (the same motion clip, byte for byte); {kept}: "
            f"open ride {existing_ride_id}, or delete it first to upload these clips again")


def _refuse_known_clips(sessions: sessionmaker[Session], bundle: RideBundle, digests: dict[str, tuple[int, str]], *,
                        club_id: int, ride_id: int, name: str) -> None:
    """`DuplicateClips` when a motion clip of the bundle is already a clip of another ride of the club."""
    hashes = [digests[source.relative_to(bundle.root).as_posix()][1]
              for source in (bundle.clip_paths.get("motion") or {}).values()]
    with session_scope(sessions) as session:
        existing = RecordingRepository(session, club_id=club_id).ride_with_clip(hashes, exclude_ride_id=ride_id)
    if existing is not None:
        raise DuplicateClips(duplicate_message(f"{name}: its clips were", existing), existing_ride_id=existing)


def register_bundle(sessions: sessionmaker[Session], storage: Storage, bundle: Path | str | BinaryIO, *,
                    club_name: str = "Demo club", club_id: int | None = None, rig_id: int | None = None,
                    ridden_on: dt.date | None = None, chosen: Mapping[str, Any] | None = None,
                    name: str = "the bundle") -> int:
    """Create a ride (and its horse and rider if new) from a bundle; returns the ride id.

    `bundle` is a folder or a zip (validated by `saddlescope.io.bundle.open_bundle`, which raises
    `BundleError` naming what is wrong), or a seekable stream of a zip named `name` in errors (a bucket's
    object read by ranges: `open_zip_stream` checks it in place and its members are copied one by one,
    nothing on this machine's disk). Its files are copied into storage under
    ``rides/<id>/bundle`` with their own relative paths, and each clip of the four standard sets
    becomes a recording row with its size and sha256. The ride belongs to club `club_id`, or to the
    club named `club_name` (created if new) when no id is given; `rig_id` (a rig of that club)
    makes the ride use, or calibrate, that rig's calibration. `chosen` holds what the user chose at
    upload (horse_id, rider_id, gait, direction, ridden_on, notes): each one given wins over ride.json,
    which only fills what is not given (a horse or rider named in ride.json is added when no id is).
    """
    opened = open_bundle(bundle) if isinstance(bundle, str | Path) else open_zip_stream(bundle, name)
    with opened:
        if opened.calibration_method != "board":  # its clip sets have no recording kind yet (issue 35)
            raise BundleError(f"{name}: a ride calibrated with a wand (ride.json calibration.method "
                              f"{opened.calibration_method!r}) is analysed with `saddlescope analyze` for now; to "
                              "upload it here, give the rig's board walk (clips.calibration) or its calibration_file "
                              "instead, and the wand's clips on the rig's page")
        return _register(sessions, storage, opened, club_name=club_name, club_id=club_id, rig_id=rig_id,
                         ridden_on=ridden_on, chosen=dict(chosen or {}), name=name)


MAX_NAME_CHARS = 200
_ADDED = "_bundle_added"  # meta key: the horse and rider the ride's registration added (removed with it)


def _get_or_add(session: Session, who: str, club_id: int, name: str, added: dict[str, int], **details) -> int:
    """The club's horse or rider (`who`) named `name`, added if new (then noted in `added`)."""
    model, repository = (Horse, HorseRepository) if who == "horse" else (Rider, RiderRepository)
    new = session.scalar(select(model.id).where(model.club_id == club_id, model.name == name)) is None
    row_id = repository(session, club_id=club_id).get_or_create(name=name, **details).id
    if new:
        added[who] = row_id
    return row_id


def _add_ride(session: Session, bundle: RideBundle, *, club_name: str, club_id: int | None,
              rig_id: int | None, ridden_on: dt.date | None, chosen: dict[str, Any]) -> tuple[int, int]:
    """Add the bundle's ride (and its horse and rider if new and not chosen); returns (club id, ride id)."""
    meta = bundle.meta
    horse_meta = meta.get("horse") or {}
    rider_meta = meta.get("rider") or {}
    for who, part in (("horse", horse_meta), ("rider", rider_meta)):
        if len(str(part.get("name") or "")) > MAX_NAME_CHARS:  # the API's limit for a name
            raise BundleError(f"ride.json: {who}.name is {len(str(part['name']))} characters long; "
                              f"a name has at most {MAX_NAME_CHARS}")
    if club_id is None:
        club_id = ClubRepository(session).get_or_create(club_name).id
    added: dict[str, int] = {}
    horse_id = chosen.get("horse_id") or _get_or_add(
        session, "horse", club_id, str(horse_meta.get("name") or "Unnamed horse"), added,
        breed=horse_meta.get("breed"), birth_year=horse_meta.get("birth_year"),
        height_withers_m=horse_meta.get("height_m"))
    rider_id = chosen.get("rider_id") or _get_or_add(
        session, "rider", club_id, str(rider_meta.get("name") or "Unnamed rider"), added)
    saddle_id = chosen.get("saddle_id") or _bundle_saddle(session, meta.get("saddle"), club_id, added)
    ride = RideRepository(session, club_id=club_id).add(
        horse_id=horse_id, rider_id=rider_id, rig_id=rig_id, gait=chosen.get("gait") or meta["gait"],
        direction=chosen.get("direction") or meta["direction"],
        ridden_on=chosen.get("ridden_on") or ridden_on or dt.datetime.now(dt.UTC).date(),
        notes=chosen.get("notes") or "",
        meta={**{k: meta[k] for k in ("board", "sync", "markers") if k in meta}, **({_ADDED: added} if added else {})},
        saddle_id=saddle_id, pad=chosen.get("pad") or meta.get("pad") or None,
        rider_weight_kg=chosen.get("rider_weight_kg") or rider_meta.get("weight_kg"))
    return club_id, ride.id


def _bundle_saddle(session: Session, saddle_meta: Mapping[str, Any] | None, club_id: int,
                   added: dict[str, int]) -> int | None:
    """The club's saddle ride.json names (`saddle.name`), added with its details if new; None without one."""
    if not saddle_meta:
        return None
    kind = saddle_meta.get("type")
    if kind is not None and kind not in {t.value for t in SaddleType}:
        raise BundleError(f"ride.json: saddle.type {kind!r} is not one of {', '.join(t.value for t in SaddleType)}")
    saddles = SaddleRepository(session, club_id=club_id)
    name = str(saddle_meta["name"]).strip()
    found = saddles.find_by_name(name)
    if found is not None:
        return found.id
    saddle = saddles.add(name=name, maker=saddle_meta.get("maker"), saddle_type=kind,
                         tree_width=saddle_meta.get("tree_width"))
    added["saddle"] = saddle.id
    return saddle.id


def _store_files(storage: Storage, bundle: RideBundle, bundle_key: str) -> dict[str, tuple[int, str]]:
    """Copy every file of the bundle under `bundle_key`; returns each clip's (size, sha256) by its bundle path.

    A folder is imported whole; a zip read in place (object storage) is copied member by member, each
    streamed from the zip in the bucket to its own object. Either way the digests come from the bytes
    copied: no second read of the stored copy.
    """
    clips = {source.relative_to(bundle.root).as_posix(): source
             for per_camera in bundle.clip_paths.values() for source in per_camera.values()}
    if bundle.archive is None:
        storage.import_tree(bundle_key, bundle.root)
        return {rel: tree_digest(source) if source.is_dir() else (source.stat().st_size, sha256_file(source))
                for rel, source in clips.items()}
    # A clip of numbered images: `tree_digest` of its folder, fed as its files stream past in path order.
    folders = [rel for rel, source in clips.items() if source.is_dir()]
    sizes = dict.fromkeys(folders, 0)
    hashes = {folder: hashlib.sha256() for folder in folders}
    zip_root = bundle.root
    if not isinstance(zip_root, ZipMember):  # `archive` is set with a root inside it (`open_zip_stream`)
        raise ValueError("a bundle with an archive is a zip read in place: its root is a ZipMember")
    digests: dict[str, tuple[int, str]] = {}
    for member, chunks in zip_bundle_files(bundle):
        rel = member.relative_to(zip_root).as_posix()
        inside = [folder for folder in folders if rel.startswith(folder + "/")]
        for folder in inside:
            hashes[folder].update(rel[len(folder) + 1:].encode() + b"\0")
        with storage.writer(f"{bundle_key}/{rel}") as out:
            for chunk in chunks:
                out.write(chunk)
                for folder in inside:
                    sizes[folder] += len(chunk)
                    hashes[folder].update(chunk)
            digests[rel] = out.commit()
    digests.update({folder: (sizes[folder], hashes[folder].hexdigest()) for folder in folders})
    return {rel: digests[rel] for rel in clips}


def _add_recordings(session: Session, bundle: RideBundle, digests: dict[str, tuple[int, str]], *, club_id: int,
                    ride_id: int, bundle_key: str) -> None:
    """A recording row (size, sha256) for each clip of the bundle's standard sets, stored under `bundle_key`."""
    recordings = RecordingRepository(session)
    for kind, per_camera in bundle.clip_paths.items():
        for role, source in per_camera.items():
            rel = source.relative_to(bundle.root).as_posix()
            size_bytes, sha256 = digests[rel]
            recordings.add(club_id=club_id, ride_id=ride_id, camera_role=role, clip_kind=kind,
                           path=f"{bundle_key}/{rel}", sha256=sha256, size_bytes=size_bytes)


def _register(sessions: sessionmaker[Session], storage: Storage, bundle: RideBundle, *,
              club_name: str, club_id: int | None, rig_id: int | None, ridden_on: dt.date | None,
              chosen: dict[str, Any], name: str = "the bundle") -> int:
    with session_scope(sessions) as session:
        club_id, ride_id = _add_ride(session, bundle, club_name=club_name, club_id=club_id, rig_id=rig_id,
                                     ridden_on=ridden_on, chosen=chosen)
    bundle_key = ride_bundle_key(ride_id)
    registered = False
    try:
        # The whole folder, extras included (truth.json, extra clip sets, a calibration file), so
        # the stored copy is again a complete bundle the pipeline can open.
        digests = _store_files(storage, bundle, bundle_key)
        _refuse_known_clips(sessions, bundle, digests, club_id=club_id, ride_id=ride_id, name=name)
        with session_scope(sessions) as session:
            _add_recordings(session, bundle, digests, club_id=club_id, ride_id=ride_id, bundle_key=bundle_key)
            RideRepository(session).set_bundle_key(ride_id, bundle_key)
            refresh_ride_status(session, ride_id)
        registered = True
    finally:
        if not registered:  # no half-registered ride: remove the rows and the copied files
            remove_bundle_ride(sessions, storage, ride_id)
    return ride_id


def remove_bundle_ride(sessions: sessionmaker[Session], storage: Storage, ride_id: int) -> None:
    """Take back a ride just registered from a bundle (refused, or its job could not be queued).

    Its rows go (recordings and jobs with it), then its stored files; so do the horse, rider and saddle its
    registration added, unless another ride uses them meanwhile. Nothing that existed before is touched.
    """
    with session_scope(sessions) as session:
        ride = RideRepository(session).find(ride_id)
        added = dict(dict(ride.meta or {}).get(_ADDED) or {}) if ride is not None else {}
        RideRepository(session).delete(ride_id)
        for who, model, column in (("horse", Horse, Ride.horse_id), ("rider", Rider, Ride.rider_id),
                                   ("saddle", Saddle, Ride.saddle_id)):
            row_id = added.get(who)
            if row_id is not None:
                session.execute(delete(model).where(model.id == row_id, ~exists().where(column == row_id)))
    storage.delete(f"rides/{ride_id}")

"""Registering rides: a ride bundle (CONTRACTS section 1) becomes rows plus stored clips."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from sqlalchemy.orm import Session, sessionmaker

from saddlescope.db.enums import RideStatus
from saddlescope.db.repositories import (
    ClubRepository,
    HorseRepository,
    RecordingRepository,
    RideRepository,
    RiderRepository,
)
from saddlescope.db.session import session_scope
from saddlescope.io.bundle import RideBundle, open_bundle
from saddlescope.storage import Storage, ride_bundle_key, tree_digest


def register_bundle(sessions: sessionmaker[Session], storage: Storage, bundle: Path | str, *,
                    club_name: str = "Demo club", club_id: int | None = None, rig_id: int | None = None,
                    ridden_on: dt.date | None = None) -> int:
    """Create a ride (and its horse and rider if new) from a bundle; returns the ride id.

    `bundle` is a folder or a zip (validated by `saddlescope.io.bundle.open_bundle`, which raises
    `BundleError` naming what is wrong). Its files are copied into storage under
    ``rides/<id>/bundle`` with their own relative paths, and each clip of the four standard sets
    becomes a recording row with its size and sha256. The ride belongs to club `club_id`, or to the
    club named `club_name` (created if new) when no id is given; `rig_id` (a rig of that club)
    makes the ride use, or calibrate, that rig's calibration.
    """
    with open_bundle(bundle) as opened:
        return _register(sessions, storage, opened, club_name=club_name, club_id=club_id, rig_id=rig_id,
                         ridden_on=ridden_on)


def _register(sessions: sessionmaker[Session], storage: Storage, bundle: RideBundle, *,
              club_name: str, club_id: int | None, rig_id: int | None, ridden_on: dt.date | None) -> int:
    meta = bundle.meta
    horse_meta = meta.get("horse") or {}
    rider_meta = meta.get("rider") or {}
    with session_scope(sessions) as session:
        if club_id is None:
            club_id = ClubRepository(session).get_or_create(club_name).id
        horse = HorseRepository(session, club_id=club_id).get_or_create(
            name=str(horse_meta.get("name") or "Unnamed horse"),
            breed=horse_meta.get("breed"), birth_year=horse_meta.get("birth_year"),
            height_withers_m=horse_meta.get("height_m"))
        rider = RiderRepository(session, club_id=club_id).get_or_create(
            name=str(rider_meta.get("name") or "Unnamed rider"))
        ride = RideRepository(session, club_id=club_id).add(
            horse_id=horse.id, rider_id=rider.id, rig_id=rig_id, gait=meta["gait"],
            direction=meta["direction"],
            ridden_on=ridden_on or dt.datetime.now(dt.UTC).date(),
            meta={k: meta[k] for k in ("board", "sync", "markers") if k in meta})
        ride_id = ride.id
    bundle_key = ride_bundle_key(ride_id)
    registered = False
    try:
        # The whole folder, extras included (truth.json, extra clip sets, a calibration file), so
        # the stored copy is again a complete bundle the pipeline can open.
        storage.import_tree(bundle_key, bundle.root)
        with session_scope(sessions) as session:
            recordings = RecordingRepository(session)
            for kind, per_camera in bundle.clip_paths.items():
                for role, source in per_camera.items():
                    key = f"{bundle_key}/{source.relative_to(bundle.root).as_posix()}"
                    if source.is_dir():
                        size_bytes, sha256 = tree_digest(storage.path(key))
                    else:
                        size_bytes, sha256 = storage.size(key), storage.sha256(key)
                    recordings.add(club_id=club_id, ride_id=ride_id, camera_role=role, clip_kind=kind,
                                   path=key, sha256=sha256, size_bytes=size_bytes)
            rides = RideRepository(session)
            rides.set_bundle_key(ride_id, bundle_key)
            rides.set_status(ride_id, RideStatus.READY.value)
        registered = True
    finally:
        if not registered:  # no half-registered ride: remove the row and the copied files
            storage.delete(f"rides/{ride_id}")
            with session_scope(sessions) as session:
                RideRepository(session).delete(ride_id)
    return ride_id

"""Registering rides: a ride bundle folder (CONTRACTS section 1) becomes rows plus stored clips."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import BundleError
from saddlescope.core.types import CAMERA_ROLES, CLIP_KINDS, DIRECTIONS, GAITS
from saddlescope.db.models import RideStatus
from saddlescope.db.repositories import (
    ClubRepository,
    HorseRepository,
    RecordingRepository,
    RideRepository,
    RiderRepository,
)
from saddlescope.db.session import session_scope
from saddlescope.storage import Storage, ride_bundle_key, tree_digest

BUNDLE_FORMAT = "saddlescope.ride/1"
# Small side files of a bundle that travel with it (truth.json: the exact answer of a synthetic ride).
SIDE_FILES = ("ride.json", "truth.json")


def read_ride_json(bundle: Path | str) -> dict[str, Any]:
    """Read and check a bundle's ``ride.json``: format, gait, direction and the 4 x 3 clips."""
    bundle = Path(bundle)
    path = bundle / "ride.json"
    if not path.is_file():
        raise BundleError(f"{bundle}: no ride.json (is this a ride bundle folder?)")
    try:
        meta = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise BundleError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise BundleError(f"{path}: must hold a JSON object")
    if meta.get("format") != BUNDLE_FORMAT:
        raise BundleError(f"{path}: format must be {BUNDLE_FORMAT!r}, got {meta.get('format')!r}")
    if meta.get("gait") not in GAITS:
        raise BundleError(f"{path}: gait must be one of {', '.join(GAITS)}, got {meta.get('gait')!r}")
    if meta.get("direction") not in DIRECTIONS:
        raise BundleError(f"{path}: direction must be CW or CCW, got {meta.get('direction')!r}")
    clips = meta.get("clips")
    if not isinstance(clips, dict):
        raise BundleError(f"{path}: 'clips' must map clip kinds to cameras")
    for kind, per_camera in clips.items():
        if kind not in CLIP_KINDS:
            raise BundleError(f"{path}: unknown clip kind {kind!r} (expected {', '.join(CLIP_KINDS)})")
        if not isinstance(per_camera, dict):
            raise BundleError(f"{path}: clips.{kind} must map camera roles to files")
        for role, rel in per_camera.items():
            if role not in CAMERA_ROLES:
                raise BundleError(f"{path}: clips.{kind} has unknown camera role {role!r}")
            if not isinstance(rel, str) or Path(rel).is_absolute() or ".." in Path(rel).parts:
                raise BundleError(f"{path}: clips.{kind}.{role} must be a relative path inside the bundle, "
                                  f"got {rel!r}")
            if not (bundle / rel).exists():
                raise BundleError(f"{bundle}: the {kind} clip of the {role} camera ({rel}) is missing")
    return meta


def register_bundle(sessions: sessionmaker[Session], storage: Storage, bundle: Path | str, *,
                    club_name: str = "Demo club") -> int:
    """Create a ride (and its club, horse, rider if new) from a bundle folder; returns the ride id.

    The bundle's clips and ``ride.json`` are copied into storage under ``rides/<id>/bundle`` with
    the bundle's own relative paths, so the stored folder is again a valid bundle.
    """
    bundle = Path(bundle)
    meta = read_ride_json(bundle)
    horse_meta = meta.get("horse") or {}
    rider_meta = meta.get("rider") or {}
    with session_scope(sessions) as session:
        club = ClubRepository(session).get_or_create(club_name)
        horse = HorseRepository(session).get_or_create(
            club_id=club.id, name=str(horse_meta.get("name") or "Unnamed horse"),
            breed=horse_meta.get("breed"), birth_year=horse_meta.get("birth_year"),
            height_withers_m=horse_meta.get("height_m"))
        rider = RiderRepository(session).get_or_create(club_id=club.id,
                                                        name=str(rider_meta.get("name") or "Unnamed rider"))
        ride = RideRepository(session).add(club_id=club.id, horse_id=horse.id, rider_id=rider.id,
                                           gait=meta["gait"], direction=meta["direction"])
        club_id, ride_id = club.id, ride.id
    bundle_key = ride_bundle_key(ride_id)
    for name in SIDE_FILES:
        if (bundle / name).is_file():
            storage.import_file(f"{bundle_key}/{name}", bundle / name)
    with session_scope(sessions) as session:
        recordings = RecordingRepository(session)
        for kind, per_camera in meta["clips"].items():
            for role, rel in per_camera.items():
                source = bundle / rel
                key = f"{bundle_key}/{Path(rel).as_posix()}"
                if source.is_dir():
                    storage.import_tree(key, source)
                    size_bytes, sha256 = tree_digest(storage.path(key))
                else:
                    size_bytes, sha256 = storage.import_file(key, source)
                recordings.add(club_id=club_id, ride_id=ride_id, camera_role=role, clip_kind=kind, path=key,
                               sha256=sha256, size_bytes=size_bytes)
        rides = RideRepository(session)
        rides.set_bundle_key(ride_id, bundle_key)
        rides.set_status(ride_id, RideStatus.READY.value)
    return ride_id

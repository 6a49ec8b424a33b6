"""Read a ride bundle zip's ride.json only, to pre-fill the upload form the user then confirms.

The bundle's horse, rider, gait and direction are suggestions: the ride is filed under what the
form sends at finalise (`services.uploads.intake.finalise_upload`'s ``chosen``), never under the zip's
horse unless the user kept it.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any, BinaryIO

from sqlalchemy import select
from sqlalchemy.orm import Session

from saddlescope.core.errors import BundleError
from saddlescope.db.models import Horse, Rider, Saddle

__all__ = ["BundleMeta", "MAX_RIDE_JSON_BYTES", "NamedInClub", "read_bundle_meta"]

MAX_RIDE_JSON_BYTES = 1024**2  # a ride.json is a few kB; more is not a ride.json


@dataclass(frozen=True)
class NamedInClub:
    """A horse, rider or saddle a bundle names, and the club's one of that name."""

    name: str | None  # as ride.json says it; None: ride.json names none
    id: int | None  # the club's horse, rider or saddle of that name; None: the club has none


@dataclass(frozen=True)
class BundleMeta:
    """A bundle's ride.json as suggestions for the upload form (its text as written, unchecked)."""

    horse: NamedInClub
    rider: NamedInClub
    gait: str | None
    direction: str | None
    ridden_on: str | None  # ride.json's ``date`` (else ``ridden_on``) as written
    notes: str
    saddle: NamedInClub
    pad: str | None
    rider_weight_kg: float | None


def _ride_json(zf: zipfile.ZipFile, shown: str) -> dict[str, Any]:
    """ride.json at the zip's top, or inside its single top folder (zips often nest one)."""
    candidates = [i for i in zf.infolist() if PurePosixPath(i.filename).name == "ride.json"
                  and len(PurePosixPath(i.filename).parts) <= 2 and not i.is_dir()]
    if not candidates:
        raise BundleError(f"{shown}: no ride.json (is this a ride bundle?)")
    info = min(candidates, key=lambda i: len(PurePosixPath(i.filename).parts))
    if info.file_size > MAX_RIDE_JSON_BYTES:
        raise BundleError(f"{shown}: ride.json is {info.file_size} bytes; a ride.json is a few kB")
    try:
        meta = json.loads(zf.read(info).decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise BundleError(f"{shown}: ride.json is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise BundleError(f"{shown}: ride.json is not a JSON object")
    return meta


def _named(meta: dict[str, Any], key: str) -> str | None:
    value = meta.get(key)
    name = value.get("name") if isinstance(value, dict) else None
    return name.strip()[:200] if isinstance(name, str) and name.strip() else None


def read_bundle_meta(session: Session, zip_path: Path | BinaryIO, *, club_id: int, shown: str) -> BundleMeta:
    """The form's suggestions from a bundle zip's ride.json.

    The horse, rider and saddle by name (with the id of the club's one of that name, or None), gait, direction,
    date, notes, pad and the rider's weight.
    """
    try:
        with zipfile.ZipFile(zip_path) as zf:
            meta = _ride_json(zf, shown)
    except (zipfile.BadZipFile, OSError):
        # Word for word what finalising the same file says (`io.bundle.open_bundle`).
        raise BundleError(f"{shown}: a ride bundle must be a folder or a .zip archive") from None
    horse_name, rider_name, saddle_name = _named(meta, "horse"), _named(meta, "rider"), _named(meta, "saddle")
    saddle_id = None
    if saddle_name:
        saddle_id = session.scalars(select(Saddle.id).where(Saddle.club_id == club_id,
                                                            Saddle.name == saddle_name)).first()
    weight = (meta.get("rider") or {}).get("weight_kg") if isinstance(meta.get("rider"), dict) else None
    horse_id = rider_id = None
    if horse_name:
        horse_id = session.scalars(select(Horse.id).where(Horse.club_id == club_id, Horse.name == horse_name)).first()
    if rider_name:
        rider_id = session.scalars(select(Rider.id).where(Rider.club_id == club_id, Rider.name == rider_name)).first()

    def text(key: str) -> str | None:
        value = meta.get(key)
        return value if isinstance(value, str) else None

    return BundleMeta(
        horse=NamedInClub(horse_name, horse_id),
        rider=NamedInClub(rider_name, rider_id),
        gait=text("gait"),
        direction=text("direction"),
        ridden_on=text("date") or text("ridden_on"),
        notes=text("notes") or "",
        saddle=NamedInClub(saddle_name, saddle_id),
        pad=text("pad"),
        rider_weight_kg=weight if isinstance(weight, int | float) and not isinstance(weight, bool) else None,
    )

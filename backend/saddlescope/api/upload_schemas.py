"""The resumable uploads' answers: the upload itself (`UploadOut`) and what finalising made.

How to send its bytes, the parts of a direct upload and a bundle's ride.json read before finalising.
"""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from saddlescope.api.rider_weight import RiderWeightKg
from saddlescope.api.schemas import Direction, ErrorOut, Gait, Pad, RefId, Text, _In, _Out
from saddlescope.services.uploads.direct import MAX_URLS

__all__ = ["BundleChoice", "BundleFinalisedOut", "BundleMetaOut", "ClipFinalisedOut", "DirectPartsOut",
           "FinalisedOut", "NamedInClubOut", "OffsetConflictOut", "PartNumbers", "PartOut", "PartUrlsOut",
           "PartsOut", "StreamedPartsOut", "UploadCreatedOut", "UploadOut"]


def _absent_when_none(value: object) -> bool:
    return value is None


class ClipFinalisedOut(BaseModel):
    """A clip's upload finalised: its recording, and the job the clip let start."""

    model_config = ConfigDict(from_attributes=True)

    recording_id: int
    job_id: int | None = Field(description="null: nothing to start yet (or a job already queued or running)")
    missing: list[str] | None = Field(default=None, exclude_if=_absent_when_none,  # absent, not null, as ever
                                      description="a ride's clip that started no job: what the ride still needs "
                                                  "(absent otherwise)")


class BundleFinalisedOut(BaseModel):
    """A ride bundle's upload finalised: the new ride, and its analysis job."""

    model_config = ConfigDict(from_attributes=True)

    ride_id: int
    job_id: int


FinalisedOut = ClipFinalisedOut | BundleFinalisedOut


class UploadOut(_Out):
    """A resumable upload's state (`offset_bytes` is where to resume)."""

    id: str
    target: str
    ride_id: int | None
    rig_id: int | None
    clip_kind: str | None
    camera_role: str | None
    filename: str | None
    length_bytes: int
    offset_bytes: int
    status: str
    error: str | None
    outcome: FinalisedOut | None = Field(description="what finalising made (the same answer as the finalise); null "
                                         "until the upload is finalised")
    created_at: dt.datetime
    updated_at: dt.datetime

    @field_validator("outcome", mode="before")
    @classmethod
    def _nothing_yet(cls, kept: object) -> object:
        return kept or None  # an upload's row keeps {} until it is finalised


class UploadCreatedOut(UploadOut):
    """A new upload, and how to send its bytes.

    ``stream``: PATCH chunks to the API; ``s3-parts``: PUT parts of `part_bytes` straight to the bucket,
    to the URLs from ``POST /uploads/{id}/parts``.
    """

    transport: Literal["stream", "s3-parts"] = "stream"
    part_bytes: int | None = None
    parts_total: int | None = None


class OffsetConflictOut(ErrorOut):
    """A chunk refused (409): its Upload-Offset is not where the upload stands, or the upload takes no more bytes."""

    offset_bytes: int | None = Field(default=None, description="where the upload stands: send the next chunk from "
                                     "here (also the Upload-Offset header); absent when it takes no more bytes")


class PartNumbers(_In):
    """The parts (1-based) of a direct upload to sign URLs for."""

    numbers: list[Annotated[int, Field(ge=1, le=10_000)]] = Field(min_length=1, max_length=MAX_URLS)


class PartUrlsOut(BaseModel):
    """Pre-signed URLs to PUT parts of a direct upload to."""

    model_config = ConfigDict(from_attributes=True)

    urls: dict[str, str] = Field(description='part number ("1") -> the URL to PUT it to')
    expires_s: int = Field(description="how long the URLs work")
    part_bytes: int = Field(description="each part's size in bytes (the last one shorter)")


class PartOut(BaseModel):
    """A part the bucket has, of the size its place needs."""

    model_config = ConfigDict(from_attributes=True)

    number: int
    size: int = Field(description="bytes")


class StreamedPartsOut(BaseModel):
    """A streamed upload has no parts: its bytes arrive through the API (resume from `offset_bytes`)."""

    model_config = ConfigDict(from_attributes=True)

    transport: Literal["stream"]
    parts: list[PartOut] = Field(description="always empty")
    offset_bytes: int


class DirectPartsOut(BaseModel):
    """Which parts of a direct upload the bucket has (a part of the wrong size is missing: send it again)."""

    model_config = ConfigDict(from_attributes=True)

    transport: Literal["s3-parts"]
    part_bytes: int
    parts_total: int
    parts: list[PartOut]
    offset_bytes: int = Field(description="the bytes of the parts in order from the first")


PartsOut = Annotated[StreamedPartsOut | DirectPartsOut, Field(discriminator="transport")]


class NamedInClubOut(BaseModel):
    """A horse, rider or saddle a bundle names, and the club's one of that name."""

    model_config = ConfigDict(from_attributes=True)

    name: str | None = Field(description="as ride.json says it; null: ride.json names none")
    id: int | None = Field(description="the club's horse, rider or saddle of that name; null: the club has none")


class BundleMetaOut(BaseModel):
    """A complete bundle upload's ride.json, to pre-fill the upload form (suggestions: its text, unchecked)."""

    model_config = ConfigDict(from_attributes=True)

    horse: NamedInClubOut
    rider: NamedInClubOut
    gait: str | None
    direction: str | None
    ridden_on: str | None = Field(description="ride.json's date as written")
    notes: str
    saddle: NamedInClubOut
    pad: str | None
    rider_weight_kg: int | float | None = Field(description="kg, as ride.json writes it")  # an int stays one


class BundleChoice(_In):
    """What the user chose for a bundle's ride at upload; each given field wins over ride.json."""

    horse_id: RefId | None = Field(default=None, description="None: the horse ride.json names (added if new)")
    rider_id: RefId | None = Field(default=None, description="None: the rider ride.json names (added if new)")
    gait: Gait | None = None
    direction: Direction | None = None
    ridden_on: dt.date | None = None
    notes: Text | None = None
    rig_id: RefId | None = Field(default=None, description="the rig the ride uses (over the one named at creation)")
    saddle_id: RefId | None = Field(default=None, description="the club's saddle (None: the one ride.json names)")
    pad: Pad | None = None
    rider_weight_kg: RiderWeightKg = Field(default=None, description="kg; default: ride.json's, else the rider's")



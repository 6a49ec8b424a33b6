"""Direct uploads (issue 26 part 2).

On object storage the client sends a resumable upload's bytes straight to the bucket, as the parts of an S3 multipart
upload, with URLs the API pre-signs; the API signs, says which parts arrived, and joins them when the upload is
finalised. No byte of the file passes through the API on the way in; finalising still reads the joined object once,
streamed, for its sha256 (moving that to the worker's probe stage is left to do).

The embedded mode (a folder tree) keeps the streamed upload (PATCH chunks through the API); the
client is told which way to send when it creates the upload (`transport`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from sqlalchemy.orm import Session

from saddlescope.core.errors import InputError
from saddlescope.db.enums import UploadStatus
from saddlescope.db.repositories import Conflict, UploadRepository
from saddlescope.settings import Settings
from saddlescope.storage import S3Storage, Storage, direct_upload_key

__all__ = [
    "ArrivedPart", "DIRECT_PART_BYTES", "DirectUploadError", "MAX_URLS", "PART_URL_EXPIRY_S", "PartUrls", "PartsState",
    "STREAM", "S3_PARTS", "check_parts", "is_direct", "part_count", "part_urls", "parts_state", "start_direct",
    "transport_for",
]

STREAM, S3_PARTS = "stream", "s3-parts"
# 16 MiB parts: S3's smallest (but the last) is 5 MiB, and a 4 GiB clip stays at 256 of its 10,000 parts.
DIRECT_PART_BYTES = 16 * 1024**2
PART_URL_EXPIRY_S = 3600
MAX_URLS = 100  # part URLs signed per request


class DirectUploadError(Conflict):
    """A direct upload's parts are not (yet) what its length needs (HTTP 409)."""


@dataclass(frozen=True)
class PartUrls:
    """Pre-signed URLs to PUT parts of a direct upload to."""

    urls: Mapping[str, str]  # part number ("1", 1-based) -> its URL
    expires_s: int  # how long the URLs work
    part_bytes: int  # each part's size (the last one shorter)


@dataclass(frozen=True)
class ArrivedPart:
    """A part of a direct upload the bucket has, of the size its place needs."""

    number: int
    size: int  # bytes


@dataclass(frozen=True)
class PartsState:
    """What of a resumable upload arrived: the parts in the bucket (``s3-parts``), or the bytes streamed."""

    transport: str  # STREAM or S3_PARTS
    parts: tuple[ArrivedPart, ...]  # none for a streamed upload
    offset_bytes: int  # the bytes in order from the start
    part_bytes: int | None = None  # a direct upload's part size
    parts_total: int | None = None  # and how many parts it takes


def transport_for(storage: Storage, settings: Settings) -> str:
    """How a new resumable upload's bytes travel: straight to the bucket, or streamed through the API."""
    if storage.kind == "s3" and settings.direct_uploads is not False:
        return S3_PARTS
    return STREAM


def part_count(length_bytes: int) -> int:
    """How many parts of `DIRECT_PART_BYTES` (the last one shorter) a file of `length_bytes` takes."""
    return max(1, -(-length_bytes // DIRECT_PART_BYTES))


def _bucket(storage: Storage) -> S3Storage:
    """The store as the bucket a direct upload's parts go to (`transport_for` sends them to an S3 store only)."""
    if not isinstance(storage, S3Storage):
        raise TypeError(f"direct uploads go to an S3 bucket, not to {storage.describe()}")
    return storage


def start_direct(storage: Storage, upload_id: str, length_bytes: int) -> dict[str, Any]:
    """Open the bucket's multipart upload for a new upload; returns what the client needs to send it."""
    _bucket(storage).start_direct(direct_upload_key(upload_id))
    return {"transport": S3_PARTS, "part_bytes": DIRECT_PART_BYTES, "parts_total": part_count(length_bytes)}


def is_direct(storage: Storage, upload_id: str) -> bool:
    """Whether the upload's bytes go straight to the bucket (its multipart upload is open)."""
    return isinstance(storage, S3Storage) and storage.direct_id(direct_upload_key(upload_id)) is not None


def _open_direct(session: Session, storage: Storage, upload_id: str, club_id: int | None):
    upload = UploadRepository(session, club_id=club_id).get(upload_id)  # NotFound: 404
    if upload.status != UploadStatus.OPEN.value:
        raise DirectUploadError(f"upload {upload_id} is {upload.status}; it takes no more bytes")
    direct_id = storage.direct_id(direct_upload_key(upload_id)) if isinstance(storage, S3Storage) else None
    return upload, direct_id


def part_urls(session: Session, storage: Storage, upload_id: str, numbers: list[int], *,
              club_id: int | None) -> PartUrls:
    """Pre-signed PUT URLs for parts `numbers` (1-based) of a direct upload."""
    upload, direct_id = _open_direct(session, storage, upload_id, club_id)
    if direct_id is None:
        raise DirectUploadError(f"upload {upload_id} is not sent to the bucket directly; PATCH its chunks")
    total = part_count(upload.length_bytes)
    if not numbers or len(numbers) > MAX_URLS:
        raise InputError(f"ask for 1 to {MAX_URLS} part numbers at a time, got {len(numbers)}")
    wrong = [n for n in numbers if not 1 <= n <= total]
    if wrong:
        raise InputError(f"upload {upload_id} has parts 1 to {total}; no part {wrong[0]}")
    key, bucket = direct_upload_key(upload_id), _bucket(storage)
    return PartUrls(urls={str(n): bucket.part_url(key, direct_id, n, expires_s=PART_URL_EXPIRY_S) for n in numbers},
                    expires_s=PART_URL_EXPIRY_S, part_bytes=DIRECT_PART_BYTES)


def _expected_size(number: int, length_bytes: int) -> int:
    return min(DIRECT_PART_BYTES, length_bytes - (number - 1) * DIRECT_PART_BYTES)


def parts_state(session: Session, storage: Storage, upload_id: str, *, club_id: int | None) -> PartsState:
    """Which parts arrived (a part of the wrong size counts as missing: send it again) and the bytes in order."""
    upload, direct_id = _open_direct(session, storage, upload_id, club_id)
    if direct_id is None:
        return PartsState(transport=STREAM, parts=(), offset_bytes=upload.offset_bytes)
    arrived = _bucket(storage).direct_parts(direct_upload_key(upload_id), direct_id)
    good = [p for p in arrived if p["size"] == _expected_size(p["number"], upload.length_bytes)]
    numbers = {p["number"] for p in good}
    in_order = 0
    while in_order + 1 in numbers:
        in_order += 1
    return PartsState(transport=S3_PARTS, part_bytes=DIRECT_PART_BYTES, parts_total=part_count(upload.length_bytes),
                      parts=tuple(ArrivedPart(number=p["number"], size=p["size"]) for p in good),
                      offset_bytes=sum(p["size"] for p in good if p["number"] <= in_order))


def check_parts(storage: Storage, upload_id: str, length_bytes: int) -> None:
    """Join a direct upload's parts into its object; `DirectUploadError` (409) naming what is missing."""
    key, bucket = direct_upload_key(upload_id), _bucket(storage)
    direct_id = bucket.direct_id(key)
    if direct_id is None:
        raise DirectUploadError(f"upload {upload_id} has no open parts in the bucket")
    parts = {p["number"]: p for p in bucket.direct_parts(key, direct_id)}
    total = part_count(length_bytes)
    missing = [n for n in range(1, total + 1)
               if n not in parts or parts[n]["size"] != _expected_size(n, length_bytes)]
    if missing:
        have = sum(parts[n]["size"] for n in parts if n not in missing and n <= total)
        raise DirectUploadError(
            f"upload {upload_id} has {have} of its {length_bytes} bytes; send part(s) "
            f"{', '.join(map(str, missing[:10]))}{' ...' if len(missing) > 10 else ''} first")
    bucket.complete_direct(key, direct_id, [parts[n] for n in range(1, total + 1)])

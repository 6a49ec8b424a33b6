"""Where uploaded videos and result documents live: `Storage`, and its two back ends.

`FileStorage` (a folder tree, the embedded default) and `S3Storage` (an S3-compatible bucket),
chosen by `open_storage` from the settings: ``SADDLESCOPE_STORAGE_URL=s3://BUCKET[/PREFIX]`` for a
bucket, a path, ``file://PATH`` or nothing (``SADDLESCOPE_STORAGE_DIR``) for the filesystem.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from saddlescope.storage.base import Storage, StorageWriter
from saddlescope.storage.files import CHUNK_BYTES, AtomicWriter, FileStorage, TooLarge, sha256_file, tree_digest
from saddlescope.storage.keys import (
    direct_upload_key,
    ride_bundle_key,
    rig_stage_output_key,
    stage_output_key,
    upload_chunk_key,
    upload_key,
)
from saddlescope.storage.s3 import S3Storage, StoreUnavailable, parse_s3_url

if TYPE_CHECKING:
    from saddlescope.settings import Settings

__all__ = [
    "CHUNK_BYTES", "AtomicWriter", "FileStorage", "S3Storage", "Storage", "StorageWriter", "StoreUnavailable",
    "TooLarge",
    "direct_upload_key",
    "open_storage", "parse_s3_url", "rig_stage_output_key", "ride_bundle_key", "sha256_file", "stage_output_key",
    "storage_for_url", "tree_digest", "upload_chunk_key", "upload_key",
]


def storage_for_url(url: str, *, endpoint_url: str | None = None, public_endpoint_url: str | None = None) -> Storage:
    """The store a URL names: ``s3://BUCKET[/PREFIX]``, ``file://PATH`` or a plain path."""
    if url.startswith("s3://"):
        return S3Storage.from_url(url, endpoint_url=endpoint_url, public_endpoint_url=public_endpoint_url)
    if url.startswith("file://"):
        return FileStorage(url.removeprefix("file://"))
    if "://" in url:
        raise ValueError(f"storage URL {url!r}: use s3://BUCKET[/PREFIX], file://PATH or a plain path")
    return FileStorage(Path(url))


def open_storage(settings: Settings) -> Storage:
    """The store the settings choose (`storage_url`, else the folder `storage_dir`)."""
    if settings.storage_url:
        return storage_for_url(settings.storage_url, endpoint_url=settings.s3_endpoint_url,
                               public_endpoint_url=settings.s3_public_endpoint_url)
    return FileStorage(settings.storage_dir)

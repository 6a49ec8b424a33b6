"""The storage interface every back end implements (the filesystem, an S3-compatible bucket)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO, Protocol, runtime_checkable

__all__ = ["Storage", "StorageWriter"]


class StorageWriter(Protocol):
    """Bytes written in chunks under one key, hashed and counted; nothing is visible before `commit`."""

    key: str
    size: int

    def write(self, chunk: bytes) -> None:
        """Add `chunk` to the bytes written."""

    def commit(self) -> tuple[int, str]:
        """Make the bytes visible under `key`; returns (size in bytes, sha256 hex)."""

    def abort(self) -> None:
        """Drop the bytes written; nothing appears under `key`."""

    def __enter__(self) -> StorageWriter: ...

    def __exit__(self, exc_type, exc, tb) -> None: ...


@runtime_checkable
class Storage(Protocol):
    """Where clips and result documents live, addressed by keys (`saddlescope.storage.keys`).

    A key names a file; a key's "folder" is every key under ``key + "/"``. Readers never see half a
    file. `fetch` puts a stored file (or folder) on this machine's disk, for code that needs a path
    (decoding a video): a stage fetches its inputs into its own scratch folder.
    """

    kind: str  # "file" or "s3"
    local: bool  # True: keys are files on this machine's disk (`FileStorage.path`)

    def describe(self) -> str:
        """Where the store is, for a person (a folder or a bucket URL)."""

    def exists(self, key: str) -> bool:
        """Whether a file is stored under `key`."""

    def size(self, key: str) -> int:
        """The size in bytes of the file under `key`."""

    def open(self, key: str) -> BinaryIO:
        """The file under `key`, opened for reading."""

    def writer(self, key: str, *, max_bytes: int | None = None) -> StorageWriter:
        """A writer for `key`; `TooLarge` past `max_bytes`."""

    def write_stream(self, key: str, stream: BinaryIO, *, max_bytes: int | None = None) -> tuple[int, str]:
        """Store `stream` under `key`; returns (size in bytes, sha256 hex)."""

    def write_bytes(self, key: str, data: bytes) -> tuple[int, str]:
        """Store `data` under `key`; returns (size in bytes, sha256 hex)."""

    def read_bytes(self, key: str) -> bytes:
        """The bytes of the file under `key`."""

    def import_file(self, key: str, source: Path | str) -> tuple[int, str]:
        """Store the local file `source` under `key`; returns (size in bytes, sha256 hex)."""

    def import_tree(self, key: str, source: Path | str) -> None:
        """Store the local folder `source` under the folder `key`."""

    def fetch(self, key: str, target: Path | str) -> Path:
        """Put the file or folder under `key` at `target` on this machine's disk; returns its path."""

    def move(self, source_key: str, target_key: str) -> None:
        """Move the file or folder under `source_key` to `target_key`."""

    def sha256(self, key: str) -> str:
        """The sha256 (hex) of the file under `key`."""

    def iter_keys(self, prefix: str) -> Iterator[str]:
        """The keys of the files under the folder `prefix`."""

    def delete(self, prefix: str) -> None:
        """Remove the file or folder under `prefix`."""

    def check(self) -> str:
        """Write, read and delete a probe; returns a short description of the store."""

    # Resumable uploads: bytes collected at offsets under one key, then sealed into a file.
    def open_seekable(self, key: str, *, block_bytes: int = ...) -> BinaryIO:
        """The resumable upload's bytes under `key`, opened to write at any offset."""

    def same_bytes(self, key: str, offset: int, other_key: str, length: int) -> bool:
        """Whether `length` bytes of `key` from `offset` equal the first `length` bytes of `other_key`."""

    def append_from(self, key: str, at: int, source_key: str, skip: int) -> None:
        """Write `source_key` from byte `skip` on into `key` from byte `at` (anything after `at` dropped)."""

    def seal(self, key: str, target_key: str) -> None:
        """Turn the resumable upload under `key` into the file under `target_key`."""

    # Abandoned bytes (a process killed mid-write, an upload given up): found by their age, removed.
    def stale_keys(self, prefix: str, *, older_than_s: float) -> list[str]:
        """The keys under the folder `prefix` last written more than `older_than_s` ago."""

    def sweep_partial_writes(self, *, older_than_s: float) -> int:
        """Remove the temporary files of writes untouched for `older_than_s`; returns how many."""

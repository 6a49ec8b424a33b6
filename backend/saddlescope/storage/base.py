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

    def write(self, chunk: bytes) -> None: ...

    def commit(self) -> tuple[int, str]: ...  # (size in bytes, sha256 hex)

    def abort(self) -> None: ...

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

    def describe(self) -> str: ...

    def exists(self, key: str) -> bool: ...

    def size(self, key: str) -> int: ...

    def open(self, key: str) -> BinaryIO: ...

    def writer(self, key: str, *, max_bytes: int | None = None) -> StorageWriter: ...

    def write_stream(self, key: str, stream: BinaryIO, *, max_bytes: int | None = None) -> tuple[int, str]: ...

    def write_bytes(self, key: str, data: bytes) -> tuple[int, str]: ...

    def read_bytes(self, key: str) -> bytes: ...

    def import_file(self, key: str, source: Path | str) -> tuple[int, str]: ...

    def import_tree(self, key: str, source: Path | str) -> None: ...

    def fetch(self, key: str, target: Path | str) -> Path: ...

    def move(self, source_key: str, target_key: str) -> None: ...

    def sha256(self, key: str) -> str: ...

    def iter_keys(self, prefix: str) -> Iterator[str]: ...

    def delete(self, prefix: str) -> None: ...

    def check(self) -> str: ...

    # Resumable uploads: bytes collected at offsets under one key, then sealed into a file.
    def open_seekable(self, key: str, *, block_bytes: int = ...) -> BinaryIO: ...

    def same_bytes(self, key: str, offset: int, other_key: str, length: int) -> bool: ...

    def append_from(self, key: str, at: int, source_key: str, skip: int) -> None: ...

    def seal(self, key: str, target_key: str) -> None: ...

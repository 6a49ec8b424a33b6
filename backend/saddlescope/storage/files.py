"""The filesystem store (the embedded default): a folder tree addressed by storage keys.

Writes go to a temporary file first and are renamed into place, so a reader never sees half a
file. Beyond the `Storage` interface it offers what only a local disk can: paths, hard links,
writes at an offset and file locks (the streamed resumable uploads of embedded mode use them).
"""

from __future__ import annotations

import fcntl
import hashlib
import io
import os
import shutil
import tempfile
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO

from saddlescope.core.errors import InputError

__all__ = ["CHUNK_BYTES", "AtomicWriter", "FileStorage", "TooLarge", "same_prefix", "sha256_file", "tree_digest"]

CHUNK_BYTES = 1 << 20


class TooLarge(InputError):
    """An upload exceeds the size limit (HTTP 413)."""


def same_prefix(ours: BinaryIO, theirs: BinaryIO, length: int) -> bool:
    """Whether the next `length` bytes of both streams are equal, read a chunk at a time."""
    while length > 0:
        size = min(length, CHUNK_BYTES)
        mine = ours.read(size)
        if len(mine) != size or mine != theirs.read(size):
            return False
        length -= size
    return True


class AtomicWriter:
    """Bytes written in chunks to a temporary file next to `key`, hashed and counted on the way.

    `commit` renames the file into place (a reader never sees half a file); `abort` (or leaving a
    ``with`` block by an exception) removes it. More than `max_bytes` raises `TooLarge` at once, so
    an oversized upload is refused while it streams, not after.
    """

    def __init__(self, storage: FileStorage, key: str, *, max_bytes: int | None = None) -> None:
        self.key = key
        self.target = storage.path(key)
        self.target.parent.mkdir(parents=True, exist_ok=True)
        self.max_bytes = max_bytes
        self.size = 0
        self._digest = hashlib.sha256()
        fd, tmp_name = tempfile.mkstemp(dir=self.target.parent, prefix=".part-")
        self._tmp = Path(tmp_name)
        self._out = os.fdopen(fd, "wb")

    def write(self, chunk: bytes) -> None:
        """Add `chunk` to the temporary file; `TooLarge` (and the bytes dropped) past `max_bytes`."""
        self.size += len(chunk)
        if self.max_bytes is not None and self.size > self.max_bytes:
            self.abort()
            raise TooLarge(f"{self.key.rsplit('/', 1)[-1]}: larger than the upload limit of "
                           f"{self.max_bytes} bytes ({self.max_bytes / 1024**2:.0f} MiB)")
        self._digest.update(chunk)
        self._out.write(chunk)

    @property
    def sha256(self) -> str:
        """The sha256 (hex) of the bytes written so far."""
        return self._digest.hexdigest()

    def commit(self) -> tuple[int, str]:
        """Move the bytes into place under `key`; returns (size in bytes, sha256 hex).

        A failure (the last buffered bytes meet a full disk at close) removes the temporary file too.
        """
        try:
            self._out.close()
            self._tmp.replace(self.target)
        except BaseException:
            self.abort()
            raise
        return self.size, self.sha256

    def abort(self) -> None:
        """Drop the temporary file; nothing appears under `key`."""
        if not self._out.closed:
            self._out.close()
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> AtomicWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None or not self._out.closed:
            self.abort()


class FileStorage:
    """A filesystem store rooted at `root` (created on first use)."""

    kind = "file"
    local = True  # keys are files on this machine: `path` works

    def __init__(self, root: Path | str) -> None:
        self.root = Path(root).expanduser().resolve()

    def __repr__(self) -> str:
        return f"FileStorage({str(self.root)!r})"

    def describe(self) -> str:
        """The store's folder."""
        return str(self.root)

    def fetch(self, key: str, target: Path | str) -> Path:
        """Put the file (or folder) `key` at local `target` (a hard link where possible); returns `target`."""
        if not self.exists(key):
            raise FileNotFoundError(f"{key} is not in storage")
        self.link_or_copy(key, Path(target))
        return Path(target)

    def path(self, key: str) -> Path:
        """The absolute path of `key`; refuses keys that would leave the root."""
        parts = key.split("/")
        if not key or "\\" in key or "\0" in key or any(part in ("", ".", "..") for part in parts):
            raise InputError(f"storage key {key!r} must be a relative path without '..', '.' or '//'")
        return self.root.joinpath(*parts)

    def exists(self, key: str) -> bool:
        """Whether a file is stored under `key`."""
        return self.path(key).exists()

    def size(self, key: str) -> int:
        """The size in bytes of the file under `key`."""
        return self.path(key).stat().st_size

    def open(self, key: str) -> BinaryIO:
        """The file under `key`, opened for reading."""
        return self.path(key).open("rb")

    def writer(self, key: str, *, max_bytes: int | None = None) -> AtomicWriter:
        """An `AtomicWriter` for `key` (write chunks, then commit)."""
        return AtomicWriter(self, key, max_bytes=max_bytes)

    def write_stream(self, key: str, stream: BinaryIO, *, max_bytes: int | None = None) -> tuple[int, str]:
        """Copy `stream` to `key` atomically; returns (size in bytes, sha256 hex).

        Raises `TooLarge` (an `InputError`, and keeps nothing) when the stream exceeds `max_bytes`.
        """
        with self.writer(key, max_bytes=max_bytes) as out:
            while chunk := stream.read(CHUNK_BYTES):
                out.write(chunk)
            return out.commit()

    def move(self, source_key: str, target_key: str) -> None:
        """Rename a stored file (same file system: atomic)."""
        target = self.path(target_key)
        target.parent.mkdir(parents=True, exist_ok=True)
        self.path(source_key).replace(target)

    def link_or_copy(self, source_key: str, target: Path) -> None:
        """Put a stored file at `target` (a hard link where possible: no copy of a large video)."""
        source = self.path(source_key)
        target.parent.mkdir(parents=True, exist_ok=True)
        if source.is_dir():
            shutil.copytree(source, target)
            return
        try:
            os.link(source, target)
        except OSError:
            shutil.copyfile(source, target)

    def open_at(self, key: str, offset: int) -> BinaryIO:
        """`key` opened for writing from byte `offset` (created if absent; anything after it dropped)."""
        path = self.path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = open(path, "r+b" if path.exists() else "w+b")  # noqa: SIM115 (the caller closes it)
        handle.seek(offset)
        handle.truncate()
        return handle

    def open_seekable(self, key: str, *, block_bytes: int = CHUNK_BYTES) -> BinaryIO:
        """`key` as a seekable stream (the file itself; `block_bytes` matters to a remote store only)."""
        return self.open(key)

    def append_from(self, key: str, at: int, source_key: str, skip: int) -> None:
        """Write `source_key` from byte `skip` on into `key` from byte `at` (anything after `at` dropped)."""
        with self.open(source_key) as src, self.open_at(key, at) as out:
            src.seek(skip)
            while block := src.read(CHUNK_BYTES):
                out.write(block)
            out.flush()
            os.fsync(out.fileno())

    def seal(self, key: str, target_key: str) -> None:
        """Make the collected bytes of `key` the file `target_key` (a rename)."""
        self.move(key, target_key)

    @contextmanager
    def locked(self, key: str) -> Iterator[None]:
        """Hold an exclusive lock on file `key` (created if absent) across processes of this host."""
        path = self.path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "ab") as handle:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(handle.fileno(), fcntl.LOCK_UN)

    def same_bytes(self, key: str, offset: int, other_key: str, length: int) -> bool:
        """Whether `length` bytes of `key` from `offset` equal the first `length` bytes of `other_key`."""
        with self.open(key) as ours, self.open(other_key) as theirs:
            ours.seek(offset)
            return same_prefix(ours, theirs, length)

    def write_bytes(self, key: str, data: bytes) -> tuple[int, str]:
        """Store `data` under `key`; returns (size in bytes, sha256 hex)."""
        return self.write_stream(key, io.BytesIO(data))

    def read_bytes(self, key: str) -> bytes:
        """The bytes of the file under `key`."""
        return self.path(key).read_bytes()

    def import_file(self, key: str, source: Path | str) -> tuple[int, str]:
        """Copy a local file under `key`; returns (size in bytes, sha256 hex)."""
        # A copy, not a hard link: a later rewrite of the source must not change stored clips.
        with Path(source).open("rb") as stream:
            return self.write_stream(key, stream)

    def import_tree(self, key: str, source: Path | str) -> None:
        """Put a local folder (e.g. a clip given as numbered images) under `key`."""
        source = Path(source)
        for file in sorted(p for p in source.rglob("*") if p.is_file()):
            self.import_file(f"{key}/{file.relative_to(source).as_posix()}", file)

    def sha256(self, key: str) -> str:
        """The sha256 (hex) of the file under `key`."""
        return sha256_file(self.path(key))

    def iter_keys(self, prefix: str) -> Iterator[str]:
        """Every file key under the folder `prefix`, sorted."""
        base = self.path(prefix)
        if base.is_file():
            yield prefix
            return
        if base.is_dir():
            for file in sorted(p for p in base.rglob("*") if p.is_file() and not p.name.startswith(".part-")):
                yield file.relative_to(self.root).as_posix()

    def delete(self, prefix: str) -> None:
        """Remove a file or a whole folder (no error when absent)."""
        target = self.path(prefix)
        if target.is_dir():
            shutil.rmtree(target)
        else:
            target.unlink(missing_ok=True)

    def stale_keys(self, prefix: str, *, older_than_s: float) -> list[str]:
        """The keys under the folder `prefix` last written more than `older_than_s` ago."""
        cutoff = time.time() - older_than_s
        stale = []
        for key in self.iter_keys(prefix):
            try:
                if self.path(key).stat().st_mtime < cutoff:
                    stale.append(key)
            except FileNotFoundError:  # removed meanwhile
                continue
        return stale

    def sweep_partial_writes(self, *, older_than_s: float) -> int:
        """Remove the temporary files of writes never committed nor aborted, untouched for `older_than_s`.

        A process killed while writing leaves `AtomicWriter`'s ".part-" files.
        Returns how many.
        """
        if not self.root.exists():
            return 0
        cutoff, removed = time.time() - older_than_s, 0
        for tmp in self.root.rglob(".part-*"):
            try:
                if tmp.is_file() and tmp.stat().st_mtime < cutoff:
                    tmp.unlink()
                    removed += 1
            except FileNotFoundError:
                continue
        return removed

    def fresh_dir(self, key: str) -> Path:
        """An empty folder at `key`, replacing whatever an earlier run left there."""
        self.delete(key)
        target = self.path(key)
        target.mkdir(parents=True)
        return target

    def check(self) -> str:
        """Write, read and delete a probe file; returns a short description or raises OSError.

        Each call has its own probe file, so concurrent checks (50 health probes at once) never
        read or delete one another's.
        """
        self.root.mkdir(parents=True, exist_ok=True)
        probe = self.root / f".health-{os.getpid()}-{uuid.uuid4().hex}"
        try:
            probe.write_bytes(b"ok")
            if probe.read_bytes() != b"ok":
                raise OSError(f"storage {self.root} returned different bytes than written")
        finally:
            probe.unlink(missing_ok=True)
        free_gib = shutil.disk_usage(self.root).free / 1024**3
        return f"{self.root} writable, {free_gib:.1f} GiB free"


def sha256_file(path: Path | str) -> str:
    """The sha256 (hex) of the file at `path`."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as stream:
        while chunk := stream.read(CHUNK_BYTES):
            digest.update(chunk)
    return digest.hexdigest()


def tree_digest(folder: Path | str) -> tuple[int, str]:
    """Total size and sha256 of a folder (e.g. a clip given as numbered images): names and bytes, in order."""
    folder = Path(folder)
    digest = hashlib.sha256()
    size = 0
    for file in sorted(p for p in folder.rglob("*") if p.is_file()):
        digest.update(file.relative_to(folder).as_posix().encode() + b"\0")
        with file.open("rb") as stream:
            while chunk := stream.read(CHUNK_BYTES):
                digest.update(chunk)
                size += len(chunk)
    return size, digest.hexdigest()

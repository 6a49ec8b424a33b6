"""S3-compatible object storage (AWS S3, SeaweedFS, MinIO, ...) through boto3.

Every key lives under ``PREFIX/`` in one bucket. Large writes stream as multipart uploads of
`PART_BYTES` parts (memory stays at one part, whatever the file's size) and become visible only
when completed, so a reader never sees half an object. Nothing here touches the local disk except
`fetch`, which a stage calls to get a clip onto its own scratch folder.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import io
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

from saddlescope.core.errors import InputError, SaddleScopeError
from saddlescope.storage.files import CHUNK_BYTES, TooLarge, same_prefix

__all__ = ["PART_BYTES", "S3Storage", "S3Writer", "StoreUnavailable", "parse_s3_url"]

# S3's smallest part (but the last) is 5 MiB; 8 MiB parts keep a 4 GiB clip well under its 10,000 parts.
PART_BYTES = 8 * 1024**2


def parse_s3_url(url: str) -> tuple[str, str]:
    """``s3://BUCKET[/PREFIX]`` as (bucket, prefix without slashes at either end)."""
    if not url.startswith("s3://"):
        raise InputError(f"storage URL {url!r} is not an s3://BUCKET[/PREFIX] URL")
    bucket, _, prefix = url.removeprefix("s3://").partition("/")
    if not bucket:
        raise InputError(f"storage URL {url!r} names no bucket (s3://BUCKET[/PREFIX])")
    return bucket, prefix.strip("/")


def _check_key(key: str) -> str:
    parts = key.split("/")
    if not key or "\\" in key or "\0" in key or any(part in ("", ".", "..") for part in parts):
        raise InputError(f"storage key {key!r} must be a relative path without '..', '.' or '//'")
    return key


class S3Writer:
    """Chunks streamed to one object as a multipart upload, hashed and counted on the way.

    `commit` completes the upload (the object appears whole); `abort` (or an exception in a
    ``with`` block) aborts it, and the store keeps nothing. More than `max_bytes` raises `TooLarge`.
    """

    def __init__(self, storage: S3Storage, key: str, *, max_bytes: int | None = None) -> None:
        self.storage, self.key, self.max_bytes = storage, key, max_bytes
        self.size = 0
        self._digest = hashlib.sha256()
        self._buffer = bytearray()
        self._upload_id: str | None = None
        self._parts: list[dict[str, Any]] = []
        self._done = False

    def write(self, chunk: bytes) -> None:
        """Add `chunk`, sending a part whenever enough are buffered; `TooLarge` past `max_bytes`."""
        self.size += len(chunk)
        if self.max_bytes is not None and self.size > self.max_bytes:
            self.abort()
            raise TooLarge(f"{self.key.rsplit('/', 1)[-1]}: larger than the upload limit of "
                           f"{self.max_bytes} bytes ({self.max_bytes / 1024**2:.0f} MiB)")
        self._digest.update(chunk)
        self._buffer += chunk
        while len(self._buffer) >= PART_BYTES:
            self._send_part(bytes(self._buffer[:PART_BYTES]))
            del self._buffer[:PART_BYTES]

    def _send_part(self, data: bytes) -> None:
        s3, bucket, name = self.storage.client, self.storage.bucket, self.storage.object_name(self.key)
        if self._upload_id is None:
            self._upload_id = s3.create_multipart_upload(Bucket=bucket, Key=name)["UploadId"]
        number = len(self._parts) + 1
        etag = s3.upload_part(Bucket=bucket, Key=name, UploadId=self._upload_id, PartNumber=number,
                              Body=data)["ETag"]
        self._parts.append({"PartNumber": number, "ETag": etag})

    @property
    def sha256(self) -> str:
        """The sha256 (hex) of the bytes written so far."""
        return self._digest.hexdigest()

    def commit(self) -> tuple[int, str]:
        """Make the object visible under `key`; returns (size in bytes, sha256 hex)."""
        s3, bucket, name = self.storage.client, self.storage.bucket, self.storage.object_name(self.key)
        if self._upload_id is None:  # small: one PUT
            s3.put_object(Bucket=bucket, Key=name, Body=bytes(self._buffer))
        else:
            if self._buffer:
                self._send_part(bytes(self._buffer))
            s3.complete_multipart_upload(Bucket=bucket, Key=name, UploadId=self._upload_id,
                                         MultipartUpload={"Parts": self._parts})
        self._buffer.clear()
        self._done = True
        return self.size, self.sha256

    def abort(self) -> None:
        """Abort the multipart upload and drop the buffer; nothing appears under `key`."""
        if self._upload_id is not None and not self._done:
            self.storage.client.abort_multipart_upload(Bucket=self.storage.bucket,
                                                       Key=self.storage.object_name(self.key),
                                                       UploadId=self._upload_id)
        self._buffer.clear()
        self._done = True

    def __enter__(self) -> S3Writer:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if not self._done:
            self.abort()


class _RangeReader(io.RawIOBase):
    """A seekable read-only view of objects laid end to end (one object, or an upload's parts), by ranged GETs."""

    def __init__(self, storage: S3Storage, segments: list[tuple[str, int]]) -> None:
        self.storage, self.segments = storage, segments  # (object name, size) in order
        self.length = sum(size for _, size in segments)
        self.position = 0

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self.position, io.SEEK_END: self.length}[whence]
        self.position = max(0, base + offset)
        return self.position

    def tell(self) -> int:
        return self.position

    def readinto(self, buffer) -> int:
        wanted = min(len(buffer), self.length - self.position)
        if wanted <= 0:
            return 0
        start = 0
        for name, size in self.segments:
            if self.position < start + size:
                inner = self.position - start
                count = min(wanted, size - inner)
                body = self.storage.client.get_object(Bucket=self.storage.bucket, Key=name,
                                                      Range=f"bytes={inner}-{inner + count - 1}")["Body"]
                data = body.read()
                buffer[:len(data)] = data
                self.position += len(data)
                return len(data)
            start += size
        return 0


def _new_client(endpoint_url: str | None) -> Any:
    import boto3
    from botocore.config import Config

    # Path-style addressing: SeaweedFS and MinIO serve buckets under the endpoint's path.
    # Its own session: credentials are read from the environment now, not from a process-wide cache.
    return boto3.session.Session().client(
        "s3", endpoint_url=endpoint_url, config=Config(s3={"addressing_style": "path"}, retries={"max_attempts": 3}))


class StoreUnavailable(SaddleScopeError, OSError):
    """The object store does not answer (connection refused or reset, time-out, a 5xx after botocore's retries).

    The API answers it with 503 and this reason; in a job it is a passing failure worth retrying, unlike a
    missing key or a refused request, which stay botocore's `ClientError`.
    """

    retryable = True
    retry_after_s = 10


def _unavailable(exc: Exception) -> bool:
    from botocore.exceptions import ClientError, ConnectionError, HTTPClientError

    if isinstance(exc, (ConnectionError, HTTPClientError)):  # refused, reset, connect/read time-outs
        return True
    if isinstance(exc, ClientError):
        code = exc.response.get("ResponseMetadata", {}).get("HTTPStatusCode") or 0
        return code >= 500 or exc.response.get("Error", {}).get("Code") in ("SlowDown", "ServiceUnavailable")
    return False


class _GuardedClient:
    """A boto3 S3 client whose calls raise `StoreUnavailable` when the store does not answer.

    The error carries a reason a person reads.

    Every other error passes unchanged (a 404 is still `ClientError`).
    """

    def __init__(self, client: Any, where: str) -> None:
        self._client, self._where = client, where

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._client, name)
        if not callable(attr) or name in ("generate_presigned_url", "get_paginator", "can_paginate"):
            return attr

        def call(*args, **kwargs):
            try:
                return attr(*args, **kwargs)
            except Exception as exc:
                if _unavailable(exc):
                    raise StoreUnavailable(f"the file store is not answering ({self._where}: "
                                           f"{type(exc).__name__}: {exc}); try again in a moment") from exc
                raise
        return call


class S3Storage:
    """Keys as objects ``PREFIX/key`` in `bucket` of an S3-compatible store.

    `public_endpoint_url`: the store's address as the browser reaches it, for pre-signed part URLs
    (``SADDLESCOPE_S3_PUBLIC_ENDPOINT_URL``; None: `endpoint_url`). A signature covers the host, so
    those URLs are signed by a client of that endpoint; no request goes to it from here.
    """

    kind = "s3"
    local = False

    def __init__(self, bucket: str, prefix: str = "", *, endpoint_url: str | None = None,
                 client: Any | None = None, public_endpoint_url: str | None = None) -> None:
        if client is None:
            client = _new_client(endpoint_url)
        self.bucket, self.prefix, self.endpoint_url = bucket, prefix.strip("/"), endpoint_url
        self.client = _GuardedClient(client, self.describe())
        self.public_endpoint_url = public_endpoint_url
        self._signer = _new_client(public_endpoint_url) if public_endpoint_url else self.client

    @classmethod
    def from_url(cls, url: str, *, endpoint_url: str | None = None,
                 public_endpoint_url: str | None = None) -> S3Storage:
        """The store an ``s3://bucket/prefix`` URL names."""
        bucket, prefix = parse_s3_url(url)
        return cls(bucket, prefix, endpoint_url=endpoint_url, public_endpoint_url=public_endpoint_url)

    def __repr__(self) -> str:
        return f"S3Storage({self.describe()!r})"

    def describe(self) -> str:
        """The bucket URL, with its endpoint when not AWS's."""
        where = f" at {self.endpoint_url}" if self.endpoint_url else ""
        return f"s3://{self.bucket}/{self.prefix}{where}".replace(f"{self.bucket}/ at", f"{self.bucket} at")

    def object_name(self, key: str) -> str:
        """The object name of `key` in the bucket (under the store's prefix)."""
        _check_key(key)
        return f"{self.prefix}/{key}" if self.prefix else key

    def _key_of(self, name: str) -> str:
        return name[len(self.prefix) + 1:] if self.prefix else name

    def _head(self, key: str) -> dict[str, Any] | None:
        from botocore.exceptions import ClientError

        try:
            return self.client.head_object(Bucket=self.bucket, Key=self.object_name(key))
        except ClientError as exc:
            if exc.response.get("Error", {}).get("Code") in ("404", "NoSuchKey", "NotFound"):
                return None
            raise

    def exists(self, key: str) -> bool:
        """Whether `key` is an object, or the folder of one."""
        return self._head(key) is not None or next(self.iter_keys(key), None) is not None

    def size(self, key: str) -> int:
        """The size in bytes of the object under `key`."""
        head = self._head(key)
        if head is None:
            raise FileNotFoundError(f"{key} is not in storage")
        return int(head["ContentLength"])

    def open(self, key: str) -> BinaryIO:
        """A stream of the object's bytes (read it in chunks; close it)."""
        from botocore.exceptions import ClientError

        try:
            return self.client.get_object(Bucket=self.bucket, Key=self.object_name(key))["Body"]
        except ClientError as exc:
            if exc.response.get("Error", {}).get("Code") in ("404", "NoSuchKey"):
                raise FileNotFoundError(f"{key} is not in storage") from None
            raise

    def writer(self, key: str, *, max_bytes: int | None = None) -> S3Writer:
        """A writer for `key` that sends the object in parts; `TooLarge` past `max_bytes`."""
        return S3Writer(self, _check_key(key), max_bytes=max_bytes)

    def write_stream(self, key: str, stream: BinaryIO, *, max_bytes: int | None = None) -> tuple[int, str]:
        """Store `stream` under `key`; returns (size in bytes, sha256 hex)."""
        with self.writer(key, max_bytes=max_bytes) as out:
            while chunk := stream.read(CHUNK_BYTES):
                out.write(chunk)
            return out.commit()

    def write_bytes(self, key: str, data: bytes) -> tuple[int, str]:
        """Store `data` under `key`; returns (size in bytes, sha256 hex)."""
        return self.write_stream(key, io.BytesIO(data))

    def read_bytes(self, key: str) -> bytes:
        """The bytes of the object under `key`."""
        with self.open(key) as body:
            return body.read()

    def import_file(self, key: str, source: Path | str) -> tuple[int, str]:
        """Store the local file `source` under `key`; returns (size in bytes, sha256 hex)."""
        with Path(source).open("rb") as stream:
            return self.write_stream(key, stream)

    def import_tree(self, key: str, source: Path | str) -> None:
        """Store the local folder `source` under the folder `key`."""
        source = Path(source)
        for file in sorted(p for p in source.rglob("*") if p.is_file()):
            self.import_file(f"{key}/{file.relative_to(source).as_posix()}", file)

    # --- resumable uploads: the bytes collect as part objects ``KEY/<start offset, 20 digits>`` --------

    def _segments(self, key: str) -> list[tuple[str, int]]:
        """(object name, size) of `key`: itself when it is an object, else its part objects in order."""
        head = self._head(key)
        if head is not None:
            return [(self.object_name(key), int(head["ContentLength"]))]
        pages = self.client.get_paginator("list_objects_v2").paginate(
            Bucket=self.bucket, Prefix=self.object_name(key) + "/")
        items = sorted((item["Key"], int(item["Size"])) for page in pages for item in page.get("Contents", []))
        if not items:
            raise FileNotFoundError(f"{key} is not in storage")
        return items

    def open_seekable(self, key: str, *, block_bytes: int = CHUNK_BYTES) -> BinaryIO:
        """`key` (an object, or an upload's parts read as one file) as a seekable stream, read by ranges.

        For readers that jump about (a zip's directory at its end): nothing is copied to local disk. Each
        ranged GET fetches at least `block_bytes` (held in memory); a seek within them costs no request.
        """
        return io.BufferedReader(_RangeReader(self, self._segments(key)), buffer_size=block_bytes)

    def same_bytes(self, key: str, offset: int, other_key: str, length: int) -> bool:
        """Whether `length` bytes of `key` from `offset` equal the first `length` bytes of `other_key`."""
        with self.open_seekable(key) as ours, self.open(other_key) as theirs:
            ours.seek(offset)
            return same_prefix(ours, theirs, length)

    def append_from(self, key: str, at: int, source_key: str, skip: int) -> None:
        """Add `source_key` from its byte `skip` on as the part of `key` starting at byte `at`.

        Parts at or after `at` (left by a chunk that was never acknowledged) are dropped first. With
        nothing to skip the part is a server-side copy; its bytes never pass through this process.
        """
        for name, _ in self._parts_from(key, at):
            self.client.delete_object(Bucket=self.bucket, Key=name)
        part = f"{key}/{at:020d}"
        if skip == 0:
            self.client.copy({"Bucket": self.bucket, "Key": self.object_name(source_key)}, self.bucket,
                             self.object_name(part))
            return
        with self.open_seekable(source_key) as source:
            source.seek(skip)
            self.write_stream(part, source)

    def _parts_from(self, key: str, at: int) -> list[tuple[str, int]]:
        try:
            segments = self._segments(key)
        except FileNotFoundError:
            return []
        return [(name, size) for name, size in segments if name.rsplit("/", 1)[-1].isdigit()
                and int(name.rsplit("/", 1)[-1]) >= at]

    def seal(self, key: str, target_key: str) -> None:
        """Make the collected bytes of `key` one object `target_key` (streamed part by part), then drop `key`.

        Bytes that are one object already (a joined direct upload) are moved by the store, not through here.
        """
        if self._head(key) is not None:
            self.move(key, target_key)
            return
        with self.open_seekable(key) as source:
            self.write_stream(target_key, source)
        self.delete(key)

    # --- direct uploads: the browser sends parts straight to the store with pre-signed URLs ---------

    def start_direct(self, key: str) -> str:
        """Open a multipart upload of `key` the client will fill; returns its S3 upload id."""
        return self.client.create_multipart_upload(Bucket=self.bucket, Key=self.object_name(key))["UploadId"]

    def direct_id(self, key: str) -> str | None:
        """The S3 upload id of the open multipart upload of `key` (None: none open)."""
        found = self.client.list_multipart_uploads(Bucket=self.bucket, Prefix=self.object_name(key))
        ids = [u["UploadId"] for u in found.get("Uploads", []) if u["Key"] == self.object_name(key)]
        return ids[-1] if ids else None

    def part_url(self, key: str, direct_id: str, number: int, *, expires_s: int) -> str:
        """A pre-signed PUT URL for part `number` (1-based) of the multipart upload `direct_id`."""
        return self._signer.generate_presigned_url(
            "upload_part", ExpiresIn=expires_s,
            Params={"Bucket": self.bucket, "Key": self.object_name(key), "UploadId": direct_id,
                    "PartNumber": number})

    def direct_parts(self, key: str, direct_id: str) -> list[dict[str, Any]]:
        """The parts that arrived: ``{"number", "size", "etag"}`` in part order."""
        parts: list[dict[str, Any]] = []
        marker = 0
        while True:
            page = self.client.list_parts(Bucket=self.bucket, Key=self.object_name(key), UploadId=direct_id,
                                          PartNumberMarker=marker)
            parts += [{"number": p["PartNumber"], "size": int(p["Size"]), "etag": p["ETag"]}
                      for p in page.get("Parts", [])]
            if not page.get("IsTruncated"):
                return sorted(parts, key=lambda p: p["number"])
            marker = page["NextPartNumberMarker"]

    def complete_direct(self, key: str, direct_id: str, parts: list[dict[str, Any]]) -> None:
        """Join the parts into the object `key` (it appears whole)."""
        self.client.complete_multipart_upload(
            Bucket=self.bucket, Key=self.object_name(key), UploadId=direct_id,
            MultipartUpload={"Parts": [{"PartNumber": p["number"], "ETag": p["etag"]} for p in parts]})

    def abort_direct(self, key: str) -> None:
        """Abort every open multipart upload of `key` (its parts are removed); no error when none."""
        while (direct_id := self.direct_id(key)) is not None:
            self.client.abort_multipart_upload(Bucket=self.bucket, Key=self.object_name(key), UploadId=direct_id)

    def stale_keys(self, prefix: str, *, older_than_s: float) -> list[str]:
        """The objects under the folder `prefix` last written more than `older_than_s` ago.

        Ages are by the store's clock.
        """
        cutoff = dt.datetime.now(dt.UTC) - dt.timedelta(seconds=older_than_s)
        pages = self.client.get_paginator("list_objects_v2").paginate(
            Bucket=self.bucket, Prefix=self.object_name(prefix) + "/")
        return sorted(self._key_of(item["Key"]) for page in pages for item in page.get("Contents", [])
                      if item["LastModified"] < cutoff)

    def sweep_partial_writes(self, *, older_than_s: float) -> int:
        """Abort the multipart uploads under this store's prefix with no part sent for `older_than_s`.

        A browser's direct upload given up, a process killed mid-write.
        Their parts go. The rule a bucket's lifecycle "abort incomplete multipart uploads" would apply, on any
        S3 store.
        """
        cutoff = dt.datetime.now(dt.UTC) - dt.timedelta(seconds=older_than_s)
        pages = self.client.get_paginator("list_multipart_uploads").paginate(
            Bucket=self.bucket, Prefix=f"{self.prefix}/" if self.prefix else "")
        aborted = 0
        for upload in (u for page in pages for u in page.get("Uploads", []) if u["Initiated"] < cutoff):
            parts = self.client.list_parts(Bucket=self.bucket, Key=upload["Key"],
                                           UploadId=upload["UploadId"]).get("Parts", [])
            if max([upload["Initiated"], *(part["LastModified"] for part in parts)]) < cutoff:
                self.client.abort_multipart_upload(Bucket=self.bucket, Key=upload["Key"],
                                                   UploadId=upload["UploadId"])
                aborted += 1
        return aborted

    def fetch(self, key: str, target: Path | str) -> Path:
        """Download the object (or every object of the folder) `key` to local `target`; returns `target`."""
        target = Path(target)
        if self._head(key) is not None:
            target.parent.mkdir(parents=True, exist_ok=True)
            self.client.download_file(self.bucket, self.object_name(key), str(target))
            return target
        found = False
        for inner in self.iter_keys(key):
            found = True
            local = target.joinpath(*inner[len(key) + 1:].split("/"))
            local.parent.mkdir(parents=True, exist_ok=True)
            self.client.download_file(self.bucket, self.object_name(inner), str(local))
        if not found:
            raise FileNotFoundError(f"{key} is not in storage")
        return target

    def move(self, source_key: str, target_key: str) -> None:
        """Copy then delete (S3 has no rename); the managed copy handles objects over 5 GiB."""
        self.client.copy({"Bucket": self.bucket, "Key": self.object_name(source_key)}, self.bucket,
                         self.object_name(target_key))
        self.client.delete_object(Bucket=self.bucket, Key=self.object_name(source_key))

    def sha256(self, key: str) -> str:
        """The sha256 (hex) of the object under `key`."""
        digest = hashlib.sha256()
        with self.open(key) as body:
            while chunk := body.read(CHUNK_BYTES):
                digest.update(chunk)
        return digest.hexdigest()

    def iter_keys(self, prefix: str) -> Iterator[str]:
        """Every key under the folder `prefix` (or `prefix` itself when it is an object), sorted."""
        if self._head(prefix) is not None:
            yield prefix
            return
        pages = self.client.get_paginator("list_objects_v2").paginate(
            Bucket=self.bucket, Prefix=self.object_name(prefix) + "/")
        keys = [self._key_of(item["Key"]) for page in pages for item in page.get("Contents", [])]
        yield from sorted(keys)

    def delete(self, prefix: str) -> None:
        """Remove an object or a whole folder (no error when absent)."""
        names = [self.object_name(prefix)] + [self.object_name(k) for k in self.iter_keys(prefix) if k != prefix]
        for start in range(0, len(names), 1000):  # DeleteObjects takes at most 1000 keys
            self.client.delete_objects(Bucket=self.bucket, Delete={
                "Objects": [{"Key": name} for name in names[start:start + 1000]], "Quiet": True})

    def check(self) -> str:
        """Reach the bucket and write, read and delete a probe object; returns a description or raises OSError."""
        from botocore.exceptions import BotoCoreError, ClientError

        probe = f".health/{uuid.uuid4().hex}"
        try:
            self.client.head_bucket(Bucket=self.bucket)
            self.write_bytes(probe, b"ok")
            try:
                if self.read_bytes(probe) != b"ok":
                    raise OSError(f"{self.describe()} returned different bytes than written")
            finally:
                self.client.delete_object(Bucket=self.bucket, Key=self.object_name(probe))
        except (BotoCoreError, ClientError) as exc:
            raise OSError(f"{type(exc).__name__}: {exc}") from None
        return f"{self.describe()} writable"

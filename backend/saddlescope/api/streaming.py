"""Streaming request bodies into storage at constant memory.

An upload is either ``multipart/form-data`` with the file in the field ``file`` (what a browser form
sends) or the raw bytes as the body (any other content type, e.g. ``video/mp4`` from a script). Either
way each chunk goes straight to an `AtomicWriter` (hashed, counted, size limit enforced as it comes),
written from a worker thread so a slow disk never stalls the event loop. Nothing but one chunk is ever
held in memory.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from fastapi import Request
from python_multipart.exceptions import MultipartParseError
from python_multipart.multipart import MultipartParser, parse_options_header
from starlette.concurrency import run_in_threadpool
from starlette.requests import ClientDisconnect

from saddlescope.core.errors import InputError
from saddlescope.storage import Storage, StorageWriter

if TYPE_CHECKING:
    from python_multipart.multipart import MultipartCallbacks

__all__ = [
    "FILE_FIELD", "MAX_FIELD_BYTES", "StreamedUpload", "UPLOAD_OPENAPI", "UploadFormatError",
    "WRITE_BATCH_BYTES", "stream_chunk", "stream_upload",
]

FILE_FIELD = "file"
# Writes are batched to about this size: fewer thread hops than one per network chunk.
WRITE_BATCH_BYTES = 1 << 20
MAX_FIELD_BYTES = 64 * 1024

# The request body of upload routes in the OpenAPI (the routes read the stream themselves).
UPLOAD_OPENAPI = {
    "requestBody": {
        "required": True,
        "content": {
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "required": [FILE_FIELD],
                    "properties": {FILE_FIELD: {"type": "string", "format": "binary"}},
                },
            },
            "application/octet-stream": {"schema": {"type": "string", "format": "binary"}},
        },
    }
}


MAX_FILENAME_CHARS = 255  # what a recording or an upload keeps of the user's file name


class UploadFormatError(InputError):
    """The request body is not an upload we understand (no file field, broken multipart)."""


@dataclass
class _MultipartState:
    """Collects the parts of a multipart body: the file's bytes go to `pending`, small fields to `fields`."""

    pending: list[bytes] = field(default_factory=list)
    pending_bytes: int = 0
    fields: dict[str, str] = field(default_factory=dict)
    filename: str | None = None
    found_file: bool = False
    _header_field: bytes = b""
    _header_value: bytes = b""
    _headers: dict[bytes, bytes] = field(default_factory=dict)
    _part: str | None = None  # "file", a field name, or None (ignored part)
    _field_value: bytearray = field(default_factory=bytearray)

    def callbacks(self) -> MultipartCallbacks:
        def on_part_begin() -> None:
            self._headers, self._part = {}, None
            self._field_value = bytearray()

        def on_header_field(data: bytes, start: int, end: int) -> None:
            self._header_field += data[start:end]

        def on_header_value(data: bytes, start: int, end: int) -> None:
            self._header_value += data[start:end]

        def on_header_end() -> None:
            self._headers[self._header_field.lower()] = self._header_value
            self._header_field, self._header_value = b"", b""

        def on_headers_finished() -> None:
            _, options = parse_options_header(self._headers.get(b"content-disposition", b""))
            name = options.get(b"name", b"").decode("utf-8", "replace")
            if name == FILE_FIELD:
                if self.found_file:
                    raise UploadFormatError(f"the upload has more than one '{FILE_FIELD}' field")
                self.found_file = True
                self._part = FILE_FIELD
                raw = options.get(b"filename")
                self.filename = (
                    raw.decode("utf-8", "replace").replace("\\", "/").rsplit("/", 1)[-1] if raw else None
                )
            elif name:
                self._part = f"field:{name}"

        def on_part_data(data: bytes, start: int, end: int) -> None:
            if self._part == FILE_FIELD:
                self.pending.append(data[start:end])
                self.pending_bytes += end - start
            elif self._part is not None:
                self._field_value += data[start:end]
                if len(self._field_value) > MAX_FIELD_BYTES:
                    raise UploadFormatError(
                        f"the form field {self._part[6:]!r} is longer than {MAX_FIELD_BYTES} bytes"
                    )

        def on_part_end() -> None:
            if self._part is not None and self._part.startswith("field:"):
                self.fields[self._part[6:]] = self._field_value.decode("utf-8", "replace")

        return {
            "on_part_begin": on_part_begin,
            "on_header_field": on_header_field,
            "on_header_value": on_header_value,
            "on_header_end": on_header_end,
            "on_headers_finished": on_headers_finished,
            "on_part_data": on_part_data,
            "on_part_end": on_part_end,
        }

    def take(self) -> bytes:
        data = b"".join(self.pending)
        self.pending.clear()
        self.pending_bytes = 0
        return data


@dataclass
class StreamedUpload:
    """A request body now stored under `key`: its size, sha256 and the client's file name."""

    key: str
    size_bytes: int
    sha256: str
    filename: str | None
    fields: dict[str, str]


async def _drain(writer: StorageWriter, data: bytes) -> None:
    if data:
        await run_in_threadpool(writer.write, data)


async def stream_upload(request: Request, storage: Storage, key: str, *, max_bytes: int) -> StreamedUpload:
    """Store the uploaded file of `request` under `key` (atomically); see the module docstring.

    Raises `TooLarge` (over `max_bytes`, found while streaming), `UploadFormatError` (a multipart body
    without a ``file`` field, or a broken one), `InputError` (the client went away mid-upload).
    """
    content_type, options = parse_options_header(request.headers.get("content-type", ""))
    declared = request.headers.get("content-length")
    if (
        declared is not None
        and declared.isdigit()
        and content_type != b"multipart/form-data"
        and int(declared) > max_bytes
    ):
        from saddlescope.storage import TooLarge

        raise TooLarge(
            f"the upload is {int(declared)} bytes, larger than the upload limit of {max_bytes} bytes"
        )
    writer = storage.writer(key, max_bytes=max_bytes)
    try:
        if content_type == b"multipart/form-data":
            boundary = options.get(b"boundary")
            if not boundary:
                raise UploadFormatError("multipart/form-data without a boundary")
            state = _MultipartState()
            parser = MultipartParser(boundary, state.callbacks())
            async for chunk in request.stream():
                try:
                    parser.write(chunk)
                except MultipartParseError as exc:
                    hint = " (a part's headers, e.g. the file name, are too long)" if "header" in str(exc) else ""
                    raise UploadFormatError(f"the multipart body is broken: {exc}{hint}") from None
                if state.pending_bytes >= WRITE_BATCH_BYTES:
                    await _drain(writer, state.take())
            try:
                parser.finalize()
            except MultipartParseError as exc:
                raise UploadFormatError(f"the multipart body is broken: {exc}") from None
            if not state.found_file:
                raise UploadFormatError(f"the multipart body has no '{FILE_FIELD}' field with the file")
            await _drain(writer, state.take())
            filename, fields = state.filename, state.fields
        else:
            batch: list[bytes] = []
            batch_bytes = 0
            async for chunk in request.stream():
                batch.append(chunk)
                batch_bytes += len(chunk)
                if batch_bytes >= WRITE_BATCH_BYTES:
                    await _drain(writer, b"".join(batch))
                    batch, batch_bytes = [], 0
            await _drain(writer, b"".join(batch))
            filename, fields = request.headers.get("x-filename") or request.query_params.get("filename"), {}
        if filename is not None and len(filename) > MAX_FILENAME_CHARS:
            raise UploadFormatError(f"the file name has {len(filename)} characters; a file name may have at most "
                                    f"{MAX_FILENAME_CHARS}")
        size, sha256 = await run_in_threadpool(writer.commit)
    except ClientDisconnect:
        writer.abort()
        raise InputError("the client went away before the upload was complete") from None
    except BaseException:
        writer.abort()
        raise
    return StreamedUpload(key, size, sha256, filename, fields)


async def stream_chunk(request: Request, storage: Storage, key: str, *, offset: int, limit: int) -> int:
    """Write the raw body of a resumable-upload PATCH meant for byte `offset` into a new file `key`.

    Returns how many bytes came. Bytes that arrived before a dropped connection are kept (the client
    resumes from the offset it is told); more than `limit` bytes in total raise `TooLarge`.
    """
    from saddlescope.storage import TooLarge

    writer = storage.writer(key)
    size = 0
    try:
        async for chunk in request.stream():
            if offset + size + len(chunk) > limit:
                raise TooLarge(
                    f"more bytes than the {limit} announced for this upload (offset {offset + size} + "
                    f"{len(chunk)})"
                )
            await _drain(writer, chunk)
            size += len(chunk)
    except ClientDisconnect:
        pass  # keep what came; the client asks for the offset and resumes
    except BaseException:
        writer.abort()
        raise
    await run_in_threadpool(writer.commit)
    return size

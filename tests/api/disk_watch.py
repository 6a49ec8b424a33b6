"""Which local files the API process writes while a test watches: an audit hook on every open and mkdir.

Python's audit events see every file opened for writing (``open``, ``os.open``, so also `tempfile` and
any library) and every folder made, from any thread. The hook is installed once per process (audit
hooks cannot be removed) and records only while a `watching_local_writes` block runs. Jobs a test's
embedded queue runs in threads of its own (``run_job``) are workers, not the API: they are left out
(and `queue_of` waits for them, as their downloads run in boto3's threads).
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

from saddlescope.storage import sha256_file, tree_digest

__all__ = ["HeldQueue", "bundle_clip_digests", "in_a_job_thread", "queue_of", "watching_local_writes"]

_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_APPEND | os.O_TRUNC
_records: list[list[str]] = []  # the lists of the blocks watching now
_installed = False


def in_a_job_thread() -> bool:
    """Whether the caller runs a job of the embedded queue (a worker's own disk, not the API's)."""
    return "run_job" in threading.current_thread().name


def _audit(event: str, args: tuple) -> None:
    if not _records or event not in ("open", "os.mkdir") or in_a_job_thread():
        return
    path = args[0]
    if isinstance(path, int):  # an open file descriptor, opened (and recorded) before
        return
    if event == "open" and not (args[2] or 0) & _WRITE_FLAGS:
        return
    for record in _records:
        record.append(f"{event} {os.fsdecode(path)}")


@contextlib.contextmanager
def watching_local_writes() -> Iterator[list[str]]:
    """Yield a list that fills with ``"open PATH"`` / ``"os.mkdir PATH"`` for each local write meanwhile."""
    global _installed
    if not _installed:
        sys.addaudithook(_audit)
        _installed = True
    record: list[str] = []
    _records.append(record)
    try:
        yield record
    finally:
        _records.remove(record)


class HeldQueue:
    """A job queue that takes jobs and runs none (the test looks at what the API did, not at the worker)."""

    mode = "embedded"

    def __init__(self) -> None:
        self.jobs: list[int] = []

    def submit(self, job_id: int) -> None:
        self.jobs.append(job_id)

    def health(self) -> tuple[bool, str]:
        return True, "embedded: held by the test"

    def close(self) -> None:
        pass


@contextlib.contextmanager
def queue_of(app, queue) -> Iterator[object]:
    """The app's job queue is `queue` while the block runs (then the one it had).

    Jobs the old queue runs in threads of this process (`api_helpers.ThreadQueue`) are waited for first:
    a worker's downloads (in threads of boto3's own) are no writes of the API.
    """
    for thread in getattr(app.state.queue, "threads", []):
        thread.join(timeout=120)
    saved, app.state.queue = app.state.queue, queue
    try:
        yield queue
    finally:
        app.state.queue = saved


def bundle_clip_digests(folder: Path) -> dict[tuple[str, str], tuple[int, str]]:
    """(clip kind, camera) -> (size, sha256) of a bundle folder's clips, as the API must record them."""
    import json

    meta = json.loads((folder / "ride.json").read_text())
    out = {}
    for kind, cams in meta["clips"].items():
        for camera, rel in cams.items():
            path = folder / rel
            out[kind, camera] = tree_digest(path) if path.is_dir() else (path.stat().st_size, sha256_file(path))
    return out

"""Rendered arena rides for tests, kept between runs: `cached_ride_bundle` is `write_ride_bundle` with a cache.

Half of a rendered ride test's CPU is the render (frame synthesis and libx264), and the renders repeat run after
run. A bundle is stored once under a key made of everything that makes it: the arguments, the source of every
saddlescope module `saddlescope.io.synth_writer` imports (found by grimp, so a change to the arena, the writer or
the core code the truth uses renders again), and the versions of Python, numpy, OpenCV, PyAV and its codecs. Each
test gets its own copy of the stored bundle in the folder it asks for, as `write_ride_bundle` writes it.

The cache lives in ``$SADDLESCOPE_TEST_RENDER_CACHE`` (default ``~/.cache/saddlescope/test-rides``); ``off``
renders every time (a cold run). It keeps at most ``CACHE_LIMIT_BYTES``, the least recently used going first.
libx264 gives different bytes from run to run (its threads), so a cached bundle also makes a test's input the
same from one run to the next; `tests/io/test_synth_writer.py` renders without the cache.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import functools
import hashlib
import json
import os
import platform
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path

CACHE_ENV = "SADDLESCOPE_TEST_RENDER_CACHE"
CACHE_LIMIT_BYTES = 6 * 1024**3  # about 60 rides at 1280x720 and beyond
_WRITER = "saddlescope.io.synth_writer"


def cache_root() -> Path | None:
    """The cache's folder, or None where ``$SADDLESCOPE_TEST_RENDER_CACHE`` is ``off``."""
    setting = os.environ.get(CACHE_ENV, "").strip()
    if setting.lower() in {"off", "0", "no", "false"}:
        return None
    return Path(setting).expanduser() if setting else Path.home() / ".cache" / "saddlescope" / "test-rides"


@functools.lru_cache(maxsize=1)
def renderer_modules() -> tuple[str, ...]:
    """The writer and every saddlescope module and package it imports, directly or not (grimp's import graph)."""
    import grimp

    graph = grimp.build_graph("saddlescope", cache_dir=None)
    modules = set(graph.find_upstream_modules(_WRITER)) | {_WRITER}
    modules |= {".".join(m.split(".")[:i]) for m in modules for i in range(1, m.count(".") + 1)}  # the packages
    return tuple(sorted(modules))


@functools.lru_cache(maxsize=1)
def renderer_fingerprint() -> str:
    """SHA-256 of the source of `renderer_modules` and of the libraries' versions."""
    import av
    import cv2
    import numpy as np

    digest = hashlib.sha256()
    for name in renderer_modules():
        digest.update(name.encode())
        digest.update(_module_source(name))
    versions = {"python": platform.python_version(), "numpy": np.__version__, "cv2": cv2.__version__,
                "av": av.__version__, "codecs": {k: list(v) for k, v in sorted(av.library_versions.items())}}
    digest.update(json.dumps(versions, sort_keys=True).encode())
    return digest.hexdigest()


def _module_source(name: str) -> bytes:
    import importlib.util

    spec = importlib.util.find_spec(name)
    if spec is None or spec.origin is None:
        raise RuntimeError(f"render cache: no source for {name}")
    return Path(spec.origin).read_bytes()


def _plain(value):
    """Arguments as JSON: a dataclass (RenderOptions) by its type and fields, tuples as lists."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"dataclass": type(value).__qualname__, **{k: _plain(v) for k, v in dataclasses.asdict(value).items()}}
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"render cache: cannot key an argument of type {type(value).__name__}")


def bundle_key(arguments: dict) -> str:
    """The cache key of ``write_ride_bundle(**arguments)`` with the renderer as it is now."""
    text = json.dumps({"arguments": _plain(arguments), "renderer": renderer_fingerprint()}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def cached_ride_bundle(out_dir: Path, **arguments) -> Path:
    """``write_ride_bundle(out_dir, **arguments)``, from the cache when this renderer made the same bundle before.

    Returns ``out_dir``, a copy of its own the test may change. Keyword arguments only (``on_progress`` has no
    place in a key).
    """
    from saddlescope.io.synth_writer import write_ride_bundle

    out_dir = Path(out_dir)
    root = cache_root()
    if root is None:
        return write_ride_bundle(out_dir, **arguments)
    root.mkdir(parents=True, exist_ok=True)

    def render(folder: Path) -> None:
        write_ride_bundle(folder, **arguments)
        (folder / "arguments.json").write_text(json.dumps(_plain(arguments), indent=1, sort_keys=True))
        _evict(root, keep=folder)

    with built_once(root / bundle_key(arguments), render) as stored:  # held while copied: never evicted meanwhile
        os.utime(stored)  # recently used
        shutil.copytree(stored, out_dir, ignore=shutil.ignore_patterns("arguments.json"), dirs_exist_ok=True)
    return out_dir


@contextlib.contextmanager
def built_once(folder: Path, build: Callable[[Path], object]) -> Iterator[Path]:
    """`folder`, made by `build(folder)` unless a build of it finished before; under its lock while in use.

    Another process building or using it waits for the lock; a build that stopped half-way (no
    ``<folder>.built`` beside it) is thrown away and made again.
    """
    done = _marker(folder, "built")
    with _marker(folder, "lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)
            build(folder)
            done.touch()
        yield folder


def _marker(folder: Path, what: str) -> Path:
    return folder.with_name(f"{folder.name}.{what}")


def _evict(root: Path, *, keep: Path) -> None:
    """Least recently used bundles out until the cache holds at most CACHE_LIMIT_BYTES.

    Never `keep`, nor a bundle another process is rendering or copying (its lock is taken).
    """
    entries = []
    for folder in root.iterdir():
        if folder.is_dir():
            size = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file())
            entries.append((folder.stat().st_mtime, size, folder))
    total = sum(size for _, size, _ in entries)
    for _, size, folder in sorted(entries, key=lambda e: e[0]):
        if total <= CACHE_LIMIT_BYTES:
            break
        if folder == keep:
            continue
        with _marker(folder, "lock").open("w") as lock:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                continue
            _marker(folder, "built").unlink(missing_ok=True)  # first: a bundle without it is made again
            shutil.rmtree(folder, ignore_errors=True)
            total -= size

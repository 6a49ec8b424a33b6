"""glibc's allocator told to give decoded frames back to the system, whatever the host's load (issue 39).

A 2160p frame is 8-12 MB. glibc serves a block that large with its own ``mmap`` (returned to the system
when freed) only until the first such block is freed: from then on its *dynamic* mmap threshold rises to
that size and every later frame comes from a heap, one heap (an "arena") per thread up to eight per
core. Freed frames then stay resident in whichever arena held them, and how many arenas hold how many
freed frames depends on how the decoder, search and sync threads interleave, so on how busy the host
is: the benchmark's 2160p30 ride peaked at 1.1 GB on a quiet machine and at 2.1-2.8 GB at load 5-7,
with the process still holding 1.1 GB while no decoder was open. Measured on the same ride at load
14-22 (docs/capacity.md): 1,252 MB as glibc ships, 788 MB with a fixed mmap threshold, 774 MB with two
arenas, 725 MB with both.

So a process that decodes frames fixes the mmap threshold at :data:`FRAME_MMAP_THRESHOLD_BYTES` (every
frame-sized block is mapped alone and unmapped when freed: the resident size follows the frames alive)
and caps the arenas at :data:`MALLOC_ARENAS`. A value set in the environment (``MALLOC_ARENA_MAX``,
``MALLOC_MMAP_THRESHOLD_``, read by glibc at start-up) is left as it is. Elsewhere than glibc (musl,
macOS) nothing is done.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import os
import threading

__all__ = ["FRAME_MMAP_THRESHOLD_BYTES", "MALLOC_ARENAS", "limit_frame_memory", "mapped_bytes",
           "release_freed_memory"]

# Blocks from 4 MiB are mapped alone: a 2160p grey frame (8.3 MB) and its YUV planes, a 1080p YUV frame's
# luma (2.1 MB) stays on the heap (cheaper to reuse; its arenas hold a few MB, not hundreds).
FRAME_MMAP_THRESHOLD_BYTES = 4 * 1024 * 1024
MALLOC_ARENAS = 2  # the worker's threads share two heaps (decoding is in FFmpeg's own frame pools)

_M_MMAP_THRESHOLD = -3  # glibc's malloc.h
_M_ARENA_MAX = -8

_lock = threading.Lock()
_applied: bool | None = None  # None: not tried yet in this process


@functools.cache  # find_library may run ldconfig: once a process
def _glibc() -> ctypes.CDLL | None:
    """The C library when it is glibc (it has ``mallopt`` and ``malloc_trim``), else None."""
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name or "libc.so.6")
    except OSError:
        return None
    if not all(hasattr(libc, fn) for fn in ("gnu_get_libc_version", "mallopt", "malloc_trim")):
        return None
    return libc


def limit_frame_memory() -> bool:
    """Fix glibc's mmap threshold for frame-sized blocks and cap its arenas (once per process).

    Returns whether glibc took the settings (False elsewhere). Best called before the process starts its
    threads; called later, the threads made since keep the arenas they have, and no new ones are made.
    """
    global _applied
    with _lock:
        if _applied is None:
            _applied = _apply()
        return _applied


def _apply() -> bool:
    libc = _glibc()
    if libc is None:
        return False
    libc.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    ok = True
    if "MALLOC_MMAP_THRESHOLD_" not in os.environ:
        ok = libc.mallopt(_M_MMAP_THRESHOLD, FRAME_MMAP_THRESHOLD_BYTES) == 1 and ok
    if "MALLOC_ARENA_MAX" not in os.environ:
        ok = libc.mallopt(_M_ARENA_MAX, MALLOC_ARENAS) == 1 and ok
    return ok


def release_freed_memory() -> bool:
    """Give the heaps' free pages back to the system (``malloc_trim``), e.g. once a clip's frames are dropped.

    Returns whether any memory was released (False also where the C library is not glibc).
    """
    libc = _glibc()
    if libc is None:
        return False
    libc.malloc_trim.argtypes = [ctypes.c_size_t]
    return bool(libc.malloc_trim(0))


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]


def mapped_bytes() -> int | None:
    """Bytes glibc holds in blocks mapped alone (``mallinfo2().hblkhd``); None where it cannot tell (glibc < 2.33)."""
    libc = _glibc()
    if libc is None or not hasattr(libc, "mallinfo2"):
        return None
    libc.mallinfo2.restype = _MallInfo2
    return int(libc.mallinfo2().hblkhd)

"""How many threads a worker may use: the CPUs its container is given, not the machine's.

``os.cpu_count()`` counts the host's cores; a worker in a container limited to two CPUs that starts a
thread per host core (and FFmpeg's decoder as many again) only queues them behind each other. The
budget is the cgroup's CPU quota (v2 ``cpu.max``, v1 ``cpu.cfs_quota_us / cpu.cfs_period_us``), else
the CPUs this process may run on (``os.sched_getaffinity``), rounded up and at least one.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["cgroup_cpu_quota", "default_worker_threads", "single_threaded_numerics"]

CGROUP_ROOT = Path("/sys/fs/cgroup")


def _read(path: Path) -> str | None:
    try:
        return path.read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError):
        return None


def cgroup_cpu_quota(root: Path = CGROUP_ROOT) -> float | None:
    """CPUs the cgroup's quota allows (e.g. 1.5), or None when there is no quota ("max", -1 or no cgroup)."""
    v2 = _read(root / "cpu.max")  # "<quota> <period>" or "max <period>"
    if v2 is not None:
        parts = v2.split()
        if len(parts) == 2 and parts[0] != "max":
            try:
                quota, period = int(parts[0]), int(parts[1])
            except ValueError:
                return None
            return quota / period if quota > 0 and period > 0 else None
        return None
    for base in (root / "cpu", root / "cpu,cpuacct", root):
        quota_s, period_s = _read(base / "cpu.cfs_quota_us"), _read(base / "cpu.cfs_period_us")
        if quota_s is None or period_s is None:
            continue
        try:
            quota, period = int(quota_s), int(period_s)
        except ValueError:
            return None
        return quota / period if quota > 0 and period > 0 else None
    return None


def _affinity_cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux: no affinity mask to read
        return 1


def default_worker_threads(root: Path = CGROUP_ROOT) -> int:
    """The thread budget when none is set: the cgroup quota rounded up, capped by the CPUs allowed, >= 1."""
    cpus = _affinity_cpus()
    quota = cgroup_cpu_quota(root)
    if quota is not None:
        cpus = min(cpus, math.ceil(quota))
    return max(1, cpus)


@contextmanager
def single_threaded_numerics() -> Iterator[None]:
    """Numpy's BLAS (and any OpenMP pool) at one thread while an analysis runs.

    The analysis's threads are its cameras, each decoding and searching its own clip; a BLAS call in
    each of them starting a thread per core on top only makes them wait for each other, spinning. The
    matrices are small (a bundle adjustment's normal equations, 3 x 3 fits), so one thread loses
    nothing: on the default 640x480 ride the calibration's solve took 4.9 CPU-s with OpenBLAS's threads
    and 4.2 without, in the same wall time, and three cameras' fits at once 9.5 against 4.3 (issue 28).
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield

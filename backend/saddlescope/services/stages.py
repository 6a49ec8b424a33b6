"""The stage registry: what each job kind runs, in which order.

A *stage* is a function ``run(ctx: StageContext) -> None`` that reads its inputs (database rows,
stored clips, the folders of earlier stages) and writes only its own outputs: its folder under
``rides/<id>/stages/<name>`` (`StageContext.outputs`, emptied before each run) and the rows it owns.
Re-running a stage therefore replaces exactly what it made before (idempotent jobs).

A *job kind* is an ordered list of stages. To add a pipeline stage::

    @stage("triangulate", weight=3.0)
    def triangulate(ctx: StageContext) -> None:
        tracks = ctx.stage_dir("detect") / "tracks.npz"   # an earlier stage's output
        ...
        ctx.report(0.5, "pair left-right")                # progress within this stage
        np.savez(ctx.outputs() / "points.npz", ...)

    define_job_kind(JobKind("analyze", ("probe", "calibrate", ..., "triangulate", ...), ...))

Stages never see Celery: the same functions run in a Celery worker and in the embedded pool.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import BundleError, InputError, SaddleScopeError
from saddlescope.db.models import RideStatus
from saddlescope.db.repositories import RecordingRepository, ResultRepository, RideRepository
from saddlescope.db.session import session_scope
from saddlescope.settings import Settings
from saddlescope.storage import Storage, stage_output_key, tree_digest


class StageUnavailable(SaddleScopeError):
    """A stage needs a part of SaddleScope that is not installed in this process."""


class JobCancelled(Exception):
    """Raised inside a stage (at a progress report) when the job was cancelled meanwhile."""


@dataclass
class StageContext:
    """What a stage may use. `report` writes progress and raises `JobCancelled` when cancelled."""

    job_id: int
    kind: str
    stage: str
    club_id: int | None
    ride_id: int | None
    rig_id: int | None
    payload: dict[str, Any]
    settings: Settings
    storage: Storage
    sessions: sessionmaker[Session]
    report: Callable[[float, str | None], None] = field(repr=False)

    @contextmanager
    def session(self) -> Iterator[Session]:
        """A short transaction (commit on success)."""
        with session_scope(self.sessions) as session:
            yield session

    def _require_ride(self) -> int:
        if self.ride_id is None:
            raise InputError(f"stage {self.stage!r} of job {self.job_id} needs a ride, the job has none")
        return self.ride_id

    def outputs(self) -> Path:
        """This stage's own folder for the job's ride, emptied first (so re-runs replace outputs)."""
        return self.storage.fresh_dir(stage_output_key(self._require_ride(), self.stage))

    def output_key(self, name: str) -> str:
        """Storage key of file `name` in this stage's folder."""
        return f"{stage_output_key(self._require_ride(), self.stage)}/{name}"

    def stage_dir(self, stage: str) -> Path:
        """The folder an earlier stage wrote for this ride (read it, never write it)."""
        return self.storage.path(stage_output_key(self._require_ride(), stage))


@dataclass(frozen=True)
class Stage:
    name: str
    run: Callable[[StageContext], None]
    weight: float = 1.0  # share of the job's progress bar, relative to the other stages
    description: str = ""


@dataclass(frozen=True)
class JobKind:
    """An ordered list of stage names, plus the ride status to show while running and after."""

    name: str
    stages: tuple[str, ...]
    needs_ride: bool = False
    ride_status_running: str | None = None
    ride_status_done: str | None = None
    ride_status_failed: str | None = None
    validate_payload: Callable[[dict[str, Any]], dict[str, Any]] | None = None
    description: str = ""


STAGES: dict[str, Stage] = {}
JOB_KINDS: dict[str, JobKind] = {}


def stage(name: str, *, weight: float = 1.0) -> Callable[[Callable[[StageContext], None]], Callable]:
    """Decorator registering a stage function under `name` (its docstring's first line describes it)."""
    if not name or len(name) > 48:
        raise ValueError(f"stage name {name!r} must have 1 to 48 characters")
    if not (weight > 0 and math.isfinite(weight)):
        raise ValueError(f"stage {name!r}: weight must be positive, got {weight}")

    def register(func: Callable[[StageContext], None]) -> Callable[[StageContext], None]:
        doc = (func.__doc__ or "").strip().splitlines()
        STAGES[name] = Stage(name, func, weight, doc[0] if doc else "")
        return func

    return register


def define_job_kind(kind: JobKind) -> JobKind:
    """Register (or replace) a job kind; every stage must already be registered."""
    missing = [s for s in kind.stages if s not in STAGES]
    if missing:
        raise ValueError(f"job kind {kind.name!r} uses unregistered stage(s): {', '.join(missing)}")
    if not kind.stages:
        raise ValueError(f"job kind {kind.name!r} has no stages")
    JOB_KINDS[kind.name] = kind
    return kind


def job_kind(name: str) -> JobKind:
    try:
        return JOB_KINDS[name]
    except KeyError:
        raise InputError(f"unknown job kind {name!r}; known kinds: {', '.join(sorted(JOB_KINDS))}") from None


# --- built-in stages -------------------------------------------------------------------------------

def _selftest_payload(payload: dict[str, Any]) -> dict[str, Any]:
    steps, delay_s, fail = payload.get("steps", 5), payload.get("delay_s", 0.02), payload.get("fail", False)
    if not isinstance(steps, int) or isinstance(steps, bool) or not 1 <= steps <= 1000:
        raise InputError(f"selftest payload: steps must be an integer from 1 to 1000, got {steps!r}")
    if not isinstance(delay_s, int | float) or isinstance(delay_s, bool) or not 0 <= delay_s <= 5:
        raise InputError(f"selftest payload: delay_s must be 0 to 5 seconds, got {delay_s!r}")
    if not isinstance(fail, bool):
        raise InputError(f"selftest payload: fail must be true or false, got {fail!r}")
    return {"steps": steps, "delay_s": float(delay_s), "fail": fail}


@stage("selftest", weight=1.0)
def run_selftest(ctx: StageContext) -> None:
    """Count steps with a short sleep, reporting progress (proves the queue and progress path)."""
    payload = _selftest_payload(ctx.payload)
    for step in range(payload["steps"]):
        time.sleep(payload["delay_s"])
        ctx.report((step + 1) / payload["steps"], f"step {step + 1}/{payload['steps']}")
    if payload["fail"]:
        raise InputError(f"selftest job {ctx.job_id} failed on request (payload fail=true)")


@stage("probe", weight=1.0)
def run_probe(ctx: StageContext) -> None:
    """Read every clip of the ride (or rig): size, sha256, fps, frame count and frame size."""
    from saddlescope.io.video import probe_video

    with ctx.session() as session:
        repo = RecordingRepository(session)
        if ctx.ride_id is not None:
            recordings = repo.for_ride(ctx.ride_id)
            owner = f"ride {ctx.ride_id}"
        elif ctx.rig_id is not None:
            recordings = repo.for_rig(ctx.rig_id)
            owner = f"rig {ctx.rig_id}"
        else:
            raise InputError(f"probe job {ctx.job_id} names neither a ride nor a rig")
        clips = [(r.id, r.path, r.clip_kind, r.camera_role) for r in recordings]
    if not clips:
        raise BundleError(f"{owner} has no recordings to probe")
    for i, (recording_id, key, clip_kind, camera_role) in enumerate(clips):
        ctx.report(i / len(clips), f"{clip_kind}/{camera_role}")
        path = ctx.storage.path(key)
        if not path.exists():
            raise BundleError(f"{owner}: {clip_kind} clip of the {camera_role} camera is missing from "
                              f"storage ({key})")
        if path.is_dir():
            size_bytes, sha256 = tree_digest(path)
        else:
            size_bytes, sha256 = path.stat().st_size, ctx.storage.sha256(key)
        info = probe_video(path)
        with ctx.session() as session:
            RecordingRepository(session).set_probe(recording_id, sha256=sha256, size_bytes=size_bytes,
                                                   fps=info.fps, frame_count=info.frame_count,
                                                   width=info.width, height=info.height)
    ctx.report(1.0, None)


def _result_arrays(result: dict[str, Any]) -> dict[str, np.ndarray]:
    """The result's time series as float arrays (saddle.* and angular.*) for the .npz file."""
    arrays = {}
    for group in ("saddle", "angular"):
        for name, value in (result.get(group) or {}).items():
            if isinstance(value, list) and value:
                arrays[f"{group}.{name}"] = np.asarray(value, dtype=np.float64)
    return arrays


@stage("analyze", weight=20.0)
def run_analyze(ctx: StageContext) -> None:
    """Run the whole pipeline on the ride's bundle and store its result (replacing an earlier one)."""
    try:
        from saddlescope.services.analysis import analyze_bundle
    except ImportError as exc:
        if exc.name not in ("saddlescope.services.analysis", "saddlescope.services"):
            raise
        raise StageUnavailable("the analysis pipeline (saddlescope.services.analysis) is not part of this "
                               "installation yet, so rides cannot be analysed") from None
    ride_id = ctx._require_ride()
    with ctx.session() as session:
        ride = RideRepository(session).get(ride_id)
        bundle_key, club_id = ride.bundle_key, ride.club_id
    if bundle_key is None:
        raise BundleError(f"ride {ride_id} has no ride bundle in storage (register its clips first)")
    result = analyze_bundle(ctx.storage.path(bundle_key), on_progress=lambda f, s: ctx.report(f, s))
    ctx.outputs()
    result_key, arrays_key = ctx.output_key("result.json"), ctx.output_key("arrays.npz")
    ctx.storage.write_bytes(result_key, json.dumps(result, allow_nan=False).encode())
    ctx.storage.save_arrays(arrays_key, _result_arrays(result))
    with ctx.session() as session:
        ResultRepository(session).replace_for_ride(
            club_id=club_id, ride_id=ride_id, job_id=ctx.job_id, indicators=result.get("indicators", {}),
            quality=result.get("quality", {}), result_key=result_key, arrays_key=arrays_key,
            code_version=ctx.settings.resolved_code_version)
    ctx.report(1.0, None)


define_job_kind(JobKind("selftest", ("selftest",), validate_payload=_selftest_payload,
                        description="a few timed steps, no files: checks that workers pick up jobs"))
define_job_kind(JobKind("probe", ("probe",),
                        description="read the clips of a ride or rig and record their sizes and checksums"))
define_job_kind(JobKind("analyze", ("probe", "analyze"), needs_ride=True,
                        ride_status_running=RideStatus.PROCESSING.value,
                        ride_status_done=RideStatus.ANALYSED.value,
                        ride_status_failed=RideStatus.FAILED.value,
                        description="the whole pipeline on a ride: kinematics and vibration indicators"))

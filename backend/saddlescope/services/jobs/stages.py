"""The stage registry: what each job kind runs, in which order.

A *stage* is a function ``run(ctx: StageContext) -> None`` that reads its inputs (the ride's or rig's
rows read once per run, `StageContext.inputs` / `rig_inputs` (`services.jobs.inputs`), stored clips
fetched with `StageContext.fetch`, the folders of earlier stages of the same run) and
writes only its own outputs: its folder in the run's scratch folder (`StageContext.outputs`, emptied
before each run; local to the worker and removed when the job ends) and, through fenced writes
(`commit_result`), the rows and stored documents it owns, under keys naming the job and its attempt.
Re-running a stage therefore replaces exactly what it made before (idempotent jobs), and nothing in a
stage assumes the API's filesystem: with object storage, the worker fetches what it reads.

A *job kind* is an ordered list of stages. To add a pipeline stage::

    @stage("triangulate", weight=3.0)
    def triangulate(ctx: StageContext) -> None:
        tracks = ctx.stage_dir("detect") / "tracks.npz"   # an earlier stage's output (same run)
        ...
        ctx.report(0.5, "pair left-right")                # progress within this stage
        np.savez(ctx.outputs() / "points.npz", ...)

    define_job_kind(JobKind("analyze", ("probe", "calibrate", ..., "triangulate", ...), ...))

Stages never see Celery: the same functions run in a Celery worker and in the embedded pool.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import BundleError, CalibrationError, InputError, SaddleScopeError, VideoError
from saddlescope.db.repositories import Conflict, JobRepository, RecordingRepository, RigRepository
from saddlescope.db.session import session_scope
from saddlescope.services.jobs.fencing import JobFenced
from saddlescope.services.jobs.inputs import (
    DEFAULT_MARKERS,
    ClipInput,
    RideJobInputs,
    RigInputs,
    _rig_inputs,
    bundle_clip_paths,
    ride_document,
)
from saddlescope.services.rides.registration import (
    ANALYSIS_JOB_KIND,
    complete_clip_sets,
    note_analysed_settings,
    refresh_rig_rides_status,
)
from saddlescope.settings import Settings
from saddlescope.storage import Storage, sha256_file, tree_digest

if TYPE_CHECKING:
    from saddlescope.io.video import VideoInfo
    from saddlescope.services.rigs.calibration_way import CalibrationWay

__all__ = [
    "ASSEMBLED_BUNDLE", "DEFAULT_MARKERS", "JOB_KINDS", "JobCancelled", "JobFenced", "JobKind", "STAGES", "Stage",
    "StageContext", "StageUnavailable", "define_job_kind", "job_kind", "ride_document", "run_analyze",
    "run_assemble", "run_calibrate", "run_calibrate_rig", "run_check_calibration",
    "run_probe", "run_selftest", "run_similarity", "stage",
]

ASSEMBLED_BUNDLE = "bundle"  # folder name of the assembled ride bundle in the assemble stage's outputs


class StageUnavailable(SaddleScopeError):
    """A stage needs a part of SaddleScope that is not installed in this process."""


class JobCancelled(Exception):
    """Raised inside a stage (at a progress report) when the job was cancelled meanwhile."""


@dataclass
class StageContext:
    """What a stage may use. `report` writes progress and raises `JobCancelled` when cancelled."""

    job_id: int
    attempt: int  # with `host`, the fence on every write of the job's outputs (`commit_result`)
    host: str
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
    # This run's own local folder (one per job attempt): fetched inputs and the stages' outputs.
    scratch: Path = field(default_factory=lambda: Path(tempfile.mkdtemp(prefix="saddlescope-stage-")))
    # Read the job's ride (rig) from the database, once per run: the runner shares one reader by all stages.
    read_inputs: Callable[[], RideJobInputs] | None = field(default=None, repr=False)
    read_rig_inputs: Callable[[], RigInputs] | None = field(default=None, repr=False)

    @property
    def inputs(self) -> RideJobInputs:
        """The job's ride, its rig and their clips as read once for this run; `InputError` for a job without one."""
        self._require_ride()
        if self.read_inputs is None:
            raise InputError(f"stage {self.stage!r} of job {self.job_id}: no reader of the ride's inputs was given")
        return self.read_inputs()

    @property
    def rig_inputs(self) -> RigInputs:
        """The job's rig and its clips as read once for this run; `InputError` for a job without one."""
        if self.rig_id is None:
            raise InputError(f"stage {self.stage!r} of job {self.job_id} needs a rig, the job has none")
        if self.read_rig_inputs is None:
            raise InputError(f"stage {self.stage!r} of job {self.job_id}: no reader of the rig's inputs was given")
        return self.read_rig_inputs()

    @contextmanager
    def session(self) -> Iterator[Session]:
        """A short transaction (commit on success)."""
        with session_scope(self.sessions) as session:
            yield session

    def hold(self, session: Session) -> None:
        """Fence: lock the job's row in `session` while this attempt runs it; `JobFenced` once another does.

        Call it first in the transaction that writes a stage's lasting outputs (rows shared beyond the job).
        """
        if not JobRepository(session).hold(self.job_id, attempt=self.attempt, host=self.host):
            import logging

            logging.getLogger(__name__).warning(
                "job %s: %s's write of attempt %s on %s refused: the job was taken over", self.job_id,
                self.stage, self.attempt, self.host)
            raise JobFenced(self.job_id, self.attempt)

    def _require_ride(self) -> int:
        if self.ride_id is None:
            raise InputError(f"stage {self.stage!r} of job {self.job_id} needs a ride, the job has none")
        return self.ride_id

    def outputs(self) -> Path:
        """The current stage's own folder in this run's scratch, emptied first (re-runs replace outputs)."""
        folder = self.stage_dir(self.stage)
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        return folder

    def stage_dir(self, stage: str) -> Path:
        """The folder stage `stage` writes in this run's scratch (an earlier stage's: read it, never write it)."""
        if not stage or "/" in stage or stage.startswith("."):
            raise InputError(f"stage name {stage!r} cannot name a folder")
        return self.scratch / "stages" / stage

    def fetch(self, key: str) -> Path:
        """A stored file (or folder) on this worker's disk, in this run's scratch (fetched once per run)."""
        # One folder per key (a bundle fetched whole never mixes with its clips fetched one by one).
        target = self.scratch / "inputs" / hashlib.sha256(key.encode()).hexdigest()[:16] / key.rsplit("/", 1)[-1]
        if not target.exists():
            try:
                self.storage.fetch(key, target)
            except FileNotFoundError:
                raise BundleError(f"{key.rsplit('/', 1)[-1]} is missing from storage ({key})") from None
        return target


@dataclass(frozen=True)
class Stage:
    """A registered stage: its function, its share of the progress bar and its description."""

    name: str
    run: Callable[[StageContext], None]
    weight: float = 1.0  # share of the job's progress bar, relative to the other stages
    description: str = ""


@dataclass(frozen=True)
class JobKind:
    """An ordered list of stage names (a ride's status shows the outcome of its latest `analyze` job)."""

    name: str
    stages: tuple[str, ...]
    needs_ride: bool = False
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
    """The registered job kind `name`; `InputError` naming the known ones otherwise."""
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


def _recorded_probe(clip: ClipInput) -> tuple[int, VideoInfo] | None:
    """(size in bytes, clip facts) a clip was probed with (at upload, or by an earlier job), or None."""
    from saddlescope.io.video import VideoInfo

    c = clip
    if (not c.probed or not c.sha256 or c.size_bytes is None or c.fps is None or c.frame_count is None
            or c.width is None or c.height is None):
        return None
    return c.size_bytes, VideoInfo(Path(c.key), float(c.fps), int(c.frame_count), int(c.width), int(c.height),
                                   c.codec or "", c.frame_count / c.fps if c.fps else 0.0)


def _stored_file_size(storage, key: str) -> int | None:
    """The stored clip's size in bytes, or None where it is a folder of images (or cannot be sized)."""
    path_of = getattr(storage, "path", None)  # the folder tree: a folder of images has no single size
    if path_of is not None and path_of(key).is_dir():
        return None
    try:
        return int(storage.size(key))
    except (OSError, ValueError, KeyError, IsADirectoryError):
        return None


@stage("probe", weight=1.0)
def run_probe(ctx: StageContext) -> None:
    """Read every clip of the ride (or rig): size, sha256, fps, frame count and frame size."""
    from saddlescope.io.video import probe_video, too_short_for

    if ctx.ride_id is not None:
        recordings, owner = ctx.inputs.clips, f"ride {ctx.ride_id}"
    elif ctx.rig_id is not None:
        recordings, owner = ctx.rig_inputs.clips, f"rig {ctx.rig_id}"
    else:
        raise InputError(f"probe job {ctx.job_id} names neither a ride nor a rig")
    clips = [(c.recording_id, c.key, c.clip_kind, c.camera_role, _recorded_probe(c)) for c in recordings]
    if not clips:
        raise BundleError(f"{owner} has no recordings to probe")
    probed: dict[str, list] = {}
    for i, (recording_id, key, clip_kind, camera_role, recorded) in enumerate(clips):
        ctx.report(i / len(clips), f"{clip_kind}/{camera_role}")
        if not ctx.storage.exists(key):
            raise BundleError(f"{owner}: {clip_kind} clip of the {camera_role} camera is missing from "
                              f"storage ({key})")
        if recorded is not None and _stored_file_size(ctx.storage, key) == recorded[0]:
            # probed and hashed when it was uploaded (the key names its checksum): not fetched nor read again
            probed.setdefault(clip_kind, []).append((camera_role, recorded[1]))
            continue
        path = ctx.fetch(key)
        if path.is_dir():
            size_bytes, sha256 = tree_digest(path)
        else:
            size_bytes, sha256 = path.stat().st_size, sha256_file(path)
        try:
            info = probe_video(path)
        except VideoError as exc:
            name = key.rsplit("/", 1)[-1]  # not where storage lives
            reason = str(exc).replace(str(path), name).removeprefix(f"{name}: ")
            raise VideoError(f"{owner}: the {clip_kind} clip of the {camera_role} camera ({name}) is not a "
                             f"usable video: {reason}") from None
        if short := too_short_for(clip_kind, info):  # on object storage the API could not probe it
            raise VideoError(f"{owner}: the {clip_kind} clip of the {camera_role} camera "
                             f"({key.rsplit('/', 1)[-1]}) is too short: {short}")
        probed.setdefault(clip_kind, []).append((camera_role, info))
        with ctx.session() as session:
            RecordingRepository(session).set_probe(recording_id, sha256=sha256, size_bytes=size_bytes,
                                                   fps=info.fps, frame_count=info.frame_count,
                                                   width=info.width, height=info.height, codec=info.codec)
    # The cameras of one clip set recorded one scene together: same frame rate and frame size.
    for clip_kind, infos in probed.items():
        (first_role, first), *others = infos
        for role, info in others:
            if abs(info.fps - first.fps) > 0.005 * first.fps or (info.width, info.height) != (
                    first.width, first.height):
                raise VideoError(f"{owner}: the {clip_kind} clips disagree: the {first_role} camera's is "
                                 f"{first.width}x{first.height} px at {first.fps:.3f} fps, the {role} "
                                 f"camera's {info.width}x{info.height} px at {info.fps:.3f} fps")
    ctx.report(1.0, None)


@stage("assemble", weight=0.5)
def run_assemble(ctx: StageContext) -> None:
    """Put the ride's clips (and its rig's shared ones) together as a ride bundle."""
    inputs = ctx.inputs
    if inputs.bundle_key is not None:
        replaced = inputs.replaced_bundle_clips()
        if replaced:
            _bundle_with_replacements(ctx, inputs.bundle_key, replaced)
        else:
            (ctx.outputs() / "source.json").write_text(json.dumps({"bundle_key": inputs.bundle_key}))
        return
    plan = inputs.require_clip_plan()
    clips = bundle_clip_paths(plan)
    doc = ride_document(inputs, clips=clips, calibration_file="calibration.json" if "calibration" not in plan else None)
    folder = ctx.outputs() / ASSEMBLED_BUNDLE
    folder.mkdir()
    for i, (kind, cams) in enumerate(plan.items()):
        for role, key in cams.items():
            ctx.storage.fetch(key, folder / clips[kind][role])
        ctx.report((i + 1) / (len(plan) + 1), kind)
    if "calibration" not in plan:  # the plan leaves the clips out only when the rig's calibration is stored
        (folder / "calibration.json").write_text(json.dumps(inputs.calibration, allow_nan=False))
    (folder / "ride.json").write_text(json.dumps(doc, indent=1, allow_nan=False))
    ctx.report(1.0, None)


def _bundle_with_replacements(ctx: StageContext, bundle_key: str, replaced: dict[str, dict[str, str]]) -> None:
    """The ride's bundle as a folder, its replaced clips put in place of the uploaded bundle's (ride.json too)."""
    source = ctx.fetch(bundle_key)
    folder = ctx.outputs() / ASSEMBLED_BUNDLE
    shutil.copytree(source, folder)
    meta_path = folder / "ride.json"
    meta = json.loads(meta_path.read_text(encoding="utf-8"))
    clips = meta.setdefault("clips", {})
    for kind, cams in replaced.items():
        for camera, key in cams.items():
            old = clips.get(kind, {}).get(camera)
            if old is not None and not Path(old).is_absolute() and ".." not in Path(old).parts:
                (folder / old).unlink(missing_ok=True)
            rel = f"replaced/{kind}/{camera}{Path(key).suffix}"
            ctx.storage.fetch(key, folder / rel)
            clips.setdefault(kind, {})[camera] = rel
    meta_path.write_text(json.dumps(meta, indent=1, allow_nan=False), encoding="utf-8")
    ctx.report(1.0, None)


def _bundle_path(ctx: StageContext, inputs: RideJobInputs) -> Path:
    """The ride's bundle on this worker: the one assembled in this run, else its uploaded bundle fetched."""
    assembled = ctx.stage_dir("assemble") / ASSEMBLED_BUNDLE
    if (assembled / "ride.json").is_file():  # a bundle ride with a clip replaced, or a ride of clips
        return assembled
    if inputs.bundle_key is not None:
        return ctx.fetch(inputs.bundle_key)
    raise BundleError(f"ride {inputs.ride_id}: its clips were not assembled into a bundle (run the assemble "
                      "stage)")


def _calibrate_and_store(ctx: StageContext, rig_id: int, paths: dict[str, Path], board: dict, sync: dict | None,
                         *, replace: bool, made_from: CalibrationWay | None = None) -> dict[str, Any]:
    from saddlescope.services.rigs.calibration import calibrate_clips

    calibration = calibrate_clips(paths, board=board, sync=sync, on_progress=lambda f, s: ctx.report(f, s))
    return _store_calibration(ctx, rig_id, calibration, replace=replace, made_from=made_from)


def _store_calibration(ctx: StageContext, rig_id: int, calibration: dict[str, Any], *,
                       replace: bool, made_from: CalibrationWay | None = None) -> dict[str, Any]:
    """Keep a rig's new calibration (the job's output and the rig's row); returns the one the rig has.

    The stage's calibration.json is the one the rig has once stored (another job's, when it came first):
    the analyze stage of the same run reads it there. ``made_from``: the way and clips the calibration was made
    from; when the rig's clips are no longer those (a clip uploaded while the job ran), nothing is stored and the
    job fails saying so: the upload queued a job behind this one (`start_processing`), which calibrates from them.
    """
    from saddlescope.services.rigs.calibration import calibration_quality

    out = ctx.outputs()
    with ctx.session() as session:
        ctx.hold(session)
        rigs = RigRepository(session)
        if made_from is not None:
            _still_the_rigs_clips(session, rigs.lock(rig_id), made_from, ctx.payload.get("method"))
        if replace:
            rigs.set_calibration(rig_id, calibration, calibration_quality(calibration))
        elif not rigs.set_calibration_if_missing(rig_id, calibration, calibration_quality(calibration)):
            calibration = dict(rigs.get(rig_id).calibration)  # another job calibrated it first: use that
        refresh_rig_rides_status(session, rig_id)  # a calibrated rig completes rides that lacked its clips
    (out / "calibration.json").write_text(json.dumps(calibration, allow_nan=False))
    ctx.report(1.0, None)
    return calibration


def _still_the_rigs_clips(session: Session, rig: Any, made_from: CalibrationWay, method: str | None) -> None:
    """Raise `CalibrationError` when the way and clips the rig would be calibrated with now are not `made_from`."""
    from saddlescope.services.rigs.calibration_way import choose_calibration_way

    current = _rig_inputs(session, rig)
    try:
        now = choose_calibration_way(current, current.recordings(), method)
    except (Conflict, InputError):
        now = None
    if now is None or (now.method, now.clips) != (made_from.method, made_from.clips):
        raise CalibrationError(f"rig {rig.id} ({rig.name}): its clips changed while this job calibrated it (a clip "
                               "was uploaded meanwhile), so its calibration is not kept; the job queued after the "
                               "upload calibrates it from its clips as they are now")


@stage("calibrate", weight=6.0)
def run_calibrate(ctx: StageContext) -> None:
    """The rig's calibration: reused when stored, else computed once from the rig's clips and stored."""
    inputs = ctx.inputs
    rig = inputs.rig
    if rig is None or rig.calibration:
        note = {"source": "ride" if rig is None else "rig", "rig_id": rig.rig_id if rig else None,
                "reused": rig is not None}
        (ctx.outputs() / "source.json").write_text(json.dumps(note))
        return
    rig_clips = rig.calibration_clips
    if rig_clips is not None:
        if not rig.board:
            raise CalibrationError(f"rig {rig.rig_id} has no 'board' (the calibration board its clips show)")
        paths = {role: ctx.fetch(key) for role, key in rig_clips.items()}
        _calibrate_and_store(ctx, rig.rig_id, paths, dict(rig.board), _copied(inputs.sync), replace=False)
        return
    # A ride bundle uploaded for a rig without calibration clips: the bundle's own clips calibrate the rig.
    from saddlescope.io.bundle import open_bundle

    with open_bundle(_bundle_path(ctx, inputs)) as bundle:
        if "calibration" not in bundle.clip_paths:
            raise CalibrationError(f"rig {rig.rig_id} has no calibration, and neither the rig nor ride "
                                   f"{inputs.ride_id} has calibration clips to compute it")
        _calibrate_and_store(ctx, rig.rig_id, dict(bundle.clip_paths["calibration"]), bundle.meta["board"],
                             bundle.meta.get("sync"), replace=False)


def _copied(section: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """A ride.json section of the inputs as a dict of the stage's own (None stays None)."""
    return copy.deepcopy(dict(section)) if section is not None else None


def _calibrate_rig_from_ride(ctx: StageContext, rig: RigInputs) -> None:
    """Calibrate rig `rig` from the job's ride's own calibration clips (a bundle's), replacing its calibration."""
    inputs = ctx.inputs
    clips = complete_clip_sets(inputs.clips_as_recordings()).get("calibration")
    board = inputs.board or rig.board
    if clips is None:
        raise CalibrationError(f"ride {inputs.ride_id} has no calibration clips of the left, middle and right "
                               "cameras to calibrate its rig with")
    if not board:
        raise CalibrationError(f"neither ride {inputs.ride_id} nor rig {rig.rig_id} describes the calibration "
                               "board its clips show")
    paths = {role: ctx.fetch(key) for role, key in clips.items()}
    _calibrate_and_store(ctx, rig.rig_id, paths, _copied(board) or {},
                         ctx.payload.get("sync") or _copied(inputs.sync), replace=True)


@stage("calibrate_rig", weight=6.0)
def run_calibrate_rig(ctx: StageContext) -> None:
    """Calibrate a rig from its calibration clips, its wand and close-up clips, or both (replacing an earlier one).

    The payload's ``method`` (``board``, ``wand`` or ``board+wand``) chooses; without it
    (:func:`~saddlescope.services.rigs.calibration_way.choose_calibration_way`) the board walk refined by the
    wand when the rig has its calibration and wand clips and a wand length, else the wand way when it has its
    wand and close-up clips and a wand length, else the board walk.
    """
    if ctx.rig_id is None:
        raise InputError(f"calibrate_rig job {ctx.job_id} names no rig")
    rig = ctx.rig_inputs
    if ctx.ride_id is not None:  # "use this ride's calibration for the rig": the ride's own calibration clips
        _calibrate_rig_from_ride(ctx, rig)
        return
    from saddlescope.services.rigs.calibration_way import choose_calibration_way

    try:  # the board walk, or the wand way when the rig has its wand clips and length (issue 35)
        way = choose_calibration_way(rig, rig.recordings(), ctx.payload.get("method"))
    except Conflict as exc:
        raise CalibrationError(str(exc)) from None
    board = copy.deepcopy(dict(rig.board or {}))
    if way.method == "board":
        paths = {role: ctx.fetch(key) for role, key in way.clips["calibration"].items()}
        _calibrate_and_store(ctx, ctx.rig_id, paths, board, ctx.payload.get("sync"), replace=True, made_from=way)
        return
    from saddlescope.services.rigs.calibration import calibrate_board_and_wand_clips, calibrate_wand_clips

    fetched = {kind: {role: ctx.fetch(key) for role, key in cams.items()} for kind, cams in way.clips.items()}
    if way.method == "board+wand":  # the board walk, refined by the wand where that helps (issue 35)
        calibration = calibrate_board_and_wand_clips(fetched["calibration"], fetched["wand"], board=board,
                                                     wand_length_m=way.wand_length_m or 0.0,
                                                     sync=ctx.payload.get("sync"),
                                                     on_progress=lambda f, s: ctx.report(f, s))
    else:
        calibration = calibrate_wand_clips(fetched["wand"], fetched["close_up"], board=board,
                                           wand_length_m=way.wand_length_m or 0.0, sync=ctx.payload.get("sync"),
                                           on_progress=lambda f, s: ctx.report(f, s))
    _store_calibration(ctx, ctx.rig_id, calibration, replace=True, made_from=way)


@stage("check_calibration", weight=2.0)
def run_check_calibration(ctx: StageContext) -> None:
    """Check the rig's calibration clips uploaded so far: where the board, and the wand, went in each view (issue 35).

    The board's clips are checked when the rig describes its board; the wand's when the rig has its length.
    Each check is stored on its own (`check_storage_key`), for the rig page.
    """
    from saddlescope.services.rigs.calibration_check import (
        check_calibration_clips,
        check_storage_key,
        check_wand_clips,
        checked_with,
        merged_check_document,
        reusable_cameras,
    )

    if ctx.rig_id is None:
        raise InputError(f"check_calibration job {ctx.job_id} names no rig")
    rig = ctx.rig_inputs
    board_clips = {c.camera_role: c for c in rig.clips if c.clip_kind == "calibration"}
    wand_clips = {c.camera_role: c for c in rig.clips if c.clip_kind == "wand"}
    board = _copied(rig.board)
    checks: list[tuple[str, dict[str, ClipInput]]] = []
    if board_clips and board:
        checks.append(("board", board_clips))
    if wand_clips and rig.wand_length_m is not None:
        checks.append(("wand", wand_clips))
    if not checks:
        raise CalibrationError(
            f"rig {ctx.rig_id} has nothing to check yet: " + ("no 'board' described for its calibration clips"
                                                             if board_clips else "no calibration clip")
            + (" and no wand length for its wand clips" if wand_clips else ""))
    for n, (what, clips) in enumerate(checks):
        def progress(f: float, step: str | None, n: int = n) -> None:
            ctx.report((n + f) / len(checks), step)

        key, inputs = check_storage_key(ctx.rig_id, what), checked_with(what, board=board,
                                                                          wand_length_m=rig.wand_length_m)
        ids = {role: clip.recording_id for role, clip in clips.items()}
        sha256 = {role: clip.sha256 for role, clip in clips.items()}
        # a clip checked before (same bytes, board or wand) keeps its answer: uploads come one by one
        reused = reusable_cameras(_stored_json(ctx.storage, key), sha256, inputs)
        paths = {role: ctx.fetch(clip.key) for role, clip in clips.items() if role not in reused}
        check = None if not paths else (
            check_calibration_clips(paths, board or {}, on_progress=progress) if what == "board" else
            check_wand_clips(paths, float(rig.wand_length_m or 0.0), on_progress=progress))
        document = merged_check_document(check, reused, clips=ids, sha256=sha256, inputs=inputs)
        ctx.storage.write_bytes(key, json.dumps(document, allow_nan=False).encode())
    ctx.report(1.0, None)


def _stored_json(storage: Storage, key: str) -> dict[str, Any] | None:
    """A JSON document stored at `key`, or None where there is none or it does not parse."""
    try:
        document = json.loads(storage.read_bytes(key)) if storage.exists(key) else None
    except (ValueError, UnicodeDecodeError):
        return None
    return document if isinstance(document, dict) else None


def _calibration_for_analysis(ctx: StageContext, inputs: RideJobInputs) -> dict[str, Any] | None:
    """The rig's calibration: stored when the job started, else the one this run's calibrate stage stored."""
    if inputs.calibration is not None:
        return copy.deepcopy(dict(inputs.calibration))
    calibrated = ctx.stage_dir("calibrate") / "calibration.json"
    if inputs.rig is not None and calibrated.is_file():
        return dict(json.loads(calibrated.read_text(encoding="utf-8")))
    return None


@stage("analyze", weight=20.0)
def run_analyze(ctx: StageContext) -> None:
    """Run the whole pipeline on the ride's bundle and store its result (replacing an earlier one)."""
    try:
        from saddlescope.services.analysis.ride_bundle import analyze_bundle
    except ImportError as exc:
        if exc.name not in ("saddlescope.services.analysis.ride_bundle", "saddlescope.services"):
            raise
        raise StageUnavailable("the analysis pipeline (saddlescope.services.analysis.ride_bundle) is not part of this "
                               "installation yet, so rides cannot be analysed") from None
    inputs = ctx.inputs
    if inputs.bundle_key is None and not (ctx.stage_dir("assemble") / ASSEMBLED_BUNDLE).is_dir():
        raise BundleError(f"ride {inputs.ride_id} has no ride bundle in storage (register its clips first)")
    path = _bundle_path(ctx, inputs)
    calibration = _calibration_for_analysis(ctx, inputs)
    rig_model = None
    if calibration is not None:
        from saddlescope.services.rigs.calibration import rig_from_calibration

        rig_model = rig_from_calibration(calibration)
    # where the rig's board (and a wand that refined it) has been: the lens model is held to it and markers
    # outside it are flagged (issues 27, 35)
    rig_report = {k: calibration[k] for k in ("n_views", "board_coverage", "lens_coverage")
                  if calibration and calibration.get(k)}
    # The ride's own settings win over what a bundle's ride.json says (edited after the upload, or chosen then).
    settings = inputs.analysed_settings
    result = analyze_bundle(path, on_progress=lambda f, s: ctx.report(f, s), rig=rig_model, rig_report=rig_report,
                            meta_overrides=dict(settings))
    # The result document is what the dashboard and the exports read (its series decimated on the way);
    # it replaces the previous one atomically (the old one stays readable until the new one is committed).
    from saddlescope.services.results.documents import commit_result

    commit_result(ctx.sessions, ctx.storage, club_id=inputs.club_id, ride_id=inputs.ride_id, job_id=ctx.job_id,
                  document=result, code_version=ctx.settings.resolved_code_version,
                  attempt=ctx.attempt, host=ctx.host)
    with ctx.session() as session:
        note_analysed_settings(session, inputs.ride_id, settings)
    ctx.report(1.0, None)


def _similarity_payload(payload: dict[str, Any]) -> dict[str, Any]:
    from saddlescope.services.similarity.club import similarity_payload

    return similarity_payload(payload)


@stage("similarity", weight=1.0)
def run_similarity(ctx: StageContext) -> None:
    """Compare the payload's pairs of analysed rides and cache each comparison (skipping cached ones)."""
    from saddlescope.services.similarity.club import method_version, run_pairs_job

    counts = run_pairs_job(ctx.sessions, ctx.storage, ctx.payload, club_id=ctx.club_id,
                           version=method_version(ctx.settings), report=ctx.report)
    ctx.report(1.0, f"{counts['computed']} compared, {counts['cached']} cached, {counts['gone']} gone")


define_job_kind(JobKind("selftest", ("selftest",), validate_payload=_selftest_payload,
                        description="a few timed steps, no files: checks that workers pick up jobs"))
define_job_kind(JobKind("probe", ("probe",),
                        description="read the clips of a ride or rig and record their sizes and checksums"))
define_job_kind(JobKind(ANALYSIS_JOB_KIND, ("probe", "assemble", "calibrate", "analyze"), needs_ride=True,
                        description="the whole pipeline on a ride: kinematics and vibration indicators"))
define_job_kind(JobKind("similarity", ("similarity",), validate_payload=_similarity_payload,
                        description="compare pairs of analysed rides and cache the answers (the most-alike "
                                    "lists and a horse's consistency read them)"))
define_job_kind(JobKind("check_calibration", ("check_calibration",),
                        description="check a rig's calibration clips as they arrive: where the board went in "
                                    "each camera's view, before anyone rides"))
define_job_kind(JobKind("calibrate_rig", ("probe", "calibrate_rig"),
                        description="calibrate a rig once from its three calibration clips (used by its "
                                    "rides)"))

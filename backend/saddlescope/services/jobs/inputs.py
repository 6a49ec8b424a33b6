"""What a job reads from the database, read once per job attempt into one frozen, typed description.

A ride's job (probe, assemble, calibrate, analyze) used to open a session in every stage and read the
ride, its rig, its clips and the rig's calibration again. Now the runner reads them once, in one
transaction, when a stage first asks (`StageContext.inputs`), and every stage of that attempt reads the
same snapshot: the assembled ride.json is written from it and the analysis gets the ride's settings from
it. What stages write (probe facts, a calibration, the result) still goes to the database as before.

A ride or rig deleted before its job ran is a `RideGone` / `RigGone` naming both.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy.orm import Session, sessionmaker

from saddlescope.core.errors import BundleError, InputError
from saddlescope.core.types import CAMERA_ROLES
from saddlescope.db.repositories import RecordingRepository, RideRepository, RigRepository
from saddlescope.db.session import session_scope
from saddlescope.services.rides.registration import RESULT_SETTINGS, complete_clip_sets, ride_clip_plan

if TYPE_CHECKING:
    from saddlescope.db.models import Recording, Rig

__all__ = [
    "DEFAULT_MARKERS", "ClipInput", "ClipPlan", "HorseDetails", "RideGone", "RideJobInputs", "RigGone", "RigInputs",
    "bundle_clip_paths",
    "read_ride_job_inputs", "read_rig_inputs", "ride_document",
]

DEFAULT_MARKERS = {"horse": 3, "plumb": 2, "saddle": 1}

ClipPlan = Mapping[str, Mapping[str, str]]  # clip kind -> camera role -> storage key


class RideGone(InputError):
    """The job's ride is no longer in the database (deleted after the job was queued)."""


class RigGone(InputError):
    """The job's rig is no longer in the database (deleted after the job was queued)."""


@dataclass(frozen=True)
class ClipInput:
    """One stored clip (a recording row) as the job found it, with what an earlier probe recorded."""

    recording_id: int
    clip_kind: str
    camera_role: str
    key: str  # where the clip is stored
    sha256: str | None = None
    size_bytes: int | None = None
    probed: bool = False  # probed at upload or by an earlier job (the facts below are then filled)
    fps: float | None = None
    frame_count: int | None = None
    width: int | None = None
    height: int | None = None
    codec: str | None = None

    @classmethod
    def of(cls, recording: Recording) -> ClipInput:
        """The clip of a recording row."""
        r = recording
        return cls(r.id, r.clip_kind, r.camera_role, r.path, r.sha256, r.size_bytes, r.probed_at is not None,
                   r.fps, r.frame_count, r.width, r.height, r.codec)


@dataclass(frozen=True)
class RigInputs:
    """A rig as its job (or a ride's job) reads it: its board, its stored calibration and its clips."""

    rig_id: int
    name: str
    board: Mapping[str, Any] | None
    calibration: Mapping[str, Any] | None  # the stored calibration (result format's `calibration`), if any
    wand_length_m: float | None
    clips: tuple[ClipInput, ...]

    @property
    def calibration_clips(self) -> Mapping[str, str] | None:
        """Camera role -> storage key of the rig's calibration clips, when all three cameras have one."""
        return complete_clip_sets(_as_recordings(self.clips)).get("calibration")

    # `choose_calibration_way` reads a rig's `id` and its clips as recordings (`clip_kind`, `camera_role`, `path`).
    @property
    def id(self) -> int:
        """The rig's id (the name `choose_calibration_way` reads)."""
        return self.rig_id

    def recordings(self) -> list[_Recorded]:
        """The rig's clips in the shape of recording rows (`clip_kind`, `camera_role`, `path`)."""
        return _as_recordings(self.clips)


@dataclass(frozen=True)
class _Recorded:
    clip_kind: str
    camera_role: str
    path: str


def _as_recordings(clips: tuple[ClipInput, ...]) -> list[_Recorded]:
    return [_Recorded(c.clip_kind, c.camera_role, c.key) for c in clips]


@dataclass(frozen=True)
class HorseDetails:
    """The horse as ride.json describes it (it only labels the result)."""

    name: str
    breed: str | None = None
    birth_year: int | None = None
    height_m: float | None = None  # at the withers


@dataclass(frozen=True)
class RideJobInputs:
    """Everything a ride's job reads from the database, read once when its first stage asks.

    `clip_plan`: for a ride of uploaded clips, which stored clip each camera of each kind comes from
    (the ride's own, else its rig's); None for a ride registered from a bundle, or when clips are missing
    (`missing_clips` then says which, raised by the assemble stage as before). `board`, `sync` and
    `markers` are the ride's own ride.json sections (None: not given, the rig's board or the defaults apply).
    """

    ride_id: int
    club_id: int
    gait: str
    direction: str
    horse: HorseDetails
    rider_name: str
    bundle_key: str | None
    clips: tuple[ClipInput, ...]  # the ride's own clips (a bundle's, and any uploaded again from its page)
    rig: RigInputs | None
    board: Mapping[str, Any] | None = None
    sync: Mapping[str, Any] | None = None
    markers: Mapping[str, Any] | None = None
    clip_plan: ClipPlan | None = None
    missing_clips: str | None = None

    @property
    def analysed_settings(self) -> dict[str, str]:
        """The ride's RESULT_SETTINGS (gait, direction) the analysis reads: the ride's own win over a bundle's."""
        return {name: getattr(self, name) for name in RESULT_SETTINGS}

    @property
    def calibration(self) -> Mapping[str, Any] | None:
        """The rig's calibration stored when the job started (None: no rig, or not calibrated yet)."""
        return self.rig.calibration if self.rig is not None else None

    def require_clip_plan(self) -> ClipPlan:
        """The clip plan of a ride of uploaded clips; `BundleError` naming the clips still missing."""
        if self.clip_plan is None:
            raise BundleError(self.missing_clips or f"ride {self.ride_id} has no clip plan (it is a bundle ride)")
        return self.clip_plan

    def clips_as_recordings(self) -> list[_Recorded]:
        """The ride's own clips in the shape of recording rows (`clip_kind`, `camera_role`, `path`)."""
        return _as_recordings(self.clips)

    def replaced_bundle_clips(self) -> dict[str, dict[str, str]]:
        """The clips of a bundle ride uploaded again from its ride page: {kind: {camera: storage key}}.

        A bundle's own clips are stored under its bundle key; a clip replaced later is stored with the ride's
        clips (`services.uploads.intake.accept_clip`) and takes the bundle clip's place when it is assembled.
        """
        replaced: dict[str, dict[str, str]] = {}
        for clip in self.clips:
            if clip.key and not clip.key.startswith(f"{self.bundle_key}/"):
                replaced.setdefault(clip.clip_kind, {})[clip.camera_role] = clip.key
        return replaced


def _json_copy(value: Any) -> Any:
    """A copy of a JSON column's value the job owns (never the session's object)."""
    return copy.deepcopy(value) if value else None


def _rig_inputs(session: Session, rig: Rig) -> RigInputs:
    clips = tuple(ClipInput.of(r) for r in RecordingRepository(session).for_rig(rig.id))
    return RigInputs(rig.id, rig.name, _json_copy(rig.board), _json_copy(rig.calibration), rig.wand_length_m, clips)


def read_rig_inputs(sessions: sessionmaker[Session], rig_id: int, *, job_id: int) -> RigInputs:
    """Rig `rig_id` with its clips, read in one transaction; `RigGone` when it was deleted."""
    with session_scope(sessions) as session:
        rig = RigRepository(session).find(rig_id)
        if rig is None:
            raise RigGone(f"rig {rig_id} of job {job_id} no longer exists (deleted after the job was queued)")
        return _rig_inputs(session, rig)


def _clip_plan(ride_clips: list[Recording], rig: RigInputs | None) -> tuple[ClipPlan | None, str | None]:
    """(the plan, None), or (None, what is missing); the rig's calibration replaces its clips when stored."""
    try:
        plan = ride_clip_plan(ride_clips, rig.recordings() if rig else [], rig_calibrated=bool(rig and rig.calibration))
    except BundleError as exc:
        return None, str(exc)
    if rig is not None and rig.calibration and plan.get("calibration") and plan["calibration"] == rig.calibration_clips:
        plan.pop("calibration")  # no need to carry the rig's calibration clips into every ride
    return plan, None


def read_ride_job_inputs(sessions: sessionmaker[Session], ride_id: int, *, job_id: int) -> RideJobInputs:
    """Ride `ride_id`, its rig and their clips, read in one transaction; `RideGone` when it was deleted.

    A rig deleted meanwhile leaves the ride without one (its row's rig is set to null), as before.
    """
    with session_scope(sessions) as session:
        ride = RideRepository(session).find(ride_id)
        if ride is None:
            raise RideGone(f"ride {ride_id} of job {job_id} no longer exists (deleted after the job was queued)")
        found = RigRepository(session).find(ride.rig_id) if ride.rig_id is not None else None
        rig = _rig_inputs(session, found) if found is not None else None
        ride_clips = list(RecordingRepository(session).for_ride(ride_id))
        plan, missing = (None, None) if ride.bundle_key is not None else _clip_plan(ride_clips, rig)
        meta = dict(ride.meta or {})
        horse = ride.horse
        return RideJobInputs(
            ride_id=ride.id, club_id=ride.club_id, gait=ride.gait, direction=ride.direction,
            horse=HorseDetails(horse.name, horse.breed, horse.birth_year, horse.height_withers_m),
            rider_name=ride.rider.name, bundle_key=ride.bundle_key,
            clips=tuple(ClipInput.of(r) for r in ride_clips), rig=rig, board=_json_copy(meta.get("board")),
            sync=_json_copy(meta.get("sync")), markers=_json_copy(meta.get("markers")), clip_plan=plan,
            missing_clips=missing)


def ride_document(inputs: RideJobInputs, *, clips: ClipPlan, calibration_file: str | None) -> dict[str, Any]:
    """ride.json (CONTRACTS section 1) of a ride assembled from stored clips (`clips`: paths in the bundle)."""
    board = inputs.board or (inputs.rig.board if inputs.rig is not None else None)
    if not board:
        raise InputError(f"ride {inputs.ride_id}: no calibration board described (give the rig a 'board', or "
                         "the ride a meta.board)")
    horse = inputs.horse
    doc: dict[str, Any] = {
        "format": "saddlescope.ride/1", "cameras": list(CAMERA_ROLES), "board": copy.deepcopy(dict(board)),
        "sync": copy.deepcopy(dict(inputs.sync)) if inputs.sync else {"method": "flash"},
        "markers": copy.deepcopy(dict(inputs.markers)) if inputs.markers else dict(DEFAULT_MARKERS),
        "horse": {"name": horse.name, "breed": horse.breed, "birth_year": horse.birth_year,
                  "height_m": horse.height_m},
        "rider": {"name": inputs.rider_name}, "gait": inputs.gait, "direction": inputs.direction,
        "clips": {kind: dict(cams) for kind, cams in clips.items()},
    }
    if calibration_file is not None:
        doc["calibration_file"] = calibration_file
    return doc


def bundle_clip_paths(plan: ClipPlan) -> dict[str, dict[str, str]]:
    """Where each planned clip goes inside an assembled bundle: ``<kind>/<camera><suffix>``."""
    return {kind: {role: f"{kind}/{role}{Path(key).suffix}" for role, key in cams.items()}
            for kind, cams in plan.items()}

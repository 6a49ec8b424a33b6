"""Request and response bodies of the REST API (pydantic; the OpenAPI at /docs comes from these)."""

from __future__ import annotations

import datetime as dt
import json
import re
from typing import TYPE_CHECKING, Annotated, Any, Generic, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, create_model, field_validator, model_validator

from saddlescope.api.board_schemas import BoardIn
from saddlescope.api.comparison_schemas import (
    ComparisonOut,
    CorrelationOut,
    GaitComparison,
    GroupStats,
    HorseComparisonOut,
    HorseGroupStats,
    HorsesInGait,
)
from saddlescope.api.horse_height import HeightWithersM
from saddlescope.api.leaderboard_schemas import LeaderboardEntry, LeaderboardOut, UncertainRide
from saddlescope.api.pass_schemas import PassesOut, PassOut
from saddlescope.api.rider_weight import RiderWeightKg
from saddlescope.api.rig_schemas import WandLengthM
from saddlescope.core.types import CAMERA_ROLES, CLIP_KINDS, DIRECTIONS, GAITS
from saddlescope.services.results.series import DERIVED

__all__ = [
    "BoardIn", "BundleUploaded", "MocapRideOut", "CameraRole", "ClipKind", "ClipUploaded", "ClubCreate", "ClubCreated",
    "ClubOut", "ComparisonOut", "CorrelationOut", "Decimation", "Direction", "Email", "ErrorOut", "FailureOut", "Gait",
    "GaitComparison", "GradeIn", "GradeOut", "GradeUpdate", "GroupStats", "HealthOut", "HorseComparisonOut",
    "HorseGroupStats", "HorseIn", "HorseOut", "HorseUpdate", "HorsesInGait", "IndicatorOut", "JobCreate",
    "JobKindOut", "JobOut", "LeaderboardEntry", "LeaderboardOut", "LoginIn", "MAX_ID", "MarkersIn", "MeOut",
    "UncertainRide", "Name", "Offsets", "Page", "PartHealth", "PassOut", "PassesOut", "Password", "QualityNoteOut",
    "QualitySummaryOut", "RecordingOut", "RefId", "ResultOut", "ResultSeries",
    "RideDetail", "RideIn", "RideMetaIn", "RideOut", "RideUpdate", "RiderIn", "RiderOut", "RiderUpdate",
    "RigDetail", "RigIn", "RigOut", "RigUpdate", "RoleName", "SpectrumOut", "Pad",
    "SyncIn", "Text", "TokenOut", "UploadCreate",
    "UserCreate", "UserOut", "UserUpdate",
    "HealthSummaryOut", "PartState",  # the public health answer (accounts area)
]

T = TypeVar("T")

Gait = Literal[GAITS]  # type: ignore[valid-type]
Direction = Literal[DIRECTIONS]  # type: ignore[valid-type]
CameraRole = Literal[CAMERA_ROLES]  # type: ignore[valid-type]
ClipKind = Literal[CLIP_KINDS]  # type: ignore[valid-type]
RoleName = Literal["admin", "member"]
Name = Annotated[str, StringConstraints(strip_whitespace=True, min_length=1, max_length=200)]
Text = Annotated[str, StringConstraints(max_length=10_000)]
Pad = Annotated[str, StringConstraints(strip_whitespace=True, max_length=200)]
Email = Annotated[str, StringConstraints(strip_whitespace=True, min_length=3, max_length=320)]
Password = Annotated[str, StringConstraints(min_length=8, max_length=1024)]


# Ids fit the database's 32-bit integer columns (a larger number is simply not found).
MAX_ID = 2_147_483_647
RefId = Annotated[int, Field(ge=1, le=MAX_ID)]


_SURROGATE = re.compile("[\ud800-\udfff]")
# A job's options are small; the largest (a similarity job's 50,000 pairs) fits well under this.
MAX_JOB_PAYLOAD_BYTES = 1024**2


def _nul_free(value: Any, where: str = "body") -> None:
    """Refuse NUL characters and lone UTF-16 surrogates anywhere in a body: neither can be stored as text."""
    if isinstance(value, str):
        if "\x00" in value:
            raise ValueError(f"{where}: text may not contain the NUL character")
        if _SURROGATE.search(value):
            raise ValueError(f"{where}: text may not contain a lone UTF-16 surrogate (e.g. \\ud800); "
                             "it is not valid Unicode")
    elif isinstance(value, dict):
        for key, item in value.items():
            _nul_free(key, where)
            _nul_free(item, f"{where}.{key}")
    elif isinstance(value, list | tuple):
        for item in value:
            _nul_free(item, where)


class _In(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _no_nul(cls, data: Any) -> Any:
        _nul_free(data)
        return data


class _Out(BaseModel):
    model_config = ConfigDict(from_attributes=True)


class Page(BaseModel, Generic[T]):
    """One page of a list, and how many rows match in all."""

    items: list[T]
    total: int = Field(description="rows matching the filters (all pages)")
    limit: int
    offset: int


# --- health, errors ----------------------------------------------------------------------------------


class PartHealth(BaseModel):
    """One part's health: ok or not, with what it said."""

    ok: bool
    status: Literal["ok", "degraded", "error"]
    detail: str
    free_bytes: int | None = Field(default=None, description="storage only: free bytes of the folder's disk")


class HealthOut(BaseModel):
    """Whether the service can work: the database, the job queue and the storage (admins: details)."""

    status: Literal["ok", "degraded", "error"]
    summary: str = Field(description='"Service OK" or "Service degraded: <what a club cannot do now>"')
    mode: Literal["embedded", "celery"]
    version: str
    parts: dict[str, PartHealth] = Field(description="database, broker and storage")


class PartState(BaseModel):
    """One part's health without its detail (what anyone may see)."""

    ok: bool
    status: Literal["ok", "degraded", "error"]
    free_bytes: int | None = Field(default=None, description="storage only: free bytes of the folder's disk")


class HealthSummaryOut(BaseModel):
    """The public health answer: one line and each part ok or not; no paths, versions or addresses."""

    status: Literal["ok", "degraded", "error"]
    summary: str = Field(description='"Service OK" or "Service degraded: <what a club cannot do now>"')
    parts: dict[str, PartState] = Field(description="database, broker and storage: ok or not")


class ErrorOut(BaseModel):
    """An error's reason, in words for the user."""

    detail: str
    ride_id: int | None = Field(default=None, description="409 for clips uploaded again: the ride they already are")


# --- accounts ----------------------------------------------------------------------------------------


class ClubOut(_Out):
    """A club."""

    id: int
    name: str
    created_at: dt.datetime


class UserOut(_Out):
    """A user of a club (an account; never its password)."""

    id: int
    club_id: int
    email: str
    display_name: str
    role: RoleName
    is_active: bool
    created_at: dt.datetime


class ClubCreate(_In):
    """A new club and its first user, who becomes its admin."""

    club_name: Name
    email: Email
    password: Password
    display_name: Annotated[str, StringConstraints(max_length=200)] = ""


class ClubCreated(BaseModel):
    """The club created, and its admin."""

    club: ClubOut
    user: UserOut


class LoginIn(_In):
    """An e-mail address and password to sign in with."""

    email: Email
    password: Annotated[str, StringConstraints(max_length=1024)]


class TokenOut(BaseModel):
    """A signed-in session: the bearer token (also set as a cookie) and the CSRF token to send with it."""

    access_token: str
    token_type: Literal["bearer"] = "bearer"
    expires_in: int = Field(description="seconds until the token (and the session cookie) expire")
    csrf_token: str = Field(description="the value to send as X-CSRF-Token with the session cookie")
    user: UserOut


class MeOut(BaseModel):
    """The signed-in user and their club."""

    user: UserOut
    club: ClubOut
    permissions: dict[str, str] = Field(
        default_factory=dict,
        description="per action of docs/permissions.md what this user may do: 'all' (any such thing), "
        "'own' (only what they made) or 'none'; the dashboard hides controls the user may not use",
    )


class UserCreate(_In):
    """A new user of the club (admins only)."""

    email: Email
    password: Password
    display_name: Annotated[str, StringConstraints(max_length=200)] = ""
    role: RoleName = "member"


class UserUpdate(_In):
    """Changes to a user (unset fields stay)."""

    display_name: Annotated[str, StringConstraints(max_length=200)] | None = None
    role: RoleName | None = None
    is_active: bool | None = None
    password: Password | None = None


# --- horses, riders, rigs ----------------------------------------------------------------------------


class HorseIn(_In):
    """A new horse."""

    name: Name
    breed: Annotated[str, StringConstraints(max_length=200)] | None = None
    birth_year: int | None = Field(default=None, ge=1900, le=2100)
    height_withers_m: HeightWithersM = None


class HorseUpdate(_In):
    """Changes to a horse (unset fields stay)."""

    name: Name | None = None
    breed: Annotated[str, StringConstraints(max_length=200)] | None = None
    birth_year: int | None = Field(default=None, ge=1900, le=2100)
    height_withers_m: HeightWithersM = None


class HorseOut(_Out):
    """A horse of the club."""

    id: int
    name: str
    breed: str | None
    birth_year: int | None
    height_withers_m: float | None
    created_at: dt.datetime


class RiderIn(_In):
    """A new rider."""

    name: Name
    user_id: RefId | None = Field(default=None, description="the rider's own account, if any")
    weight_kg: RiderWeightKg = None


class RiderUpdate(_In):
    """Changes to a rider (unset fields stay)."""

    name: Name | None = None
    user_id: RefId | None = None
    weight_kg: RiderWeightKg = None


class RiderOut(_Out):
    """A rider of the club."""

    id: int
    name: str
    user_id: int | None
    weight_kg: float | None = None
    created_at: dt.datetime


# A camera's details (model, serial, lens, ...): a few short texts, not a store for anything else.
_DetailName = Annotated[str, StringConstraints(min_length=1, max_length=40)]
CameraDetails = Annotated[dict[_DetailName, Annotated[str, StringConstraints(max_length=200)]], Field(max_length=20)]


class RigIn(_In):
    """A new rig: a day's three-camera set-up."""

    name: Name
    recorded_on: dt.date | None = None
    cameras: dict[CameraRole, CameraDetails] = Field(
        default_factory=dict, description="model, serial, ... of each camera"
    )
    board: BoardIn | None = Field(
        default=None, description="the calibration board its calibration clips show"
    )
    wand_length_m: WandLengthM = None


class RigUpdate(_In):
    """Changes to a rig (unset fields stay)."""

    name: Name | None = None
    recorded_on: dt.date | None = None
    cameras: dict[CameraRole, CameraDetails] | None = None
    board: BoardIn | None = None
    wand_length_m: WandLengthM = None


class RigOut(_Out):
    """A rig, whether it is calibrated, and its calibration's quality flags."""

    id: int
    name: str
    recorded_on: dt.date | None
    cameras: dict[str, Any]
    board: dict[str, Any] | None
    board_text: str = Field(default="no board described", description="the board in words (its kind's)")
    wand_length_m: float | None = Field(default=None, description="m, between the wand's markers' centres")
    calibrated: bool
    quality: dict[str, Any] | None
    created_at: dt.datetime


class RigDetail(RigOut):
    """A rig with its calibration (the result format's ``calibration`` object)."""

    calibration: dict[str, Any] | None


# --- rides, recordings -------------------------------------------------------------------------------


class MarkersIn(_In):
    """ride.json's "markers": how many markers on the horse, the plumb line and the saddle."""

    horse: int = Field(default=3, ge=3, le=10)
    plumb: int = Field(default=2, ge=0, le=10)
    saddle: int = Field(default=1, ge=0, le=10)


Offsets = dict[CameraRole, Annotated[float, Field(ge=-1e6, le=1e6)]]


class SyncIn(_In):
    """ride.json's "sync": the flash (default), the markers' motion, or known frame offsets per clip kind and camera."""

    method: Literal["flash", "motion", "offsets"] = "flash"
    offsets: dict[ClipKind, Offsets] | None = None

    @model_validator(mode="after")
    def _offsets_given(self) -> SyncIn:
        if self.method == "offsets" and not self.offsets:
            raise ValueError("sync method 'offsets' needs the offsets")
        return self


class RideMetaIn(_In):
    """Optional ride.json sections of a ride assembled from uploaded clips."""

    board: BoardIn | None = None
    markers: MarkersIn | None = None
    sync: SyncIn | None = None


class RideIn(_In):
    """A new ride (its clips are uploaded afterwards)."""

    horse_id: RefId
    rider_id: RefId
    rig_id: RefId | None = None
    gait: Gait
    direction: Direction
    ridden_on: dt.date | None = None
    notes: Text = ""
    meta: RideMetaIn | None = None
    saddle_id: RefId | None = Field(default=None, description="the club's saddle the horse wore")
    pad: Pad | None = None
    rider_weight_kg: RiderWeightKg = Field(default=None, description="kg; default: the rider's weight")


class RideUpdate(_In):
    """Changes to a ride (unset fields stay)."""

    horse_id: RefId | None = None
    rider_id: RefId | None = None
    rig_id: RefId | None = None
    gait: Gait | None = None
    direction: Direction | None = None
    ridden_on: dt.date | None = None
    notes: Text | None = None
    saddle_id: RefId | None = Field(default=None, description="null: no saddle recorded")
    pad: Pad | None = None
    rider_weight_kg: RiderWeightKg = None


class RecordingOut(_Out):
    """A stored clip and what probing it found."""

    id: int
    ride_id: int | None
    rig_id: int | None
    clip_kind: str
    camera_role: str
    fps: float | None
    frame_count: int | None
    width: int | None
    height: int | None
    codec: str | None
    size_bytes: int | None
    sha256: str | None
    original_filename: str | None
    created_at: dt.datetime


class RideOut(_Out):
    """A ride in a list: its details, status and comfort indicators."""

    id: int
    horse_id: int
    horse_name: str = Field(description="the horse's name (so a page need not look it up by horse_id)")
    rider_id: int
    rider_name: str = Field(description="the rider's name (so a page need not look it up by rider_id)")
    rig_id: int | None
    gait: str
    direction: str
    ridden_on: dt.date | None
    status: str
    notes: str
    saddle_id: int | None = None
    pad: str | None = None
    rider_weight_kg: float | None = None
    from_bundle: bool
    indicators: dict[str, float | None] | None = Field(description="the comfort indicators once analysed")
    created_at: dt.datetime
    created_by: int | None = Field(default=None, description="the user who made the ride (None: not recorded)")
    result_outdated_by: list[str] = Field(default_factory=list, description=(
        "details changed since the shown result was computed (e.g. ['gait']): re-analyse to update it"))


class RideDetail(RideOut):
    """A ride with its ride.json sections, its clips and its latest job."""

    meta: dict[str, Any]
    recordings: list[RecordingOut]
    latest_job_id: int | None


class ClipUploaded(BaseModel):
    """The clip stored, and the job it started (if it completed a set)."""

    recording: RecordingOut
    job_id: int | None = Field(description="the job this upload started (the set of clips became complete)")


class BundleUploaded(BaseModel):
    """The ride a bundle became, and its analysis job."""

    ride: RideOut
    job_id: int


class MocapRideOut(BaseModel):
    """The analysed ride a motion-capture file became: its period, indicators and what was chosen."""

    ride: RideOut
    period_s: float
    indicators: dict[str, float]
    flags: list[str]
    source: dict[str, Any]


# --- uploads (resumable) -----------------------------------------------------------------------------


class UploadCreate(_In):
    """A resumable upload to start: what the file is for and how big it is."""

    target: Literal["ride_clip", "rig_clip", "bundle"]
    length_bytes: int = Field(ge=1, le=2**62, description="the file's total size")
    ride_id: RefId | None = None
    rig_id: RefId | None = Field(
        default=None, description="the rig (rig_clip), or the rig a bundle's ride uses"
    )
    clip_kind: ClipKind | None = None
    camera: CameraRole | None = None
    filename: Annotated[str, StringConstraints(max_length=255)] | None = None


# --- grades ------------------------------------------------------------------------------------------


class GradeIn(_In):
    """A rider's comfort grade of a ride."""

    ride_id: RefId
    rider_id: RefId
    # strict: JSON true is no grade (a lax int would store it as 1)
    grade: int = Field(ge=1, le=5, strict=True, description="1 = very uncomfortable ... 5 = very comfortable")
    comment: Text = ""


class GradeUpdate(_In):
    """Changes to a grade (unset fields stay)."""

    grade: int | None = Field(default=None, ge=1, le=5, strict=True)
    comment: Text | None = None


class GradeOut(_Out):
    """A rider's comfort grade of a ride."""

    id: int
    ride_id: int
    rider_id: int
    grade: int
    comment: str
    created_at: dt.datetime


# --- jobs --------------------------------------------------------------------------------------------


class JobCreate(_In):
    """A job to queue."""

    kind: str = Field(
        description="job kind, e.g. 'analyze', 'calibrate_rig', 'probe' or 'selftest'",
        examples=["probe"],
        max_length=32,
    )
    ride_id: RefId | None = Field(default=None, description="the ride to work on (probe, analyze)")
    rig_id: RefId | None = Field(default=None, description="the rig to work on (probe, calibrate_rig)")
    payload: dict[str, Any] = Field(
        default_factory=dict,
        description=f"kind-specific options, e.g. {{'steps': 5}} for selftest (at most {MAX_JOB_PAYLOAD_BYTES} "
        "bytes as JSON)",
    )

    @field_validator("payload")
    @classmethod
    def _bounded(cls, payload: dict[str, Any]) -> dict[str, Any]:
        size = len(json.dumps(payload, separators=(",", ":")).encode())
        if size > MAX_JOB_PAYLOAD_BYTES:
            raise ValueError(f"the job payload is {size} bytes as JSON, more than the limit of "
                             f"{MAX_JOB_PAYLOAD_BYTES} bytes")
        return payload


class FailureOut(BaseModel):
    """Why a job failed, in one sentence a club can act on, and what the ride page offers to do."""

    sentence: str = Field(description="one plain sentence naming the clip and camera where known")
    action: Literal["replace_clip", "recalibrate_rig", "film_again", "run_again"]
    camera: Literal["left", "middle", "right"] | None = Field(description="the camera whose clip failed")
    clip_kind: Literal["calibration", "plumb", "static", "motion"] | None = Field(description="the clip that failed")


class JobOut(BaseModel):
    """A job: its status, progress, per-stage timings and error."""

    id: int
    kind: str
    status: Literal["queued", "running", "done", "failed", "cancelled"]
    stage: str | None = Field(description="stage running now (with a detail after ': ')")
    progress: float = Field(ge=0, le=1)
    timings_s: dict[str, float] = Field(description="wall seconds per finished stage, and 'total'")
    error: str | None
    ride_id: int | None
    rig_id: int | None
    payload: dict[str, Any]
    attempts: int
    code_version: str | None
    host: str | None
    created_at: dt.datetime
    started_at: dt.datetime | None
    finished_at: dt.datetime | None
    note: str | None = Field(default=None, description=(
        "what an unfinished job waits for, e.g. 'waiting for a worker: ...' when no worker is alive "
        "or its worker stopped sending heartbeats"))
    progress_percent: int = Field(default=0, ge=0, le=100, description="progress as a whole percentage")
    stage_label: str = Field(default="", description="what the job is doing, in plain words")
    owner_id: int | None = Field(default=None, description=(
        "the user who made the job's ride (may cancel and retry it); None: admins only"))
    failure: FailureOut | None = Field(default=None, description="a failed job's reason in plain words")
    remaining_s: float | None = Field(default=None, description=(
        "a running job's expected remaining time, from its progress so far (None: not running, too early)"))
    duration_s: float | None = Field(default=None, description="how long a finished job ran")
    ride_label: str | None = Field(default=None, description="the job's ride as a club names it ('Bramble, canter')")


class JobKindOut(BaseModel):
    """A job kind this server runs, with its stages in order."""

    name: str
    stages: list[str]
    needs_ride: bool
    description: str


# --- results and comparisons -------------------------------------------------------------------------


class _ResultSeriesBase(BaseModel):
    """The plotted series, every ``decimation.step``-th frame (vectors as [x, y, z] in the motion frame)."""

    t_s: list[float]
    position_m: list[Any] = Field(description="the saddle point S")
    velocity_m_s: list[Any]
    acceleration_m_s2: list[Any]
    omega_rad_s: list[Any]
    alpha_rad_s2: list[Any]
    markers_position_m: list[Any] | None = Field(
        default=None, description="per frame, [x, y, z] of each marker; when the result has the markers")
    omega_versions_rad_s: list[Any] | None = Field(
        default=None, description="per frame, omega from each marker pair; when the result has them")
    omega_versions_excluded: list[Any] | None = Field(
        default=None, description="per frame, which versions were left out of omega")
    singularity_index_per_frame: list[Any] | None = Field(
        default=None, description="per frame, how close the markers' geometry is to singular")


# The derived series (services/results/series.py DERIVED: fitted curves, residuals, weighted acceleration),
# each a field of ResultSeries made from its declaration: the view serves exactly those.
if TYPE_CHECKING:
    ResultSeries = _ResultSeriesBase
else:
    ResultSeries = create_model(
        "ResultSeries", __base__=_ResultSeriesBase, __module__=__name__, __doc__=_ResultSeriesBase.__doc__,
        **{series.name: (list[Any] | None, Field(default=None, description=series.description)) for series in DERIVED})


class QualityNoteOut(BaseModel):
    """One finding of the analysis in plain words (`saddlescope.services.results.quality_notes`)."""

    code: str = Field(description="the kind of finding, e.g. rotation.weak_axis (saddlescope.core.findings)")
    severity: Literal["ok", "check", "problem"]
    message: str = Field(description="one sentence a club can act on")
    detail: str = Field(description="the pipeline's own sentence, with its numbers")


class QualitySummaryOut(BaseModel):
    """The worst severity among a result's flags and one line saying it."""

    severity: Literal["ok", "check", "problem"]
    message: str


class SpectrumOut(BaseModel):
    """S's vertical acceleration as harmonics of the stride frequency f0 (bars at k·f0), m/s² amplitudes."""

    f0_hz: float
    frequency_hz: list[float]
    amplitude_m_s2: list[float | None]
    amplitude_wb_m_s2: list[float | None]
    amplitude_wk_m_s2: list[float | None]


class Decimation(BaseModel):
    """How the series were thinned: every `step`-th of `samples` samples, for at most `max_points`."""

    step: int
    samples: int
    max_points: int


class ResultOut(BaseModel):
    """A ride's result as the dashboard shows it (`saddlescope.services.results.documents.view_of_document`)."""

    ride_id: int
    job_id: int | None
    code_version: str | None
    created_at: dt.datetime | None
    fps: float | None
    period_s: float | None
    window: dict[str, Any] | None
    indicators: dict[str, float | None]
    indicators_interval_95: dict[str, list[float | None]] = Field(
        default_factory=dict, description="95 % interval [low, high] per indicator; null: unbounded")
    units: dict[str, str]
    quality: dict[str, Any]
    quality_notes: list[QualityNoteOut] = Field(
        default_factory=list, description="the flags in plain words, most serious first")
    quality_summary: QualitySummaryOut
    strides_analysed: int | None = Field(description="whole strides in the analysed window")
    passes: PassesOut | None = Field(default=None, description="several passes: strides per pass, spread")
    spectrum: SpectrumOut | None
    calibration_checks: dict[str, Any]
    calibration_flags: list[Any]
    series: ResultSeries
    fits: dict[str, list[dict[str, Any]]] = Field(
        default_factory=dict,
        description="per axis x, y, z and marker: the curve fit's goodness of fit and 95 % intervals (thesis 5.5)")
    decimation: Decimation


class GlossaryEntryOut(BaseModel):
    """What one code the service uses means to a person (services/glossary.py)."""

    kind: Literal["indicator", "gait", "direction", "job_kind", "job_stage", "clip_kind", "camera",
                  "gravity_source", "similarity_method", "saddle_type", "caveat"]
    code: str = Field(description="the code as the API and the stored data carry it, never shown on a page")
    label: str = Field(description="what a page shows instead of the code (W_b, W_k, W_d as subscripts)")
    unit: str = Field(description="the unit of the values ('' where none)")
    short: str = Field(description="one line on what it means ('' where the label says it all)")
    expert: bool = Field(description="an expert indicator: folded under 'expert detail', after the headline numbers")


class IndicatorOut(BaseModel):
    """What an indicator key means: unit, label, thesis name and which way is more comfortable."""

    key: str
    unit: str
    label: str
    thesis_name: str | None
    better: Literal["lower", "higher"] | None
    comfort: bool = Field(description="one of the thesis's eight comfort indicators")

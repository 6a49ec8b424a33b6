"""SQLAlchemy 2 typed models: the whole schema in one page.

Every club-owned table carries ``club_id`` so the repositories can scope each query to one club.
Enumerations are stored as short strings with a CHECK constraint (portable across SQLite and
PostgreSQL). Times are timezone-aware UTC. Large arrays never go in the database: results keep
the storage key of their result document (JSON), plus the indicators a list or a ranking reads.
"""

from __future__ import annotations

import datetime as dt
import enum
from typing import Any

from sqlalchemy import (
    JSON,
    BigInteger,
    CheckConstraint,
    Date,
    DateTime,
    Enum,
    Float,
    ForeignKey,
    Index,
    MetaData,
    String,
    Text,
    TypeDecorator,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

from saddlescope.core.types import CAMERA_ROLES, CLIP_KINDS, DIRECTIONS, GAITS, WAND_CLIP_KINDS
from saddlescope.db.enums import (
    RIDER_WEIGHT_RANGE_KG,
    WAND_LENGTH_RANGE_M,
    JobStatus,
    RideStatus,
    Role,
    SaddleType,
    UploadStatus,
    UploadTarget,
)

__all__ = [
    "Base", "Club", "EndedSignIn", "Grade", "Horse", "Job", "LEADERBOARD_COLUMNS", "NAMING_CONVENTION",
    "PasswordReset", "Recording", "Result", "Ride", "Rider", "Rig", "Saddle", "ShareLink", "SimilarityPair",
    "TimestampMixin",
    "UTCDateTime", "Upload", "User", "utcnow",
]

# Stable constraint names, so Alembic migrations are the same on SQLite and PostgreSQL.
NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


def utcnow() -> dt.datetime:
    """The current time, timezone-aware UTC (what every timestamp column stores)."""
    return dt.datetime.now(dt.UTC)


class UTCDateTime(TypeDecorator):
    """A timezone-aware UTC timestamp, also on SQLite (which forgets the zone)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: dt.datetime | None, dialect) -> dt.datetime | None:
        """Refuse naive datetimes; store aware ones in UTC."""
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime given; use an aware UTC datetime")
        return value.astimezone(dt.UTC)

    def process_result_value(self, value: dt.datetime | None, dialect) -> dt.datetime | None:
        """Read back an aware UTC datetime (SQLite returns naive ones)."""
        if value is None:
            return None
        return value.replace(tzinfo=dt.UTC) if value.tzinfo is None else value.astimezone(dt.UTC)


def _str_enum(values: tuple[str, ...] | type[enum.StrEnum], name: str, length: int = 16) -> Enum:
    """A portable string enumeration: VARCHAR plus a named CHECK constraint."""
    if isinstance(values, type):
        values = tuple(v.value for v in values)
    return Enum(*values, name=name, native_enum=False, create_constraint=True, length=length,
                validate_strings=True)


class Base(DeclarativeBase):
    """The models' base: stable constraint names, UTC timestamps, JSON for dicts and lists."""

    metadata = MetaData(naming_convention=NAMING_CONVENTION)
    type_annotation_map = {dt.datetime: UTCDateTime(), dict[str, Any]: JSON(), list[Any]: JSON()}


class TimestampMixin:
    """A ``created_at`` column, set when the row is added."""

    created_at: Mapped[dt.datetime] = mapped_column(default=utcnow)


class Club(TimestampMixin, Base):
    """A riding club: every other row belongs to one (its ``club_id``)."""

    __tablename__ = "clubs"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)


class User(TimestampMixin, Base):
    """An account of a club: a member, or an admin who also manages users."""

    __tablename__ = "users"

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    email: Mapped[str] = mapped_column(String(320), unique=True)  # stored lower-case
    display_name: Mapped[str] = mapped_column(String(200), default="")
    password_hash: Mapped[str] = mapped_column(String(255))
    role: Mapped[str] = mapped_column(_str_enum(Role, "user_role"), default=Role.MEMBER.value)
    is_active: Mapped[bool] = mapped_column(default=True)
    # In every token; bumped by logout-everywhere and password changes, so older tokens stop working.
    session_version: Mapped[int] = mapped_column(default=0, server_default="0")

    club: Mapped[Club] = relationship()


class PasswordReset(TimestampMixin, Base):
    """A one-time password reset an admin issued: only the SHA-256 of its token is kept."""

    __tablename__ = "password_resets"

    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    expires_at: Mapped[dt.datetime]
    used_at: Mapped[dt.datetime | None]

    user: Mapped[User] = relationship()


class EndedSignIn(Base):
    """A signed-out sign-in: its token (cookie and bearer alike) is refused until it would have expired."""

    __tablename__ = "ended_sign_ins"

    sign_in_id: Mapped[str] = mapped_column(String(64), primary_key=True)  # the token's ``sid`` claim
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id", ondelete="CASCADE"), index=True)
    expires_at: Mapped[dt.datetime] = mapped_column(index=True)  # the token's expiry: then the row may go


class Horse(TimestampMixin, Base):
    """A horse of the club (names unique within the club)."""

    __tablename__ = "horses"
    __table_args__ = (
        UniqueConstraint("club_id", "name"),
        CheckConstraint("height_withers_m IS NULL OR (height_withers_m > 0.5 AND height_withers_m < 2.5)",
                        name="height_range"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    breed: Mapped[str | None] = mapped_column(String(200))
    birth_year: Mapped[int | None]
    height_withers_m: Mapped[float | None] = mapped_column(Float)


_LOW_KG, _HIGH_KG = RIDER_WEIGHT_RANGE_KG


class Rider(TimestampMixin, Base):
    """A rider of the club, maybe with an account of their own (to grade rides)."""

    __tablename__ = "riders"
    __table_args__ = (
        UniqueConstraint("club_id", "name"),
        CheckConstraint(f"weight_kg IS NULL OR (weight_kg >= {_LOW_KG:g} AND weight_kg <= {_HIGH_KG:g})",
                        name="weight_range"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    # A rider may also log in (to grade rides); riders without accounts are fine.
    user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"), index=True)
    # The rider's usual weight (kg); a new ride copies it (migration 0012_saddles).
    weight_kg: Mapped[float | None] = mapped_column(Float)


class Saddle(TimestampMixin, Base):
    """A saddle of the club (names unique within the club): what a ride's horse wore (migration 0012_saddles)."""

    __tablename__ = "saddles"
    __table_args__ = (UniqueConstraint("club_id", "name"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    maker: Mapped[str | None] = mapped_column(String(200))
    saddle_type: Mapped[str | None] = mapped_column(_str_enum(SaddleType, "saddle_type"))
    # As the maker or fitter states it ("medium", "32 cm", "MW"): no one unit across makers.
    tree_width: Mapped[str | None] = mapped_column(String(40))
    notes: Mapped[str] = mapped_column(Text, default="")


class Rig(TimestampMixin, Base):
    """A camera set-up on one day: three cameras, their calibration and its quality flags."""

    __tablename__ = "rigs"
    __table_args__ = (
        CheckConstraint(f"wand_length_m IS NULL OR (wand_length_m >= {WAND_LENGTH_RANGE_M[0]:g} AND "
                        f"wand_length_m <= {WAND_LENGTH_RANGE_M[1]:g})", name="wand_length_range"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    recorded_on: Mapped[dt.date | None] = mapped_column(Date)
    # {"left": {"model": ..., "serial": ...}, "middle": ..., "right": ...}
    cameras: Mapped[dict[str, Any]] = mapped_column(default=dict)
    # ride.json's "board" (CONTRACTS section 1) the calibration clips show; None: not given yet.
    board: Mapped[dict[str, Any] | None]
    # The `calibration` object of the result format (CONTRACTS section 2), once calibrated.
    calibration: Mapped[dict[str, Any] | None]
    quality: Mapped[dict[str, Any] | None]
    # Between the centres of the wand's two markers, for a wand calibration (migration 0014_rig_wand).
    wand_length_m: Mapped[float | None] = mapped_column(Float)


class Ride(TimestampMixin, Base):
    """One ride: a horse, a rider, a gait and direction, and the clips of its recording."""

    __tablename__ = "rides"
    __table_args__ = (
        Index("ix_rides_club_id_gait", "club_id", "gait"),
        # The rides list's filters and sorts (migration 0007_lists).
        Index("ix_rides_club_ridden_on", "club_id", "ridden_on", "id"),
        Index("ix_rides_club_created_at", "club_id", "created_at"),
        Index("ix_rides_club_horse_ridden_on", "club_id", "horse_id", "ridden_on"),
        Index("ix_rides_club_rider_ridden_on", "club_id", "rider_id", "ridden_on"),
        Index("ix_rides_club_status_ridden_on", "club_id", "status", "ridden_on"),
        Index("ix_rides_club_saddle_ridden_on", "club_id", "saddle_id", "ridden_on"),
        CheckConstraint(f"rider_weight_kg IS NULL OR (rider_weight_kg >= {_LOW_KG:g} AND rider_weight_kg <= "
                        f"{_HIGH_KG:g})", name="rider_weight_range"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    horse_id: Mapped[int] = mapped_column(ForeignKey("horses.id", ondelete="RESTRICT"), index=True)
    rider_id: Mapped[int] = mapped_column(ForeignKey("riders.id", ondelete="RESTRICT"), index=True)
    rig_id: Mapped[int | None] = mapped_column(ForeignKey("rigs.id", ondelete="SET NULL"), index=True)
    # The saddle and pad the horse wore, and the rider's weight that day (migration 0012_saddles).
    saddle_id: Mapped[int | None] = mapped_column(ForeignKey("saddles.id", ondelete="RESTRICT"), index=True)
    pad: Mapped[str | None] = mapped_column(String(200))
    rider_weight_kg: Mapped[float | None] = mapped_column(Float)
    gait: Mapped[str] = mapped_column(_str_enum(GAITS, "gait"))
    direction: Mapped[str] = mapped_column(_str_enum(DIRECTIONS, "direction", length=4))
    ridden_on: Mapped[dt.date | None] = mapped_column(Date)
    status: Mapped[str] = mapped_column(_str_enum(RideStatus, "ride_status"), default=RideStatus.NEW.value)
    notes: Mapped[str] = mapped_column(Text, default="")
    # Storage key of the folder holding the ride bundle (ride.json + clips), when registered from one.
    bundle_key: Mapped[str | None] = mapped_column(String(500))
    # Other ride.json sections of a ride assembled from uploaded clips ("sync", "markers", "board").
    meta: Mapped[dict[str, Any]] = mapped_column(default=dict)

    horse: Mapped[Horse] = relationship()
    rider: Mapped[Rider] = relationship()
    saddle: Mapped[Saddle | None] = relationship()
    recordings: Mapped[list[Recording]] = relationship(back_populates="ride", order_by="Recording.id")


class Recording(TimestampMixin, Base):
    """One clip of one camera: belongs to a ride, or to a rig (calibration clips shared by rides)."""

    __tablename__ = "recordings"
    __table_args__ = (
        UniqueConstraint("ride_id", "clip_kind", "camera_role"),
        UniqueConstraint("rig_id", "clip_kind", "camera_role"),
        CheckConstraint("ride_id IS NOT NULL OR rig_id IS NOT NULL", name="owner"),
        CheckConstraint("size_bytes IS NULL OR size_bytes >= 0", name="size_bytes"),
        # The same clip never makes two rides: looked up by content (migration 0012_saddles).
        Index("ix_recordings_club_sha256", "club_id", "sha256"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    ride_id: Mapped[int | None] = mapped_column(ForeignKey("rides.id", ondelete="CASCADE"), index=True)
    rig_id: Mapped[int | None] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"), index=True)
    camera_role: Mapped[str] = mapped_column(_str_enum(CAMERA_ROLES, "camera_role", length=8))
    # A rig's wand calibration clips too (migration 0014_rig_wand).
    clip_kind: Mapped[str] = mapped_column(_str_enum(CLIP_KINDS + WAND_CLIP_KINDS, "clip_kind"))
    # Storage key (relative to the storage root), never an absolute path.
    path: Mapped[str] = mapped_column(String(500))
    sha256: Mapped[str | None] = mapped_column(String(64))
    fps: Mapped[float | None] = mapped_column(Float)
    frame_count: Mapped[int | None]
    width: Mapped[int | None]
    height: Mapped[int | None]
    size_bytes: Mapped[int | None] = mapped_column(BigInteger)  # videos exceed 2 GiB
    probed_at: Mapped[dt.datetime | None]
    codec: Mapped[str | None] = mapped_column(String(32))
    original_filename: Mapped[str | None] = mapped_column(String(255))

    ride: Mapped[Ride | None] = relationship(back_populates="recordings")


class Job(Base):
    """A unit of background work (analysis, calibration, probe): its state, progress and timings."""

    __tablename__ = "jobs"
    __table_args__ = (
        CheckConstraint("progress >= 0 AND progress <= 1", name="progress_range"),
        Index("ix_jobs_status_created_at", "status", "created_at"),
        # The jobs list's filters, newest first (migration 0007_lists).
        Index("ix_jobs_club_id_id", "club_id", "id"),
        Index("ix_jobs_club_status_id", "club_id", "status", "id"),
        Index("ix_jobs_club_kind_id", "club_id", "kind", "id"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    # NULL for system jobs (self-test, maintenance) that belong to no club.
    club_id: Mapped[int | None] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    ride_id: Mapped[int | None] = mapped_column(ForeignKey("rides.id", ondelete="CASCADE"), index=True)
    rig_id: Mapped[int | None] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"), index=True)
    kind: Mapped[str] = mapped_column(String(32))
    payload: Mapped[dict[str, Any]] = mapped_column(default=dict)
    stage: Mapped[str | None] = mapped_column(String(64))
    status: Mapped[str] = mapped_column(_str_enum(JobStatus, "job_status"), default=JobStatus.QUEUED.value)
    progress: Mapped[float] = mapped_column(Float, default=0.0)
    # {"probe": 0.12, ...} wall seconds per finished stage
    timings: Mapped[dict[str, Any]] = mapped_column(default=dict)
    error: Mapped[str | None] = mapped_column(Text)
    code_version: Mapped[str | None] = mapped_column(String(64))
    host: Mapped[str | None] = mapped_column(String(255))
    attempts: Mapped[int] = mapped_column(default=0)
    created_at: Mapped[dt.datetime] = mapped_column(default=utcnow)
    started_at: Mapped[dt.datetime | None]
    finished_at: Mapped[dt.datetime | None]
    updated_at: Mapped[dt.datetime | None]


# Indicators (keys of core.vibration.INDICATORS) copied out of a result's JSON into indexed columns,
# so that leaderboards sort them in the database; every other indicator is ranked from the JSON.
LEADERBOARD_COLUMNS = ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vdv_y_wk", "vel_x_avg_kmh",
                       "amplitude_y_m", "stride_frequency_hz")


class Result(TimestampMixin, Base):
    """The analysis of one ride; a re-run replaces it."""

    __tablename__ = "results"
    __table_args__ = (
        # Covering (club, ride, value): a leaderboard reads these narrow entries, never the wide rows
        # with their JSON (ten thousand rides ranked in milliseconds).
        *(Index(f"ix_results_leaderboard_{name}", "club_id", "ride_id", name) for name in LEADERBOARD_COLUMNS),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    ride_id: Mapped[int] = mapped_column(ForeignKey("rides.id", ondelete="CASCADE"), unique=True)
    job_id: Mapped[int | None] = mapped_column(ForeignKey("jobs.id", ondelete="SET NULL"), index=True)
    # Which attempt of the job stored this result (its writes are fenced by it; migration 0008_fencing).
    job_attempt: Mapped[int | None]
    indicators: Mapped[dict[str, Any]] = mapped_column(default=dict)
    # Leaderboard columns copied out of `indicators` so they can be indexed and sorted.
    acc_y_wb_rms: Mapped[float | None] = mapped_column(Float)
    acc_y_wk_rms: Mapped[float | None] = mapped_column(Float)
    vdv_y_wb: Mapped[float | None] = mapped_column(Float)
    vdv_y_wk: Mapped[float | None] = mapped_column(Float)
    vel_x_avg_kmh: Mapped[float | None] = mapped_column(Float)
    amplitude_y_m: Mapped[float | None] = mapped_column(Float)
    stride_frequency_hz: Mapped[float | None] = mapped_column(Float)
    # Why the ride is too uncertain for a decision (quality.decision.reason), None when it is not:
    # such rides stay out of leaderboards unless asked for (issue 27, migration 0009_intervals).
    uncertain_reason: Mapped[str | None] = mapped_column(Text)
    # Storage key of the full result JSON (CONTRACTS section 2): series, quality flags, calibration.
    result_key: Mapped[str | None] = mapped_column(String(500))
    code_version: Mapped[str | None] = mapped_column(String(64))


class Grade(TimestampMixin, Base):
    """A rider's comfort grade of a ride (1 = very uncomfortable ... 5 = very comfortable)."""

    __tablename__ = "grades"
    __table_args__ = (
        UniqueConstraint("ride_id", "rider_id"),
        CheckConstraint("grade >= 1 AND grade <= 5", name="grade_range"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    ride_id: Mapped[int] = mapped_column(ForeignKey("rides.id", ondelete="CASCADE"), index=True)
    rider_id: Mapped[int] = mapped_column(ForeignKey("riders.id", ondelete="CASCADE"), index=True)
    grade: Mapped[int]
    comment: Mapped[str] = mapped_column(Text, default="")


class Upload(Base):
    """A resumable upload (tus-like): bytes arrive in chunks at increasing offsets, then it is finalised."""

    __tablename__ = "uploads"
    __table_args__ = (
        CheckConstraint("offset_bytes >= 0 AND offset_bytes <= length_bytes", name="offset_range"),
    )

    id: Mapped[str] = mapped_column(String(32), primary_key=True)  # random hex: not guessable
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    user_id: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"), index=True)
    target: Mapped[str] = mapped_column(_str_enum(UploadTarget, "upload_target"))
    ride_id: Mapped[int | None] = mapped_column(ForeignKey("rides.id", ondelete="CASCADE"), index=True)
    rig_id: Mapped[int | None] = mapped_column(ForeignKey("rigs.id", ondelete="CASCADE"), index=True)
    clip_kind: Mapped[str | None] = mapped_column(_str_enum(CLIP_KINDS + WAND_CLIP_KINDS, "upload_clip_kind"))
    camera_role: Mapped[str | None] = mapped_column(_str_enum(CAMERA_ROLES, "upload_camera_role", length=8))
    filename: Mapped[str | None] = mapped_column(String(255))
    length_bytes: Mapped[int] = mapped_column(BigInteger)
    offset_bytes: Mapped[int] = mapped_column(BigInteger, default=0)
    status: Mapped[str] = mapped_column(_str_enum(UploadStatus, "upload_status"),
                                        default=UploadStatus.OPEN.value)
    error: Mapped[str | None] = mapped_column(Text)
    # What finalising made: {"recording_id": 3} or {"ride_id": 5, "job_id": 9}.
    outcome: Mapped[dict[str, Any]] = mapped_column(default=dict)
    created_at: Mapped[dt.datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[dt.datetime] = mapped_column(default=utcnow)


class SimilarityPair(TimestampMixin, Base):
    """A cached comparison of two analysed rides (``services.similarity.compare.compare_ride_documents``' answer).

    One row per pair of rides (``ride_a_id < ride_b_id``), marker set and span. It is valid while both
    rides keep the analysis it was computed from (``version_a``, ``version_b``: each result's code
    version and time) and the similarity method keeps its version; a re-analysed ride's rows are
    deleted when its result is replaced. ``similarity`` is NULL when the rides could not be compared
    (``error`` says why).
    """

    __tablename__ = "similarity_pairs"
    __table_args__ = (
        UniqueConstraint("ride_a_id", "ride_b_id", "markers", "span"),
        CheckConstraint("ride_a_id < ride_b_id", name="ordered"),
        CheckConstraint("similarity IS NULL OR (similarity >= 0 AND similarity <= 1)", name="similarity_range"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    ride_a_id: Mapped[int] = mapped_column(ForeignKey("rides.id", ondelete="CASCADE"), index=True)
    ride_b_id: Mapped[int] = mapped_column(ForeignKey("rides.id", ondelete="CASCADE"), index=True)
    markers: Mapped[str] = mapped_column(String(16))
    span: Mapped[str] = mapped_column(String(16))
    version_a: Mapped[str] = mapped_column(String(100))
    version_b: Mapped[str] = mapped_column(String(100))
    method_version: Mapped[str] = mapped_column(String(100))
    similarity: Mapped[float | None] = mapped_column(Float)
    measure: Mapped[str | None] = mapped_column(String(64))
    # The whole answer of compare_ride_documents (measures, frame, step, ...), JSON.
    answer: Mapped[dict[str, Any]] = mapped_column(default=dict)
    error: Mapped[str | None] = mapped_column(Text)


class ShareLink(TimestampMixin, Base):
    """A read-only link for someone without an account (a vet): one ride's report or one horse's page.

    Only the SHA-256 of the link's token is kept (the token itself is shown once, to its maker). A link
    shows exactly one ride (``ride_id``) or one horse (``horse_id``) until ``expires_at`` or until an
    admin withdraws it (``revoked_at``); deleting the ride or horse deletes its links.
    """

    __tablename__ = "share_links"
    __table_args__ = (
        CheckConstraint("(ride_id IS NULL) <> (horse_id IS NULL)", name="one_target"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    club_id: Mapped[int] = mapped_column(ForeignKey("clubs.id", ondelete="CASCADE"), index=True)
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    ride_id: Mapped[int | None] = mapped_column(ForeignKey("rides.id", ondelete="CASCADE"), index=True)
    horse_id: Mapped[int | None] = mapped_column(ForeignKey("horses.id", ondelete="CASCADE"), index=True)
    created_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))
    expires_at: Mapped[dt.datetime]
    revoked_at: Mapped[dt.datetime | None]
    revoked_by: Mapped[int | None] = mapped_column(ForeignKey("users.id", ondelete="SET NULL"))

    ride: Mapped[Ride | None] = relationship()
    horse: Mapped[Horse | None] = relationship()
    maker: Mapped[User | None] = relationship(foreign_keys=[created_by])

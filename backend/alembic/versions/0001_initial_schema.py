"""Initial schema: clubs, users, horses, riders, rigs, rides, recordings, jobs, results, grades.

Revision ID: 0001
Revises:
Create Date: 2026-11-21
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0001"
down_revision: str | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def _create_clubs() -> None:
    """The clubs."""
    op.create_table(
        "clubs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_clubs")),
        sa.UniqueConstraint("name", name=op.f("uq_clubs_name")),
    )


def _create_horses() -> None:
    """The club's horses."""
    op.create_table(
        "horses",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("breed", sa.String(length=200), nullable=True),
        sa.Column("birth_year", sa.Integer(), nullable=True),
        sa.Column("height_withers_m", sa.Float(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint(
            "height_withers_m IS NULL OR (height_withers_m > 0.5 AND height_withers_m < 2.5)",
            name=op.f("ck_horses_height_range"),
        ),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_horses_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_horses")),
        sa.UniqueConstraint("club_id", "name", name=op.f("uq_horses_club_id_name")),
    )
    op.create_index(op.f("ix_horses_club_id"), "horses", ["club_id"], unique=False)


def _create_rigs() -> None:
    """The club's rigs (camera set-ups)."""
    op.create_table(
        "rigs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("recorded_on", sa.Date(), nullable=True),
        sa.Column("cameras", sa.JSON(), nullable=False),
        sa.Column("calibration", sa.JSON(), nullable=True),
        sa.Column("quality", sa.JSON(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_rigs_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_rigs")),
    )
    op.create_index(op.f("ix_rigs_club_id"), "rigs", ["club_id"], unique=False)


def _create_users() -> None:
    """The club's users (accounts)."""
    op.create_table(
        "users",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("email", sa.String(length=320), nullable=False),
        sa.Column("display_name", sa.String(length=200), nullable=False),
        sa.Column("password_hash", sa.String(length=255), nullable=False),
        sa.Column(
            "role",
            sa.Enum(
                "member", "admin", name="user_role", native_enum=False, create_constraint=True, length=16
            ),
            nullable=False,
        ),
        sa.Column("is_active", sa.Boolean(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_users_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_users")),
        sa.UniqueConstraint("email", name=op.f("uq_users_email")),
    )
    op.create_index(op.f("ix_users_club_id"), "users", ["club_id"], unique=False)


def _create_riders() -> None:
    """The club's riders."""
    op.create_table(
        "riders",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_riders_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["user_id"], ["users.id"], name=op.f("fk_riders_user_id_users"), ondelete="SET NULL"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_riders")),
        sa.UniqueConstraint("club_id", "name", name=op.f("uq_riders_club_id_name")),
    )
    op.create_index(op.f("ix_riders_club_id"), "riders", ["club_id"], unique=False)
    op.create_index(op.f("ix_riders_user_id"), "riders", ["user_id"], unique=False)


def _create_rides() -> None:
    """The rides."""
    op.create_table(
        "rides",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("horse_id", sa.Integer(), nullable=False),
        sa.Column("rider_id", sa.Integer(), nullable=False),
        sa.Column("rig_id", sa.Integer(), nullable=True),
        sa.Column(
            "gait",
            sa.Enum(
                "walk",
                "sitting_trot",
                "rising_trot",
                "canter",
                name="gait",
                native_enum=False,
                create_constraint=True,
                length=16,
            ),
            nullable=False,
        ),
        sa.Column(
            "direction",
            sa.Enum("CW", "CCW", name="direction", native_enum=False, create_constraint=True, length=4),
            nullable=False,
        ),
        sa.Column("ridden_on", sa.Date(), nullable=True),
        sa.Column(
            "status",
            sa.Enum(
                "new",
                "ready",
                "processing",
                "analysed",
                "failed",
                name="ride_status",
                native_enum=False,
                create_constraint=True,
                length=16,
            ),
            nullable=False,
        ),
        sa.Column("notes", sa.Text(), nullable=False),
        sa.Column("bundle_key", sa.String(length=500), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_rides_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["horse_id"], ["horses.id"], name=op.f("fk_rides_horse_id_horses"), ondelete="RESTRICT"
        ),
        sa.ForeignKeyConstraint(
            ["rider_id"], ["riders.id"], name=op.f("fk_rides_rider_id_riders"), ondelete="RESTRICT"
        ),
        sa.ForeignKeyConstraint(
            ["rig_id"], ["rigs.id"], name=op.f("fk_rides_rig_id_rigs"), ondelete="SET NULL"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_rides")),
    )
    op.create_index(op.f("ix_rides_club_id"), "rides", ["club_id"], unique=False)
    op.create_index("ix_rides_club_id_gait", "rides", ["club_id", "gait"], unique=False)
    op.create_index(op.f("ix_rides_horse_id"), "rides", ["horse_id"], unique=False)
    op.create_index(op.f("ix_rides_rider_id"), "rides", ["rider_id"], unique=False)
    op.create_index(op.f("ix_rides_rig_id"), "rides", ["rig_id"], unique=False)


def _create_grades() -> None:
    """Riders' comfort grades of rides."""
    op.create_table(
        "grades",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("ride_id", sa.Integer(), nullable=False),
        sa.Column("rider_id", sa.Integer(), nullable=False),
        sa.Column("grade", sa.Integer(), nullable=False),
        sa.Column("comment", sa.Text(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("grade >= 1 AND grade <= 5", name=op.f("ck_grades_grade_range")),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_grades_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["ride_id"], ["rides.id"], name=op.f("fk_grades_ride_id_rides"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["rider_id"], ["riders.id"], name=op.f("fk_grades_rider_id_riders"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_grades")),
        sa.UniqueConstraint("ride_id", "rider_id", name=op.f("uq_grades_ride_id_rider_id")),
    )
    op.create_index(op.f("ix_grades_club_id"), "grades", ["club_id"], unique=False)
    op.create_index(op.f("ix_grades_ride_id"), "grades", ["ride_id"], unique=False)
    op.create_index(op.f("ix_grades_rider_id"), "grades", ["rider_id"], unique=False)


def _create_jobs() -> None:
    """Background jobs."""
    op.create_table(
        "jobs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=True),
        sa.Column("ride_id", sa.Integer(), nullable=True),
        sa.Column("rig_id", sa.Integer(), nullable=True),
        sa.Column("kind", sa.String(length=32), nullable=False),
        sa.Column("payload", sa.JSON(), nullable=False),
        sa.Column("stage", sa.String(length=64), nullable=True),
        sa.Column(
            "status",
            sa.Enum(
                "queued",
                "running",
                "done",
                "failed",
                "cancelled",
                name="job_status",
                native_enum=False,
                create_constraint=True,
                length=16,
            ),
            nullable=False,
        ),
        sa.Column("progress", sa.Float(), nullable=False),
        sa.Column("timings", sa.JSON(), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("code_version", sa.String(length=64), nullable=True),
        sa.Column("host", sa.String(length=255), nullable=True),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("started_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("finished_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=True),
        sa.CheckConstraint("progress >= 0 AND progress <= 1", name=op.f("ck_jobs_progress_range")),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_jobs_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["ride_id"], ["rides.id"], name=op.f("fk_jobs_ride_id_rides"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["rig_id"], ["rigs.id"], name=op.f("fk_jobs_rig_id_rigs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_jobs")),
    )
    op.create_index(op.f("ix_jobs_club_id"), "jobs", ["club_id"], unique=False)
    op.create_index(op.f("ix_jobs_ride_id"), "jobs", ["ride_id"], unique=False)
    op.create_index(op.f("ix_jobs_rig_id"), "jobs", ["rig_id"], unique=False)
    op.create_index("ix_jobs_status_created_at", "jobs", ["status", "created_at"], unique=False)


def _create_recordings() -> None:
    """The clips of rides and rigs."""
    op.create_table(
        "recordings",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("ride_id", sa.Integer(), nullable=True),
        sa.Column("rig_id", sa.Integer(), nullable=True),
        sa.Column(
            "camera_role",
            sa.Enum(
                "left",
                "middle",
                "right",
                name="camera_role",
                native_enum=False,
                create_constraint=True,
                length=8,
            ),
            nullable=False,
        ),
        sa.Column(
            "clip_kind",
            sa.Enum(
                "calibration",
                "plumb",
                "static",
                "motion",
                name="clip_kind",
                native_enum=False,
                create_constraint=True,
                length=16,
            ),
            nullable=False,
        ),
        sa.Column("path", sa.String(length=500), nullable=False),
        sa.Column("sha256", sa.String(length=64), nullable=True),
        sa.Column("fps", sa.Float(), nullable=True),
        sa.Column("frame_count", sa.Integer(), nullable=True),
        sa.Column("width", sa.Integer(), nullable=True),
        sa.Column("height", sa.Integer(), nullable=True),
        sa.Column("size_bytes", sa.BigInteger(), nullable=True),
        sa.Column("probed_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("ride_id IS NOT NULL OR rig_id IS NOT NULL", name=op.f("ck_recordings_owner")),
        sa.CheckConstraint("size_bytes IS NULL OR size_bytes >= 0", name=op.f("ck_recordings_size_bytes")),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_recordings_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["ride_id"], ["rides.id"], name=op.f("fk_recordings_ride_id_rides"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["rig_id"], ["rigs.id"], name=op.f("fk_recordings_rig_id_rigs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_recordings")),
        sa.UniqueConstraint(
            "ride_id", "clip_kind", "camera_role", name=op.f("uq_recordings_ride_id_clip_kind_camera_role")
        ),
    )
    op.create_index(op.f("ix_recordings_club_id"), "recordings", ["club_id"], unique=False)
    op.create_index(op.f("ix_recordings_ride_id"), "recordings", ["ride_id"], unique=False)
    op.create_index(op.f("ix_recordings_rig_id"), "recordings", ["rig_id"], unique=False)


def _create_results() -> None:
    """The rides' results."""
    op.create_table(
        "results",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("ride_id", sa.Integer(), nullable=False),
        sa.Column("job_id", sa.Integer(), nullable=True),
        sa.Column("indicators", sa.JSON(), nullable=False),
        sa.Column("quality", sa.JSON(), nullable=False),
        sa.Column("acc_y_wb_rms", sa.Float(), nullable=True),
        sa.Column("acc_y_wk_rms", sa.Float(), nullable=True),
        sa.Column("vdv_y_wb", sa.Float(), nullable=True),
        sa.Column("vdv_y_wk", sa.Float(), nullable=True),
        sa.Column("vel_x_avg_kmh", sa.Float(), nullable=True),
        sa.Column("amplitude_y_m", sa.Float(), nullable=True),
        sa.Column("stride_frequency_hz", sa.Float(), nullable=True),
        sa.Column("result_key", sa.String(length=500), nullable=True),
        sa.Column("arrays_key", sa.String(length=500), nullable=True),
        sa.Column("code_version", sa.String(length=64), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_results_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["job_id"], ["jobs.id"], name=op.f("fk_results_job_id_jobs"), ondelete="SET NULL"
        ),
        sa.ForeignKeyConstraint(
            ["ride_id"], ["rides.id"], name=op.f("fk_results_ride_id_rides"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_results")),
        sa.UniqueConstraint("ride_id", name=op.f("uq_results_ride_id")),
    )
    op.create_index(op.f("ix_results_club_id"), "results", ["club_id"], unique=False)
    op.create_index("ix_results_club_id_acc_y_wb_rms", "results", ["club_id", "acc_y_wb_rms"], unique=False)
    op.create_index("ix_results_club_id_vdv_y_wb", "results", ["club_id", "vdv_y_wb"], unique=False)
    op.create_index("ix_results_club_id_vel_x_avg_kmh", "results", ["club_id", "vel_x_avg_kmh"], unique=False)
    op.create_index(op.f("ix_results_job_id"), "results", ["job_id"], unique=False)


def upgrade() -> None:
    """Create every table of the first schema."""
    _create_clubs()
    _create_horses()
    _create_rigs()
    _create_users()
    _create_riders()
    _create_rides()
    _create_grades()
    _create_jobs()
    _create_recordings()
    _create_results()


def downgrade() -> None:
    """Drop every table."""
    op.drop_index(op.f("ix_results_job_id"), table_name="results")
    op.drop_index("ix_results_club_id_vel_x_avg_kmh", table_name="results")
    op.drop_index("ix_results_club_id_vdv_y_wb", table_name="results")
    op.drop_index("ix_results_club_id_acc_y_wb_rms", table_name="results")
    op.drop_index(op.f("ix_results_club_id"), table_name="results")

    op.drop_table("results")
    op.drop_index(op.f("ix_recordings_rig_id"), table_name="recordings")
    op.drop_index(op.f("ix_recordings_ride_id"), table_name="recordings")
    op.drop_index(op.f("ix_recordings_club_id"), table_name="recordings")

    op.drop_table("recordings")
    op.drop_index("ix_jobs_status_created_at", table_name="jobs")
    op.drop_index(op.f("ix_jobs_rig_id"), table_name="jobs")
    op.drop_index(op.f("ix_jobs_ride_id"), table_name="jobs")
    op.drop_index(op.f("ix_jobs_club_id"), table_name="jobs")

    op.drop_table("jobs")
    op.drop_index(op.f("ix_grades_rider_id"), table_name="grades")
    op.drop_index(op.f("ix_grades_ride_id"), table_name="grades")
    op.drop_index(op.f("ix_grades_club_id"), table_name="grades")

    op.drop_table("grades")
    op.drop_index(op.f("ix_rides_rig_id"), table_name="rides")
    op.drop_index(op.f("ix_rides_rider_id"), table_name="rides")
    op.drop_index(op.f("ix_rides_horse_id"), table_name="rides")
    op.drop_index("ix_rides_club_id_gait", table_name="rides")
    op.drop_index(op.f("ix_rides_club_id"), table_name="rides")

    op.drop_table("rides")
    op.drop_index(op.f("ix_riders_user_id"), table_name="riders")
    op.drop_index(op.f("ix_riders_club_id"), table_name="riders")

    op.drop_table("riders")
    op.drop_index(op.f("ix_users_club_id"), table_name="users")

    op.drop_table("users")
    op.drop_index(op.f("ix_rigs_club_id"), table_name="rigs")

    op.drop_table("rigs")
    op.drop_index(op.f("ix_horses_club_id"), table_name="horses")

    op.drop_table("horses")
    op.drop_table("clubs")

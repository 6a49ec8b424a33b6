"""Service accounts and uploads: resumable uploads, a rig's board, a ride's ride.json sections, clip facts.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-24
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def _enum(*values: str, name: str, length: int = 16) -> sa.Enum:
    return sa.Enum(*values, name=name, native_enum=False, create_constraint=True, length=length)


def upgrade() -> None:
    """Add uploads, a rig's board, a ride's meta and the clip facts."""
    with op.batch_alter_table("rigs") as batch:
        batch.add_column(sa.Column("board", sa.JSON(), nullable=True))
    # Existing rides get an empty object, then the default moves to the application (as for the others).
    with op.batch_alter_table("rides") as batch:
        batch.add_column(sa.Column("meta", sa.JSON(), nullable=False, server_default=sa.text("'{}'")))
    with op.batch_alter_table("rides") as batch:
        batch.alter_column("meta", server_default=None)
    with op.batch_alter_table("recordings") as batch:
        batch.add_column(sa.Column("codec", sa.String(length=32), nullable=True))
        batch.add_column(sa.Column("original_filename", sa.String(length=255), nullable=True))
        batch.create_unique_constraint(
            op.f("uq_recordings_rig_id_clip_kind_camera_role"), ["rig_id", "clip_kind", "camera_role"]
        )
    op.create_table(
        "uploads",
        sa.Column("id", sa.String(length=32), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=True),
        sa.Column("target", _enum("ride_clip", "rig_clip", "bundle", name="upload_target"), nullable=False),
        sa.Column("ride_id", sa.Integer(), nullable=True),
        sa.Column("rig_id", sa.Integer(), nullable=True),
        sa.Column(
            "clip_kind",
            _enum("calibration", "plumb", "static", "motion", name="upload_clip_kind"),
            nullable=True,
        ),
        sa.Column(
            "camera_role",
            _enum("left", "middle", "right", name="upload_camera_role", length=8),
            nullable=True,
        ),
        sa.Column("filename", sa.String(length=255), nullable=True),
        sa.Column("length_bytes", sa.BigInteger(), nullable=False),
        sa.Column("offset_bytes", sa.BigInteger(), nullable=False),
        sa.Column("status", _enum("open", "finalised", "failed", name="upload_status"), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("outcome", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint(
            "offset_bytes >= 0 AND offset_bytes <= length_bytes", name=op.f("ck_uploads_offset_range")
        ),
        sa.ForeignKeyConstraint(
            ["club_id"], ["clubs.id"], name=op.f("fk_uploads_club_id_clubs"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["user_id"], ["users.id"], name=op.f("fk_uploads_user_id_users"), ondelete="SET NULL"
        ),
        sa.ForeignKeyConstraint(
            ["ride_id"], ["rides.id"], name=op.f("fk_uploads_ride_id_rides"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["rig_id"], ["rigs.id"], name=op.f("fk_uploads_rig_id_rigs"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_uploads")),
    )
    for column in ("club_id", "user_id", "ride_id", "rig_id"):
        op.create_index(op.f(f"ix_uploads_{column}"), "uploads", [column], unique=False)


def downgrade() -> None:
    """Remove what `upgrade` added."""
    for column in ("rig_id", "ride_id", "user_id", "club_id"):
        op.drop_index(op.f(f"ix_uploads_{column}"), table_name="uploads")
    op.drop_table("uploads")
    with op.batch_alter_table("recordings") as batch:
        batch.drop_constraint(op.f("uq_recordings_rig_id_clip_kind_camera_role"), type_="unique")
        batch.drop_column("original_filename")
        batch.drop_column("codec")
    with op.batch_alter_table("rides") as batch:
        batch.drop_column("meta")
    with op.batch_alter_table("rigs") as batch:
        batch.drop_column("board")

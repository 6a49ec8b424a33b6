"""Saddles and riders' weight (issue 37, item 3): a club's saddles, the saddle and pad of each ride, weights.

Also an index of clips by content hash: the same clips never make two rides (issue 37, item 4).

A ride may name the saddle the horse wore (``rides.saddle_id``, a saddle of the club: deleting a saddle
that rides use is refused) and the pad (free text); riders have a usual weight and each ride the
rider's weight that day (kg, 20-200; a new ride copies the rider's). Existing rides have none of these.

Revision ID: 0012_saddles
Revises: 0011_ended_sign_ins
Create Date: 2026-11-29
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0012_saddles"
down_revision: str | None = "0011_ended_sign_ins"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

SADDLE_TYPES = ("gp", "dressage", "jump", "treeless", "endurance", "western", "other")


def upgrade() -> None:
    """Create the saddles table; add the saddle, pad and rider's weight to rides and a weight to riders."""
    op.create_table(
        "saddles",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("maker", sa.String(200), nullable=True),
        sa.Column("saddle_type", sa.Enum(*SADDLE_TYPES, name="saddle_type", native_enum=False,
                                         create_constraint=True, length=16), nullable=True),
        sa.Column("tree_width", sa.String(40), nullable=True),
        sa.Column("notes", sa.Text(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["club_id"], ["clubs.id"], name=op.f("fk_saddles_club_id_clubs"), ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_saddles")),
        sa.UniqueConstraint("club_id", "name", name=op.f("uq_saddles_club_id_name")),
    )
    op.create_index(op.f("ix_saddles_club_id"), "saddles", ["club_id"])
    with op.batch_alter_table("riders") as batch:
        batch.add_column(sa.Column("weight_kg", sa.Float(), nullable=True))
        batch.create_check_constraint("weight_range", "weight_kg IS NULL OR (weight_kg >= 20 AND weight_kg <= 200)")
    with op.batch_alter_table("rides") as batch:
        batch.add_column(sa.Column("saddle_id", sa.Integer(), nullable=True))
        batch.add_column(sa.Column("pad", sa.String(200), nullable=True))
        batch.add_column(sa.Column("rider_weight_kg", sa.Float(), nullable=True))
        batch.create_foreign_key(op.f("fk_rides_saddle_id_saddles"), "saddles", ["saddle_id"], ["id"],
                                 ondelete="RESTRICT")
        batch.create_check_constraint(
            "rider_weight_range", "rider_weight_kg IS NULL OR (rider_weight_kg >= 20 AND rider_weight_kg <= 200)")
        batch.create_index(op.f("ix_rides_saddle_id"), ["saddle_id"])
        batch.create_index("ix_rides_club_saddle_ridden_on", ["club_id", "saddle_id", "ridden_on"])
    # A clip's content hash is looked up on every upload (the same clips never make two rides).
    op.create_index("ix_recordings_club_sha256", "recordings", ["club_id", "sha256"])


def downgrade() -> None:
    """Drop the columns and the saddles table (the saddles recorded are lost)."""
    op.drop_index("ix_recordings_club_sha256", table_name="recordings")
    with op.batch_alter_table("rides") as batch:
        batch.drop_index("ix_rides_club_saddle_ridden_on")
        batch.drop_index(op.f("ix_rides_saddle_id"))
        batch.drop_constraint("rider_weight_range", type_="check")
        batch.drop_constraint(op.f("fk_rides_saddle_id_saddles"), type_="foreignkey")
        batch.drop_column("rider_weight_kg")
        batch.drop_column("pad")
        batch.drop_column("saddle_id")
    with op.batch_alter_table("riders") as batch:
        batch.drop_constraint("weight_range", type_="check")
        batch.drop_column("weight_kg")
    op.drop_index(op.f("ix_saddles_club_id"), table_name="saddles")
    op.drop_table("saddles")

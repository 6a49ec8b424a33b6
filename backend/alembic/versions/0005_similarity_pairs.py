"""Cached ride comparisons: the ``similarity_pairs`` table.

One row per pair of analysed rides, marker set and span, holding the similarity service's answer and
the analysis versions it was computed from (see ``saddlescope.db.models.SimilarityPair``).

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-27
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0005"
down_revision: str | None = "0004"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_INDEXED = ("club_id", "ride_a_id", "ride_b_id")


def upgrade() -> None:
    """Create ``similarity_pairs`` with its indexes."""
    op.create_table(
        "similarity_pairs",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("ride_a_id", sa.Integer(), nullable=False),
        sa.Column("ride_b_id", sa.Integer(), nullable=False),
        sa.Column("markers", sa.String(length=16), nullable=False),
        sa.Column("span", sa.String(length=16), nullable=False),
        sa.Column("version_a", sa.String(length=100), nullable=False),
        sa.Column("version_b", sa.String(length=100), nullable=False),
        sa.Column("method_version", sa.String(length=100), nullable=False),
        sa.Column("similarity", sa.Float(), nullable=True),
        sa.Column("measure", sa.String(length=64), nullable=True),
        sa.Column("answer", sa.JSON(), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("ride_a_id < ride_b_id", name=op.f("ck_similarity_pairs_ordered")),
        sa.CheckConstraint("similarity IS NULL OR (similarity >= 0 AND similarity <= 1)",
                           name=op.f("ck_similarity_pairs_similarity_range")),
        sa.ForeignKeyConstraint(["club_id"], ["clubs.id"], name=op.f("fk_similarity_pairs_club_id_clubs"),
                                ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["ride_a_id"], ["rides.id"], name=op.f("fk_similarity_pairs_ride_a_id_rides"),
                                ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["ride_b_id"], ["rides.id"], name=op.f("fk_similarity_pairs_ride_b_id_rides"),
                                ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_similarity_pairs")),
        sa.UniqueConstraint("ride_a_id", "ride_b_id", "markers", "span",
                            name=op.f("uq_similarity_pairs_ride_a_id_ride_b_id_markers_span")),
    )
    for column in _INDEXED:
        op.create_index(op.f(f"ix_similarity_pairs_{column}"), "similarity_pairs", [column], unique=False)


def downgrade() -> None:
    """Drop ``similarity_pairs`` (the cache; nothing else is lost)."""
    for column in _INDEXED:
        op.drop_index(op.f(f"ix_similarity_pairs_{column}"), table_name="similarity_pairs")
    op.drop_table("similarity_pairs")

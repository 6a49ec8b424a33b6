"""Share links (issue 37, the vet's view): a read-only link to one ride's report or one horse's page.

Only the SHA-256 of each link's token is stored; a link expires at ``expires_at`` and an admin may
withdraw it (``revoked_at``, ``revoked_by``).

Revision ID: 0013_share_links
Revises: 0012_saddles
Create Date: 2026-11-29
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0013_share_links"
down_revision: str | None = "0012_saddles"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    """Create the table of share links (empty)."""
    op.create_table(
        "share_links",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("club_id", sa.Integer(), nullable=False),
        sa.Column("token_hash", sa.String(64), nullable=False),
        sa.Column("ride_id", sa.Integer(), nullable=True),
        sa.Column("horse_id", sa.Integer(), nullable=True),
        sa.Column("created_by", sa.Integer(), nullable=True),
        sa.Column("expires_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("revoked_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("revoked_by", sa.Integer(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("(ride_id IS NULL) <> (horse_id IS NULL)", name=op.f("ck_share_links_one_target")),
        sa.ForeignKeyConstraint(["club_id"], ["clubs.id"], name=op.f("fk_share_links_club_id_clubs"),
                                ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["ride_id"], ["rides.id"], name=op.f("fk_share_links_ride_id_rides"),
                                ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["horse_id"], ["horses.id"], name=op.f("fk_share_links_horse_id_horses"),
                                ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["created_by"], ["users.id"], name=op.f("fk_share_links_created_by_users"),
                                ondelete="SET NULL"),
        sa.ForeignKeyConstraint(["revoked_by"], ["users.id"], name=op.f("fk_share_links_revoked_by_users"),
                                ondelete="SET NULL"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_share_links")),
        sa.UniqueConstraint("token_hash", name=op.f("uq_share_links_token_hash")),
    )
    op.create_index(op.f("ix_share_links_club_id"), "share_links", ["club_id"])
    op.create_index(op.f("ix_share_links_ride_id"), "share_links", ["ride_id"])
    op.create_index(op.f("ix_share_links_horse_id"), "share_links", ["horse_id"])


def downgrade() -> None:
    """Drop the table (every share link stops working)."""
    op.drop_table("share_links")

"""Signing out ends that one sign-in (issue 39): the token's id is kept until the token would expire.

Tokens carry a random ``sid``; ``POST /api/auth/logout`` stores it in ``ended_sign_ins`` and every later
request with that token (cookie or bearer) is refused. Rows past ``expires_at`` are no longer needed.

Revision ID: 0011_ended_sign_ins
Revises: 0010_upload_finalising
Create Date: 2026-11-29
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0011_ended_sign_ins"
down_revision: str | None = "0010_upload_finalising"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    """Create the table of ended sign-ins (empty: tokens issued before have no id and expire as before)."""
    op.create_table(
        "ended_sign_ins",
        sa.Column("sign_in_id", sa.String(64), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        sa.Column("expires_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(["user_id"], ["users.id"], name=op.f("fk_ended_sign_ins_user_id_users"),
                                ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("sign_in_id", name=op.f("pk_ended_sign_ins")),
    )
    op.create_index(op.f("ix_ended_sign_ins_user_id"), "ended_sign_ins", ["user_id"])
    op.create_index(op.f("ix_ended_sign_ins_expires_at"), "ended_sign_ins", ["expires_at"])


def downgrade() -> None:
    """Drop the table (signed-out tokens are then accepted until they expire)."""
    op.drop_table("ended_sign_ins")

"""Results keep only what is read: the quality flags and the arrays file's key go.

``results.quality`` copied the result document's quality object and ``results.arrays_key`` named an
``arrays.npz`` of the series; nothing read either (the dashboard and the exports read the result
document, which holds both). The analysis no longer writes them.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-26
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    """Drop ``results.quality`` and ``results.arrays_key``."""
    with op.batch_alter_table("results") as batch:
        batch.drop_column("arrays_key")
        batch.drop_column("quality")


def downgrade() -> None:
    """Bring both columns back, empty (existing results get ``{}`` and no arrays file)."""
    with op.batch_alter_table("results") as batch:
        batch.add_column(sa.Column("quality", sa.JSON(), nullable=False, server_default=sa.text("'{}'")))
        batch.add_column(sa.Column("arrays_key", sa.String(length=500), nullable=True))
    with op.batch_alter_table("results") as batch:
        batch.alter_column("quality", server_default=None)

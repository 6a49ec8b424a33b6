"""Results say whether their ride is too uncertain for a decision (issue 27: kept out of leaderboards).

``results.uncertain_reason`` holds the result document's ``quality.decision.reason`` (a sentence), or
NULL for a ride whose W_b r.m.s. interval is narrow enough, and for results made before intervals.

Revision ID: 0009_intervals
Revises: 0008_fencing
Create Date: 2026-11-26
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0009_intervals"
down_revision: str | None = "0008_fencing"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    """Add the nullable reason column (existing results stay in the leaderboards)."""
    op.add_column("results", sa.Column("uncertain_reason", sa.Text(), nullable=True))


def downgrade() -> None:
    """Drop the reason column."""
    op.drop_column("results", "uncertain_reason")

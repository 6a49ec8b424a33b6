"""Fenced jobs: a ride's result records which attempt of its job stored it.

Every write of a job's state, progress and outputs is guarded by the job's attempt and host
(`db.repositories.jobs.JobRepository`); a result is stored only while its attempt holds the job's row,
so a stale worker's late result is refused. ``results.ride_id`` is unique (one result per ride, since
0001: a re-analysis replaces it), and ``results.job_attempt`` says which run that result came from.

Revision ID: 0008_fencing
Revises: 0007_lists
Create Date: 2026-11-26
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0008_fencing"
down_revision: str | None = "0007_lists"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    """Add ``results.job_attempt`` (NULL for results stored before fencing)."""
    with op.batch_alter_table("results") as batch:
        batch.add_column(sa.Column("job_attempt", sa.Integer(), nullable=True))


def downgrade() -> None:
    """Drop ``results.job_attempt`` (the results themselves are kept)."""
    with op.batch_alter_table("results") as batch:
        batch.drop_column("job_attempt")

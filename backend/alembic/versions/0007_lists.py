"""Indexes for the paged, filtered and sorted lists of rides and jobs (10,000 rides stay fast).

The rides list filters by horse, rider, gait or status within a club and sorts newest ridden first
(ties by id, so pages never overlap); the jobs list filters by status, kind or ride, newest first.
Each index leads with ``club_id`` (every list is one club's) and ends with the default sort.

Revision ID: 0007_lists
Revises: 0006
Create Date: 2026-11-26
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

__all__ = ["INDEXES", "branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0007_lists"
down_revision: str | None = "0006"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# name -> (table, columns); the same as the models' __table_args__ (db/models.py).
INDEXES: dict[str, tuple[str, tuple[str, ...]]] = {
    "ix_rides_club_ridden_on": ("rides", ("club_id", "ridden_on", "id")),
    "ix_rides_club_created_at": ("rides", ("club_id", "created_at")),
    "ix_rides_club_horse_ridden_on": ("rides", ("club_id", "horse_id", "ridden_on")),
    "ix_rides_club_rider_ridden_on": ("rides", ("club_id", "rider_id", "ridden_on")),
    "ix_rides_club_status_ridden_on": ("rides", ("club_id", "status", "ridden_on")),
    "ix_jobs_club_id_id": ("jobs", ("club_id", "id")),
    "ix_jobs_club_status_id": ("jobs", ("club_id", "status", "id")),
    "ix_jobs_club_kind_id": ("jobs", ("club_id", "kind", "id")),
}


def upgrade() -> None:
    """Create the list indexes."""
    for name, (table, columns) in INDEXES.items():
        op.create_index(name, table, list(columns))


def downgrade() -> None:
    """Drop the list indexes (no data is touched)."""
    for name, (table, _) in INDEXES.items():
        op.drop_index(name, table_name=table)

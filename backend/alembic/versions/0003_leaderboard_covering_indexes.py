"""Covering indexes (club, ride, value) for the leaderboard columns of results.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-25
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

__all__ = [
    "COLUMNS", "OLD", "branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade",
]

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

COLUMNS = (
    "acc_y_wb_rms",
    "acc_y_wk_rms",
    "vdv_y_wb",
    "vdv_y_wk",
    "vel_x_avg_kmh",
    "amplitude_y_m",
    "stride_frequency_hz",
)
OLD = ("acc_y_wb_rms", "vdv_y_wb", "vel_x_avg_kmh")


def upgrade() -> None:
    """Replace the (club, value) indexes by covering (club, ride, value) ones."""
    for name in OLD:  # (club, value) only: a ranking still had to read every wide row for its ride
        op.drop_index(f"ix_results_club_id_{name}", table_name="results")
    for name in COLUMNS:
        op.create_index(
            f"ix_results_leaderboard_{name}", "results", ["club_id", "ride_id", name], unique=False
        )


def downgrade() -> None:
    """Go back to the (club, value) indexes."""
    for name in COLUMNS:
        op.drop_index(f"ix_results_leaderboard_{name}", table_name="results")
    for name in OLD:
        op.create_index(f"ix_results_club_id_{name}", "results", ["club_id", name], unique=False)

"""An upload being finalised is claimed: ``uploads.status`` may be ``finalising`` (issue 39).

One finalise request turns the upload's status from ``open`` to ``finalising`` in one conditional UPDATE
before its bytes move; a concurrent or repeated finalise finds the claim and waits for (or answers) the
first one's outcome instead of racing it for the same bytes.

Revision ID: 0010_upload_finalising
Revises: 0009_intervals
Create Date: 2026-11-29
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0010_upload_finalising"
down_revision: str | None = "0009_intervals"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_WITH = "status IN ('open', 'finalising', 'finalised', 'failed')"
_WITHOUT = "status IN ('open', 'finalised', 'failed')"


def _status_check(condition: str) -> None:
    with op.batch_alter_table("uploads") as batch:
        batch.drop_constraint(op.f("ck_uploads_upload_status"), type_="check")
        batch.create_check_constraint("upload_status", condition)


def upgrade() -> None:
    """Allow the ``finalising`` status."""
    _status_check(_WITH)


def downgrade() -> None:
    """Back to three statuses; an upload caught finalising is open again (its bytes were not moved yet or
    are gone: the sweep removes it)."""
    op.execute("UPDATE uploads SET status = 'open' WHERE status = 'finalising'")
    _status_check(_WITHOUT)

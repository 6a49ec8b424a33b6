"""A rig calibrated with a wand (issue 35, item 3): the ``wand`` and ``close_up`` clips and the wand's length.

A rig (and an upload for it) may hold each camera's ``wand`` clip (two markers at a known distance waved
through the riding volume, all cameras at once) and ``close_up`` clip (a small board filmed close to each
camera, for its lens); ``rigs.wand_length_m`` is the distance between the wand's two markers' centres
(0.05-5 m), None until given. Existing rigs have none of these.

Revision ID: 0014_rig_wand
Revises: 0013_share_links
Create Date: 2026-11-29
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

__all__ = ["branch_labels", "depends_on", "down_revision", "downgrade", "revision", "upgrade"]

revision: str = "0014_rig_wand"
down_revision: str | None = "0013_share_links"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_BOARD_KINDS = ("calibration", "plumb", "static", "motion")
_WAND_KINDS = ("wand", "close_up")
# (table, the CHECK's name as the models' Enum names it)
_CLIP_KIND_CHECKS = (("recordings", "clip_kind"), ("uploads", "upload_clip_kind"))


def _clip_kind_checks(kinds: tuple[str, ...]) -> None:
    listed = ", ".join(f"'{kind}'" for kind in kinds)
    for table, name in _CLIP_KIND_CHECKS:
        with op.batch_alter_table(table) as batch:
            batch.drop_constraint(op.f(f"ck_{table}_{name}"), type_="check")
            batch.create_check_constraint(name, f"clip_kind IN ({listed})")


def upgrade() -> None:
    """Allow the ``wand`` and ``close_up`` clip kinds; add the rig's wand length."""
    _clip_kind_checks(_BOARD_KINDS + _WAND_KINDS)
    with op.batch_alter_table("rigs") as batch:
        batch.add_column(sa.Column("wand_length_m", sa.Float(), nullable=True))
        batch.create_check_constraint(
            "wand_length_range", "wand_length_m IS NULL OR (wand_length_m >= 0.05 AND wand_length_m <= 5)")


def downgrade() -> None:
    """Drop the wand length and the rigs' wand and close-up clips (their files stay in storage)."""
    with op.batch_alter_table("rigs") as batch:
        batch.drop_constraint(op.f("ck_rigs_wand_length_range"), type_="check")
        batch.drop_column("wand_length_m")
    kinds = ", ".join(f"'{kind}'" for kind in _WAND_KINDS)
    op.execute(f"DELETE FROM recordings WHERE clip_kind IN ({kinds})")
    op.execute(f"DELETE FROM uploads WHERE clip_kind IN ({kinds})")
    _clip_kind_checks(_BOARD_KINDS)

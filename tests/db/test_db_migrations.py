"""Alembic builds the schema on SQLite and PostgreSQL, and the models agree with the migrations."""

from __future__ import annotations

import integration_services
import pytest
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import Column, Integer, MetaData, String, Table, inspect

from saddlescope.db.migrate import alembic_config, current_revision, head_revision, upgrade_to_head
from saddlescope.db.models import Base
from saddlescope.db.session import make_engine

pg_database_url = integration_services.pg_database_url

TABLES = {"clubs", "users", "horses", "riders", "rigs", "rides", "recordings", "jobs", "results", "grades"}


def schema_diff(engine, metadata=Base.metadata) -> list:
    with engine.connect() as conn:
        context = MigrationContext.configure(conn, opts={"compare_type": True})
        return compare_metadata(context, metadata)


def _copy_with_extra_column(metadata: MetaData) -> MetaData:
    changed = MetaData(naming_convention=metadata.naming_convention)
    for table in metadata.sorted_tables:
        table.to_metadata(changed)
    Table("horses", changed, Column("colour", String(20)), extend_existing=True)
    Table("clubs", changed, Column("founded_year", Integer), extend_existing=True)
    return changed


def check_upgrade_builds_the_models(database_url: str) -> None:
    upgrade_to_head(database_url)
    engine = make_engine(database_url)
    try:
        assert TABLES <= set(inspect(engine).get_table_names())
        assert current_revision(engine) == head_revision()
        assert schema_diff(engine) == [], "models and migrations disagree: write a migration"
        # the comparison can fail: a model change without a migration shows up
        diff = schema_diff(engine, _copy_with_extra_column(Base.metadata))
        added = {(d[0], d[3].name) for d in diff if d[0] == "add_column"}
        assert added == {("add_column", "colour"), ("add_column", "founded_year")}
        upgrade_to_head(database_url)  # a no-op when up to date
        assert current_revision(engine) == head_revision()
    finally:
        engine.dispose()


def test_sqlite_upgrade_head_matches_the_models(tmp_path):
    check_upgrade_builds_the_models(f"sqlite:///{tmp_path / 'fresh.db'}")


def test_sqlite_downgrade_to_base_removes_every_table(tmp_path):
    url = f"sqlite:///{tmp_path / 'down.db'}"
    upgrade_to_head(url)
    command.downgrade(alembic_config(url), "base")
    engine = make_engine(url)
    try:
        assert set(inspect(engine).get_table_names()) <= {"alembic_version"}
    finally:
        engine.dispose()


def test_offline_sql_renders_for_postgresql():
    # `alembic upgrade head --sql` is how a DBA reviews a migration before running it
    import contextlib
    import io

    buffer = io.StringIO()
    config = alembic_config("postgresql+psycopg://user@host/db")
    config.output_buffer = buffer
    with contextlib.redirect_stdout(buffer):
        command.upgrade(config, "head", sql=True)
    sql = buffer.getvalue()
    assert "CREATE TABLE jobs" in sql and "CREATE INDEX ix_results_club_id_acc_y_wb_rms" in sql


@pytest.mark.integration
def test_postgresql_upgrade_head_matches_the_models(pg_database_url):
    check_upgrade_builds_the_models(pg_database_url)

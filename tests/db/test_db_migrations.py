"""Alembic builds the schema on SQLite and PostgreSQL, and the models agree with the migrations."""

from __future__ import annotations

import integration_services
import pytest
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import Column, Integer, MetaData, String, Table, inspect, text
from sqlalchemy.exc import IntegrityError

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


ANALYSED_RIDE_AT_0003 = [
    "INSERT INTO clubs (id, name, created_at) VALUES (1, 'Club', CURRENT_TIMESTAMP)",
    "INSERT INTO horses (id, club_id, name, created_at) VALUES (1, 1, 'Horse', CURRENT_TIMESTAMP)",
    "INSERT INTO riders (id, club_id, name, created_at) VALUES (1, 1, 'Rider', CURRENT_TIMESTAMP)",
    "INSERT INTO rides (id, club_id, horse_id, rider_id, gait, direction, status, notes, meta, created_at) "
    "VALUES (1, 1, 1, 1, 'walk', 'CW', 'analysed', '', '{}', CURRENT_TIMESTAMP)",
    "INSERT INTO results (id, club_id, ride_id, indicators, quality, result_key, arrays_key, acc_y_wb_rms, "
    "created_at) VALUES (1, 1, 1, '{\"acc_y_wb_rms\": 2.5}', '{\"flags\": []}', 'rides/1/r.json', "
    "'rides/1/arrays.npz', 2.5, CURRENT_TIMESTAMP)",
]


def check_0004_drops_the_unread_result_columns(database_url: str) -> None:
    config = alembic_config(database_url)
    upgrade_to_head(database_url)
    command.downgrade(config, "0003")
    engine = make_engine(database_url)
    try:
        with engine.begin() as conn:
            for statement in ANALYSED_RIDE_AT_0003:
                conn.execute(text(statement))
        command.upgrade(config, "0004")
        columns = {c["name"] for c in inspect(engine).get_columns("results")}
        assert {"quality", "arrays_key"}.isdisjoint(columns) and {"indicators", "result_key"} <= columns
        with engine.connect() as conn:  # the result itself is kept
            assert conn.execute(text("SELECT result_key, acc_y_wb_rms FROM results")).all() == [
                ("rides/1/r.json", 2.5)
            ]
        command.downgrade(config, "0003")
        with engine.connect() as conn:
            quality, arrays_key = conn.execute(text("SELECT quality, arrays_key FROM results")).one()
        assert quality in ("{}", {}) and arrays_key is None
        with engine.begin() as conn:
            for table in ("results", "rides", "riders", "horses", "clubs"):
                conn.execute(text(f"DELETE FROM {table}"))
        upgrade_to_head(database_url)
    finally:
        engine.dispose()


def test_sqlite_0004_drops_the_unread_result_columns_and_keeps_the_results(tmp_path):
    check_0004_drops_the_unread_result_columns(f"sqlite:///{tmp_path / 'results.db'}")


@pytest.mark.integration
def test_postgresql_0004_drops_the_unread_result_columns_and_keeps_the_results(pg_database_url):
    check_0004_drops_the_unread_result_columns(pg_database_url)


RIG_WITH_A_WAND = [
    "INSERT INTO clubs (id, name, created_at) VALUES (1, 'Club', CURRENT_TIMESTAMP)",
    "INSERT INTO rigs (id, club_id, name, cameras, wand_length_m, created_at) "
    "VALUES (1, 1, 'Arena', '{}', 1.0, CURRENT_TIMESTAMP)",
    "INSERT INTO recordings (club_id, rig_id, camera_role, clip_kind, path, created_at) "
    "VALUES (1, 1, 'left', 'wand', 'rigs/1/clips/wand/left.mp4', CURRENT_TIMESTAMP)",
    "INSERT INTO recordings (club_id, rig_id, camera_role, clip_kind, path, created_at) "
    "VALUES (1, 1, 'left', 'close_up', 'rigs/1/clips/close_up/left.mp4', CURRENT_TIMESTAMP)",
]
A_WAND_CLIP = ("INSERT INTO recordings (club_id, rig_id, camera_role, clip_kind, path, created_at) "
               "VALUES (1, 1, 'middle', 'wand', 'rigs/1/clips/wand/middle.mp4', CURRENT_TIMESTAMP)")


def _refused(engine, statement: str) -> bool:
    try:
        with engine.begin() as conn:
            conn.execute(text(statement))
    except IntegrityError:
        return True
    return False


def check_0014_takes_a_rigs_wand(database_url: str) -> None:
    config = alembic_config(database_url)
    upgrade_to_head(database_url)
    engine = make_engine(database_url)
    try:
        with engine.begin() as conn:
            for statement in RIG_WITH_A_WAND:
                conn.execute(text(statement))
        assert _refused(engine, "UPDATE rigs SET wand_length_m = 12 WHERE id = 1")  # 12 m: not a wand
        assert _refused(engine, A_WAND_CLIP.replace("'wand'", "'wands'"))
        command.downgrade(config, "0013_share_links")
        assert "wand_length_m" not in {c["name"] for c in inspect(engine).get_columns("rigs")}
        with engine.connect() as conn:  # the wand clips went with the kinds that named them
            assert conn.execute(text("SELECT COUNT(*) FROM recordings")).scalar() == 0
        assert _refused(engine, A_WAND_CLIP)
        command.upgrade(config, "0014_rig_wand")
        assert not _refused(engine, A_WAND_CLIP)
        with engine.begin() as conn:
            for table in ("recordings", "rigs", "clubs"):
                conn.execute(text(f"DELETE FROM {table}"))
    finally:
        engine.dispose()


def test_sqlite_0014_takes_a_rigs_wand_clips_and_length(tmp_path):
    check_0014_takes_a_rigs_wand(f"sqlite:///{tmp_path / 'wand.db'}")


@pytest.mark.integration
def test_postgresql_0014_takes_a_rigs_wand_clips_and_length(pg_database_url):
    check_0014_takes_a_rigs_wand(pg_database_url)

"""Migration 0007_lists adds the list indexes and takes them away again, keeping every row."""

from __future__ import annotations

import importlib.util

import integration_services
import pytest
from alembic import command
from sqlalchemy import inspect, text

from saddlescope.db.migrate import alembic_config, upgrade_to_head
from saddlescope.db.session import make_engine

pg_database_url = integration_services.pg_database_url


ROWS = [
    "INSERT INTO clubs (id, name, created_at) VALUES (1, 'Club', CURRENT_TIMESTAMP)",
    "INSERT INTO horses (id, club_id, name, created_at) VALUES (1, 1, 'H', CURRENT_TIMESTAMP)",
    "INSERT INTO riders (id, club_id, name, created_at) VALUES (1, 1, 'R', CURRENT_TIMESTAMP)",
    "INSERT INTO rides (id, club_id, horse_id, rider_id, gait, direction, status, notes, meta, created_at) "
    "VALUES (1, 1, 1, 1, 'walk', 'CW', 'new', '', '{}', CURRENT_TIMESTAMP)",
]


def _indexes_of_0007() -> dict:
    spec = importlib.util.find_spec("saddlescope")
    from pathlib import Path

    path = Path(spec.origin).parents[1] / "alembic" / "versions" / "0007_lists.py"
    module_spec = importlib.util.spec_from_file_location("migration_0007_lists", path)
    module = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(module)
    return module.INDEXES


def _index_names(engine, table: str) -> set[str]:
    return {ix["name"] for ix in inspect(engine).get_indexes(table)}


def check_0007_up_and_down(database_url: str) -> None:
    indexes = _indexes_of_0007()
    upgrade_to_head(database_url)
    engine = make_engine(database_url)
    try:
        with engine.begin() as conn:
            for statement in ROWS:
                conn.execute(text(statement))
        for name, (table, _) in indexes.items():
            assert name in _index_names(engine, table), f"{name} missing after upgrade"
        command.downgrade(alembic_config(database_url), "0006")
        for name, (table, _) in indexes.items():
            assert name not in _index_names(engine, table), f"{name} left after downgrade"
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM rides")).scalar() == 1
        command.upgrade(alembic_config(database_url), "head")
        for name, (table, _) in indexes.items():
            assert name in _index_names(engine, table)
    finally:
        engine.dispose()


def test_sqlite_0007_adds_and_removes_the_list_indexes(tmp_path):
    check_0007_up_and_down(f"sqlite:///{tmp_path / 'db.sqlite'}")


@pytest.mark.integration
def test_postgresql_0007_adds_and_removes_the_list_indexes(pg_database_url):
    check_0007_up_and_down(pg_database_url)

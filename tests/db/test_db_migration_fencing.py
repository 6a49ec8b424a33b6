"""Migration 0008_fencing adds results.job_attempt and takes it away again, keeping every result."""

from __future__ import annotations

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
    "INSERT INTO results (id, club_id, ride_id, indicators, created_at, job_attempt) "
    "VALUES (1, 1, 1, '{}', CURRENT_TIMESTAMP, 2)",
]


def _columns(engine) -> set[str]:
    return {column["name"] for column in inspect(engine).get_columns("results")}


def check_0008_up_and_down(database_url: str) -> None:
    upgrade_to_head(database_url)
    engine = make_engine(database_url)
    try:
        with engine.begin() as conn:
            for statement in ROWS:
                conn.execute(text(statement))
        assert "job_attempt" in _columns(engine)
        command.downgrade(alembic_config(database_url), "0007_lists")
        assert "job_attempt" not in _columns(engine)
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM results")).scalar() == 1
        command.upgrade(alembic_config(database_url), "head")
        with engine.connect() as conn:
            assert conn.execute(text("SELECT ride_id, job_attempt FROM results")).one() == (1, None)
        with pytest.raises(Exception, match="(?i)unique"):  # still one result per ride
            with engine.begin() as conn:
                conn.execute(text("INSERT INTO results (id, club_id, ride_id, indicators, created_at) "
                                  "VALUES (2, 1, 1, '{}', CURRENT_TIMESTAMP)"))
    finally:
        engine.dispose()


def test_sqlite_0008_adds_and_removes_the_attempt_of_a_result(tmp_path):
    check_0008_up_and_down(f"sqlite:///{tmp_path / 'db.sqlite'}")


@pytest.mark.integration
def test_postgresql_0008_adds_and_removes_the_attempt_of_a_result(pg_database_url):
    check_0008_up_and_down(pg_database_url)

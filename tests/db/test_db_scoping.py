"""Club scoping in the repositories (the one place the API's ownership rule lives), migrations of existing
data to the newest schema, and the storage writer the uploads stream into."""

from __future__ import annotations

import datetime as dt

import pytest
from alembic import command
from sqlalchemy import text

from saddlescope.db.migrate import alembic_config, upgrade_to_head
from saddlescope.db.models import Ride
from saddlescope.db.repositories import (
    AnalyticsRepository,
    ClubRepository,
    Conflict,
    GradeRepository,
    HorseRepository,
    JobRepository,
    NotFound,
    RecordingRepository,
    ResultRepository,
    RideRepository,
    RiderRepository,
    RigRepository,
)
from saddlescope.db.session import make_engine, make_session_factory, session_scope
from saddlescope.storage import FileStorage, TooLarge


@pytest.fixture
def sessions(tmp_path):
    url = f"sqlite:///{tmp_path / 'db.sqlite'}"
    upgrade_to_head(url)
    engine = make_engine(url)
    yield make_session_factory(engine)
    engine.dispose()


@pytest.fixture
def two_clubs(sessions):
    with session_scope(sessions) as s:
        ids = {}
        for name in ("A", "B"):
            club = ClubRepository(s).add(f"Club {name}")
            horse = HorseRepository(s, club_id=club.id).add(name=f"Horse {name}")
            rider = RiderRepository(s, club_id=club.id).add(name=f"Rider {name}")
            rig = RigRepository(s, club_id=club.id).add(name=f"Rig {name}")
            ride = RideRepository(s, club_id=club.id).add(
                horse_id=horse.id, rider_id=rider.id, rig_id=rig.id, gait="walk", direction="CW"
            )
            ids[name] = {
                "club": club.id,
                "horse": horse.id,
                "rider": rider.id,
                "rig": rig.id,
                "ride": ride.id,
            }
    return ids


def test_a_scoped_repository_sees_only_its_club(sessions, two_clubs):
    a, b = two_clubs["A"], two_clubs["B"]
    with session_scope(sessions) as s:
        for repo, key in (
            (HorseRepository, "horse"),
            (RiderRepository, "rider"),
            (RigRepository, "rig"),
            (RideRepository, "ride"),
        ):
            assert repo(s, club_id=a["club"]).get(a[key]).club_id == a["club"]
            assert repo(s, club_id=a["club"]).find(b[key]) is None
            with pytest.raises(NotFound):
                repo(s, club_id=a["club"]).get(b[key])
            page = repo(s, club_id=a["club"]).list_page()
            assert page.total == 1 and [r.id for r in page.items] == [a[key]]
        # references to another club's rows are not found either
        with pytest.raises(NotFound, match="horse"):
            RideRepository(s, club_id=a["club"]).add(
                horse_id=b["horse"], rider_id=a["rider"], gait="walk", direction="CW"
            )
        with pytest.raises(NotFound, match="rig"):
            RideRepository(s, club_id=a["club"]).update_fields(a["ride"], rig_id=b["rig"])
        with pytest.raises(NotFound, match="ride"):
            GradeRepository(s, club_id=a["club"]).check_references(ride_id=b["ride"], rider_id=a["rider"])
        with pytest.raises(PermissionError):
            HorseRepository(s, club_id=a["club"]).add(club_id=b["club"], name="Smuggled")
        RideRepository(s, club_id=a["club"]).delete(b["ride"])  # silently nothing: not in club A
        RideRepository(s, club_id=a["club"]).set_status(b["ride"], "failed")
    with session_scope(sessions) as s:
        assert s.get(Ride, b["ride"]).status == "new"


def test_names_are_unique_per_club_and_used_rows_are_kept(sessions, two_clubs):
    a, b = two_clubs["A"], two_clubs["B"]
    with session_scope(sessions) as s:
        HorseRepository(s, club_id=b["club"]).add(name="Horse A")  # the same name in another club is fine
        with pytest.raises(Conflict, match="already has a horse named 'Horse A'"):
            HorseRepository(s, club_id=a["club"]).add(name="Horse A")
        with pytest.raises(Conflict, match=r"still has \d+ rides?; delete those rides first"):
            HorseRepository(s, club_id=a["club"]).delete(a["horse"])
        with pytest.raises(Conflict, match="used by rides"):
            RigRepository(s, club_id=a["club"]).delete(a["rig"])


def test_the_leaderboard_values_come_from_the_clubs_results_only(sessions, two_clubs):
    with session_scope(sessions) as s:
        for name, value in (("A", 1.5), ("B", 9.0)):
            ids = two_clubs[name]
            ResultRepository(s).replace_for_ride(
                club_id=ids["club"],
                ride_id=ids["ride"],
                job_id=None,
                indicators={"acc_y_wb_rms": value, "t_a8_limit_wb_h": 2 * value},
                result_key=None,
                code_version=None, uncertain_reason=None,
            )
        a = AnalyticsRepository(s, club_id=two_clubs["A"]["club"])
        assert a.indicator_values("acc_y_wb_rms", gait="walk") == [(two_clubs["A"]["horse"], "Horse A", 1.5)]
        assert a.indicator_values("t_a8_limit_wb_h", gait="walk") == [
            (two_clubs["A"]["horse"], "Horse A", 3.0)
        ]
        assert a.indicator_values("acc_y_wb_rms", gait="canter") == []
        rows = a.indicator_rows()
        assert [(r["horse"], r["indicators"]["acc_y_wb_rms"]) for r in rows] == [("Horse A", 1.5)]


def test_jobs_of_another_club_and_system_jobs_are_invisible(sessions, two_clubs):
    with session_scope(sessions) as s:
        mine = JobRepository(s).add(kind="selftest", club_id=two_clubs["A"]["club"]).id
        theirs = JobRepository(s).add(kind="selftest", club_id=two_clubs["B"]["club"]).id
        system = JobRepository(s).add(kind="selftest").id
        scoped = JobRepository(s, club_id=two_clubs["A"]["club"])
        assert scoped.find(mine) is not None and scoped.find(theirs) is None and scoped.find(system) is None
        assert [j.id for j in scoped.list_page().items] == [mine]


def test_a_rig_keeps_the_first_calibration_two_jobs_race_to_store(sessions, two_clubs):
    rig = two_clubs["A"]["rig"]
    with session_scope(sessions) as s:
        rigs = RigRepository(s, club_id=two_clubs["A"]["club"])
        assert rigs.set_calibration_if_missing(rig, {"cameras": {"left": 1}}, {"ok": True})
        assert not rigs.set_calibration_if_missing(rig, {"cameras": {"left": 2}}, {"ok": True})
        assert rigs.get(rig).calibration == {"cameras": {"left": 1}}
        RecordingRepository(s, club_id=two_clubs["A"]["club"]).add(
            rig_id=rig, camera_role="left", clip_kind="calibration", path="x"
        )
        rigs.clear_calibration(rig)
        assert rigs.get(rig).calibration is None


def test_existing_rides_migrate_to_the_newest_schema(tmp_path):
    url = f"sqlite:///{tmp_path / 'old.db'}"
    command.upgrade(alembic_config(url), "0001")
    engine = make_engine(url)
    now = dt.datetime.now(dt.UTC).isoformat()
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO clubs (id, name, created_at) VALUES (1, 'Old club', :t)"), {"t": now})
        conn.execute(
            text("INSERT INTO horses (id, club_id, name, created_at) VALUES (1, 1, 'Old horse', :t)"),
            {"t": now},
        )
        conn.execute(
            text("INSERT INTO riders (id, club_id, name, created_at) VALUES (1, 1, 'Old rider', :t)"),
            {"t": now},
        )
        conn.execute(
            text(
                "INSERT INTO rides (id, club_id, horse_id, rider_id, gait, direction, status, notes, "
                "created_at) VALUES (1, 1, 1, 1, 'walk', 'CW', 'new', '', :t)"
            ),
            {"t": now},
        )
    engine.dispose()
    upgrade_to_head(url)
    engine = make_engine(url)
    try:
        with make_session_factory(engine)() as s:
            assert s.get(Ride, 1).meta == {}
    finally:
        engine.dispose()
    command.downgrade(alembic_config(url), "0001")  # and back, keeping the ride
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            assert conn.execute(text("SELECT count(*) FROM rides")).scalar() == 1
    finally:
        engine.dispose()


def test_the_atomic_writer_hashes_counts_and_refuses_past_its_limit(tmp_path):
    import hashlib

    storage = FileStorage(tmp_path / "s")
    with storage.writer("a/clip.mp4", max_bytes=10) as out:
        out.write(b"01234")
        out.write(b"56789")
        size, digest = out.commit()
    assert (size, digest) == (10, hashlib.sha256(b"0123456789").hexdigest())
    assert storage.read_bytes("a/clip.mp4") == b"0123456789"
    with (
        pytest.raises(TooLarge, match="larger than the upload limit of 10 bytes"),
        storage.writer("a/clip.mp4", max_bytes=10) as out,
    ):
        out.write(b"0123456789")
        out.write(b"!")
    assert storage.read_bytes("a/clip.mp4") == b"0123456789"  # the earlier file is untouched
    assert [p.name for p in (tmp_path / "s" / "a").iterdir()] == ["clip.mp4"]  # no half file left
    handle = storage.open_at("a/clip.mp4", 4)
    handle.write(b"xy")
    handle.close()
    assert storage.read_bytes("a/clip.mp4") == b"0123xy"

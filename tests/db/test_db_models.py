"""Models and repositories on SQLite (schema built by the real migrations)."""

from __future__ import annotations

import datetime as dt

import pytest
from sqlalchemy import text, update
from sqlalchemy.exc import IntegrityError, StatementError

from saddlescope.db.enums import JobStatus
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.models import Job, utcnow
from saddlescope.db.repositories import (
    ClubRepository,
    GradeRepository,
    HorseRepository,
    JobRepository,
    NotFound,
    RecordingRepository,
    ResultRepository,
    RideRepository,
    RiderRepository,
)
from saddlescope.db.session import make_engine, make_session_factory, session_scope


@pytest.fixture
def sessions(tmp_path):
    url = f"sqlite:///{tmp_path / 'db' / 'test.db'}"
    upgrade_to_head(url)
    engine = make_engine(url)
    yield make_session_factory(engine)
    engine.dispose()


@pytest.fixture
def ride_ids(sessions):
    """(club_id, ride_id, rider_id) of one ride in club A, plus a second club B with its own ride."""
    with session_scope(sessions) as s:
        ids = {}
        for club_name in ("A", "B"):
            club = ClubRepository(s).get_or_create(club_name)
            horse = HorseRepository(s).get_or_create(
                club_id=club.id, name="Horse 2", breed="Dutch", birth_year=1999, height_withers_m=1.73
            )
            rider = RiderRepository(s).get_or_create(club_id=club.id, name="Rider B")
            ride = RideRepository(s).add(
                club_id=club.id,
                horse_id=horse.id,
                rider_id=rider.id,
                gait="canter",
                direction="CCW",
                ridden_on=dt.date(2008, 5, 1),
            )
            ids[club_name] = (club.id, ride.id, rider.id)
    return ids


def test_sqlite_is_in_wal_mode_with_foreign_keys(sessions):
    with sessions() as s:
        assert s.execute(text("PRAGMA journal_mode")).scalar() == "wal"
        assert s.execute(text("PRAGMA foreign_keys")).scalar() == 1


def test_foreign_keys_are_enforced(sessions):
    with pytest.raises(IntegrityError), session_scope(sessions) as s:
        RiderRepository(s).get_or_create(club_id=999, name="nobody's rider")


def test_get_or_create_returns_the_same_rows(sessions, ride_ids):
    club_id = ride_ids["A"][0]
    with session_scope(sessions) as s:
        assert HorseRepository(s).get_or_create(club_id=club_id, name="Horse 2").birth_year == 1999
        assert ClubRepository(s).get_or_create("A").id == club_id


def test_enumerations_are_checked_in_python_and_in_the_database(sessions, ride_ids):
    club_id, ride_id, rider_id = ride_ids["A"]
    with pytest.raises(StatementError, match="gallop"), session_scope(sessions) as s:
        horse = HorseRepository(s).get_or_create(club_id=club_id, name="Horse 3")
        RideRepository(s).add(
            club_id=club_id, horse_id=horse.id, rider_id=rider_id, gait="gallop", direction="CW"
        )
    # the CHECK constraint from the migration catches writes that bypass the ORM
    with pytest.raises(IntegrityError, match="CHECK"), session_scope(sessions) as s:
        s.execute(text("UPDATE rides SET gait = 'gallop' WHERE id = :id"), {"id": ride_id})


def test_club_scoped_repository_hides_other_clubs(sessions, ride_ids):
    (club_a, ride_a, _), (club_b, ride_b, _) = ride_ids["A"], ride_ids["B"]
    with session_scope(sessions) as s:
        rides_a = RideRepository(s, club_id=club_a)
        assert rides_a.get(ride_a).id == ride_a
        with pytest.raises(NotFound, match=f"ride {ride_b} not found"):
            rides_a.get(ride_b)
        assert [r.id for r in rides_a.latest()] == [ride_a]
        with pytest.raises(PermissionError):
            RiderRepository(s, club_id=club_a).get_or_create(club_id=club_b, name="intruder")


def test_grades_are_one_per_ride_and_rider_and_within_1_to_5(sessions, ride_ids):
    club_id, ride_id, rider_id = ride_ids["A"]
    with session_scope(sessions) as s:
        grades = GradeRepository(s)
        first = grades.set_grade(club_id=club_id, ride_id=ride_id, rider_id=rider_id, grade=2)
        again = grades.set_grade(
            club_id=club_id, ride_id=ride_id, rider_id=rider_id, grade=4, comment="better"
        )
        assert first.id == again.id and again.grade == 4
    with pytest.raises(IntegrityError), session_scope(sessions) as s:
        GradeRepository(s).set_grade(club_id=club_id, ride_id=ride_id, rider_id=ride_ids["B"][2], grade=6)


def test_recordings_are_unique_per_ride_clip_kind_and_camera(sessions, ride_ids):
    club_id, ride_id, _ = ride_ids["A"]
    with pytest.raises(IntegrityError), session_scope(sessions) as s:
        recordings = RecordingRepository(s)
        recordings.add(club_id=club_id, ride_id=ride_id, camera_role="left", clip_kind="motion", path="a.mp4")
        recordings.add(club_id=club_id, ride_id=ride_id, camera_role="left", clip_kind="motion", path="b.mp4")


def test_recording_needs_a_ride_or_a_rig(sessions, ride_ids):
    with pytest.raises(IntegrityError), session_scope(sessions) as s:
        RecordingRepository(s).add(club_id=ride_ids["A"][0], camera_role="left", clip_kind="motion", path="x")


def test_recording_sizes_above_4_gib_fit(sessions, ride_ids):
    club_id, ride_id, _ = ride_ids["A"]
    with session_scope(sessions) as s:
        rec = RecordingRepository(s).add(
            club_id=club_id,
            ride_id=ride_id,
            camera_role="right",
            clip_kind="static",
            path="big.mp4",
            size_bytes=5 * 1024**3,
        )
    with sessions() as s:
        assert RecordingRepository(s).get(rec.id).size_bytes == 5 * 1024**3


def test_timestamps_come_back_timezone_aware_utc(sessions):
    with session_scope(sessions) as s:
        job = JobRepository(s).add(kind="selftest")
    with sessions() as s:
        created = s.get(Job, job.id).created_at
    assert created.tzinfo is not None and created.utcoffset() == dt.timedelta(0)
    assert abs((dt.datetime.now(dt.UTC) - created).total_seconds()) < 60


def test_job_lifecycle_is_guarded(sessions):
    with session_scope(sessions) as s:
        job_id = JobRepository(s).add(kind="selftest", payload={"steps": 1}).id
    with session_scope(sessions) as s:
        jobs = JobRepository(s)
        assert jobs.mark_running(job_id, host="h", code_version="v")
        jobs.set_progress(job_id, 1.7, "selftest")  # clamped to the CHECK range
        assert jobs.request_cancel(job_id)
        assert not jobs.finish(job_id, JobStatus.DONE)  # a cancelled job stays cancelled
        assert not jobs.mark_running(job_id, host="h", code_version="v")  # and is not restarted
    with sessions() as s:
        job = s.get(Job, job_id)
        assert (job.status, job.progress, job.attempts) == ("cancelled", 1.0, 1)
        assert job.finished_at is not None


def test_restarting_a_running_job_clears_the_earlier_attempt(sessions):
    with session_scope(sessions) as s:
        jobs = JobRepository(s)
        job_id = jobs.add(kind="selftest").id
        jobs.mark_running(job_id, host="h1", code_version="v")
        jobs.set_timings(job_id, {"selftest": 1.0})
        # Issue 25 item 6: a copy re-sent after the broker lost its data must not start the job
        # again while its worker is alive (heartbeat fresh by the database's clock) ...
        assert not jobs.mark_running(job_id, host="h2", code_version="v", stale_after_s=180)
        assert jobs.mark_running(job_id, host="h1", code_version="v", stale_after_s=180)  # a retry, same worker
        s.execute(update(Job).where(Job.id == job_id).values(updated_at=utcnow() - dt.timedelta(hours=1)))
        # ... but one whose heartbeat stopped is taken over: lost worker, delivered again
        assert jobs.mark_running(job_id, host="h2", code_version="v", stale_after_s=180)
    with sessions() as s:
        job = s.get(Job, job_id)
        assert (job.status, job.timings, job.host, job.attempts) == ("running", {}, "h2", 3)


def test_result_replaces_the_previous_one_and_fills_leaderboard_columns(sessions, ride_ids):
    club_id, ride_id, _ = ride_ids["A"]
    with session_scope(sessions) as s:
        results = ResultRepository(s)
        first = results.replace_for_ride(
            club_id=club_id,
            ride_id=ride_id,
            job_id=None,
            indicators={"acc_y_wb_rms": 2.0, "vel_x_avg_kmh": 19.5},
            result_key=None,
            code_version="v1", uncertain_reason=None,
        )
        second = results.replace_for_ride(
            club_id=club_id,
            ride_id=ride_id,
            job_id=None,
            indicators={"acc_y_wb_rms": 2.5, "vdv_y_wb": 4.0, "note": "x"},
            result_key="r.json",
            code_version="v2", uncertain_reason=None,
        )
        assert first.id == second.id
    with sessions() as s:
        result = ResultRepository(s).for_ride(ride_id)
        assert (result.acc_y_wb_rms, result.vdv_y_wb, result.vel_x_avg_kmh) == (2.5, 4.0, None)
        assert result.indicators["note"] == "x" and result.code_version == "v2"


def test_cascade_deletes_a_rides_recordings(sessions, ride_ids):
    club_id, ride_id, _ = ride_ids["A"]
    with session_scope(sessions) as s:
        RecordingRepository(s).add(
            club_id=club_id, ride_id=ride_id, camera_role="left", clip_kind="motion", path="m.mp4"
        )
    with session_scope(sessions) as s:
        s.execute(text("DELETE FROM rides WHERE id = :id"), {"id": ride_id})
    with sessions() as s:
        assert RecordingRepository(s).for_ride(ride_id) == []

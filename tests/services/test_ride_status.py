"""A ride's status is derived in one place (saddlescope.services.rides.registration): from its clips, its latest
analysis job and its result."""

from __future__ import annotations

import pytest

from saddlescope.db.enums import JobStatus, RideStatus
from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.repositories import (
    ClubRepository,
    HorseRepository,
    JobRepository,
    RecordingRepository,
    ResultRepository,
    RideRepository,
    RiderRepository,
)
from saddlescope.db.session import make_engine, make_session_factory, session_scope
from saddlescope.services.rides.registration import refresh_ride_status, ride_status


@pytest.mark.parametrize(
    ("clips_complete", "analysis", "analysed", "expected"),
    [
        (False, None, False, RideStatus.NEW),
        (True, None, False, RideStatus.READY),
        (True, JobStatus.QUEUED, False, RideStatus.READY),  # waiting for a worker
        (True, JobStatus.RUNNING, False, RideStatus.PROCESSING),
        (True, JobStatus.RUNNING, True, RideStatus.PROCESSING),  # a re-analysis
        (True, JobStatus.DONE, True, RideStatus.ANALYSED),
        (True, JobStatus.QUEUED, True, RideStatus.ANALYSED),  # the earlier result still stands
        (True, JobStatus.FAILED, False, RideStatus.FAILED),
        (True, JobStatus.FAILED, True, RideStatus.FAILED),  # the latest analysis is what shows
        (True, JobStatus.CANCELLED, False, RideStatus.FAILED),
        (False, None, True, RideStatus.ANALYSED),
    ],
)
def test_the_status_rule(clips_complete, analysis, analysed, expected):
    assert ride_status(clips_complete=clips_complete, analysis=analysis, analysed=analysed) is expected


@pytest.fixture
def sessions(tmp_path):
    url = f"sqlite:///{tmp_path / 'db' / 'test.db'}"
    upgrade_to_head(url)
    engine = make_engine(url)
    yield make_session_factory(engine)
    engine.dispose()


def _status(sessions, ride_id: int) -> str:
    with session_scope(sessions) as s:
        refresh_ride_status(s, ride_id)
    with session_scope(sessions) as s:
        return RideRepository(s).get(ride_id).status


def test_a_ride_through_clips_jobs_and_results(sessions):
    with session_scope(sessions) as s:
        club = ClubRepository(s).get_or_create("A")
        horse = HorseRepository(s, club_id=club.id).add(name="Horse")
        rider = RiderRepository(s, club_id=club.id).add(name="Rider")
        ride_id = RideRepository(s, club_id=club.id).add(
            horse_id=horse.id, rider_id=rider.id, gait="walk", direction="CW"
        ).id
    assert _status(sessions, ride_id) == "new"
    with session_scope(sessions) as s:
        for kind in ("calibration", "static", "motion"):
            for camera in ("left", "middle", "right"):
                RecordingRepository(s).add(
                    club_id=club.id, ride_id=ride_id, camera_role=camera, clip_kind=kind, path=f"{kind}/{camera}"
                )
    assert _status(sessions, ride_id) == "ready"
    with session_scope(sessions) as s:
        first = JobRepository(s).add(kind="analyze", club_id=club.id, ride_id=ride_id).id
        JobRepository(s).add(kind="probe", club_id=club.id, ride_id=ride_id)  # not an analysis: ignored
    assert _status(sessions, ride_id) == "ready"
    with session_scope(sessions) as s:
        JobRepository(s).mark_running(first, host="test", code_version="test")
    assert _status(sessions, ride_id) == "processing"
    with session_scope(sessions) as s:
        JobRepository(s).finish(first, JobStatus.FAILED, error="no marker found")
    assert _status(sessions, ride_id) == "failed"
    with session_scope(sessions) as s:
        second = JobRepository(s).add(kind="analyze", club_id=club.id, ride_id=ride_id).id
        JobRepository(s).mark_running(second, host="test", code_version="test")
        ResultRepository(s).replace_for_ride(
            club_id=club.id, ride_id=ride_id, job_id=second, indicators={}, result_key="r.json",
            code_version="test", uncertain_reason=None,
        )
        JobRepository(s).finish(second, JobStatus.DONE)
    assert _status(sessions, ride_id) == "analysed"


def test_an_unknown_ride_has_no_status(sessions):
    with session_scope(sessions) as s:
        assert refresh_ride_status(s, 12345) is None and refresh_ride_status(s, None) is None


def test_a_rides_status_follows_its_rigs_clips_and_calibration(sessions):
    """A ride filmed with a rig needs the rig's calibration clips or its calibration: when they arrive (or the
    calibration goes) the ride's status follows at once, not at the ride's next change."""
    from saddlescope.db.repositories import RigRepository
    from saddlescope.services.rides.registration import refresh_rig_rides_status

    with session_scope(sessions) as s:
        club = ClubRepository(s).get_or_create("B")
        horse = HorseRepository(s, club_id=club.id).add(name="Horse")
        rider = RiderRepository(s, club_id=club.id).add(name="Rider")
        rig = RigRepository(s, club_id=club.id).add(name="Monday")
        rides = RideRepository(s, club_id=club.id)
        ride_ids = [rides.add(horse_id=horse.id, rider_id=rider.id, gait="walk", direction="CW", rig_id=rig.id).id
                    for _ in range(2)]
        other = rides.add(horse_id=horse.id, rider_id=rider.id, gait="walk", direction="CW").id
        for ride_id in ride_ids:
            for kind in ("static", "motion"):
                for camera in ("left", "middle", "right"):
                    RecordingRepository(s).add(club_id=club.id, ride_id=ride_id, camera_role=camera,
                                               clip_kind=kind, path=f"{ride_id}/{kind}/{camera}")
        for ride_id in (*ride_ids, other):
            refresh_ride_status(s, ride_id)
    with session_scope(sessions) as s:
        assert [RideRepository(s).get(r).status for r in ride_ids] == ["new", "new"]  # no calibration yet
    with session_scope(sessions) as s:
        RigRepository(s).set_calibration(rig.id, {"cameras": {}}, {})
        refresh_rig_rides_status(s, rig.id)
    with session_scope(sessions) as s:
        assert [RideRepository(s).get(r).status for r in ride_ids] == ["ready", "ready"]
        assert RideRepository(s).get(other).status == "new"  # another rig's (none): untouched
    with session_scope(sessions) as s:
        RigRepository(s).clear_calibration(rig.id)
        refresh_rig_rides_status(s, rig.id)
    with session_scope(sessions) as s:
        assert [RideRepository(s).get(r).status for r in ride_ids] == ["new", "new"]
        refresh_rig_rides_status(s, None)  # no rig: nothing to do

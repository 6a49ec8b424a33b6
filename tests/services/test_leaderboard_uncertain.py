"""Rides too uncertain for a decision stay out of the leaderboard by default: shown, marked, with the reason
(issue 27; services/comparisons/analytics.py, results.uncertain_reason of migration 0009_intervals)."""

from __future__ import annotations

import pytest

from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.repositories import (
    ClubRepository,
    HorseRepository,
    ResultRepository,
    RideRepository,
    RiderRepository,
)
from saddlescope.db.session import make_engine, make_session_factory, session_scope
from saddlescope.services.comparisons.analytics import club_leaderboard

REASON = "the W_b r.m.s. is known only to ±19 % (95 % interval 3.4-5.0 m/s²; a decision needs ±10 %)"


@pytest.fixture
def club_with_an_uncertain_ride(tmp_path):
    url = f"sqlite:///{tmp_path / 'db.sqlite'}"
    upgrade_to_head(url)
    engine = make_engine(url)
    sessions = make_session_factory(engine)
    with session_scope(sessions) as s:
        club = ClubRepository(s).add("Club").id
        rider = RiderRepository(s, club_id=club).add(name="Rider").id
        rides = {}
        horses = {name: HorseRepository(s, club_id=club).add(name=name).id for name in ("Ajax", "Bella")}
        # Ajax: 4.0 (good) and 9.0 (too uncertain); Bella 5.0 (good)
        for horse_name, value, reason in (("Ajax", 4.0, None), ("Ajax", 9.0, REASON), ("Bella", 5.0, None)):
            ride = RideRepository(s, club_id=club).add(horse_id=horses[horse_name], rider_id=rider, gait="canter",
                                                       direction="CW")
            ResultRepository(s).replace_for_ride(club_id=club, ride_id=ride.id, job_id=None,
                                                 indicators={"acc_y_wb_rms": value}, result_key=None,
                                                 code_version=None, uncertain_reason=reason)
            rides[(horse_name, value)] = ride.id
    yield sessions, club, rides
    engine.dispose()


def test_an_uncertain_ride_is_left_out_shown_and_marked(club_with_an_uncertain_ride):
    sessions, club, rides = club_with_an_uncertain_ride
    with session_scope(sessions) as s:
        board = club_leaderboard(s, club_id=club, gait="canter", indicator="acc_y_wb_rms")
    assert [(e["horse"], e["n"], e["mean"], e["uncertain_rides"]) for e in board["entries"]] == [
        ("Ajax", 1, 4.0, 0), ("Bella", 1, 5.0, 0)]
    assert board["rides"] == 2 and board["include_uncertain"] is False
    assert board["uncertain"] == [{"ride_id": rides[("Ajax", 9.0)], "horse_id": board["entries"][0]["horse_id"],
                                   "horse": "Ajax", "value": 9.0, "reason": REASON, "included": False}]


def test_include_uncertain_ranks_it_and_marks_the_horse(club_with_an_uncertain_ride):
    sessions, club, _ = club_with_an_uncertain_ride
    with session_scope(sessions) as s:
        board = club_leaderboard(s, club_id=club, gait="canter", indicator="acc_y_wb_rms", include_uncertain=True)
    # Ajax's mean is now (4 + 9) / 2 = 6.5: Bella first
    assert [(e["horse"], e["n"], e["mean"], e["uncertain_rides"]) for e in board["entries"]] == [
        ("Bella", 1, 5.0, 0), ("Ajax", 2, 6.5, 1)]
    assert board["uncertain"][0]["included"] is True and board["rides"] == 3

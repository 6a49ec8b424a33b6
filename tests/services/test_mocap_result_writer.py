"""A motion-capture ride is stored through the one result writer (`services.results.documents.commit_result`), so a
result the analysis marks too uncertain is never ranked on the leaderboard (issue 34: the mocap path
skipped the uncertainty reason and its ride came first, seen in the browser)."""

from __future__ import annotations

from datetime import date

import numpy as np
import pytest

from saddlescope.db.migrate import upgrade_to_head
from saddlescope.db.repositories import ClubRepository, HorseRepository, ResultRepository, RiderRepository
from saddlescope.db.session import make_engine, make_session_factory, session_scope
from saddlescope.io.mocap import write_trc
from saddlescope.services.analysis.mocap import MocapChoice, store_mocap_ride
from saddlescope.services.comparisons.analytics import club_leaderboard
from saddlescope.services.results.documents import series_key
from saddlescope.storage.files import FileStorage


def _cantering_triad_trc(path, *, noise_m: float, seconds: float = 3.0, rate_hz: float = 100.0):
    """Three markers on a body cantering at 3 m/s, 0.7 s strides, with Gaussian noise of ``noise_m``."""
    t = np.arange(int(seconds * rate_hz)) / rate_hz
    w = 2 * np.pi / 0.7
    body = np.array([[0.25, 0.0, 0.1], [-0.25, 0.02, 0.1], [0.0, -0.08, -0.12]])  # x forward, y up
    centre = np.stack([3.0 * t, 1.2 + 0.03 * np.cos(w * t) + 0.01 * np.cos(2 * w * t), 0.01 * np.sin(w * t)], axis=1)
    points = centre[:, None, :] + body[None] + np.random.default_rng(3).normal(0, noise_m, (len(t), 3, 3))
    return write_trc(path, ["A", "B", "C"], points, rate_hz, units="m")


@pytest.fixture
def club(tmp_path):
    url = f"sqlite:///{tmp_path / 'db.sqlite'}"
    upgrade_to_head(url)
    engine = make_engine(url)
    sessions = make_session_factory(engine)
    with session_scope(sessions) as s:
        club_id = ClubRepository(s).add("Club").id
        rider_id = RiderRepository(s, club_id=club_id).add(name="Rider").id
        horse_ids = [HorseRepository(s, club_id=club_id).add(name=name).id for name in ("Noisy", "Clean")]
    yield sessions, FileStorage(tmp_path / "store"), club_id, rider_id, horse_ids
    engine.dispose()


def _store(sessions, storage, tmp_path, *, club_id, horse_id, rider_id, noise_m):
    trc = _cantering_triad_trc(tmp_path / f"ride-{horse_id}.trc", noise_m=noise_m)
    storage.write_bytes(f"staged/{horse_id}", trc.read_bytes())
    ride = {"horse_id": horse_id, "rider_id": rider_id, "gait": "canter", "direction": "CW",
            "ridden_on": date(2026, 11, 1), "notes": ""}
    choice = MocapChoice(("A", "B", "C"), None, (0.0, 50.0, 0.0), None, None, "canter")
    return store_mocap_ride(sessions, storage, f"staged/{horse_id}", trc.name, choice, club_id=club_id, ride=ride)


def test_a_too_uncertain_mocap_ride_is_stored_as_such_and_not_ranked(club, tmp_path):
    sessions, storage, club_id, rider_id, (noisy, clean) = club
    noisy_ride = _store(sessions, storage, tmp_path, club_id=club_id, horse_id=noisy, rider_id=rider_id, noise_m=0.01)
    _store(sessions, storage, tmp_path, club_id=club_id, horse_id=clean, rider_id=rider_id, noise_m=0.0003)
    with session_scope(sessions) as s:
        row = ResultRepository(s).for_ride(noisy_ride)
        assert row.uncertain_reason and "W_b r.m.s. is known only to" in row.uncertain_reason
        assert storage.exists(series_key(row.result_key))  # the ride page's series stored with it (issue 37)
        board = club_leaderboard(s, club_id=club_id, gait="canter", indicator="acc_y_wb_rms")
    assert [e["horse"] for e in board["entries"]] == ["Clean"]
    assert [u["ride_id"] for u in board["uncertain"]] == [noisy_ride]
    assert not storage.exists(f"staged/{noisy}")

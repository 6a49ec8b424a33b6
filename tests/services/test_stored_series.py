"""Issue 37 (fast pages): the ride page's derived series (fitted curves, residuals, weighted acceleration)
are computed once when the result is stored, by the one result writer, and served from storage; a result
stored before that has them computed and stored on its first read (a lazy backfill)."""

from __future__ import annotations

import json
from datetime import date

import numpy as np
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
from saddlescope.services.results import documents as results
from saddlescope.services.results.documents import (
    DERIVED_SERIES,
    PAGE_POINTS,
    commit_result,
    page_key,
    result_view,
    series_key,
    view_of_document,
)
from saddlescope.services.results.series import DERIVED_FORMAT, derived_series
from saddlescope.storage.files import FileStorage

F0_HZ, FPS, N = 1.65, 200.0, 600


def saddle_document(scale: float = 1.0) -> dict:
    """Three seconds of a saddle point moving on at 5 m/s and bouncing at 1.65 Hz (3 harmonics)."""
    t = np.arange(N) / FPS
    amps, phases = scale * np.array([4.0, 1.5, 0.5]), np.array([0.3, -0.8, 1.2])
    w = 2 * np.pi * F0_HZ * np.arange(1, 4)[:, None]
    arg = w * t + phases[:, None]
    zeros = np.zeros_like(t)
    position = np.stack([5.0 * t, (-amps[:, None] / w**2 * np.cos(arg)).sum(0), zeros], 1)
    position += np.random.default_rng(5).normal(0.0, 0.0005, (N, 3))
    return {
        "fps": FPS, "period_s": 1 / F0_HZ, "window": {"start_s": 0.0, "duration_s": N / FPS},
        "saddle": {"t_s": t.tolist(), "position_m": position.tolist(),
                   "velocity_m_s": np.stack([np.full_like(t, 5.0), (amps[:, None] / w * np.sin(arg)).sum(0),
                                             zeros], 1).tolist(),
                   "acceleration_m_s2": np.stack([zeros, (amps[:, None] * np.cos(arg)).sum(0), zeros], 1).tolist()},
        "angular": {}, "indicators": {"rms_y_m_s2": float(scale)}, "quality": {"flags": []},
        "vertical_harmonics": {"f0_hz": F0_HZ, "amplitudes_m_s2": amps.tolist(), "phases_rad": phases.tolist()},
    }


@pytest.fixture
def ride(tmp_path):
    url = f"sqlite:///{tmp_path / 'db.sqlite'}"
    upgrade_to_head(url)
    engine = make_engine(url)
    sessions = make_session_factory(engine)
    with session_scope(sessions) as s:
        club_id = ClubRepository(s).add("Club").id
        rider_id = RiderRepository(s, club_id=club_id).add(name="Rider").id
        horse_id = HorseRepository(s, club_id=club_id).add(name="Bramble").id
        ride_id = RideRepository(s, club_id=club_id).add(horse_id=horse_id, rider_id=rider_id, gait="canter",
                                                         direction="CW", ridden_on=date(2026, 11, 1)).id
    yield sessions, FileStorage(tmp_path / "store"), club_id, ride_id
    engine.dispose()


def _view(sessions, storage, club_id, ride_id, max_points=100):
    with session_scope(sessions) as s:
        return result_view(s, storage, ride_id, club_id=club_id, max_points=max_points)


def _no_fitting(monkeypatch):
    def refuse(doc):
        raise AssertionError("the series were computed again in a read")

    monkeypatch.setattr(results, "derived_series", refuse)


def test_the_writer_stores_the_series_and_the_page_reads_them_without_fitting(ride, monkeypatch):
    sessions, storage, club_id, ride_id = ride
    doc = saddle_document()
    key = commit_result(sessions, storage, club_id=club_id, ride_id=ride_id, job_id=None, document=doc,
                        code_version="test")
    stored = json.loads(storage.read_bytes(series_key(key)))
    assert stored["format"] == DERIVED_FORMAT and stored["samples"] == N
    assert all(len(stored["series"][name]) == N for name in DERIVED_SERIES)
    want = view_of_document(doc, _row(sessions, ride_id), ride_id, 100)  # computed in full, as before
    _no_fitting(monkeypatch)
    got = _view(sessions, storage, club_id, ride_id)
    assert got["series"] == want["series"] and got["spectrum"] == want["spectrum"]
    assert all(got["series"][name] is not None and len(got["series"][name]) == 100 for name in DERIVED_SERIES)


def test_the_ride_pages_view_is_read_without_the_document(ride, monkeypatch):
    """At the ride page's PAGE_POINTS the stored page is all a read needs: not the 6.6 MB document."""
    sessions, storage, club_id, ride_id = ride
    doc = saddle_document()
    key = commit_result(sessions, storage, club_id=club_id, ride_id=ride_id, job_id=None, document=doc,
                        code_version="test")
    assert storage.exists(page_key(key))
    want = view_of_document(doc, _row(sessions, ride_id), ride_id, PAGE_POINTS)
    read, real_read = [], storage.read_bytes
    monkeypatch.setattr(storage, "read_bytes", lambda k: read.append(k) or real_read(k))
    _no_fitting(monkeypatch)
    assert _view(sessions, storage, club_id, ride_id, PAGE_POINTS) == want
    assert read == [page_key(key)]


def test_a_re_analysis_replaces_the_stored_series_with_its_own(ride, monkeypatch):
    sessions, storage, club_id, ride_id = ride
    first = commit_result(sessions, storage, club_id=club_id, ride_id=ride_id, job_id=None,
                          document=saddle_document(), code_version="test")
    second = commit_result(sessions, storage, club_id=club_id, ride_id=ride_id, job_id=None,
                           document=saddle_document(scale=2.0), code_version="test")
    assert not any(storage.exists(k) for k in (first, series_key(first), page_key(first)))
    assert storage.exists(series_key(second))
    _no_fitting(monkeypatch)
    for points in (100, PAGE_POINTS):
        spectrum = _view(sessions, storage, club_id, ride_id, points)["spectrum"]
        assert spectrum["amplitude_m_s2"] == pytest.approx([8.0, 3.0, 1.0])  # the new result's, not the old


def test_a_result_stored_before_has_its_series_computed_once_and_stored(ride, monkeypatch):
    sessions, storage, club_id, ride_id = ride
    doc, key = saddle_document(), f"rides/{ride_id}/results/older.json"
    storage.write_bytes(key, json.dumps(doc).encode())  # as results were stored before issue 37
    with session_scope(sessions) as s:
        ResultRepository(s).replace_for_ride(club_id=club_id, ride_id=ride_id, job_id=None, indicators={},
                                             result_key=key, code_version="old", uncertain_reason=None)
    assert not storage.exists(series_key(key))
    first = _view(sessions, storage, club_id, ride_id, PAGE_POINTS)
    assert json.loads(storage.read_bytes(series_key(key)))["samples"] == N and storage.exists(page_key(key))
    _no_fitting(monkeypatch)
    assert _view(sessions, storage, club_id, ride_id, PAGE_POINTS)["series"] == first["series"]
    assert _view(sessions, storage, club_id, ride_id)["series"]["position_fitted_m"]


def test_series_of_another_format_or_length_are_computed_again(ride):
    sessions, storage, club_id, ride_id = ride
    doc = saddle_document()
    key = commit_result(sessions, storage, club_id=club_id, ride_id=ride_id, job_id=None, document=doc,
                        code_version="test")
    for stale in ({**derived_series(doc), "format": DERIVED_FORMAT - 1}, {"format": DERIVED_FORMAT, "samples": 3},
                  b"{torn"):
        storage.write_bytes(series_key(key), stale if isinstance(stale, bytes) else json.dumps(stale).encode())
        assert all(_view(sessions, storage, club_id, ride_id)["series"][name] for name in DERIVED_SERIES)
        assert json.loads(storage.read_bytes(series_key(key))) == json.loads(json.dumps(derived_series(doc)))


def _row(sessions, ride_id):
    with session_scope(sessions) as s:
        row = ResultRepository(s).for_ride(ride_id)
        s.expunge(row)
        return row

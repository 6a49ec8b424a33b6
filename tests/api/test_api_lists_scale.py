"""10,000 rides on PostgreSQL: the rides and jobs lists answer every filter and sort with the right
totals, and their timings are printed (measured, not asserted: the machine is shared).

Rides, results and jobs are inserted in bulk with SQL into a club registered over the API, then read
through GET /api/rides and /api/jobs as the dashboard reads them. `pytest -s` shows the table.
"""

from __future__ import annotations

import statistics
import time

import integration_services
import pytest
from api_helpers import new_club
from engines import open_env
from sqlalchemy import text

from saddlescope.db.session import make_engine

pg_database_url = integration_services.pg_database_url
redis_url = integration_services.redis_url

pytestmark = [pytest.mark.integration, pytest.mark.slow]

N_RIDES, N_JOBS = 10_000, 3_000
GAITS = ("walk", "sitting_trot", "rising_trot", "canter")
STATUSES = ("new", "ready", "analysed", "failed")


@pytest.fixture(scope="module")
def env(request, tmp_path_factory):
    request.param = "celery"
    yield from open_env(request, tmp_path_factory, worker=False)


@pytest.fixture(scope="module")
def club(env):
    api, who = new_club(env.client)
    club_id = who["club"]["id"]
    horses = [api.ok("POST", "/horses", 201, json={"name": f"Horse {i}"})["id"] for i in range(20)]
    riders = [api.ok("POST", "/riders", 201, json={"name": f"Rider {i}"})["id"] for i in range(10)]
    engine = make_engine(env.settings.database_url)
    try:
        with engine.begin() as conn:
            conn.execute(text(
                "INSERT INTO rides (club_id, horse_id, rider_id, gait, direction, status, notes, meta, ridden_on, "
                "created_at) SELECT :club, (CAST(:horses AS int[]))[1 + i % 20], (CAST(:riders AS int[]))[1 + i % 10], "
                "(ARRAY['walk','sitting_trot','rising_trot','canter'])[1 + (i / 7) % 4], "
                "CASE WHEN i % 2 = 0 THEN 'CW' ELSE 'CCW' END, "
                "(ARRAY['new','ready','analysed','failed'])[1 + (i / 3) % 4], '', '{}', "
                "DATE '2020-01-01' + (i % 2000), now() FROM generate_series(0, :n - 1) AS i"),
                {"club": club_id, "horses": horses, "riders": riders, "n": N_RIDES})
            conn.execute(text(
                "INSERT INTO results (club_id, ride_id, indicators, acc_y_wb_rms, vdv_y_wb, created_at) "
                "SELECT club_id, id, json_build_object('acc_y_wb_rms', (id % 97) / 10.0), (id % 97) / 10.0, "
                "(id % 89) / 10.0, now() FROM rides WHERE club_id = :club AND status = 'analysed'"),
                {"club": club_id})
            conn.execute(text(
                "INSERT INTO jobs (club_id, ride_id, kind, status, progress, payload, timings, attempts, created_at) "
                "SELECT :club, r.id, 'analyze', (ARRAY['done','failed','queued','cancelled'])[1 + r.id % 4], "
                "0, '{}', '{}', 1, now() FROM rides r WHERE r.club_id = :club ORDER BY r.id LIMIT :n"),
                {"club": club_id, "n": N_JOBS})
            conn.execute(text("ANALYZE"))
    finally:
        engine.dispose()
    return {"api": api, "horses": horses, "riders": riders}


def _timed(api, path: str, params: dict, repeats: int = 5) -> tuple[dict, float]:
    api.ok("GET", path, params=params)  # warm
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        answer = api.ok("GET", path, params=params)
        times.append(time.perf_counter() - t0)
    return answer, statistics.median(times) * 1000


def test_ten_thousand_rides_page_filter_and_sort_with_the_right_totals(club, capsys):
    api, horse = club["api"], club["horses"][3]
    cases = [
        ("/rides", {}, N_RIDES),
        ("/rides", {"offset": N_RIDES - 50}, N_RIDES),
        ("/rides", {"horse_id": horse}, N_RIDES // 20),
        ("/rides", {"rider_id": club["riders"][2], "sort": "ridden_on"}, N_RIDES // 10),
        ("/rides", {"gait": "canter", "sort": "-created_at"}, None),
        ("/rides", {"status": "analysed"}, None),
        ("/rides", {"date_from": "2021-01-01", "date_to": "2021-12-31"}, None),
        ("/rides", {"sort": "acc_y_wb_rms"}, N_RIDES),
        ("/rides", {"sort": "-vdv_y_wb", "gait": "walk"}, None),
        ("/rides", {"horse_id": horse, "gait": "walk", "status": "analysed", "sort": "-ridden_on"}, None),
        ("/jobs", {}, N_JOBS),
        ("/jobs", {"status": "failed"}, N_JOBS // 4),
        ("/jobs", {"kind": "analyze", "offset": 2900}, N_JOBS),
        ("/horses", {"q": "Horse 1"}, 11),
    ]
    lines = []
    for path, params, expected in cases:
        answer, ms = _timed(api, path, {"limit": 50, **params})
        if expected is not None:
            assert answer["total"] == expected, (path, params, answer["total"])
        assert len(answer["items"]) == min(50, answer["total"] - params.get("offset", 0))
        lines.append(f"{ms:8.1f} ms  total {answer['total']:>6}  GET /api{path} {params}")
    with capsys.disabled():
        print(f"\nList requests over HTTP (TestClient) with {N_RIDES} rides and {N_JOBS} jobs on PostgreSQL, "
              "median of 5:")
        print("\n".join(lines))

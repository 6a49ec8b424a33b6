"""`saddlescope bench`'s dashboard part in a quick size: it runs end to end and reports its five times
to interactive under their keys (the numbers are printed by the benchmark, never asserted: the machine
is shared). Where Debian's chromium is absent the keys are None and the reason is said."""

from __future__ import annotations

import pytest
from sqlalchemy import create_engine, text

from saddlescope.bench import TTI_KEYS
from saddlescope.bench import dashboard as dashboard_bench


@pytest.mark.slow
def test_quick_dashboard_benchmark_reports_its_keys():
    out = dashboard_bench.dashboard_tti(200, samples=1_000, repeats=1)
    assert set(TTI_KEYS) <= set(out) and out["rides"] == 200 and "navigation start" in out["definition"]
    if out.get("skipped"):
        assert "chromium" in out["skipped"] or "playwright" in out["skipped"]
        assert all(out[key] is None for key in TTI_KEYS)
    else:
        assert out["database"].split()[0] in ("PostgreSQL", "SQLite")
        for key in TTI_KEYS:  # a number, or the reason it could not be measured
            name = key.removeprefix("tti_").removesuffix("_s")
            assert isinstance(out[key], float) or "error" in out[f"detail_{name}"], out


def test_the_pages_with_charts_have_a_goal_of_two_seconds_and_the_lists_one():
    assert set(TTI_KEYS) == {"tti_rides_list_s", "tti_leaderboard_s", "tti_ride_page_s", "tti_horse_page_s",
                             "tti_compare_s"}
    assert dashboard_bench._goal_s("tti_horse_page_s") == dashboard_bench._goal_s("tti_compare_s") == 2.0
    assert dashboard_bench._goal_s("tti_ride_page_s") == 2.0 and dashboard_bench._goal_s("tti_rides_list_s") == 1.0


@pytest.mark.slow
def test_without_postgresql_the_benchmark_uses_sqlite_and_says_why(monkeypatch, tmp_path):
    monkeypatch.setenv("SADDLESCOPE_BENCH_DATABASE_URL", "postgresql+psycopg://nobody@127.0.0.1:9/none")
    with dashboard_bench.bench_database(tmp_path) as (url, database):
        assert url.startswith("sqlite:///") and database.startswith("SQLite (PostgreSQL not reachable")
        with create_engine(url).connect() as conn:  # migrated, with the bench club
            assert conn.execute(text("select name from clubs")).scalars().all() == ["Bench club"]


def test_saddlescope_bench_puts_the_three_times_at_the_top_of_its_json(monkeypatch):
    import saddlescope.bench as bench

    monkeypatch.setattr(bench._analysis, "calibration_section", lambda tmp, quick: {"calibration_3cams_s": 1.0})
    monkeypatch.setattr(bench, "SECTIONS", tuple(
        bench.BenchSection(s.name, s.summary, bench._analysis.calibration_section if s.name == "calibration" else s.run)
        for s in bench.SECTIONS if s.name in ("calibration", "dashboard")))
    monkeypatch.setattr(bench, "run_dashboard_benchmarks", lambda quick: {
        "tti_rides_list_s": 0.4, "tti_leaderboard_s": 0.5, "tti_ride_page_s": None, "tti_horse_page_s": 1.5,
        "tti_compare_s": 1.2, "database": "SQLite", "skipped": None})
    out = bench.run_benchmarks(quick=True)
    assert (out["tti_rides_list_s"], out["tti_leaderboard_s"], out["tti_ride_page_s"]) == (0.4, 0.5, None)
    assert (out["tti_horse_page_s"], out["tti_compare_s"]) == (1.5, 1.2)
    assert out["calibration_3cams_s"] == 1.0 and out["dashboard"]["database"] == "SQLite"
    assert not set(bench.TTI_KEYS) & set(out["dashboard"])

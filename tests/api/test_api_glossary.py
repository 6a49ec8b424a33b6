"""GET /api/glossary: one typed entry per code a page may meet (indicators, gaits, job kinds, gravity
sources, comparison methods), open without signing in; and the grades' correlation withheld on fewer
than five points (services/comparisons/analytics.py)."""

from __future__ import annotations

import pytest
from engines import open_env

from saddlescope.core.vibration import COMFORT_INDICATORS, GAITS, INDICATORS
from saddlescope.services.comparisons.analytics import MIN_CORRELATION_POINTS, _withhold_correlation_on_few_points
from saddlescope.services.jobs.stages import JOB_KINDS


@pytest.fixture(scope="module", params=["embedded"])
def env(request, tmp_path_factory):
    yield from open_env(request, tmp_path_factory, worker=False)


def test_the_glossary_names_every_code_a_page_shows_without_signing_in(env):
    answer = env.client.get("/api/glossary")
    assert answer.status_code == 200, answer.text
    entries = answer.json()
    by_kind: dict[str, dict[str, dict]] = {}
    for e in entries:
        assert set(e) == {"kind", "code", "label", "unit", "short", "expert"}
        assert e["code"] not in by_kind.setdefault(e["kind"], {}), f"{e['kind']} {e['code']} twice"
        by_kind[e["kind"]][e["code"]] = e
    assert set(by_kind["indicator"]) == set(INDICATORS) and set(by_kind["gait"]) == set(GAITS)
    assert set(by_kind["job_kind"]) == set(JOB_KINDS)
    assert by_kind["gravity_source"]["lab_vertical"]["label"] == "the lab's vertical axis"
    assert by_kind["similarity_method"]["dtw"]["label"].startswith("shape of the stride")
    assert by_kind["job_kind"]["analyze"]["label"] == "Ride analysis"
    assert by_kind["gait"]["sitting_trot"]["label"] == "sitting trot"
    # the headline numbers are the eight comfort indicators; MTVV, the W_d axes etc. are expert detail
    assert {k for k, e in by_kind["indicator"].items() if not e["expert"]} == set(COMFORT_INDICATORS)
    assert by_kind["indicator"]["mtvv_y_wb"]["expert"] and by_kind["indicator"]["acc_x_wd_rms"]["expert"]
    assert by_kind["indicator"]["acc_y_wb_rms"]["unit"] == "m/s^2"
    for e in entries:  # a label is words, never the code itself (a one-word code may be its own label)
        assert e["label"] and ("_" not in e["label"] or "W_" in e["label"]), e
        if e["kind"] == "indicator":
            assert e["short"], e


@pytest.mark.parametrize("n", [2, 4])
def test_a_correlation_on_fewer_than_five_points_is_withheld_with_its_reason(n):
    stats = {"n": n, "pearson_r": -1.0, "pearson_p": 0.0, "pearson_ci_low": -1.0, "spearman_rho": -1.0,
             "expected_sign": -1}
    _withhold_correlation_on_few_points(stats)
    assert stats["pearson_r"] is None and stats["spearman_rho"] is None and stats["pearson_ci_low"] is None
    assert stats["withheld_reason"] == (f"needs at least {MIN_CORRELATION_POINTS} graded horse-gait pairs to "
                                        f"show a correlation ({n} so far)")
    assert stats["expected_sign"] == -1


def test_a_correlation_on_five_points_is_shown():
    stats = {"n": 5, "pearson_r": -0.8, "spearman_rho": -0.7}
    _withhold_correlation_on_few_points(stats)
    assert stats["pearson_r"] == -0.8 and stats["spearman_rho"] == -0.7 and stats["withheld_reason"] is None

"""The ride page's derived series on a long recording: 10,000 samples are fitted in full and served
decimated, every series aligned with the drawn times; the weighted acceleration is the core's."""

from __future__ import annotations

import datetime as dt
import time
import types

import numpy as np
import pytest

from saddlescope.core.vibration import harmonic_metrics
from saddlescope.services.results.documents import DERIVED_SERIES, view_of_document
from saddlescope.services.results.series import DERIVED, derived_series, fitted_saddle_series, weighted_series

F0_HZ, FPS, N = 1.65, 500.0, 10_000
AMPS, PHASES = (4.0, 1.5, 0.5), (0.3, -0.8, 1.2)


def long_document() -> dict:
    t = np.arange(N) / FPS
    w = 2 * np.pi * F0_HZ * np.arange(1, 4)[:, None]
    arg = w * t + np.asarray(PHASES)[:, None]
    a = np.asarray(AMPS)[:, None]
    pos_y = (-a / w**2 * np.cos(arg)).sum(0)
    vel_y = (a / w * np.sin(arg)).sum(0)
    acc_y = (a * np.cos(arg)).sum(0)
    zeros = np.zeros_like(t)
    noise = np.random.default_rng(5).normal(0.0, 0.0005, (N, 3))
    position = np.stack([5.0 * t, pos_y, zeros], 1) + noise
    return {
        "fps": FPS, "period_s": 1 / F0_HZ, "window": {"start_s": 0.0, "duration_s": N / FPS},
        "saddle": {"t_s": t.tolist(), "position_m": position.tolist(),
                   "velocity_m_s": np.stack([np.full_like(t, 5.0), vel_y, zeros], 1).tolist(),
                   "acceleration_m_s2": np.stack([zeros, acc_y, zeros], 1).tolist()},
        "angular": {}, "indicators": {}, "quality": {"flags": []},
        "vertical_harmonics": {"f0_hz": F0_HZ, "amplitudes_m_s2": list(AMPS), "phases_rad": list(PHASES)},
    }


@pytest.mark.slow
def test_ten_thousand_samples_are_fitted_in_full_and_served_decimated():
    doc = long_document()
    row = types.SimpleNamespace(job_id=1, code_version="test", created_at=dt.datetime.now(dt.UTC))
    start = time.perf_counter()
    view = view_of_document(doc, row, ride_id=1, max_points=2000)
    assert time.perf_counter() - start < 60  # a few seconds on an idle machine; cached per result after
    series = view["series"]
    n = len(series["t_s"])
    assert n == 2000
    for name in DERIVED_SERIES:
        assert series[name] is not None and len(series[name]) == n, name
    residual_y = np.array([r[1] for r in series["position_residual_m"]], dtype=float)
    # the residual is the tracking noise (0.5 mm) and at most the third harmonic the order rule may drop
    # (0.5 mm amplitude in position): well under a millimetre, never the stride itself (38 mm)
    assert 0.0004 < np.nanstd(residual_y) < 0.001


def test_the_weighted_series_has_the_cores_harmonic_rms():
    doc = long_document()
    period = 1 / F0_HZ
    t = np.linspace(0.0, 2 * period, 4001)[:-1]
    series, spectrum = weighted_series(doc, t.tolist())
    for suffix, name in (("wb", "Wb"), ("wk", "Wk")):
        want = harmonic_metrics(F0_HZ, AMPS, PHASES, name, 2 * period)["rms"]
        assert np.sqrt(np.mean(np.square(series[f"acc_y_{suffix}_m_s2"]))) == pytest.approx(want, rel=1e-6)
    assert spectrum["frequency_hz"] == pytest.approx([F0_HZ, 2 * F0_HZ, 3 * F0_HZ])


def test_a_result_without_a_track_gives_no_derived_series():
    assert fitted_saddle_series({"saddle": {}}) == {}
    assert weighted_series({"saddle": {}}, []) == ({}, None)


def test_the_series_computed_are_the_declared_ones_and_the_api_serves_each():
    """A new series is its computation and its declaration (DERIVED); the view and ResultSeries follow from it."""
    from saddlescope.api.schemas import ResultSeries

    doc = long_document()
    doc["saddle"] = {key: values[:1500] for key, values in doc["saddle"].items()}  # ten strides: quick to fit
    computed = derived_series(doc)["series"]
    assert sorted(computed) == sorted(DERIVED_SERIES) and all(len(computed[name]) == 1500 for name in computed)
    fields = ResultSeries.model_fields
    assert all(fields[s.name].description == s.description for s in DERIVED)


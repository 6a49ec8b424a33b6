"""The horse's own normal band (services.normal_band): mean ± 2 SD of earlier rides, from 4 rides on."""

from __future__ import annotations

import datetime as dt
import math

import pytest

from saddlescope.services.normal_band import band_of, normal_bands_before


def test_band_needs_four_rides_and_uses_the_sample_sd():
    assert band_of([1.0, 2.0, 3.0]) is None
    band = band_of([1.0, 2.0, 3.0, 4.0, float("nan"), None])
    sd = math.sqrt(sum((v - 2.5) ** 2 for v in (1, 2, 3, 4)) / 3)
    assert band["n"] == 4 and band["mean"] == pytest.approx(2.5) and band["sd"] == pytest.approx(sd)
    assert band["low"] == pytest.approx(2.5 - 2 * sd) and band["high"] == pytest.approx(2.5 + 2 * sd)


def test_band_is_taken_over_earlier_rides_only():
    day = dt.date(2026, 1, 1)
    history = [{"ride_id": i, "date": day + dt.timedelta(days=i), "indicators": {"acc_y_wb_rms": float(i)}}
               for i in range(1, 7)]
    assert normal_bands_before(history, 4, ["acc_y_wb_rms"])["acc_y_wb_rms"] is None  # 3 earlier
    band = normal_bands_before(history, 6, ["acc_y_wb_rms"])["acc_y_wb_rms"]
    assert band["n"] == 5 and band["mean"] == pytest.approx(3.0)
    # a ride not analysed yet is compared with the whole history
    assert normal_bands_before(history, 99, ["acc_y_wb_rms"])["acc_y_wb_rms"]["n"] == 6

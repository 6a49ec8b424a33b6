"""The horse's own normal band (services.horses.normal_band): mean ± 2 SD of earlier rides, from 4 rides on."""

from __future__ import annotations

import datetime as dt
import math
import statistics

import pytest

from saddlescope.services.horses.normal_band import band_of, normal_bands_before, page_band


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


def test_the_page_band_is_the_horses_own_from_five_rides_with_its_edges_uncertainty():

    own = [1.0, 1.1, 1.2, 0.9, 1.0]
    band = page_band(own, [5.0] * 10, horses_in_club=3)
    assert band["source"] == "horse" and band["n"] == 5
    assert band["reason"] == "from this horse's own 5 rides in this gait"
    sd = statistics.stdev(own)
    # edge = mean ± 2 SD; its 95 % half-width 1.96 * SD * sqrt(1/n + 4/(2(n-1))) = 1.96 * SD * sqrt(0.7)
    half = 1.959964 * sd * (1 / 5 + 4 / 8) ** 0.5
    assert band["low_interval_95"] == pytest.approx([band["low"] - half, band["low"] + half])
    assert band["high_interval_95"] == pytest.approx([band["high"] - half, band["high"] + half])


def test_with_fewer_rides_the_page_band_is_the_clubs_and_says_so():

    band = page_band([1.0], [0.8, 1.2, 1.0, 0.9, 1.1, None], horses_in_club=2)
    assert band["source"] == "club" and band["n"] == 5 and band["horses"] == 2
    assert band["reason"] == ("from the club's 2 other horses in this gait (5 rides): this horse has 1 of the 5 rides "
                              "its own band needs")
    assert band["low"] < 1.0 < band["high"]
    assert page_band([1.0], [0.8, 1.2], horses_in_club=1) is None  # too few rides anywhere: no band

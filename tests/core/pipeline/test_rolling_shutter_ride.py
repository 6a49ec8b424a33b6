"""A ride filmed by phones with a rolling shutter (issue 38, item 3): readout measured, sync and speed right.

Rows exposed top to bottom over 25 ms at 30 fps (three quarters of a frame): the flash sweeps down the rows
of every clip and each marker is seen at its row's instant. Seed 4103: used by no other test nor the bench.
"""

from __future__ import annotations

import json

import pytest

from saddlescope.arena import RenderOptions

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def rolling_ride(tmp_path_factory):
    from rendered_rides import cached_ride_bundle

    from saddlescope.services.analysis.ride_bundle import analyze_bundle

    out = cached_ride_bundle(tmp_path_factory.mktemp("rolling") / "ride", gait="canter", seed=4103, rig="thesis",
                             duration_s=3.0, calibration_poses=30, extras=False,
                             options=RenderOptions(readout_s=0.025))
    return analyze_bundle(out), json.loads((out / "truth.json").read_text())


def test_the_readout_is_measured_from_the_flash_sweep(rolling_ride):
    doc, _ = rolling_ride
    for kind in ("calibration", "static", "motion"):
        sync = doc["quality"]["sync"][kind]
        assert set(sync["readout_source"].values()) == {"flash sweep"}, kind
        for cam, ms in sync["readout_ms"].items():
            # within three of its own standard errors (0.5-0.8 ms at 640x480) and a band's quantisation
            assert abs(ms - 25.0) <= 3 * sync["readout_sigma_ms"][cam] + 0.8, (kind, cam)


def test_sync_and_speed_with_a_rolling_shutter(rolling_ride):
    doc, truth = rolling_ride
    for kind in ("calibration", "static", "motion"):
        for cam, offset in truth["sync"][kind].items():
            assert abs(doc["sync"][kind][cam] - offset) < 0.05, (kind, cam)
    # +0.76 % on this short ride with a 30-pose calibration (the bench's 60-pose rides: -0.03 % and +0.06 %);
    # the issue measured -1.1 % before the row delays
    assert abs(doc["indicators"]["vel_x_avg_kmh"] / truth["truth"]["speed_kmh"] - 1) < 0.01

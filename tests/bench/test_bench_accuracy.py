"""`saddlescope bench`'s accuracy loop, without rendering: every ride of the loop is drawn with the
clip length asked for (the loop once passed the previous ride's analysed window on to the next
rides, whose clips came out too short for two strides), and a perfect analysis reads no error."""

from __future__ import annotations

import dataclasses
import json

import pytest

from saddlescope import bench
from saddlescope.arena import RenderOptions, build_scene, build_truth


def test_every_ride_of_the_accuracy_loop_gets_the_clip_length_asked_for(monkeypatch, tmp_path):
    asked: list[tuple[str, float | None]] = []

    def write_ride_bundle(ride, *, gait, seed, rig, duration_s=None, extras=True, options=None):
        asked.append((gait, duration_s))
        # nothing is rendered here: no textured backgrounds (truth.json does not depend on them)
        scene = build_scene(gait=gait, seed=seed, rig=rig, duration_s=duration_s, extras=False, calibration_poses=4,
                            options=dataclasses.replace(options or RenderOptions(), textured_background=False))
        ride.mkdir(parents=True)
        (ride / "truth.json").write_text(json.dumps(build_truth(scene)))
        return ride

    def analyze_bundle(ride):  # the exact answer: truth.json is in the result format
        return json.loads((ride / "truth.json").read_text())

    monkeypatch.setattr("saddlescope.io.synth_writer.write_ride_bundle", write_ride_bundle)
    monkeypatch.setattr("saddlescope.services.analysis.ride_bundle.analyze_bundle", analyze_bundle)
    rows = bench.accuracy(tmp_path, rig="thesis", gaits=("sitting_trot", "canter"), seeds=(1,))
    assert asked == [("sitting_trot", None), ("canter", None)]
    for row in rows:
        assert "error" not in row
        assert row["acc_y_rms_error_pct_of_rms"] == pytest.approx(0.0, abs=1e-6)
        assert row["acc_y_wb_rms_error_pct"] == pytest.approx(0.0, abs=1e-6)
        assert row["vdv_y_wb_error_pct"] == pytest.approx(0.0, abs=1e-6)

"""Rides of several passes in the arena (issue 38): the horse crosses the view, leaves it, comes back."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.arena import GaitModel, build_scene, build_truth, visible_in
from saddlescope.arena.scene import PASS_GAP_S, PASS_SPEED_SHARE
from saddlescope.core.errors import InputError

KW = {"gait": "canter", "seed": 4, "rig": "wide", "size": (640, 360), "fps": 30, "calibration_poses": 1,
      "extras": False}


def test_one_pass_is_the_ride_it_always_was():
    one, default = build_scene(**KW, passes=1), build_scene(**KW)
    assert one.model.passes == default.model.passes == ()
    assert one.timings["motion"].n_left == default.timings["motion"].n_left
    assert one.model.t_cross_s == default.model.t_cross_s
    assert "passes" not in build_truth(default)["truth"]


def test_three_passes_leave_the_view_between_and_keep_the_stride():
    scene = build_scene(**KW, passes=3)
    truth = build_truth(scene)["truth"]
    crossings = np.array([c for c, _ in scene.model.passes])
    speeds = np.array([v for _, v in scene.model.passes])
    assert len(truth["passes"]) == 3 and np.all(np.diff(crossings) > 0)
    assert np.all(np.abs(speeds / speeds[0] - 1) <= PASS_SPEED_SHARE)
    assert truth["speed_m_s"] == pytest.approx(speeds.mean())
    # every pass is in the rig's common view for more than a stride, and the window is in the first
    for p in truth["passes"]:
        assert p["strides_in_view"] > 1
    assert truth["passes"][0]["in_view_s"][0] <= scene.window_start_s <= truth["passes"][0]["in_view_s"][1]
    # between two passes no camera sees a marker for PASS_GAP_S
    t = scene.timings["motion"].left_times
    seen = visible_in(scene.views, scene.model.marker_positions(t, skin=False)[:, :3] @ scene.m_dir.T, 1)
    for a, b in zip(crossings[:-1], crossings[1:], strict=True):
        between = (t > a) & (t < b)
        assert (~seen[between]).sum() / scene.fps >= PASS_GAP_S - 2 / scene.fps
    # the same horse: the saddle's motion (all but the travel) repeats across the passes' change
    m = scene.model
    mid = 0.5 * (crossings[0] + crossings[1])
    t_k = np.array([mid - 3 * m.period_s, mid + 3 * m.period_s])
    y = m.point(m.body_points_m["saddle"], t_k, derivative=2)[:, 1]
    assert y[0] == pytest.approx(y[1], abs=1e-9)
    # out of view the horse waits at the travel's reach: never far along the track (near a camera's image plane)
    assert np.all(np.abs(m.origin(t)[:, 0]) <= m.pass_reach_m + 0.1)
    # the model reads back from truth.json with its passes
    back = GaitModel.from_dict(truth["model"])
    assert (back.passes, back.pass_reach_m) == (m.passes, m.pass_reach_m)


def test_passes_outside_one_to_six_are_refused():
    with pytest.raises(InputError, match="passes must be 1-6"):
        build_scene(**KW, passes=0)
    with pytest.raises(InputError, match="passes must be 1-6"):
        build_scene(**KW, passes=7)

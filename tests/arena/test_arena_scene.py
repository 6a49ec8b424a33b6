"""The synthetic arena's scenes: the thesis and wide rigs, bad arguments, board poses, determinism."""

from __future__ import annotations

import json

import numpy as np
import pytest

from saddlescope.arena import (
    GAIT_RANGES,
    build_scene,
    build_truth,
    render_clip_frames,
)
from saddlescope.core.errors import InputError
from saddlescope.core.types import GAITS


@pytest.fixture(scope="module")
def scene():
    return build_scene(gait="canter", seed=7, calibration_poses=8)


def test_thesis_rig_matches_thesis_tables(scene):
    rig = scene.rig
    for cam in rig.cameras.values():
        assert cam.image_size == (640, 480)
        assert 710 <= cam.K[0, 0] <= 745 and 300 <= cam.K[0, 2] <= 340 and 220 <= cam.K[1, 2] <= 245
        assert -0.15 <= cam.dist[0] <= -0.11
    c = {r: cam.center_mm for r, cam in rig.cameras.items()}
    assert 220 <= np.linalg.norm(c["middle"] - c["left"]) <= 245
    assert 200 <= np.linalg.norm(c["right"] - c["middle"]) <= 245
    assert rig.fps == 30.0
    mid = scene.views["middle"].center_w
    assert abs(mid[2]) == pytest.approx(7.5, abs=0.2)  # 7.5 m from the track centre line


def test_wide_rig_and_size_override():
    s = build_scene(rig="wide", seed=2, size=(960, 540), calibration_poses=2, extras=False)
    c = {r: cam.center_mm for r, cam in s.rig.cameras.items()}
    assert np.linalg.norm(c["right"] - c["left"]) > 4000
    assert s.rig.fps == 60.0
    cam = s.rig.cameras["middle"]
    assert cam.image_size == (960, 540)
    assert cam.K[0, 0] == pytest.approx(725, abs=30)  # 1450 px at 1920 wide, halved
    w = build_scene(rig="wide", seed=2, fps=25.0, size=(640, 360), calibration_poses=2, extras=False)
    assert w.fps == 25.0


def test_bad_arguments_raise_input_errors():
    with pytest.raises(InputError, match="gait"):
        build_scene(gait="gallop")
    with pytest.raises(InputError, match="rig"):
        build_scene(rig="phone")
    with pytest.raises(InputError, match="short"):
        build_scene(gait="walk", duration_s=1.0, calibration_poses=2, extras=False)
    with pytest.raises(InputError, match="even"):
        build_scene(size=(641, 480), calibration_poses=2, extras=False)


def test_calibration_clip_length():
    s = build_scene(gait="walk", seed=0, calibration_poses=90, extras=False)
    tm = s.timings["calibration"]
    assert len(s.contents["calibration"].poses) == 90
    assert tm.n_left >= 90 + 3
    centres = np.array([o for _, o in s.contents["calibration"].poses])
    # spread through the volume: about the thesis's 6.5 m x 0.7 m x 0.5 m
    assert np.ptp(centres[:, 0]) > 4.5 and np.ptp(centres[:, 1]) > 0.4 and np.ptp(centres[:, 2]) > 0.3


def test_scene_and_frames_are_deterministic():
    a = build_scene(gait="rising_trot", seed=11, calibration_poses=3, extras=False)
    b = build_scene(gait="rising_trot", seed=11, calibration_poses=3, extras=False)
    assert json.dumps(build_truth(a)) == json.dumps(build_truth(b))
    for kind, k in (("motion", 50), ("calibration", 20)):
        fa = list(render_clip_frames(a, "middle", kind, start=k, stop=k + 2))
        fb = list(render_clip_frames(b, "middle", kind, start=k, stop=k + 2))
        assert all(np.array_equal(x, y) for x, y in zip(fa, fb, strict=True))
        # a sub-range equals the same frames of a longer render
        longer = list(render_clip_frames(a, "middle", kind, start=k - 1, stop=k + 2))
        assert np.array_equal(longer[1], fa[0])
    c = build_scene(gait="rising_trot", seed=12, calibration_poses=3, extras=False)
    assert c.model.speed_m_s != a.model.speed_m_s


def test_all_gaits_build_and_give_a_two_period_window():
    for gait in GAITS:
        s = build_scene(gait=gait, seed=4, calibration_poses=2, extras=False)
        assert s.window_periods == 2
        assert s.timings["motion"].n_left / s.fps >= 3.5
        assert GAIT_RANGES[gait]["stride_hz"][0] <= s.model.stride_hz <= GAIT_RANGES[gait]["stride_hz"][1]

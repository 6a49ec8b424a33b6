"""The field's nuisances in the arena (issue 38): the rider's boot, a rolling shutter, compression, a 6th harmonic."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from saddlescope.arena import (
    RenderOptions,
    acceleration_harmonics,
    build_scene,
    build_truth,
    render_clip_frames,
    row_instants,
    true_marker_pixels,
)
from saddlescope.arena.content import BOOT_RADIUS_M
from saddlescope.core.errors import InputError

CLEAN = RenderOptions(noise_sigma=0.0, shot_noise=0.0, motion_blur=False, lighting_drift=False, marker_halo=0.0,
                      distractors=False, occluder=False)


def test_the_default_ride_has_no_nuisance_and_its_truth_says_so():
    options = RenderOptions()
    assert (options.boot_share, options.readout_s, options.crf, options.high_harmonic_share) == (0.0, 0.0, 20, 0.0)
    scene = build_scene(gait="sitting_trot", seed=5, calibration_poses=2, extras=False)
    truth = build_truth(scene)["truth"]
    assert truth["nuisances"] == {"boot_share": 0.0, "readout_s": 0.0, "crf": 20, "high_harmonic": None,
                                  "high_harmonic_share": 0.0, "passes": 1}
    assert not scene.contents["motion"].boot_covers(scene.window_times).any()


@pytest.mark.parametrize("bad", [{"boot_share": 0.4}, {"boot_share": -0.1}, {"readout_s": 0.05}, {"crf": 60},
                                 {"high_harmonic": 3, "high_harmonic_share": 0.1}])
def test_nuisances_outside_what_the_arena_models_are_refused(bad):
    with pytest.raises(InputError):
        build_scene(gait="canter", seed=1, calibration_poses=2, extras=False, options=RenderOptions(**bad))


def test_the_boot_covers_the_rear_marker_for_its_share_of_every_stride_phase_locked():
    scene = build_scene(gait="canter", seed=11, calibration_poses=2, extras=False,
                        options=RenderOptions(boot_share=0.2))
    horse = scene.contents["motion"]
    period = scene.model.period_s
    t = scene.window_start_s + np.linspace(0.0, 3 * period, 3000, endpoint=False)
    covered = horse.boot_covers(t)
    assert not covered[:, [0, 1, 3]].any()  # only the rear marker (marker3)
    assert covered[:, 2].mean() == pytest.approx(0.2, abs=0.01)
    # phase-locked: the same instants of each stride
    per_stride = covered[:, 2].reshape(3, -1)
    assert np.array_equal(per_stride[0], per_stride[1]) and np.array_equal(per_stride[1], per_stride[2])
    truth = build_truth(scene)["truth"]["nuisances"]["boot"]
    assert truth["marker"] == "marker3" and truth["share_of_stride"] == 0.2
    assert truth["window_share_covered"] == pytest.approx(0.2, abs=0.06)
    # the pixels' truth leaves the covered samples out; some are covered only partly (the disc's edge)
    tp = true_marker_pixels(scene, "middle", "motion")
    assert np.array_equal(tp["occluded"][:, 2] & tp["visible"][:, 2], np.zeros(len(tp["visible"]), bool))
    offset = horse.boot_offset_m(tp["frame_times_s"])
    partly = (offset > BOOT_RADIUS_M - 0.015) & (offset < BOOT_RADIUS_M + 0.015)
    assert partly.any()


def test_the_boot_darkens_the_rear_marker_in_the_frames_it_covers():
    options = dataclasses.replace(CLEAN, boot_share=0.2)
    scene = build_scene(gait="canter", seed=11, calibration_poses=2, extras=False, options=options)
    bare = build_scene(gait="canter", seed=11, calibration_poses=2, extras=False, options=CLEAN)
    horse = scene.contents["motion"]
    times = scene.timings["motion"].frame_times("middle")
    xy = true_marker_pixels(bare, "middle", "motion")["xy_px"]
    whole = np.flatnonzero((horse.boot_offset_m(times) < 0.02) & np.all(np.isfinite(xy[:, :3, 0]), axis=1))
    assert whole.size
    k = int(whole[0])
    with_boot = next(render_clip_frames(scene, "middle", "motion", start=k, stop=k + 1))
    without = next(render_clip_frames(bare, "middle", "motion", start=k, stop=k + 1))
    x, y = np.round(xy[k, 2]).astype(int)
    assert without[y, x] > 200 and with_boot[y, x] < 60  # the rear marker gone under the boot
    x1, y1 = np.round(xy[k, 0]).astype(int)
    assert abs(int(with_boot[y1, x1]) - int(without[y1, x1])) < 3  # the front marker untouched


def _blob_centroid(frame: np.ndarray, xy: np.ndarray, r: int = 6) -> np.ndarray:
    x0, y0 = np.round(xy).astype(int)
    patch = frame[y0 - r:y0 + r + 1, x0 - r:x0 + r + 1].astype(float)
    w = np.clip(patch - 150.0, 0, None)
    ys, xs = np.mgrid[-r:r + 1, -r:r + 1]
    return np.array([x0 + (w * xs).sum() / w.sum(), y0 + (w * ys).sum() / w.sum()])


def test_a_rolling_shutter_draws_each_row_at_its_own_instant():
    readout_s = 0.033
    options = dataclasses.replace(CLEAN, readout_s=readout_s, rolling_bands=48)
    scene = build_scene(gait="canter", seed=12, calibration_poses=2, extras=False, options=options)
    glob = build_scene(gait="canter", seed=12, calibration_poses=2, extras=False, options=CLEAN)
    tp = true_marker_pixels(scene, "middle", "motion")
    tg = true_marker_pixels(glob, "middle", "motion")
    k = int(np.flatnonzero(np.all(tp["visible"][:, :3], axis=1))[3])
    # the truth: each marker where it was when its row was exposed, a few pixels on at a canter
    shift = np.linalg.norm(tp["xy_px"][k, :3] - tg["xy_px"][k, :3], axis=1)
    assert np.all(shift > 1.0)
    inst = row_instants(scene, "middle", "motion", tp["xy_px"][:, :3])[k]
    t_frame = scene.timings["motion"].frame_times("middle")[k]
    assert np.allclose(inst - t_frame, readout_s * (tp["xy_px"][k, :3, 1] + 0.5) / 480, atol=1e-9)
    frame = next(render_clip_frames(scene, "middle", "motion", start=k, stop=k + 1))
    for m in range(3):
        c = _blob_centroid(frame, tp["xy_px"][k, m])
        assert np.linalg.norm(c - tp["xy_px"][k, m]) < 0.35 * shift[m] + 0.2  # drawn where the truth says


def test_a_sixth_harmonic_carries_its_share_of_the_vertical_acceleration():
    scene = build_scene(gait="sitting_trot", seed=13, calibration_poses=2, extras=False,
                        options=RenderOptions(high_harmonic_share=0.15))
    bare = build_scene(gait="sitting_trot", seed=13, calibration_poses=2, extras=False)
    amps, _ = scene.model.harmonics["y"]
    assert len(amps) == 6 and amps[4] == 0.0 and amps[5] > 0
    body = scene.model.body_points_m["saddle"]
    acc, _ = acceleration_harmonics(scene.model, body, axis=1, n_harmonics=12)
    acc0, _ = acceleration_harmonics(bare.model, body, axis=1, n_harmonics=12)
    assert acc[5] == pytest.approx(0.15 * np.sqrt(np.sum(acc0 ** 2)), rel=0.2)
    assert acc0[5] < 0.02 * acc[5]
    assert build_truth(scene)["truth"]["nuisances"]["high_harmonic"] == 6

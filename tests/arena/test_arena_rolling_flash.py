"""A rolling shutter sweeps the sync flash down the rows of every clip, not only the ride's (issue 38, item 3)."""

from __future__ import annotations

import dataclasses

import numpy as np

from saddlescope.arena import RenderOptions, build_scene, render_clip_frames

CLEAN = RenderOptions(noise_sigma=0.0, shot_noise=0.0, motion_blur=False, lighting_drift=False, marker_halo=0.0,
                      distractors=False, occluder=False)


def _top_minus_bottom_on_the_rise(options: RenderOptions) -> float:
    """The static clip's top-row band minus its bottom-row band in the frame where the flash rises most."""
    scene = build_scene(gait="walk", seed=13, calibration_poses=2, extras=False, options=options)
    timing = scene.timings["static"]
    k0 = int(np.floor(timing.flash_on_s * scene.fps + timing.offsets["left"]))
    frames = np.stack(list(render_clip_frames(scene, "left", "static", start=k0 - 1, stop=k0 + 4))).astype(float)
    rise = int(np.argmax(np.diff(frames.mean(axis=(1, 2))))) + 1
    diff = frames[rise] - frames[0]  # the flash's light alone (the horse stands still)
    return float(diff[:60].mean() - diff[-60:].mean())


def test_the_flash_reaches_the_top_rows_first_in_a_still_clip():
    swept = _top_minus_bottom_on_the_rise(dataclasses.replace(CLEAN, readout_s=0.033))
    assert swept < -5.0  # the bottom rows are exposed later, when the lamp is brighter
    assert abs(_top_minus_bottom_on_the_rise(CLEAN)) < 0.5  # a global shutter lights every row alike

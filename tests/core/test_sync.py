"""Flash synchronisation: sub-frame onsets, offsets between cameras, and clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import SyncError
from saddlescope.core.sync import (
    clip_frames_at,
    clip_offsets,
    flash_interval,
    flash_onset,
    nominal_frames_of,
    offsets_from_spec,
)


def brightness(n_frames, onset, duration, *, rng, base=80.0, amp=30.0, noise=0.3, integration=1.0,
               drift=2.0):
    """Mean frame brightness of a clip whose frame k integrates light over [k, k + integration)."""
    k = np.arange(n_frames)
    lit = np.clip(np.minimum(k + integration, onset + duration) - np.maximum(k, onset), 0, None) / integration
    return base + amp * lit + rng.normal(0, noise, n_frames) + drift * np.sin(k / 15)


def test_subframe_onset_and_end():
    rng = np.random.default_rng(0)
    errors = []
    for _ in range(100):
        onset, duration = rng.uniform(20, 40), rng.uniform(3, 10)
        on, end = flash_interval(brightness(120, onset, duration, rng=rng), clip="motion", camera="left")
        errors.append((on - onset, end - onset - duration))
    errors = np.abs(errors)
    assert errors.max() < 0.2  # frames
    assert np.sqrt(np.mean(errors ** 2)) < 0.05


def test_global_shutter_with_short_exposure():
    rng = np.random.default_rng(1)
    for onset in (30.1, 30.3, 30.45):
        b = brightness(90, onset, 6.0, rng=rng, integration=0.5, noise=0.1)
        assert abs(flash_onset(b, clip="motion", camera="left", integration=0.5) - onset) < 0.05


def test_offsets_between_three_cameras():
    rng = np.random.default_rng(2)
    flash_at = 30.37  # seconds-free: in left-camera frames
    true = {"left": 0.0, "middle": 53.25, "right": 126.6}  # the thesis's 53 and 53 + 73 frames
    curves = {cam: brightness(220, flash_at + off, 5.0, rng=rng, base=60 + 20 * i, amp=15 + 10 * i)
              for i, (cam, off) in enumerate(true.items())}
    offsets = clip_offsets(curves, {"left": 30.0, "middle": 30.0, "right": 30.0}, clip="motion")
    assert list(offsets) == ["left", "middle", "right"] and offsets["left"] == 0.0
    for cam in true:
        assert abs(offsets[cam] - true[cam]) < 0.1


def test_reference_can_be_another_camera():
    rng = np.random.default_rng(3)
    curves = {"a": brightness(100, 20.5, 4, rng=rng), "b": brightness(100, 30.0, 4, rng=rng)}
    offsets = clip_offsets(curves, {"a": 25, "b": 25}, clip="plumb", reference="b")
    assert offsets["b"] == 0.0 and abs(offsets["a"] + 9.5) < 0.1


def test_no_flash_names_clip_and_camera():
    rng = np.random.default_rng(4)
    flat = 100 + rng.normal(0, 0.5, 200)
    with pytest.raises(SyncError, match="no sync flash found in the static clip of the middle camera"):
        flash_onset(flat, clip="static", camera="middle")


def test_too_short_clip():
    with pytest.raises(SyncError, match="motion clip of the right camera has only 5 frame"):
        flash_onset(np.array([1.0, 1, 50, 50, 1]), clip="motion", camera="right")


def test_a_step_that_never_comes_down_is_not_a_flash():
    rng = np.random.default_rng(5)
    b = 80 + rng.normal(0, 0.3, 100)
    b[60:] += 40  # lights switched on
    with pytest.raises(SyncError, match="never comes back down"):
        flash_onset(b, clip="motion", camera="left")
    b = 80 + rng.normal(0, 0.3, 100)
    b[10:80] += 40  # bright for most of the clip
    with pytest.raises(SyncError, match="lasts more than 50%"):
        flash_onset(b, clip="motion", camera="left")


def test_different_frame_rates_are_refused():
    rng = np.random.default_rng(6)
    curves = {"left": brightness(100, 20, 4, rng=rng), "middle": brightness(100, 30, 4, rng=rng)}
    with pytest.raises(SyncError, match="middle camera runs at 25 fps but the left camera at 30 fps"):
        clip_offsets(curves, {"left": 30.0, "middle": 25.0}, clip="motion")
    with pytest.raises(SyncError, match="frame rate unknown for camera"):
        clip_offsets(curves, {"left": 30.0}, clip="motion")


def test_flash_in_one_camera_only():
    rng = np.random.default_rng(7)
    curves = {"left": brightness(100, 20, 4, rng=rng), "right": 90 + rng.normal(0, 0.3, 100)}
    with pytest.raises(SyncError, match="motion clip of the right camera"):
        clip_offsets(curves, {"left": 30.0, "right": 30.0}, clip="motion")


def test_known_offsets_from_ride_json():
    sync = {"method": "offsets", "offsets": {"motion": {"left": 2, "middle": 55, "right": 128.5}}}
    assert offsets_from_spec(sync, clip="motion", cameras=["left", "middle", "right"]) == {
        "left": 0.0, "middle": 53.0, "right": 126.5}
    assert offsets_from_spec({"method": "flash"}, clip="motion", cameras=["left"]) is None
    with pytest.raises(SyncError, match="offsets for the static clip are missing"):
        offsets_from_spec(sync, clip="static", cameras=["left", "middle", "right"])
    bad = {"method": "offsets", "offsets": {"motion": {"left": 0, "middle": "x"}}}
    with pytest.raises(SyncError, match="middle camera in the motion clip is missing or not a number"):
        offsets_from_spec(bad, clip="motion", cameras=["left", "middle"])
    with pytest.raises(SyncError, match="not 'flash' or 'offsets'"):
        offsets_from_spec({"method": "clap"}, clip="motion", cameras=["left"])


def test_nominal_clock_of_a_variable_rate_clip():
    fps = 30.0
    even = np.arange(50) / fps
    # an even clip: nominal frames are its frames, whatever the anchor
    np.testing.assert_allclose(clip_frames_at(np.array([3.0, 10.5, 40.25]), even, 4.3, fps), [3.0, 10.5, 40.25])
    # a clip that dropped frame 20 and runs late by 0.2 frame from frame 30
    late = np.where(np.arange(50) >= 20, 1.0, 0.0) + np.where(np.arange(50) >= 30, 0.2, 0.0)
    times = (np.arange(50) + late) / fps
    got = clip_frames_at(np.array([5.0, 19.0, 21.0, 25.0, 35.0, 60.0]), times, 2.0, fps)
    np.testing.assert_allclose(got[:4], [5.0, 19.0, 20.0, 24.0])
    assert got[4] == pytest.approx(35.0 - 1.2 + 0.0)  # nominal 35 = clip frame 33.8
    assert np.isnan(got[5])  # past the clip's last frame
    back = nominal_frames_of(got[:5], times, 2.0, fps)
    np.testing.assert_allclose(back, [5.0, 19.0, 21.0, 25.0, 35.0])

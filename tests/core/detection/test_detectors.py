"""The marker-detector registry and the typed detection options (issue 34 part 4)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from saddlescope.core.detection import (
    DetectionSettings,
    TrackOptions,
    detector_names,
    marker_detector,
    register_detector,
)
from saddlescope.core.detection.detectors import BrightDiscs, unregister_detector
from saddlescope.core.errors import InputError
from saddlescope.core.params import PipelineParams
from saddlescope.core.pipeline.detection import motion_tracks_alone


class _Dots:
    """Three cameras' motion clips: three bright dots moving over a dark, noisy floor."""

    def cameras(self, kind):
        return ["left", "middle", "right"]

    def gray_frames(self, kind, camera, start=0, stop=None, step=1):
        rng = np.random.default_rng({"left": 1, "middle": 2, "right": 3}[camera])
        yy, xx = np.mgrid[0:120, 0:160]
        for i in range(start, 30, step):
            img = rng.integers(10, 30, (120, 160), dtype=np.uint8)
            for k, (x0, y0) in enumerate(((30, 40), (60, 50), (90, 45))):
                img[(xx - x0 - 1.5 * i) ** 2 + (yy - y0 - 8 * np.sin(0.3 * i + k)) ** 2 <= 9] = 230
            yield i, img


@dataclass(frozen=True)
class _Recording:
    """A detector that delegates to the thesis's chain and records the options each camera got."""

    name: str = "recording"
    calls: list = field(default_factory=list)

    def track(self, frames, *, n_markers, camera, clip, options, first_frame_xy=None, moving=False):
        self.calls.append((camera, clip, options, moving))
        return BrightDiscs().track(frames, n_markers=n_markers, camera=camera, clip=clip, options=options,
                                   first_frame_xy=first_frame_xy, moving=moving)


@pytest.mark.parametrize("options, words", [
    (dict(threshold=300.0), "between 0 and 255"),
    (dict(area_range_px=(40.0, 10.0)), "smallest first"),
    (dict(window_px=4), "at least 8 pixels"),
    (dict(distance_tol=1.5), "share between 0 and 1"),
    (dict(lost_frames=0), "at least one frame"),
])
def test_bad_options_are_refused_in_words_when_given(options, words):
    with pytest.raises(InputError, match=words):
        TrackOptions(**options)


def test_only_the_options_given_reach_the_tracker():
    assert TrackOptions().keywords() == {}
    assert TrackOptions(threshold=120.0, lost_frames=8).keywords() == {"threshold": 120.0, "lost_frames": 8}


def test_an_unknown_detector_is_refused_before_any_frame_with_the_known_names():
    with pytest.raises(InputError, match="no marker detector is called 'colour'.*bright_discs"):
        PipelineParams(marker_detector="colour")
    with pytest.raises(TypeError, match="DetectionSettings"):
        PipelineParams(detection={"motion": {"threshold": 120}})  # an untyped dict is not taken


def test_a_registered_detector_tracks_the_ride_with_each_cameras_options():
    detector = register_detector(_Recording())
    try:
        assert "recording" in detector_names() and detector_names()[0] == "bright_discs"
        with pytest.raises(InputError, match="registered already"):
            register_detector(_Recording())
        middle = TrackOptions(distance_tol=0.3)
        params = PipelineParams(marker_detector="recording", detection={
            "motion": DetectionSettings(per_camera={"middle": middle})})
        tracks = motion_tracks_alone(_Dots(), {"left": 0, "middle": 0, "right": 0}, params, 3)
        got = {camera: (clip, options, moving) for camera, clip, options, moving in detector.calls}
        assert got == {"left": ("motion", TrackOptions(), True), "middle": ("motion", middle, True),
                       "right": ("motion", TrackOptions(), True)}
        for cam in ("left", "middle", "right"):
            assert np.isfinite(tracks[cam].xy_px).all(axis=(1, 2)).mean() > 0.7
    finally:
        unregister_detector("recording")
    with pytest.raises(InputError):
        marker_detector("recording")

"""The all-cameras marker search: it pairs the cameras' frames by instant, also on phones' clocks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.errors import DetectionError
from saddlescope.core.marker_search import find_markers_multiview
from saddlescope.core.sync import clip_frames_at
from saddlescope.core.types import Camera, Rig

FPS = 30.0
# Horse markers (mm, rig frame) about 0.2 m apart, 7.5 m out, moving at 4 m/s forward and 0.6 m/s up:
# 13 cm between frames, so frames paired a few frames apart do not triangulate to one point.
TRIANGLE_MM = np.array([[-100.0, 0.0, 7500.0], [90.0, 40.0, 7550.0], [260.0, -20.0, 7600.0]])
VELOCITY_MM_S = np.array([4000.0, -600.0, 0.0])


def _rig() -> Rig:
    cams = {}
    for i, name in enumerate(("left", "middle", "right")):
        K = np.array([[730.0, 0, 320], [0, 730.0, 240], [0, 0, 1]])
        R = cv2.Rodrigues(np.array([0.0, -0.01 * i, 0.0]))[0]
        cams[name] = Camera(name, K, np.zeros(5), (640, 480), R, -R @ np.array([230.0 * i, 0.0, 0.0]))
    return Rig(cams)


def _frame(cam: Camera, t_s: float) -> np.ndarray:
    """A dark frame with the three markers as bright discs at instant t (markers start at -1.2 m)."""
    img = np.full((480, 640), 30, np.uint8)
    pts = TRIANGLE_MM + VELOCITY_MM_S * (t_s - 0.3)
    for x, y in cam.project(pts):  # drawn to 1/16 px: depth from a 0.23 m baseline needs it
        cv2.circle(img, (round(16 * x), round(16 * y)), 3 * 16, 230, -1, lineType=cv2.LINE_AA, shift=4)
    return img


def test_the_search_pairs_frames_by_their_timestamps():
    rig = _rig()
    n = 40
    # The middle camera (a phone) dropped three frames before the search starts: its frame k is the
    # instant of frame k + 3 of the even cameras. Read as an even clip, the frames paired are 0.1 s apart.
    stamps = {"left": np.arange(n) / FPS, "right": np.arange(n) / FPS,
              "middle": np.r_[np.arange(4), np.arange(7, n + 3)] / FPS}

    def frame_at(cam: str, index: int):
        times = stamps[cam]
        return _frame(rig.cameras[cam], float(times[index])) if 0 <= index < times.size else None

    offsets = {"left": 0.0, "middle": 0.0, "right": 0.0}
    with pytest.raises(DetectionError, match="layout of the static shot"):
        find_markers_multiview(rig, frame_at, offsets, [TRIANGLE_MM], first=10, last=30)

    def position(cam: str, k: int) -> float:
        return float(clip_frames_at(np.array([k + offsets[cam]]), stamps[cam], 0.0, FPS)[0])

    k, found = find_markers_multiview(rig, frame_at, offsets, [TRIANGLE_MM], first=10, last=30,
                                      frame_position=position)
    assert k == 10
    assert found["frames"] == {"left": 10, "middle": 7, "right": 10}
    assert found["rms_mm"] < 8.0  # centroids of 7 px discs; the search takes up to 12 mm here
    for cam, xy in found["xy"].items():
        at = TRIANGLE_MM + VELOCITY_MM_S * (10 / FPS - 0.3)
        np.testing.assert_allclose(xy, rig.cameras[cam].project(at), atol=0.5)
    # Past the end of the phone's stamps there is no frame to pair: nothing is found there.
    with pytest.raises(DetectionError):
        find_markers_multiview(rig, frame_at, offsets, [TRIANGLE_MM], first=n + 2, last=n + 8,
                               frame_position=position)

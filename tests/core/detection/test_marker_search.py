"""The all-cameras marker search: it pairs the cameras' frames by instant, also on phones' clocks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.detection import (
    bright_spots,
    find_markers_multiview,
    find_plumb_multiview,
    find_static_multiview,
    in_image,
    track_markers,
)
from saddlescope.core.errors import DetectionError
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


# A plumb line 7 m out: markers 0.7 m apart on a string that shows as a thin bright line, a glint
# beside the bottom marker (a fence nail 2 m further back) and glints on the wall behind.
PLUMB_MM = np.array([[-300.0, -350.0, 7000.0], [-300.0, 350.0, 7000.0]])
GLINTS_MM = np.array([[-240.0, 330.0, 9000.0], [1800.0, -300.0, 14000.0], [1900.0, 500.0, 14000.0],
                      [-3000.0, 100.0, 14000.0], [2600.0, -200.0, 14000.0], [-1500.0, 400.0, 14000.0]])


def _still_frame(cam: Camera, plumb_mm: np.ndarray = PLUMB_MM) -> np.ndarray:
    img = np.full((480, 640), 60, np.uint8)
    (x0, y0), (x1, y1) = cam.project(np.array([plumb_mm[0] - [0.0, 2000.0, 0.0], plumb_mm[1] + [0.0, 200.0, 0.0]]))
    if np.isfinite(x0):
        cv2.line(img, (round(16 * x0), round(16 * y0)), (round(16 * x1), round(16 * y1)), 150, 1, cv2.LINE_AA, shift=4)
    for x, y in cam.project(np.vstack([plumb_mm, GLINTS_MM])):
        if 0 <= x < 640 and 0 <= y < 480:
            cv2.circle(img, (round(16 * x), round(16 * y)), 3 * 16, 235, -1, lineType=cv2.LINE_AA, shift=4)
    return cv2.GaussianBlur(img, (0, 0), 0.7)


def test_the_plumb_line_is_told_from_glints_and_its_string():
    rig = _rig()
    frames = {c: _still_frame(cam) for c, cam in rig.cameras.items()}
    xy, _, points_mm = find_plumb_multiview(rig, frames)
    assert set(xy) == set(rig.names)
    for cam, pts in xy.items():  # upper marker first, as the tracker labels a vertical pair
        np.testing.assert_allclose(pts, rig.cameras[cam].project(PLUMB_MM), atol=0.5)
    np.testing.assert_allclose(points_mm, PLUMB_MM, atol=60.0)  # depth from a 0.46 m baseline at 7 m
    # Without the plumb line two wall glints 7 degrees off vertical would pass (within 25 degrees of
    # the cameras' image-down): the plumb line wins by being the more vertical pair.
    bare = {c: _still_frame(cam, plumb_mm=np.full((2, 3), np.nan)) for c, cam in rig.cameras.items()}
    np.testing.assert_allclose(find_plumb_multiview(rig, bare)[2], GLINTS_MM[[1, 2]], atol=60.0)


def test_a_plumb_line_outside_one_camera_is_found_by_the_other_two():
    rig = _rig()
    # Slide the plumb line left until the right camera no longer sees it while the others still do.
    shift = next(x for x in np.arange(0.0, -4000.0, -50.0)
                 if not in_image(rig, "right", PLUMB_MM + [x, 0.0, 0.0])
                 and in_image(rig, "middle", PLUMB_MM + [x, 0.0, 0.0]))
    plumb = PLUMB_MM + [shift - 100.0, 0.0, 0.0]
    assert in_image(rig, "left", plumb)
    frames = {c: _still_frame(cam, plumb) for c, cam in rig.cameras.items()}
    xy, _, points_mm = find_plumb_multiview(rig, frames)
    assert set(xy) == {"left", "middle"}
    for cam, pts in xy.items():
        np.testing.assert_allclose(pts, rig.cameras[cam].project(plumb), atol=0.5)


# The standing horse 7 m out: three markers along its back and the saddle marker above them, and the
# wall glints 14 m out, one of them behind the horse in the left camera's image, between two markers.
HORSE_MM = np.array([[-300.0, 0.0, 7000.0], [-50.0, -20.0, 7050.0], [200.0, 10.0, 7000.0], [-60.0, -250.0, 6950.0]])


def _static_frame(cam: Camera, glints_mm: np.ndarray) -> np.ndarray:
    img = np.full((480, 640), 60, np.uint8)
    levels = [230] * 4 + [245] * len(glints_mm)
    for (x, y), level in zip(cam.project(np.vstack([HORSE_MM, glints_mm])), levels, strict=True):
        if 0 <= x < 640 and 0 <= y < 480:
            cv2.circle(img, (round(16 * x), round(16 * y)), 3 * 16, level, -1, lineType=cv2.LINE_AA, shift=4)
    return cv2.GaussianBlur(img, (0, 0), 0.7)


def _behind_in_image(cam: Camera, xy: np.ndarray, depth_mm: float) -> np.ndarray:
    """The rig point at ``depth_mm`` that the camera sees at pixel ``xy`` (no distortion here)."""
    ray = cam.R.T @ np.linalg.solve(cam.K, [xy[0], xy[1], 1.0])
    centre = -cam.R.T @ cam.t_mm
    return centre + ray * (depth_mm - centre[2]) / ray[2]


def test_the_standing_horse_is_told_from_a_glint_behind_it():
    rig = _rig()
    left = rig.cameras["left"]
    behind = _behind_in_image(left, left.project(HORSE_MM[:2]).mean(axis=0) + [0.0, 18.0], 14000.0)
    glints = np.vstack([behind, GLINTS_MM[1:4]])
    frames = {c: _static_frame(cam, glints) for c, cam in rig.cameras.items()}
    # Alone, the left camera cannot tell the glint from the markers (five look-alikes in a cluster).
    with pytest.raises(DetectionError, match="equally plausible"):
        track_markers(iter([(0, frames["left"])]), n_markers=4, camera="left", clip="static")
    xy, _, points_mm = find_static_multiview(rig, frames, 4)
    assert set(xy) == set(rig.names)
    order = np.argsort(left.project(HORSE_MM)[:, 0])  # labelled left to right, as the tracker does
    for cam, pts in xy.items():
        np.testing.assert_allclose(pts, rig.cameras[cam].project(HORSE_MM[order]), atol=0.5)
    np.testing.assert_allclose(points_mm, HORSE_MM[order], atol=60.0)
    # Tracked from there, the left camera follows the markers, not the glint.
    tracks = track_markers(iter([(i, frames["left"]) for i in range(3)]), n_markers=4, camera="left",
                           clip="static", first_frame_xy=xy["left"])
    np.testing.assert_allclose(tracks.xy_px[0], xy["left"], atol=0.3)


def test_a_standing_horse_with_a_marker_hidden_from_one_camera_is_found_by_the_other_two():
    rig = _rig()
    hide = rig.cameras["right"].project(HORSE_MM[3:])[0]
    frames = {c: _static_frame(cam, GLINTS_MM[1:4]) for c, cam in rig.cameras.items()}
    frames["right"] = frames["right"].copy()
    cv2.circle(frames["right"], (round(hide[0]), round(hide[1])), 7, 60, -1)  # the rider's boot in front
    # The third camera does not show the saddle marker: the two others' find is not confirmed there.
    assert find_static_multiview(rig, frames, 4) is None
    frames.pop("right")
    xy, _, points_mm = find_static_multiview(rig, frames, 4)
    assert set(xy) == {"left", "middle"}
    np.testing.assert_allclose(np.sort(points_mm[:, 0]), np.sort(HORSE_MM[:, 0]), atol=30.0)


def test_a_spot_is_centred_on_its_marker_not_on_the_string_it_hangs_on():
    # A plumb's bottom marker 4 px across; the string it hangs on shows just above the threshold for
    # 19 px up from it and joins the marker's region. The spot must be the marker's centre (taking
    # the whole region, a thesis-rig camera put it 6 px up the string and gravity came out 62 degrees
    # off: the plumb's other marker was then taken at the string's end).
    img = np.full((480, 640), 140.0)
    img[214:233, 357] = 200.0
    truth = np.array([357.4, 234.3])
    yy, xx = np.mgrid[0:480, 0:640]
    img = np.maximum(img, 140.0 + 100.0 * np.clip(2.0 - np.hypot(xx - truth[0], yy - truth[1]), 0.0, 1.0))
    gray = cv2.GaussianBlur(np.clip(img, 0, 255).astype(np.uint8), (0, 0), 0.7)
    xy = bright_spots(gray, split_lines=True)
    assert len(xy) == 1
    np.testing.assert_allclose(xy[0], truth, atol=0.2)

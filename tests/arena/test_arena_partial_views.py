"""The arena's wide_partial rig and scene options (issue 27): side cameras that see part of the crossing,
cameras at different heights and distances, the board carried through a band of the volume, a faster canter."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.arena import build_scene, visible_everywhere, visible_in
from saddlescope.core.errors import InputError


@pytest.fixture(scope="module")
def partial():
    return build_scene(gait="canter", seed=1, rig="wide_partial", size=(640, 360), calibration_poses=12,
                       extras=False, board_band=0.6, speed_range_m_s=(4.0, 6.0))


def _seen_s(scene) -> dict[str, float]:
    """Seconds of the motion clip in which each camera (and two, three of them) sees every marker."""
    t = scene.timings["motion"].left_times
    pts = scene.model.marker_positions(t, skin=False)[:, :3] @ scene.m_dir.T
    out = {role: float(np.all(v.inside(v.project(pts), 10.0), axis=1).sum() / scene.fps)
           for role, v in scene.views.items()}
    out["two"] = float(visible_in(scene.views, pts, 2).sum() / scene.fps)
    out["three"] = float(visible_in(scene.views, pts, 3).sum() / scene.fps)
    assert np.array_equal(visible_in(scene.views, pts, 3), visible_everywhere(scene.views, pts))
    return out


def test_side_cameras_see_part_of_the_middle_cameras_crossing(partial):
    seen = _seen_s(partial)
    # the middle camera sees the whole crossing (every instant two cameras see), each side camera
    # about two thirds of it, all three only about a third
    assert seen["middle"] == pytest.approx(seen["two"], abs=0.05)
    for side in ("left", "right"):
        assert 0.55 <= seen[side] / seen["middle"] <= 0.85, (side, seen)
    assert seen["three"] / seen["middle"] < 0.5
    # the truth's window (two strides) needs only two cameras, which the three-camera view cannot hold
    assert partial.window_periods == 2
    assert seen["three"] < 2 * partial.model.period_s


def test_rig_geometry_resolution_and_distortion(partial):
    rig = partial.rig
    assert rig.name == "wide_partial" and rig.fps == 50.0 and rig.window_min_views == 2
    centres = {r: partial.views[r].center_w for r in rig.cameras}
    assert centres["right"][0] - centres["left"][0] == pytest.approx(3.6, abs=0.2)  # 1.8 m apart
    dists = sorted(-c[2] for c in centres.values())
    heights = sorted(c[1] for c in centres.values())
    assert dists[-1] - dists[0] > 0.8 and heights[-1] - heights[0] > 0.3  # different distances and heights
    for cam in rig.cameras.values():
        assert cam.image_size == (640, 360)  # 1280x720 halved
        assert cam.dist[0] < -0.19  # strong barrel distortion
        # r (1 + k1 r^2 + k2 r^4) stays monotonic out to twice the image corner: nothing folds into view
        r = np.linspace(0.0, 2.0 * np.hypot(*cam.image_size) / 2 / cam.K[0, 0], 200)
        assert np.all(np.diff(r * (1 + cam.dist[0] * r**2 + cam.dist[1] * r**4)) > 0)


def test_markers_reach_the_image_corners_where_the_board_never_went(partial):
    view = partial.views["middle"]
    t = partial.timings["motion"].left_times
    xy = view.project(partial.model.marker_positions(t, skin=False)[:, :3] @ partial.m_dir.T)
    w, _ = view.size
    inside = view.inside(xy, 10.0)
    reach = np.nanmax(np.abs(xy[inside][..., 0] - w / 2)) / (w / 2)
    assert reach > 0.9  # the markers cross the middle image from edge to edge
    board = partial.contents["calibration"]
    centres = np.array([o for _, o in board.poses])
    half = partial.rig.volume_half_m[0]
    assert np.max(np.abs(centres[:, 0])) <= 0.6 * half + 0.5  # the board only through the middle band


def test_speed_band_and_bad_options(partial):
    assert 4.0 <= partial.model.speed_m_s <= 6.0
    with pytest.raises(InputError, match="board_band"):
        build_scene(rig="wide_partial", calibration_poses=2, extras=False, board_band=1.5)
    with pytest.raises(InputError, match="speed range"):
        build_scene(calibration_poses=2, extras=False, speed_range_m_s=(6.0, 4.0))

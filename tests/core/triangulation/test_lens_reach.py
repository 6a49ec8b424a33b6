"""The lens model limited to the calibration board's reach (issue 27): no r^5 extrapolation, no fold."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.camera_model import undistort_normalized
from saddlescope.core.errors import InputError
from saddlescope.core.triangulation import (
    board_reach_px,
    reach_by_camera,
    reach_radius,
    triangulate_nview,
    undistort_within_reach,
)
from saddlescope.core.types import Camera, Rig

# The arena's wide_partial seed 0 middle camera (640x360): the true lens, and what a board carried
# through the middle band of the volume (reaching 111 px from the centre) made of it.
K = np.array([[441.0, 0.0, 320.0], [0.0, 441.0, 180.0], [0.0, 0.0, 1.0]])
TRUE_DIST = np.array([-0.2219, 0.0712, -0.0012, 0.0007, 0.0])
FITTED_DIST = np.array([-0.1978, -0.6011, -0.0012, 0.0010, 0.0])
REACH_PX = 111.0


def _camera(dist, name="middle", R=np.eye(3), t=np.zeros(3)) -> Camera:
    return Camera(name, K.copy(), np.asarray(dist, float), (640, 360), R, t)


def _ray_error_px(fitted: np.ndarray, xy_px: np.ndarray) -> np.ndarray:
    """How far (ideal px) normalised coordinates ``fitted`` are from the true lens's rays at ``xy_px``."""
    return np.linalg.norm(fitted - undistort_normalized(_camera(TRUE_DIST), xy_px), axis=-1) * K[0, 0]


def test_inside_the_reach_the_fitted_model_is_used_unchanged():
    cam = _camera(FITTED_DIST)
    xy = np.array([[320.0, 180.0], [380.0, 220.0], [250.0, 130.0], [np.nan, np.nan]])
    limited, beyond = undistort_within_reach(cam, xy, REACH_PX)
    assert not beyond.any()
    np.testing.assert_array_equal(limited, undistort_normalized(cam, xy))
    none, beyond_none = undistort_within_reach(cam, xy[:1] + 300, None)  # no reach: the model everywhere
    assert not beyond_none.any()
    np.testing.assert_array_equal(none, undistort_normalized(cam, xy[:1] + 300))


def test_beyond_the_reach_the_continuation_is_continuous_monotonic_and_far_closer_to_the_lens():
    cam = _camera(FITTED_DIST)
    x = np.linspace(330.0, 639.0, 300)
    xy = np.column_stack([x, np.full_like(x, 200.0)])  # a marker crossing to the image's right edge
    limited, beyond = undistort_within_reach(cam, xy, REACH_PX)
    assert beyond[-1] and not beyond[0]
    radius = np.linalg.norm(limited, axis=1)
    assert np.all(np.diff(radius) > 0)  # never folds back
    step = np.abs(np.diff(radius)) * K[0, 0]
    assert step.max() < 3 * np.median(step)  # no jump where the continuation takes over
    raw = _ray_error_px(undistort_normalized(cam, xy), xy)
    ours = _ray_error_px(limited, xy)
    # the polynomial fitted to the middle band folds and sends the edge rays anywhere; k1 alone from the
    # reach misses the true lens by about a dozen pixels at the very edge
    assert raw[-1] > 50 and ours[-1] < 15.0
    assert np.max(ours) < 0.25 * np.max(raw)


def test_reach_radius_and_board_reach():
    cam = _camera(FITTED_DIST)
    r_t, rho_t, slope = reach_radius(cam, REACH_PX)
    assert rho_t == pytest.approx(1.1 * REACH_PX / K[0, 0], rel=1e-3)
    assert slope == pytest.approx(1 + 3 * FITTED_DIST[0] * r_t**2) and r_t > rho_t  # barrel: r_d < r
    hull = [[320.0 + 111.0, 180.0], [320.0, 180.0 - 50.0], [250.0, 200.0]]
    assert board_reach_px(cam, hull) == pytest.approx(111.0)
    rig = Rig({"middle": cam})
    assert reach_by_camera(rig, {"middle": {"hull_px": hull}, "other": {"hull_px": hull}}) == {"middle": 111.0}
    assert reach_by_camera(rig, None) == {}
    with pytest.raises(InputError, match="hull"):
        board_reach_px(cam, [[np.nan, 1.0]])


def test_two_camera_points_at_the_image_edges_keep_their_depth():
    """Two cameras 1.8 m apart at 6 m, each with the band-fitted lens: points near the edges of both views."""
    R_r = cv2.Rodrigues(np.array([0.0, -0.05, 0.0]))[0]
    true_rig = Rig({"left": _camera(TRUE_DIST, "left"), "right": _camera(TRUE_DIST, "right", R_r,
                                                                          -R_r @ np.array([1800.0, 0.0, 0.0]))})
    fitted_rig = Rig({n: Camera(n, c.K, FITTED_DIST, c.image_size, c.R, c.t_mm) for n, c in true_rig.cameras.items()})
    X = np.column_stack([np.linspace(-2200.0, -1200.0, 20), np.full(20, 150.0), np.full(20, 6000.0)])
    xy = {n: c.project(X) for n, c in true_rig.cameras.items()}
    assert all(np.all((p[:, 0] > 0) & (p[:, 0] < 640)) for p in xy.values())
    raw, _, _ = triangulate_nview(fitted_rig, xy)
    ours, err, views = triangulate_nview(fitted_rig, xy, lens_reach_px={"left": REACH_PX, "right": REACH_PX})
    raw_mm = np.linalg.norm(raw - X, axis=1)
    ours_mm = np.linalg.norm(ours - X, axis=1)
    assert np.all(views == 2) and np.all(np.isfinite(err))
    # the extrapolated polynomial folds: metres off in depth; the continuation leaves centimetres, up
    # to two decimetres at the very edges (the lens is unknown there)
    assert np.nanmedian(raw_mm) > 1000
    assert np.median(ours_mm) < 100.0 and np.max(ours_mm) < 250.0


def test_a_camera_leaving_the_view_leaves_no_step_in_the_track():
    """Three cameras 1.8 m apart at 6 m; the right one's calibration is a little off (its principal point
    4 px out), and it loses the marker half way along the crossing. Each camera set then sees the marker
    somewhere else: the full set's track steps where the right camera leaves, unless each reduced set's
    offset from the full set, measured where both saw the marker, is taken off."""
    from saddlescope.core.triangulation import triangulate_tracks
    from saddlescope.core.types import ImageTracks

    cams = {}
    for name, x_mm in (("left", -1800.0), ("middle", 0.0), ("right", 1800.0)):
        R = cv2.Rodrigues(np.array([0.0, np.arctan2(x_mm, 6000.0), 0.0]))[0]  # turned in towards the track
        cams[name] = Camera(name, K.copy(), np.zeros(5), (640, 360), R, -R @ np.array([x_mm, 0.0, 0.0]))
    true_rig = Rig(cams)
    off = cams["right"].K.copy()
    off[0, 2] += 4.0
    right = cams["right"]
    used_rig = Rig({**cams, "right": Camera("right", off, np.zeros(5), (640, 360), right.R, right.t_mm)})
    n = 60
    X = np.column_stack([np.linspace(-600.0, 600.0, n), 100.0 * np.sin(np.linspace(0, 6, n)), np.full(n, 6000.0)])
    tracks = {}
    for name, cam in true_rig.cameras.items():
        xy = cam.project(X)[:, None, :].copy()
        if name == "right":
            xy[n // 2:] = np.nan  # the right camera loses the marker half way
        tracks[name] = ImageTracks(name, xy, np.arange(n))

    def step_mm(**kw) -> float:
        tr = triangulate_tracks(used_rig, tracks, {}, 50.0, match_labels=False, **kw)
        err = tr.xyz_mm[:, 0] - X
        return float(np.linalg.norm(err[n // 2] - err[n // 2 - 1]))

    plain, continuous = step_mm(), step_mm(camera_set_bias=True)
    assert plain > 20.0  # 4 px over 1.8 m baselines: centimetres between the camera sets
    assert continuous < 0.1 * plain

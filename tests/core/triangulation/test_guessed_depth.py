"""Two-camera samples whose depth rests on a lens model extrapolated beyond the calibration board's reach
are marked (issue 27: a band-calibrated partial-view canter, W_b r.m.s. three times the truth)."""

from __future__ import annotations

import cv2
import numpy as np

from saddlescope.core.triangulation import ReachCheckedTracks, triangulate_tracks
from saddlescope.core.types import Camera, ImageTracks, Rig

K = np.array([[441.0, 0.0, 320.0], [0.0, 441.0, 180.0], [0.0, 0.0, 1.0]])


def _crossing():
    """Three cameras 1.8 m apart at 6 m; a marker crossing 3 m, the right camera missing its first part and
    the left its last (the wide_partial rig's side cameras see part of the crossing)."""
    cams = {}
    for name, x_mm in (("left", -1800.0), ("middle", 0.0), ("right", 1800.0)):
        R = cv2.Rodrigues(np.array([0.0, np.arctan2(x_mm, 6000.0), 0.0]))[0]
        cams[name] = Camera(name, K.copy(), np.zeros(5), (640, 360), R, -R @ np.array([x_mm, 0.0, 0.0]))
    n = 61
    X = np.column_stack([np.linspace(-1500.0, 1500.0, n), np.zeros(n), np.full(n, 6000.0)])
    tracks = {}
    for name, cam in cams.items():
        xy = cam.project(X)[:, None, :].copy()
        xy[(X[:, 0] < -300) if name == "right" else (X[:, 0] > 300) if name == "left" else np.zeros(n, bool)] = np.nan
        tracks[name] = ImageTracks(name, xy, np.arange(n))
    return Rig(cams), tracks, X


def test_two_view_samples_with_a_camera_beyond_its_reach_are_marked():
    rig, tracks, X = _crossing()
    plain = triangulate_tracks(rig, tracks, {}, 50.0, match_labels=False)
    assert not isinstance(plain, ReachCheckedTracks)  # no reach given: nothing to say
    two_views = plain.views[:, 0] == 2
    assert two_views.sum() > 20
    cases = set()
    # the middle camera's board reached 15 or 45 px from its centre (times 1.1: 224 or 673 mm at 6 m)
    for middle_reach_px in (15.0, 45.0):
        reach = {"left": 1000.0, "middle": middle_reach_px, "right": 1000.0}
        out = triangulate_tracks(rig, tracks, {}, 50.0, match_labels=False, lens_reach_px=reach,
                                 camera_set_bias=True)
        assert isinstance(out, ReachCheckedTracks)
        beyond_middle = np.abs(X[:, 0]) > 1.1 * middle_reach_px / K[0, 0] * 6000.0
        # marked: two views, one of them beyond its reach; three views check each other; within reach is sound
        assert np.array_equal(out.lens_extrapolated[:, 0], two_views & beyond_middle)
        px = out.lens_extrapolation_px[two_views & beyond_middle, 0]
        expected_px = 441.0 * np.abs(X[two_views & beyond_middle, 0]) / 6000.0 - 1.1 * middle_reach_px
        np.testing.assert_allclose(px, expected_px, atol=0.25)  # how far beyond (reach_radius: a 0.22 px grid)
        np.testing.assert_allclose(out.xyz_mm, plain.xyz_mm, atol=1e-6)  # the marking moves no sample
        cases |= {"3 views beyond"} if np.any(~two_views & beyond_middle) else set()
        cases |= {"2 views within"} if np.any(two_views & ~beyond_middle) else set()
    assert cases == {"3 views beyond", "2 views within"}

"""The synthetic arena's rendered clips against the exact geometry: blobs, flash, pole, board corners."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from saddlescope.arena import (
    BOARD,
    RenderOptions,
    build_scene,
    build_truth,
    flash_fraction,
    make_rig,
    render_clip_frames,
    true_marker_pixels,
)
from saddlescope.core.types import CAMERA_ROLES

CLEAN = RenderOptions(
    noise_sigma=0.0,
    shot_noise=0.0,
    motion_blur=False,
    lighting_drift=False,
    marker_halo=0.0,
    distractors=False,
    occluder=False,
)


@pytest.fixture(scope="module")
def scene():
    return build_scene(gait="canter", seed=7, calibration_poses=8)


@pytest.fixture(scope="module")
def truth(scene):
    return json.loads(json.dumps(build_truth(scene)))  # exactly what truth.json holds


def _centroid(img: np.ndarray, xy: np.ndarray, half: int = 7) -> np.ndarray:
    """Intensity-weighted centroid after removing a plane fitted to the window's border."""
    x, y = np.round(xy).astype(int)
    win = img[y - half : y + half + 1, x - half : x + half + 1].astype(float)
    yy, xx = np.mgrid[-half : half + 1, -half : half + 1]
    ring = (np.abs(yy) == half) | (np.abs(xx) == half)
    coef = np.linalg.lstsq(np.column_stack([np.ones(ring.sum()), xx[ring], yy[ring]]), win[ring], rcond=None)[0]
    w = win - (coef[0] + coef[1] * xx + coef[2] * yy)
    w[w < 0.02 * w.max()] = 0.0
    return np.array([x + (w * xx).sum() / w.sum(), y + (w * yy).sum() / w.sum()])


@pytest.mark.parametrize(
    "rig,size,blur", [("thesis", None, False), ("thesis", None, True), ("wide", (960, 540), False)]
)
def test_rendered_blob_centroids_match_projection(rig, size, blur):
    opts = RenderOptions(**{**CLEAN.__dict__, "motion_blur": blur})
    s = build_scene(gait="canter", seed=3, rig=rig, size=size, calibration_poses=2, extras=False, options=opts)
    errs = []
    for kind in ("static", "motion"):
        for role in CAMERA_ROLES:
            tp = true_marker_pixels(s, role, kind)
            for k in np.nonzero(tp["visible"].any(axis=1))[0][::6]:
                frame = next(render_clip_frames(s, role, kind, start=k, stop=k + 1))
                ring_ok = None
                for m in np.nonzero(tp["visible"][k])[0]:
                    xy = tp["xy_px"][k, m]
                    others = np.delete(tp["xy_px"][k], m, axis=0)
                    if np.any(np.hypot(*(others - xy).T) < 15) or not s.views[role].inside(xy, 10):
                        continue
                    x, y = np.round(xy).astype(int)
                    win = frame[y - 7 : y + 8, x - 7 : x + 8].astype(float)
                    ring_ok = np.ptp(np.concatenate([win[0], win[-1], win[:, 0], win[:, -1]])) < 4
                    if ring_ok:  # isolated: a flat neighbourhood (the horse's coat)
                        errs.append(np.hypot(*(_centroid(frame, xy) - xy)))
    errs = np.array(errs)
    assert len(errs) > 30
    assert errs.max() < 0.05, (errs.max(), np.median(errs))


def test_marker_blobs_are_small_at_thesis_rig_and_bigger_at_wide(scene):
    tp = true_marker_pixels(scene, "middle", "motion")
    d_thesis = 2 * np.nanmedian(np.where(tp["visible"], tp["radius_px"], np.nan))
    assert 2.4 <= d_thesis <= 3.6  # 30 mm at 7.5 m, ~4 px visible with the lens blur
    wide = make_rig("wide", np.random.default_rng(1))
    cam = wide.cameras["middle"]
    assert cam.image_size == (1920, 1080)
    ends = wide.world_to_rig_mm(np.array([[0.0, 0.25, -0.27], [0.03, 0.25, -0.27]]))  # a marker on the track
    assert np.linalg.norm(np.diff(cam.project(ends), axis=0)) > 4.5


def test_markers_have_bright_cores(scene):
    tp = true_marker_pixels(scene, "left", "motion")
    k = int(np.nonzero(tp["visible"][:, :3].all(axis=1))[0][3])
    frame = next(render_clip_frames(scene, "left", "motion", start=k, stop=k + 1))
    for m in range(3):
        x, y = np.round(tp["xy_px"][k, m]).astype(int)
        patch = frame[y - 1 : y + 2, x - 1 : x + 2]
        assert patch.max() >= 200 and np.median(frame[y - 8 : y + 9, x - 8 : x + 9]) < 110


def test_flash_offsets_equal_truth(scene, truth):
    for kind in ("motion", "static"):
        crossings = {}
        for role in CAMERA_ROLES:
            n = min(scene.timings[kind].n_frames[role], 40)
            b = np.array([f[::4, ::4].mean() for f in render_clip_frames(scene, role, kind, stop=n)])
            lo, hi = np.median(b[-10:]), b.max()
            half = 0.5 * (lo + hi)
            i = int(np.nonzero(b > half)[0][0])
            crossings[role] = i - 1 + (half - b[i - 1]) / (b[i] - b[i - 1])
        for role in ("middle", "right"):
            assert crossings[role] - crossings["left"] == pytest.approx(truth["sync"][kind][role], abs=0.05)


def test_flash_fraction_closed_form():
    t = np.linspace(-0.2, 0.6, 801)
    level = flash_fraction(t, 0.01, 0.1, 0.3, 0.05)
    # brute-force mean of the trapezoid over each exposure
    tt = t[:, None] + np.linspace(-0.005, 0.005, 2001)[None]
    trap = np.clip((tt - 0.1) / 0.05, 0, 1) - np.clip((tt - 0.3) / 0.05, 0, 1)
    np.testing.assert_allclose(level, trap.mean(axis=1), atol=1e-3)


def test_occluder_hides_a_marker_in_one_camera_at_a_time(scene, truth):
    tm = scene.timings["motion"]
    occ = {role: true_marker_pixels(scene, role, "motion")["occluded"][:, :3] for role in CAMERA_ROLES}
    counts = np.zeros((tm.n_left, 3), int)
    for role in CAMERA_ROLES:
        k = np.round(np.arange(tm.n_left) + tm.offsets[role]).astype(int)
        ok = (k >= 0) & (k < tm.n_frames[role])
        counts[ok] += occ[role][k[ok]]
    w0 = int(round(truth["window"]["start_s"] * truth["fps"]))
    win = slice(w0, w0 + len(truth["saddle"]["t_s"]))
    assert counts[win].sum() >= 3  # occlusions happen inside the analysed window
    assert counts.max() <= 1  # never the same marker in two cameras at once
    # the saddle point is never rendered during the ride
    assert not true_marker_pixels(scene, "left", "motion")["visible"][:, 3].any()


def test_markers_visible_in_all_cameras_through_the_window(scene, truth):
    w0 = int(round(truth["window"]["start_s"] * truth["fps"]))
    n = len(truth["saddle"]["t_s"])
    tm = scene.timings["motion"]
    for role in CAMERA_ROLES:
        tp = true_marker_pixels(scene, role, "motion")
        k = np.round(np.arange(w0, w0 + n) + tm.offsets[role]).astype(int)
        seen = tp["visible"][k, :3] | tp["occluded"][k, :3]
        assert seen.all(), role


def test_board_corners_are_detectable_and_exact(scene, truth):
    cb = truth["truth"]["calibration_board"]
    tm = scene.timings["calibration"]
    obj = BOARD.object_points_mm()
    still = [k for k, s in enumerate(cb["still"]) if s]
    assert len(still) >= cb["n_poses"]  # every pose can be paired across cameras
    found, errs = 0, []
    for k in still[1::7][:5]:
        for role in ("left", "right"):
            kc = int(round(k + tm.offsets[role]))
            frame = next(render_clip_frames(scene, role, "calibration", start=kc, stop=kc + 1))
            up = cv2.resize(frame, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC)
            ok, corners = cv2.findChessboardCornersSB(up, BOARD.inner_corners, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
            if not ok:
                continue
            found += 1
            # INTER_CUBIC maps pixel centres x -> 2x + 0.5
            c = (corners.reshape(-1, 2) - 0.5) / 2.0
            proj = scene.rig.cameras[role].project(obj @ np.array(cb["R_board_to_rig"][k]).T + cb["t_mm"][k])
            e = np.hypot(*(c - proj).T)
            e_rev = np.hypot(*(c[::-1] - proj).T)  # the detector may start from the opposite corner
            errs.append(min(e.mean(), e_rev.mean()))
    assert found >= 6
    assert max(errs) < 0.25

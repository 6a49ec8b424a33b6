"""Video mode of the checkerboard finder: tracking, the one-square-shift guard, the saddle-point localizer,
skipping a moving board, and corners as accurate as detected ones."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from saddlescope.core.calibration import (
    BoardFinder,
    BoardTracker,
    canonical_checkerboard_order,
    detect_board_views,
    make_board,
    render_board,
    saddles,
    tracking,
)
from saddlescope.core.errors import InputError
from saddlescope.core.types import Camera

# the thesis rig's board and camera: squares of 4-5 px at 7.5 m (found on a 2x upsampled frame)
BOARD = make_board("checkerboard", (12, 11), 50.0)
CAM = Camera("a", np.array([[730.0, 0, 320], [0, 730, 240], [0, 0, 1]]), np.array([-0.13, 0.02, 0, 0, 0]),
             (640, 480))
RVEC = np.radians([15.0, -20.0, 8.0])
T_FAR = np.array([-300.0, -250.0, 7500.0])


def _truth(rvec, t):
    return CAM.project(BOARD.object_points_mm() @ cv2.Rodrigues(rvec)[0].T + t)


def _frame(rvec, t, rng, *, blur_path=None):
    """A rendered frame with the lens's blur and sensor noise; ``blur_path`` (K, 3) averages renders of
    the board shifted along it (motion blur)."""
    shifts = np.zeros((1, 3)) if blur_path is None else np.asarray(blur_path)
    img = np.mean([render_board(BOARD, CAM, rvec, t + s).astype(np.float64) for s in shifts], axis=0)
    img = cv2.GaussianBlur(img, (0, 0), 0.7)
    return np.clip(img + rng.normal(0, 1.5, img.shape), 0, 255).astype(np.uint8)


def _square_shift(rvec, di, dj):
    """Board translation (mm) that moves it by di squares along its x axis and dj along its y axis."""
    R = cv2.Rodrigues(rvec)[0]
    return BOARD.square_mm * (di * R[:, 0] + dj * R[:, 1])


def _rms(a, b):
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


@pytest.mark.slow
def test_tracking_follows_a_slowly_moving_board_as_accurately_as_detection():
    rng = np.random.default_rng(1)
    # 0.2 px a frame to the right and a slow turn: still enough for tracking, never re-detected
    poses = [(RVEC + [0, 0, np.radians(0.02 * k)], T_FAR + [2.0 * k, 0, 0]) for k in range(8)]
    frames = [(k, _frame(rv, t, rng)) for k, (rv, t) in enumerate(poses)]
    tracker = BoardTracker(BOARD)
    views = list(tracker.views(frames))
    assert [v.frame for v in views] == list(range(8))
    assert tracker.counts["tracked"] == 7
    for v, (rv, t) in zip(views, poses, strict=True):
        assert np.array_equal(v.ids, np.arange(132))
        assert _rms(v.corners_px, _truth(rv, t)) < 0.15
        # the same refinement as a fresh detection of that frame
        detected, _ = BoardFinder(BOARD, thorough=False)(frames[v.frame][1])
        assert np.abs(v.corners_px - detected).max() < 0.02


def test_detection_on_an_upsampled_frame_is_unbiased():
    # cv2.resize aligns pixel centres: dividing by 2 alone would put every corner 0.25 px off
    rng = np.random.default_rng(2)
    corners, _ = BoardFinder(BOARD, thorough=False)(_frame(RVEC, T_FAR, rng))
    assert np.abs((corners - _truth(RVEC, T_FAR)).mean(axis=0)).max() < 0.05


@pytest.mark.parametrize("shift", [(1, 0), (0, 1), (1, 1), (-1, 1)])
def test_a_board_shifted_by_one_square_is_not_tracked_into_wrong_labels(shift):
    rng = np.random.default_rng(3)
    moved = T_FAR + _square_shift(RVEC, *shift)
    frames = [(0, _frame(RVEC, T_FAR, rng)), (1, _frame(RVEC, moved, rng)), (2, _frame(RVEC, moved, rng))]
    tracker = BoardTracker(BOARD)
    views = {v.frame: v for v in tracker.views(frames)}
    assert tracker.counts["tracked"] == 0  # every corner refines onto a corner, but some are on the edge
    assert _rms(views[0].corners_px, _truth(RVEC, T_FAR)) < 0.2
    for k in (1, 2):  # found again (the frame where it moved tracked back from the next), labelled right
        assert _rms(views[k].corners_px, _truth(RVEC, moved)) < 0.2


def test_square_checks_tell_a_shifted_grid():
    rng = np.random.default_rng(4)
    img = _frame(RVEC, T_FAR, rng)
    good = _truth(RVEC, T_FAR)
    ratio, _ = tracking._square_checks(img, good, BOARD.inner_corners)
    assert np.all(np.abs(ratio) > 1.6) and (np.all(ratio > 0) or np.all(ratio < 0))
    for di, dj in [(1, 0), (1, 1)]:
        shifted = _truth(RVEC, T_FAR + _square_shift(RVEC, di, dj))
        r, _ = tracking._square_checks(img, shifted, BOARD.inner_corners)
        assert np.sum(r * np.sign(np.median(ratio)) < tracking._MIN_SQUARE_RATIO) >= 11


def test_a_lost_board_is_found_again_by_the_localizer():
    rng = np.random.default_rng(5)
    blank = np.clip(128 + rng.normal(0, 1.5, (480, 640)), 0, 255).astype(np.uint8)
    rv_b, t_b = np.radians([-10.0, 25.0, -5.0]), np.array([100.0, -100.0, 6500.0])
    frames = [(0, _frame(RVEC, T_FAR, rng)), (1, _frame(RVEC, T_FAR, rng))]
    frames += [(k, blank.copy()) for k in range(2, 6)]
    frames += [(k, _frame(rv_b, t_b, rng)) for k in range(6, 9)]
    # whole-frame searches at most on the first frame: the board must come back through the localizer
    tracker = BoardTracker(BOARD, search_every=1000)
    views = {v.frame: v for v in tracker.views(frames)}
    assert sorted(views) == [0, 1, 6, 7, 8]
    assert tracker.counts["whole_frame_searches"] <= 1
    assert tracker.counts["found_from_saddles"] + tracker.counts["found_near_saddles"] >= 1
    for k in (6, 7, 8):
        assert _rms(views[k].corners_px, _truth(rv_b, t_b)) < 0.2


def test_the_localizer_points_at_the_board():
    rng = np.random.default_rng(6)
    img = _frame(RVEC, T_FAR, rng)
    clusters = saddles._saddle_clusters(img, 132)
    truth = _truth(RVEC, T_FAR)
    x0, y0, x1, y1 = clusters[0].box
    assert x0 < truth[:, 0].min() and truth[:, 0].max() < x1 and y0 < truth[:, 1].min() and truth[:, 1].max() < y1
    grids = saddles._grids_from_saddles(clusters[0], BOARD.inner_corners)
    # one of the candidate windows is the board, up to the labelling canonical order fixes
    ordered = [canonical_checkerboard_order(img, g, BOARD.inner_corners) for g in grids]
    assert min(_rms(g, truth) for g in ordered) < 0.7


def test_a_moving_board_is_not_searched_for(monkeypatch):
    rng = np.random.default_rng(7)
    step = np.array([12.0, 3.0, 0.0])  # about 1.2 px a frame, blurred along the way
    path = np.linspace(0, 1, 5)[:, None] * step
    frames = [(0, _frame(RVEC, T_FAR, rng)), (1, _frame(RVEC, T_FAR, rng))]
    frames += [(k, _frame(RVEC, T_FAR + (k - 1) * step, rng, blur_path=path)) for k in range(2, 7)]
    searched = []
    real = saddles._grids_from_saddles
    monkeypatch.setattr(tracking, "_grids_from_saddles", lambda *a: searched.append(1) or real(*a))
    real_sb = tracking._checkerboard_corners
    monkeypatch.setattr(tracking, "_checkerboard_corners", lambda *a, **k: searched.append(2) or real_sb(*a, **k))
    tracker = BoardTracker(BOARD)
    views = {v.frame: v for v in tracker.views(frames)}
    assert sorted(views) == [0, 1]
    assert tracker.counts["skipped_moving"] >= 4
    assert len(searched) == 1  # the first frame's search only


def test_detect_board_views_tracks_video_and_keeps_stills_and_charuco_per_frame():
    rng = np.random.default_rng(8)
    frames = [(k, _frame(RVEC, T_FAR, rng)) for k in range(3)]
    views, size = detect_board_views(iter(frames), BOARD)
    assert size == (640, 480) and [v.frame for v in views] == [0, 1, 2]
    still, _ = detect_board_views(iter(frames), BOARD, thorough=True)  # still images: each searched alone
    assert [v.frame for v in still] == [0, 1, 2]
    assert max(_rms(v.corners_px, _truth(RVEC, T_FAR)) for v in views + still) < 0.2
    charuco = make_board("charuco", (4, 3), 30.0)
    near = Camera("a", CAM.K, np.zeros(5), (640, 480))
    img = render_board(charuco, near, np.array([0.3, -0.2, 0.1]), np.array([-70.0, -50.0, 450.0]))
    found, _ = detect_board_views(iter([(0, img), (1, img)]), charuco)
    assert [len(v.ids) for v in found] == [12, 12]
    with pytest.raises(InputError, match="ChArUco"):
        BoardTracker(charuco)


# a 1080p phone camera: a lost board is looked for on the frame shrunk 3x (to 640 px), refined at full size
CAM_HD = Camera("hd", np.array([[1500.0, 0, 960], [0, 1500, 540], [0, 0, 1]]), np.array([-0.1, 0.05, 0, 0, 0]),
                (1920, 1080))
HD_POSES = {  # squares of about 5 px (a board far away: a px or two when shrunk 3x), 12 px and 30 px
    "far": (np.radians([10.0, -15.0, 5.0]), np.array([2000.0, -1500.0, 15000.0])),
    "middle": (np.radians([-20.0, 25.0, -10.0]), np.array([-1500.0, 300.0, 6250.0])),
    "near": (np.radians([25.0, 10.0, 3.0]), np.array([-250.0, -300.0, 2500.0])),
}


def _hd_frame(rvec, t, rng):
    img = render_board(BOARD, CAM_HD, rvec, t).astype(np.float64)
    img = cv2.GaussianBlur(img, (0, 0), 0.7)
    return np.clip(img + rng.normal(0, 1.5, img.shape), 0, 255).astype(np.uint8)


def test_a_shrunk_frame_maps_back_onto_the_frame():
    img = np.zeros((1080, 1921), np.uint8)  # a column that does not fill a block is dropped
    img[600:603, 900:903] = 255  # one 3x3 block of the shrunk frame
    factor = tracking._shrink_factor(img.shape[1], tracking.COARSE_WIDTH_PX)
    small = tracking._shrunk_by(img, factor)
    assert factor == 3 and small.shape == (360, 640)
    y, x = np.unravel_index(np.argmax(small), small.shape)
    assert small[y, x] == 255 and np.allclose(tracking.unscale_px(np.array([x, y]), 1 / 3), [901, 601])
    assert tracking._shrink_factor(640, tracking.COARSE_WIDTH_PX) == 1  # 640x480: searched as it is
    with pytest.raises(InputError, match="coarse_width_px"):
        BoardTracker(BOARD, coarse_width_px=10)


@pytest.mark.slow
def test_the_coarse_search_finds_the_same_corners_as_a_full_size_search():
    """A board found on the shrunk frame (far, middle and near) has the corners that a search of the frame at
    full size finds (mean difference < 0.05 px) and the true ones (< 0.2 px r.m.s.)."""
    rng = np.random.default_rng(11)
    diff = []
    for name, (rv, t) in HD_POSES.items():
        truth = CAM_HD.project(BOARD.object_points_mm() @ cv2.Rodrigues(rv)[0].T + t)
        frames = [(k, _hd_frame(rv, t, rng)) for k in range(2)]
        coarse = BoardTracker(BOARD)
        full = BoardTracker(BOARD, coarse_width_px=1920)
        ours = {v.frame: v.corners_px for v in coarse.views(frames)}
        ref = {v.frame: v.corners_px for v in full.views(frames)}
        assert sorted(ours) == sorted(ref) == [0, 1], name
        assert coarse.counts["found_from_saddles"] + coarse.counts["found_near_saddles"] == 1, name
        diff += [np.mean(np.linalg.norm(ours[k] - ref[k], axis=1)) for k in ours]
        assert max(_rms(ours[k], truth) for k in ours) < 0.2, name
    print(f"coarse against full-size search: mean corner difference {np.mean(diff):.4f} px "
          f"(largest view {np.max(diff):.4f} px)")
    assert np.mean(diff) < 0.05


# issue 28: a lost board's first saddle search on a frame shrunk further while the squares last seen allow
def test_the_coarse_factor_follows_the_squares_last_seen():
    assert tracking._coarse_factor(640, 640, None) == 1  # nothing seen yet: the usual coarse width
    assert tracking._coarse_factor(640, 640, 4.3) == 2  # 640x480 ride: squares of 2 px at half size
    assert tracking._coarse_factor(640, 640, 3.9) == 1  # under 2 px there: as before
    assert tracking._coarse_factor(1920, 640, 12.0) == 6  # 1080p: twice as far while squares stay 2 px
    assert tracking._coarse_factor(1920, 640, 8.4) == 3  # or not at all


def _lost_and_back(t_back, monkeypatch):
    """Views of a board seen, lost for four blank frames and back at ``t_back``; the shapes searched."""
    rng = np.random.default_rng(21)
    blank = np.clip(128 + rng.normal(0, 1.5, (480, 640)), 0, 255).astype(np.uint8)
    rv_b = np.radians([-10.0, 25.0, -5.0])
    frames = [(0, _frame(RVEC, T_FAR, rng)), (1, _frame(RVEC, T_FAR, rng))]
    frames += [(k, blank.copy()) for k in range(2, 6)]
    frames += [(k, _frame(rv_b, t_back, rng)) for k in range(6, 8)]
    shapes = []
    real = tracking._saddle_clusters
    monkeypatch.setattr(tracking, "_saddle_clusters", lambda img, n: shapes.append(img.shape) or real(img, n))
    views = {v.frame: v.corners_px for v in BoardTracker(BOARD, search_every=1000).views(frames)}
    return views, shapes, _truth(rv_b, t_back)


def test_a_board_back_at_its_size_is_found_on_the_half_size_frame(monkeypatch):
    views, shapes, truth = _lost_and_back(np.array([100.0, -100.0, 7000.0]), monkeypatch)
    assert sorted(views) == [0, 1, 6, 7]
    assert (240, 320) in shapes  # squares of about 5 px when last seen: searched at half size
    assert max(_rms(views[k], truth) for k in (6, 7)) < 0.2


def test_a_board_back_smaller_is_found_less_shrunk(monkeypatch):
    views, shapes, truth = _lost_and_back(np.array([300.0, -200.0, 11000.0]), monkeypatch)  # squares ~3 px
    assert sorted(views) == [0, 1, 6, 7]
    assert (240, 320) in shapes and (480, 640) in shapes  # tried at half size, found at full size
    assert max(_rms(views[k], truth) for k in (6, 7)) < 0.25

"""Calibration: corner detection, intrinsics (Bouguet's real images), rig + bundle adjustment, checks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from conftest import real_data_path
from saddlescope.core.calibration import (
    BoardView,
    board_distance_errors,
    bundle_adjust,
    calibrate_intrinsics,
    calibrate_rig,
    find_board_corners,
    make_board,
    metric_checks,
    principal_point_common_shift,
    render_board,
    select_instants,
    simulate_board_views,
    stereo_extrinsics,
    thesis_like_views,
    triangulate_dlt,
)
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.types import Camera, Rig

K640 = np.array([[600.0, 0, 320], [0, 600, 240], [0, 0, 1]])


def _angle_deg(Ra, Rb):
    return float(np.degrees(np.linalg.norm(cv2.Rodrigues(Ra @ Rb.T)[0])))


def _small_rig(rng, *, baseline_mm=150.0, n_cams=2):
    cams = {}
    for i in range(n_cams):
        R = cv2.Rodrigues(np.array([0.0, np.radians(8.0 * i), 0.0]))[0]  # turned towards the board
        centre = np.array([baseline_mm * i, 0.0, 0.0])
        dist = np.array([-0.15, 0.05, 0.0005, -0.0003, 0.0])
        cams[f"c{i}"] = Camera(f"c{i}", K640 + np.diag([5.0 * i, 5.0 * i, 0]), dist, (640, 480), R=R,
                               t_mm=-R @ centre)
    return Rig(cams)


def _random_poses(n, rng, *, centre_mm=(75.0, 0.0, 700.0), board=None):
    cols, rows = board.inner_corners
    half = np.array([(cols - 1) * board.square_mm / 2, (rows - 1) * board.square_mm / 2, 0.0])
    rvecs, ts = [], []
    for _ in range(n):
        rv = np.radians([rng.uniform(-35, 35), rng.uniform(-35, 35), rng.uniform(-20, 20)])
        c = np.asarray(centre_mm) + [rng.uniform(-150, 150), rng.uniform(-100, 100), rng.uniform(-100, 150)]
        rvecs.append(rv)
        ts.append(c - cv2.Rodrigues(rv)[0] @ half)
    return np.array(rvecs), np.array(ts)


def _board_scene(seed: int, n_poses: int, noise_px: float, *, n_cams: int = 2):
    """A checkerboard, a small rig and its simulated views of `n_poses` random board poses."""
    rng = np.random.default_rng(seed)
    board = make_board("checkerboard", (8, 6), 30.0)
    rig = _small_rig(rng, n_cams=n_cams)
    views = simulate_board_views(rig, board, *_random_poses(n_poses, rng, board=board), noise_px=noise_px, rng=rng)
    return board, rig, views


# ---------------------------------------------------------------- detection


def test_rendered_checkerboard_corners_are_subpixel_accurate():
    board = make_board("checkerboard", (7, 6), 30.0)
    cam = Camera("a", K640, np.array([-0.2, 0.05, 0, 0, 0]), (640, 480))
    rv, t = np.array([0.3, -0.2, 0.1]), np.array([-90.0, -60.0, 500.0])
    img = render_board(board, cam, rv, t)
    corners, ids = find_board_corners(img, board)
    truth = cam.project(board.object_points_mm() @ cv2.Rodrigues(rv)[0].T + t)
    assert np.array_equal(ids, np.arange(42))
    assert np.sqrt(np.mean((corners - truth) ** 2)) < 0.1


def test_checkerboard_order_is_the_same_when_the_camera_is_upside_down():
    # (7, 6) has no 180-degree symmetry: the dark square at corner 0 fixes the labelling
    board = make_board("checkerboard", (7, 6), 30.0)
    cam = Camera("a", K640, np.zeros(5), (640, 480))
    img = render_board(board, cam, np.array([0.2, 0.1, 0.05]), np.array([-90.0, -70.0, 520.0]))
    c_up, _ = find_board_corners(img, board)
    c_down, _ = find_board_corners(cv2.rotate(img, cv2.ROTATE_180), board)
    assert np.allclose(c_down, [639, 479] - c_up, atol=0.2)


def test_charuco_normal_and_inverted_prints():
    board = make_board("charuco", (4, 3), 30.0, dictionary="DICT_4X4_50")
    cam = Camera("a", K640, np.zeros(5), (640, 480))
    rv, t = np.array([0.3, -0.2, 0.1]), np.array([-70.0, -50.0, 450.0])
    img = render_board(board, cam, rv, t)
    corners, ids = find_board_corners(img, board)
    truth = cam.project(board.object_points_mm()[ids] @ cv2.Rodrigues(rv)[0].T + t)
    assert len(ids) == 12 and np.abs(corners - truth).max() < 0.3
    assert find_board_corners(255 - img, board) is not None  # caliscope's white-on-black print
    assert find_board_corners(255 - img, board, inverted=False) is None


def test_no_board_in_a_blank_frame():
    board = make_board("checkerboard", (7, 6), 30.0)
    assert find_board_corners(np.full((480, 640), 90, np.uint8), board) is None


def test_make_board_rejects_nonsense():
    with pytest.raises(InputError, match="square"):
        make_board("checkerboard", (7, 6), -3)
    with pytest.raises(InputError, match="dictionary"):
        make_board("charuco", (4, 3), 30, dictionary="DICT_NOPE")
    with pytest.raises(InputError, match="kind"):
        make_board("circles", (4, 3), 30)


# ---------------------------------------------------------------- intrinsics on real data


def _bouguet_views(board):
    folder = real_data_path("bouguet_calib_example")
    views = []
    for i in range(1, 21):
        img = cv2.imread(str(folder / f"Image{i}.tif"), cv2.IMREAD_GRAYSCALE)
        found = find_board_corners(img, board)
        if found is not None:
            views.append(BoardView(i, *found))
    return views


@pytest.mark.realdata
def test_bouguet_intrinsics_within_published_three_sigma():
    board = make_board("checkerboard", (12, 13), 30.0)
    views = _bouguet_views(board)
    assert len(views) == 20  # SB finds the board in all 20 images (classic finds fewer)
    cam, report = calibrate_intrinsics(views, board, (640, 480), camera="bouguet")
    fc, fc3 = np.array([657.46290, 657.94673]), np.array([0.31819, 0.34046])
    cc, cc3 = np.array([303.13665, 242.56935]), np.array([0.64682, 0.59218])
    kc, kc3 = np.array([-0.25403, 0.12143, -0.00021, 0.00002]), np.array([0.00248, 0.00986, 0.00013, 0.00013])
    assert np.all(np.abs(np.diag(cam.K)[:2] - fc) <= fc3)
    assert np.all(np.abs(cam.K[:2, 2] - cc) <= cc3)
    assert np.all(np.abs(cam.dist[:4] - kc) <= kc3)
    assert cam.dist[4] == 0.0
    assert max(report["residual_std_px"]) < 0.2
    # OpenCV's standard deviations match Bouguet's (his bounds are 3 sigma)
    assert np.all((np.diag(cam.K_std)[:2] > 0.5 * fc3 / 3) & (np.diag(cam.K_std)[:2] < 2 * fc3 / 3))


# ---------------------------------------------------------------- rig


@pytest.mark.slow
def test_synthetic_thesis_rig_ninety_poses():
    rng = np.random.default_rng(7)
    truth, board, views, sizes = thesis_like_views(90, rng=rng, noise_px=0.1)
    rig, report = calibrate_rig(views, board, sizes)
    assert list(rig.cameras) == ["left", "middle", "right"]
    assert np.allclose(rig.cameras["left"].R, np.eye(3)) and np.allclose(rig.cameras["left"].t_mm, 0)
    for name, cam in rig.cameras.items():
        true = truth.cameras[name]
        assert abs(cam.K[0, 0] / true.K[0, 0] - 1) < 0.005
        assert abs(cam.K[1, 1] / true.K[1, 1] - 1) < 0.005
        assert np.allclose(cam.K[:2, 2], true.K[:2, 2], atol=3.0)
        assert np.abs(cam.K[0, 0] - true.K[0, 0]) < 4 * cam.K_std[0, 0]  # honest uncertainties
        assert np.linalg.norm(cam.t_mm - true.t_mm) < 3.0
        assert _angle_deg(cam.R, true.R) < 0.1
    assert report["bundle"]["rms_px"] < 0.2
    assert rig.checks["board_square_error_pct"] < 0.5
    assert abs(rig.checks["board_scale_error_pct"]) < 0.1
    assert rig.flags == ()
    assert set(rig.pairs) == {"left-middle", "left-right", "middle-right"}
    # the thesis's pair baselines (Table 8.4: about 230 and 450 mm)
    baseline_mm = np.linalg.norm(truth.cameras["right"].t_mm)
    assert abs(np.linalg.norm(rig.pairs["left-right"]["t_mm"]) - baseline_mm) < 5


@pytest.mark.slow
def test_principal_points_moved_together_by_the_joint_adjustment_are_flagged(monkeypatch):
    # Board held in a band across the images: a common shift of every principal point and a common
    # tilt of the rig fit almost equally, and a hundredth of a pixel of disagreement between the
    # cameras moved all three by 10-40 px on 50-60 fps thesis-rig rides. Each camera alone stays put;
    # the rig is flagged when the joint solution leaves them all the same way.
    from saddlescope.core.calibration import rig as rig_module

    rng = np.random.default_rng(7)
    _, board, views, sizes = thesis_like_views(40, rng=rng, noise_px=0.1)
    clean, _ = calibrate_rig(views, board, sizes)
    assert clean.checks["principal_point_common_shift_px"] < 3.0 and clean.flags == ()
    real_bundle = rig_module.bundle_adjust

    def drifting_bundle(cams, *args, dy_px, **kw):
        out, rep = real_bundle(cams, *args, **kw)
        moved = {}
        for n, c in out.items():
            K = c.K.copy()
            K[1, 2] += dy_px + (3.0 if n == "middle" else -1.5)  # each camera's own scatter differs
            moved[n] = Camera(n, K, c.dist, c.image_size, R=c.R, t_mm=c.t_mm, rms_px=c.rms_px)
        return moved, rep

    for dy, flagged in ((-25.0, True), (-5.0, False)):
        monkeypatch.setattr(rig_module, "bundle_adjust",
                            lambda cams, *a, _dy=dy, **kw: drifting_bundle(cams, *a, dy_px=_dy, **kw))
        rig, _ = calibrate_rig(views, board, sizes)
        shift = rig.checks["principal_point_common_shift_px"]
        assert abs(shift - abs(dy)) < 3.0 + clean.checks["principal_point_common_shift_px"], shift
        assert ("calibration.principal_point" in [f.code for f in rig.flags]) is flagged, rig.flags
    assert principal_point_common_shift({"a": clean.cameras["left"]}, {"a": clean.cameras["left"]}).tolist() == [0, 0]


def test_bundle_adjustment_recovers_a_disturbed_rig():
    board, truth, views = _board_scene(3, 25, 0.05, n_cams=3)
    start = {}
    for n, c in truth.cameras.items():
        R = c.R if n == "c0" else cv2.Rodrigues(np.array([0.02, -0.01, 0.01]))[0] @ c.R
        t = c.t_mm if n == "c0" else c.t_mm + [8.0, -5.0, 10.0]
        start[n] = Camera(n, c.K * [[1.02], [0.98], [1]], c.dist * 0.5, c.image_size, R=R, t_mm=t)
    cams, report = bundle_adjust(start, views, board)
    for n, c in cams.items():
        assert np.allclose(c.K, truth.cameras[n].K, atol=1.0)
        assert np.linalg.norm(c.t_mm - truth.cameras[n].t_mm) < 0.6
        assert _angle_deg(c.R, truth.cameras[n].R) < 0.15
        if n != "c0":  # errors within 4 reported standard deviations
            rv_std, t_std = report["pose_std"][n]
            assert np.all(np.abs(c.t_mm - truth.cameras[n].t_mm) < 4 * t_std)
            assert _angle_deg(c.R, truth.cameras[n].R) < 4 * np.degrees(np.linalg.norm(rv_std))
    assert report["rms_px"] < 0.1
    with pytest.raises(CalibrationError, match="camera c2 has no board view"):
        bundle_adjust(start, {**views, "c2": []}, board)


def test_stereo_pair_matches_truth_and_needs_shared_views():
    board, truth, views = _board_scene(5, 15, 0.05)
    a, b = truth.cameras["c0"], truth.cameras["c1"]
    pair = stereo_extrinsics(views["c0"], views["c1"], a, b, board)
    assert np.linalg.norm(pair["t_mm"] - b.t_mm) < 1.0 and _angle_deg(pair["R"], b.R) < 0.05
    with pytest.raises(CalibrationError, match="c0 and c1 see the board together in only 2"):
        stereo_extrinsics(views["c0"][:2], views["c1"][:2], a, b, board)


def test_metric_check_flags_a_wrongly_scaled_rig():
    board, truth, views = _board_scene(11, 10, 0.02)
    checks, flags, pairs = metric_checks(truth, views, board)
    assert checks["board_square_error_pct"] < 0.2 and flags == []
    assert checks["corner_distance_error_rms_mm"] < 0.5 and "c0-c1" in pairs
    c1 = truth.cameras["c1"]
    wrong = Rig({"c0": truth.cameras["c0"], "c1": Camera("c1", c1.K, c1.dist, c1.image_size, R=c1.R,
                                                         t_mm=c1.t_mm * 1.05)})
    checks, flags, _ = metric_checks(wrong, views, board)
    assert abs(checks["board_scale_error_pct"] - 5.0) < 1.0
    assert [f.code for f in flags] == ["calibration.square_error"]
    assert "recalibrate" in flags[0].detail and flags[0].values["limit_pct"] == 1.0
    assert flags[0].values["square_error_pct"] == pytest.approx(checks["board_square_error_pct"])
    _, flags, _ = metric_checks(truth, views, board, max_distance_rms_mm=0.001)
    assert "calibration.corner_distances" in [f.code for f in flags]


def test_triangulate_dlt_exact_without_noise_and_nan_where_unseen():
    rng = np.random.default_rng(2)
    rig = _small_rig(rng, n_cams=3)
    pts = rng.uniform([-100, -100, 500], [200, 100, 900], (20, 3))
    xy = np.stack([c.project(pts) for c in rig.cameras.values()])
    xy[1:, 0] = np.nan  # point 0 seen by one camera only
    xy[2, 1] = np.nan  # point 1 seen by two
    xyz, err = triangulate_dlt(list(rig.cameras.values()), xy)
    assert np.isnan(xyz[0]).all() and np.isnan(err[0])
    assert np.allclose(xyz[1:], pts[1:], atol=1e-6) and np.all(err[1:] < 1e-6)


def test_board_distance_errors_zero_for_truth():
    board, rig, views = _board_scene(4, 5, 0.0)
    errs = board_distance_errors(rig, views, board)
    assert errs["n_instants"] == 5
    assert np.abs(errs["distance_errors_mm"]).max() < 1e-3 and np.allclose(errs["scales"], 1, atol=1e-6)


def test_board_distance_errors_skip_a_line_of_corners_and_keep_neighbours_within_an_instant():
    from dataclasses import replace

    board, rig, views = _board_scene(5, 4, 0.0)
    full = board_distance_errors(rig, views, board)
    # one instant shows a single row of corners (no plane), another three corners (too few): both skipped
    line, few = sorted({v.frame for v in views["c0"]})[:2]
    cut = {c: [replace(v, ids=v.ids[:8], corners_px=v.corners_px[:8]) if v.frame == line
               else replace(v, ids=v.ids[:3], corners_px=v.corners_px[:3]) if v.frame == few else v for v in vs]
           for c, vs in views.items()}
    errs = board_distance_errors(rig, cut, board)
    assert full["n_instants"] == 4 and errs["n_instants"] == 2 and errs["n_points"] == 2 * 48
    # 7 x 6 horizontal and 8 x 5 vertical neighbours per whole board; none across two instants
    assert full["adjacent_errors_mm"].size == 4 * (7 * 6 + 8 * 5) and errs["adjacent_errors_mm"].size == 2 * 82
    assert np.abs(full["adjacent_errors_mm"]).max() < 1e-3
    assert full["distance_errors_mm"].size == 4 * 48 * 47 // 2


def test_select_instants_spreads_views():
    rng = np.random.default_rng(8)
    board = make_board("checkerboard", (8, 6), 30.0)
    rig = _small_rig(rng)
    rvecs, ts = _random_poses(40, rng, board=board)
    ts[:30] = ts[0]  # thirty copies of one position, ten spread ones
    rvecs[:30] = rvecs[0]
    views = simulate_board_views(rig, board, rvecs, ts, noise_px=0.0, rng=rng)
    chosen = select_instants(views, board, {"c0": (640, 480), "c1": (640, 480)}, max_instants=12)
    assert len(chosen) == 12
    assert sum(f < 30 for f in chosen) <= 3  # the repeated pose is not picked again and again


# ---------------------------------------------------------------- bad input


def test_no_board_and_too_few_views_name_the_camera():
    board = make_board("checkerboard", (8, 6), 30.0)
    with pytest.raises(CalibrationError, match="no calibration board found in the calibration clip of the "
                                               "middle camera"):
        calibrate_intrinsics([], board, (640, 480), camera="middle", clip="calibration")
    rng = np.random.default_rng(1)
    rig = _small_rig(rng)
    views = simulate_board_views(rig, board, *_random_poses(4, rng, board=board), noise_px=0.05, rng=rng)
    with pytest.raises(CalibrationError, match=r"found in only 4 frame\(s\) of the calibration clip of the "
                                               r"right camera; need at least 6"):
        calibrate_intrinsics(views["c0"], board, (640, 480), camera="right", clip="calibration")


def test_calibrate_rig_names_the_unlinked_camera():
    board, rig, views = _board_scene(6, 16, 0.05)
    # c1 sees the board only at instants c0 does not
    c0 = [v for v in views["c0"] if v.frame < 8]
    c1 = [v for v in views["c1"] if v.frame >= 8]
    with pytest.raises(CalibrationError, match="c1 never see the board together with camera c0"):
        calibrate_rig({"c0": c0, "c1": c1}, board, {"c0": (640, 480), "c1": (640, 480)}, min_views=6)


def test_bad_corner_ids_are_rejected():
    board = make_board("checkerboard", (8, 6), 30.0)
    bad = [BoardView(i, np.zeros((8, 2)), np.arange(40, 48) + 10) for i in range(6)]
    with pytest.raises(InputError, match="outside the board"):
        calibrate_intrinsics(bad, board, (640, 480), camera="left")


@pytest.mark.slow
def test_an_action_camera_lens_gets_its_k3_from_a_board_in_the_middle_of_the_view():
    # 90-degree lenses 5.5 m from the track, 1920x1080, strong barrel distortion; the 0.6 m board
    # covers the middle of each view, as a club would move it. From OpenCV's distortion-free
    # start the free-k3 fit stopped in a wrong minimum and k3 stayed fixed at zero: focal lengths
    # came out 1-2 % long, and a rig's scale with them.
    rng = np.random.default_rng(11)
    board = make_board("checkerboard", (12, 11), 50.0)
    cams = {}
    for i, (f, k) in enumerate([(1000.0, (-0.27, 0.09, 0.0003, -0.0002, -0.012)),
                                (990.0, (-0.26, 0.085, -0.0002, 0.0001, -0.013))]):
        R = cv2.Rodrigues(np.array([0.0, -np.arctan2(2000.0 * i, 5500.0), 0.0]))[0]  # turned to the track
        K = np.array([[f, 0, 960.0 + 4 * i], [0, f, 540.0 - 3 * i], [0, 0, 1]])
        cams[f"c{i}"] = Camera(f"c{i}", K, np.array(k), (1920, 1080), R=R, t_mm=-R @ [2000.0 * i, 0.0, 0.0])
    truth = Rig(cams)
    half = np.array([11 * 25.0, 10 * 25.0, 0.0])
    rvecs, ts = [], []
    for _ in range(120):
        rv = np.radians([rng.uniform(-35, 35), rng.uniform(-35, 35), rng.uniform(-15, 15)])
        c = np.array([1000.0 + rng.uniform(-2000, 2000), rng.uniform(-700, 700), 5000.0 + rng.uniform(-500, 500)])
        rvecs.append(rv)
        ts.append(c - cv2.Rodrigues(rv)[0] @ half)
    views = simulate_board_views(truth, board, np.array(rvecs), np.array(ts), noise_px=0.15, rng=rng)
    rig, report = calibrate_rig(views, board, {n: (1920, 1080) for n in cams})
    chosen = {name: report["intrinsics"][name]["k3_test"]["chosen"] for name in cams}
    assert "free" in chosen.values()
    for name, cam in rig.cameras.items():
        true = truth.cameras[name]
        assert abs(cam.K[0, 0] / true.K[0, 0] - 1) < 0.003  # was 1.0 and 1.3 % long
        if chosen[name] == "free":
            assert abs(cam.dist[4] - true.dist[4]) < 0.002


def test_an_outlier_view_is_dropped_only_where_a_round_follows():
    rng = np.random.default_rng(5)
    _, board, views, sizes = thesis_like_views(20, rng=rng, noise_px=0.1)
    left = list(views["left"])
    left[3] = BoardView(left[3].frame, left[3].corners_px + rng.normal(0.0, 4.0, left[3].corners_px.shape), left[3].ids)
    _, kept = calibrate_intrinsics(left, board, sizes["left"], max_rounds=0)  # one fit: nothing to refit with
    assert kept["dropped_frames"] == [] and kept["n_views"] == len(left)
    _, refit = calibrate_intrinsics(left, board, sizes["left"])
    assert refit["dropped_frames"] == [left[3].frame] and refit["n_views"] == len(left) - 1

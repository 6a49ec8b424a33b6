"""Triangulation: analytic truth on a thesis-like rig, outliers, gaps, labels, sync resampling, real data."""

from __future__ import annotations

import csv
import tomllib

import cv2
import numpy as np
import pytest

from conftest import real_data_path
from saddlescope.core.errors import InputError, TriangulationError
from saddlescope.core.triangulation import (
    match_markers_across_cameras,
    reprojection_errors,
    resample_tracks,
    triangulate_nview,
    triangulate_thesis_pairs,
    triangulate_tracks,
)
from saddlescope.core.types import Camera, ImageTracks, Rig


def thesis_rig() -> Rig:
    """Three 640x480 cameras, f ~730 px, 0.23 m apart, slightly toed in (thesis Tables 8.1-8.4)."""
    cams = {}
    for i, name in enumerate(("left", "middle", "right")):
        K = np.array([[730.0 + i, 0, 320 + 2 * i], [0, 728.0 - i, 240 - i], [0, 0, 1]])
        dist = np.array([-0.12 + 0.01 * i, 0.15, 0.0005, -0.0003, 0.0])
        R = np.eye(3) if i == 0 else cv2.Rodrigues(np.array([0.002 * i, -0.01 * i, 0.001]))[0]
        centre = np.array([230.0 * i, 3.0 * i, 0.0])
        cams[name] = Camera(name, K, dist, (640, 480), R, -R @ centre)
    return Rig(cams)


def scene_points(rng, n):
    """Points in a 5 m wide, 3 m high slab 6.5-8.5 m in front of the rig (mm)."""
    return np.column_stack([rng.uniform(-2500, 2500, n), rng.uniform(-1500, 1500, n),
                            rng.uniform(6500, 8500, n)])


@pytest.fixture
def rig():
    return thesis_rig()


def test_nview_exact_without_noise(rig):
    rng = np.random.default_rng(1)
    X = scene_points(rng, 300)
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    xyz, err, views = triangulate_nview(rig, xy)
    assert np.max(np.abs(xyz - X)) < 1e-6
    assert np.max(err) < 1e-6
    assert np.all(views == 3)


def test_thesis_pairs_exact_without_noise(rig):
    rng = np.random.default_rng(2)
    X = scene_points(rng, 300).reshape(100, 3, 3)  # any leading shape
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    xyz, err, views = triangulate_thesis_pairs(rig, xy)
    assert xyz.shape == (100, 3, 3)
    assert np.max(np.abs(xyz - X)) < 1e-6
    assert np.all(views == 3)


def test_thesis_pairs_use_each_pairs_own_extrinsics(rig):
    """A pair calibration stored in rig.pairs is what the pair triangulates with (eq. 5.1-5.3)."""
    rng = np.random.default_rng(3)
    X = scene_points(rng, 20)
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    m, r = rig.cameras["middle"], rig.cameras["right"]
    R_rm = r.R @ m.R.T
    exact = {"R": R_rm, "t_mm": r.t_mm - R_rm @ m.t_mm}
    off = {"R": R_rm, "t_mm": exact["t_mm"] + np.array([5.0, 0, 0])}  # 5 mm baseline error
    same, _, _ = triangulate_thesis_pairs(Rig(rig.cameras, pairs={"middle-right": exact}), xy)
    assert np.max(np.abs(same - X)) < 1e-6
    moved, _, _ = triangulate_thesis_pairs(Rig(rig.cameras, pairs={"middle-right": off}), xy)
    assert np.max(np.abs(moved - X)) > 1.0
    ignored, _, _ = triangulate_thesis_pairs(Rig(rig.cameras, pairs={"middle-right": off}), xy,
                                             use_pair_extrinsics=False)
    assert np.max(np.abs(ignored - X)) < 1e-6


def test_noise_nview_no_worse_than_pairs(rig):
    rng = np.random.default_rng(4)
    X = scene_points(rng, 400)
    xy = {n: c.project(X) + rng.normal(0, 0.1, (400, 2)) for n, c in rig.cameras.items()}
    a, err, _ = triangulate_nview(rig, xy)
    b, _, _ = triangulate_thesis_pairs(rig, xy)
    rms_a = np.sqrt(np.mean(np.sum((a - X) ** 2, axis=1)))
    rms_b = np.sqrt(np.mean(np.sum((b - X) ** 2, axis=1)))
    # 0.1 px over a 0.46 m baseline at 7.5 m: a few cm, mostly in depth.
    assert rms_a < 40 and rms_a <= 1.02 * rms_b
    assert 0.03 < np.median(err) < 0.2


def test_outlier_camera_is_rejected(rig):
    rng = np.random.default_rng(5)
    X = scene_points(rng, 60)
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    xy["right"][:20, 1] += 10.0  # a wrong blob 10 px off the epipolar line
    xyz, err, views, used = triangulate_nview(rig, xy, return_used=True)
    assert np.all(views[:20] == 2) and np.all(views[20:] == 3)
    assert not used[2, :20].any() and used[:2, :20].all()
    assert np.max(np.abs(xyz - X)) < 1e-6
    kept, _, kept_views = triangulate_nview(rig, xy, reject_outliers=False)
    assert np.all(kept_views == 3) and np.max(np.abs(kept[:20] - X[:20])) > 10


def test_outlier_in_a_four_camera_ring_is_rejected():
    """Four cameras around a volume: even an error along one epipolar direction is pinned down."""
    cams = {}
    K = np.array([[900.0, 0, 640], [0, 900, 360], [0, 0, 1]])
    target = np.array([0.0, 0.0, 3000.0])
    for i, yaw in enumerate((0.0, 0.6, -0.6, 0.3)):
        centre = target + 3000 * np.array([np.sin(yaw), -0.1 * (i % 2), -np.cos(yaw)])
        z = (target - centre) / np.linalg.norm(target - centre)  # look at the volume's centre
        x = np.cross([0.0, 1.0, 0.0], z)
        x /= np.linalg.norm(x)
        R = np.stack([x, np.cross(z, x), z])
        cams[str(i)] = Camera(str(i), K, np.zeros(5), (1280, 720), R, -R @ centre)
    rig4 = Rig(cams)
    rng = np.random.default_rng(6)
    X = np.column_stack([rng.uniform(-300, 300, 40), rng.uniform(-300, 300, 40), rng.uniform(2800, 3200, 40)])
    xy = {n: c.project(X) + rng.normal(0, 0.2, (40, 2)) for n, c in rig4.cameras.items()}
    xy["3"][:10, 0] += 25.0
    xyz, err, views, used = triangulate_nview(rig4, xy, return_used=True)
    assert not used[3, :10].any() and used[:, 10:].all()
    assert np.all(err < 1.0)
    assert np.max(np.linalg.norm(xyz - X, axis=1)) < 5


def test_error_along_a_collinear_baseline_is_not_pinned_on_a_camera(rig):
    """With three nearly collinear cameras a horizontal error fits any camera: keep all, show the error."""
    rng = np.random.default_rng(7)
    X = scene_points(rng, 10)
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    xy["middle"][:, 0] += 10.0
    _, err, views = triangulate_nview(rig, xy)
    assert np.all(views == 3)
    assert np.all(err > 2.0)


def test_gaps(rig):
    rng = np.random.default_rng(8)
    X = scene_points(rng, 6)
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    xy["left"][0] = np.nan
    xy["left"][1] = np.nan
    xy["middle"][1] = np.nan
    for fn in (triangulate_nview, triangulate_thesis_pairs):
        xyz, err, views = fn(rig, xy)
        assert views.tolist() == [2, 0, 3, 3, 3, 3]
        assert np.all(np.isnan(xyz[1])) and np.isnan(err[1])
        assert np.max(np.abs(xyz[[0, 2, 3, 4, 5]] - X[[0, 2, 3, 4, 5]])) < 1e-6


def test_bad_input(rig):
    xy = {"left": np.zeros((3, 2)), "middle": np.zeros((4, 2))}
    with pytest.raises(InputError, match="middle"):
        triangulate_nview(rig, xy)
    with pytest.raises(InputError, match="'top'"):
        triangulate_nview(rig, {"left": np.zeros((3, 2)), "top": np.zeros((3, 2))})
    with pytest.raises(InputError, match=r"\(\.\.\., 2\)"):
        triangulate_nview(rig, {"left": np.zeros((3, 3)), "middle": np.zeros((3, 3))})


def test_reprojection_errors_per_camera(rig):
    X = np.array([[100.0, -50.0, 7000.0]])
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    xy["right"] = xy["right"] + [3.0, 4.0]
    errs = reprojection_errors(rig, X, xy)
    np.testing.assert_allclose(errs["right"], [5.0], atol=1e-9)
    np.testing.assert_allclose(errs["left"], [0.0], atol=1e-9)


def horse_markers(t_s):
    """Three markers 0.3 m apart along a horse's back moving across the scene (mm), shape (F, 3, 3)."""
    t = np.asarray(t_s)[:, None]
    base = np.array([[-300.0, 0, 0], [0, 10, 0], [300, 0, 0]])
    centre = np.column_stack([-1500 + 3000 * t[:, 0], 60 * np.sin(2 * np.pi * 1.6 * t[:, 0]),
                              7500 + 200 * t[:, 0]])
    return centre[:, None, :] + base[None]


def test_match_markers_across_cameras(rig):
    X = horse_markers(np.array([0.3]))[0]
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    xy["middle"] = xy["middle"][[2, 0, 1]]
    xy["right"] = xy["right"][[1, 2, 0]]
    xy["right"][2] = np.nan  # a marker the right camera missed
    perms = match_markers_across_cameras(rig, xy)
    assert perms["left"].tolist() == [0, 1, 2]
    assert perms["middle"].tolist() == [1, 2, 0]
    assert perms["right"][[1, 2]].tolist() == [0, 1]  # the seen ones; the missing one goes where it fits


def test_match_markers_over_several_instants_outvotes_a_bad_one(rig):
    X = horse_markers(np.linspace(0.1, 0.6, 6))  # (6, 3, 3)
    xy = {n: c.project(X) for n, c in rig.cameras.items()}
    xy["middle"] = xy["middle"][:, [1, 2, 0]]
    xy["right"][2] = [[600.0, 20.0], [10.0, 400.0], [320.0, 470.0]]  # one frame of junk in one camera
    perms = match_markers_across_cameras(rig, xy)
    assert perms["middle"].tolist() == [2, 0, 1] and perms["right"].tolist() == [0, 1, 2]


def test_resample_tracks_interpolates_and_keeps_gaps():
    xy = np.arange(10 * 1 * 2, dtype=float).reshape(10, 1, 2)  # x = 2k, y = 2k + 1 at frame 10 + k
    xy[5] = np.nan
    tracks = ImageTracks("middle", xy, np.arange(10, 20))
    out = resample_tracks(tracks, np.array([10.0, 10.25, 14.0, 14.5, 15.0, 16.0, 19.0, 19.5, 9.5]))
    np.testing.assert_allclose(out[:2, 0, 0], [0.0, 0.5])
    np.testing.assert_allclose(out[2, 0], [8.0, 9.0])
    assert np.isnan(out[3]).all() and np.isnan(out[4]).all()  # next to / on the gap
    np.testing.assert_allclose(out[5, 0], [12.0, 13.0])
    np.testing.assert_allclose(out[6, 0], [18.0, 19.0])
    assert np.isnan(out[7]).all() and np.isnan(out[8]).all()  # outside the tracked frames


def test_resample_tracks_cubic_follows_curved_motion():
    k = np.arange(20, dtype=float)
    xy = np.stack([k ** 2, k ** 3 / 10], axis=-1)[:, None, :]  # accelerating marker
    tracks = ImageTracks("right", xy, np.arange(20))
    at = np.array([5.5, 10.25, 0.5, 18.5])
    cubic = resample_tracks(tracks, at)
    linear = resample_tracks(tracks, at, kind="linear")
    np.testing.assert_allclose(cubic[:2, 0], np.stack([at[:2] ** 2, at[:2] ** 3 / 10], axis=-1), atol=1e-9)
    assert abs(linear[0, 0, 0] - 5.5 ** 2) == pytest.approx(0.25)  # linear misses by a/8 = 2/8
    # At the ends (no second neighbour) the cubic falls back to linear.
    np.testing.assert_allclose(cubic[2:], linear[2:])


def test_triangulate_tracks_with_subframe_offsets_and_relabelling(rig):
    fps = 30.0
    offsets = {"left": 0.0, "middle": 53.4, "right": 126.7}
    frames_left = np.arange(0, 40)
    tracks = {}
    for name, cam in rig.cameras.items():
        # Camera frame j shows the instant of left frame j - offset (CONTRACTS: left k = camera k + offset).
        frames = np.arange(int(offsets[name]) - 2, int(offsets[name]) + 44)
        X = horse_markers((frames - offsets[name]) / fps)
        xy = cam.project(X)
        if name == "middle":
            xy = xy[:, [1, 2, 0]]  # this camera labelled the markers differently
        if name == "right":
            xy[10, 1] = np.nan  # a one-frame gap
        tracks[name] = ImageTracks(name, xy, frames)
    tracks["left"] = ImageTracks("left", tracks["left"].xy_px[2:42], frames_left)
    result = triangulate_tracks(rig, tracks, offsets, fps)
    truth = horse_markers(frames_left / fps)
    assert result.xyz_mm.shape == (40, 3, 3) and result.names == ("1", "2", "3")
    np.testing.assert_allclose(result.t_s, frames_left / fps)
    # The right camera's gap at its frame 10 + 126 - ... reaches the left frames it is blended into.
    assert np.all(result.views[:, 0] == 3)
    assert (result.views[:, 1] == 2).sum() == 2
    err = np.linalg.norm(result.xyz_mm - truth, axis=-1)
    # Linear interpolation of image tracks at 1/30 s: well under the noise of a real rig.
    assert np.nanmax(err) < 5.0
    assert np.nanmedian(err) < 1.0
    pairs = triangulate_tracks(rig, tracks, offsets, fps, method="thesis_pairs")
    assert np.nanmax(np.linalg.norm(pairs.xyz_mm - truth, axis=-1)) < 10.0


def _phone_times(n, fps, rng, *, drops, steady=6):
    """A phone's frame timestamps: even for ``steady`` frames (the sync flash), then each frame late
    by up to 0.3 frame of jitter plus the frames dropped before it (at frames ``drops``)."""
    k = np.arange(n)
    dropped = np.sum(k[:, None] > np.asarray(drops)[None, :], axis=1)
    late = np.where(k >= steady, dropped + rng.uniform(-0.3, 0.3, n), 0.0)
    return (k + late) / fps


def test_variable_rate_clips_are_placed_at_their_timestamps(rig):
    # Every camera, the reference too, drops frames and jitters; the flash (anchor) is at each clip's
    # frame 2 + offset. Tracks sampled at the stamped instants must triangulate as if even.
    fps, rng = 30.0, np.random.default_rng(5)
    offsets = {"left": 0.0, "middle": 7.4, "right": 3.7}
    n = 70
    tracks, clocks = {}, {}
    for name, cam in rig.cameras.items():
        times = _phone_times(n, fps, rng, drops=[15 + 7 * len(name), 30, 44 + len(name)])
        anchor = 2.0 + offsets[name]
        # the instant of clip frame j on the left camera's nominal clock: nominal frames from the anchor
        nominal = anchor + (times - np.interp(anchor, np.arange(n), times)) * fps
        tracks[name] = ImageTracks(name, cam.project(horse_markers((nominal - offsets[name]) / fps)), np.arange(n))
        clocks[name] = (times, anchor)
    frames_left = tracks["left"].frame_index[5:55]
    tracks["left"] = ImageTracks("left", tracks["left"].xy_px[5:55], frames_left)
    result = triangulate_tracks(rig, tracks, offsets, fps, clocks=clocks)
    np.testing.assert_allclose(result.t_s, frames_left / fps)  # the nominal clock stays even
    left_nominal_s = frames_left / fps
    err = np.linalg.norm(result.xyz_mm - horse_markers(left_nominal_s), axis=-1)
    assert np.nanmax(err) < 5.0 and np.isfinite(err).all()
    # read as even clips, the same tracks are frames off after the first drop
    naive = triangulate_tracks(rig, tracks, offsets, fps)
    assert np.nanmax(np.linalg.norm(naive.xyz_mm - horse_markers(left_nominal_s), axis=-1)) > 50.0


def test_cubic_resampling_goes_through_uneven_frames():
    times = np.array([0.0, 1.0, 2.0, 4.0, 5.0, 6.5, 7.0])  # frame 3 after a drop, frame 5 late
    xy = np.stack([times ** 3, 2.0 * times], axis=-1)[:, None, :]
    tracks = ImageTracks("right", xy, np.arange(7))
    at = np.array([2.5, 3.5, 4.0, 1.25])
    out = resample_tracks(tracks, at, frame_times_s=times)
    t_at = np.interp(at, np.arange(7), times)  # a fraction of a frame is that fraction of its interval
    np.testing.assert_allclose(out[:, 0], np.stack([t_at ** 3, 2.0 * t_at], axis=-1), atol=1e-9)
    even = resample_tracks(tracks, at)
    assert abs(even[0, 0, 0] - 3.0 ** 3) > 0.1  # even nodes miss the cubic across the double interval


def test_triangulate_tracks_bad_input(rig):
    tr = ImageTracks("left", np.zeros((5, 3, 2)), np.arange(5))
    with pytest.raises(TriangulationError, match="two cameras"):
        triangulate_tracks(rig, {"left": tr}, {}, 30.0)
    with pytest.raises(InputError, match="frame rate"):
        triangulate_tracks(rig, {"left": tr, "middle": tr}, {}, 0.0)
    other = ImageTracks("middle", np.zeros((5, 2, 2)), np.arange(5))
    with pytest.raises(InputError, match="middle"):
        triangulate_tracks(rig, {"left": tr, "middle": other}, {}, 30.0)
    with pytest.raises(InputError, match="method"):
        triangulate_tracks(rig, {"left": tr, "middle": tr}, {}, 30.0, method="magic")


# --------------------------------------------------------------------------------------------------
# Real data: caliscope's four webcams and ChArUco corners
# --------------------------------------------------------------------------------------------------

def _caliscope_rig(path) -> Rig:
    """caliscope's cameras in their world frame: x_c = R X + t with t in metres (a tiny loader)."""
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    cams = {}
    for key, c in data["cameras"].items():
        cams[key] = Camera(key, np.array(c["matrix"], float), np.array(c["distortions"], float),
                           tuple(c["size"]), np.array(c["rotation"], float),
                           np.array(c["translation"], float) * 1000.0)
    return Rig(cams)


@pytest.fixture(scope="module")
def caliscope():
    base = real_data_path("caliscope_4cam")
    rig = _caliscope_rig(base / "camera_array.toml")
    with open(base / "calibration/extrinsic/CHARUCO/xy_CHARUCO.csv") as fh:
        rows = list(csv.DictReader(fh))
    keys = sorted({(int(r["sync_index"]), int(r["keypoint_id"])) for r in rows})
    index = {k: i for i, k in enumerate(keys)}
    names = sorted({r["cam_id"] for r in rows})
    xy = {n: np.full((len(keys), 2), np.nan) for n in names}
    board_mm = np.zeros((len(keys), 3))
    for r in rows:
        i = index[(int(r["sync_index"]), int(r["keypoint_id"]))]
        xy[r["cam_id"]][i] = float(r["img_loc_x"]), float(r["img_loc_y"])
        board_mm[i] = [1000 * float(r[f"obj_loc_{a}"]) for a in "xyz"]
    with open(base / "calibration/extrinsic/CHARUCO/xyz_CHARUCO.csv") as fh:
        theirs = {(int(r["sync_index"]), int(r["keypoint_id"])):
                  1000 * np.array([float(r["x_coord"]), float(r["y_coord"]), float(r["z_coord"])])
                  for r in csv.DictReader(fh)}
    return rig, xy, board_mm, np.array([k[0] for k in keys]), keys, theirs


def _distance_errors(xyz, board_mm, frame):
    errs = []
    for f in np.unique(frame):
        idx = np.flatnonzero((frame == f) & np.isfinite(xyz[:, 0]))
        a, b = np.triu_indices(idx.size, 1)
        measured = np.linalg.norm(xyz[idx[a]] - xyz[idx[b]], axis=1)
        true = np.linalg.norm(board_mm[idx[a]] - board_mm[idx[b]], axis=1)
        errs.append(measured - true)
    return np.concatenate(errs)


@pytest.mark.realdata
def test_caliscope_corners_match_board_geometry_and_their_triangulation(caliscope):
    rig, xy, board_mm, frame, keys, theirs = caliscope
    xyz, err, views = triangulate_nview(rig, xy)
    assert np.isfinite(xyz[:, 0]).sum() == 660  # every corner seen by >= 2 cameras
    d = _distance_errors(xyz, board_mm, frame)
    assert d.size > 3000
    assert np.sqrt(np.mean(d ** 2)) < 1.5  # measured 1.18 mm
    diff = np.array([np.linalg.norm(xyz[i] - theirs[k]) for i, k in enumerate(keys) if k in theirs])
    assert diff.size == 660
    assert np.max(diff) < 4.0 and np.mean(diff) < 1.5  # measured mean 0.96, max 2.26 mm
    pairs, _, _ = triangulate_thesis_pairs(rig, xy)
    d_pairs = _distance_errors(pairs, board_mm, frame)
    assert np.sqrt(np.mean(d_pairs ** 2)) < 1.5  # measured 1.18 mm


@pytest.mark.realdata
def test_caliscope_with_the_project_loader(caliscope):
    """The project's own caliscope reader (relative to its first camera) gives the same distances."""
    from saddlescope.io.calibration_files import rig_from_caliscope_toml

    _, xy, board_mm, frame, _, _ = caliscope
    rig = rig_from_caliscope_toml(real_data_path("caliscope_4cam", "camera_array.toml"))
    xyz, _, _ = triangulate_nview(rig, {f"cam_{n}": v for n, v in xy.items()})
    d = _distance_errors(xyz, board_mm, frame)
    assert np.sqrt(np.mean(d ** 2)) < 1.5


@pytest.mark.realdata
def test_caliscope_gross_error_is_rejected(caliscope):
    rig, xy, board_mm, frame, keys, theirs = caliscope
    clean, _, _ = triangulate_nview(rig, xy)
    bad = {n: v.copy() for n, v in xy.items()}
    seen_by_all = np.flatnonzero(np.all([np.isfinite(v[:, 0]) for v in xy.values()], axis=0))[:30]
    bad["2"][seen_by_all] += [30.0, -20.0]  # a wrong blob in one camera
    xyz, err, views = triangulate_nview(rig, bad)
    assert np.all(views[seen_by_all] == 3)
    assert np.max(np.linalg.norm(xyz[seen_by_all] - clean[seen_by_all], axis=1)) < 10
    kept, _, _ = triangulate_nview(rig, bad, reject_outliers=False)
    assert np.median(np.linalg.norm(kept[seen_by_all] - clean[seen_by_all], axis=1)) > 10

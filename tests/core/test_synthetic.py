"""The synthetic arena against its own exact geometry, the literature ranges and the thesis rig."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.core.synthetic import (
    BOARD,
    build_scene,
    build_truth,
    check_result_structure,
    render_clip_frames,
    saddle_truth_at,
    true_marker_pixels,
)
from saddlescope.core.synthetic_gait import (
    GAIT_RANGES,
    SADDLE_NAME,
    acceleration_harmonics,
    fourier_series,
    saddle_vertical_peak_to_peak,
    sample_gait,
)
from saddlescope.core.synthetic_render import RenderOptions, flash_fraction
from saddlescope.core.synthetic_rig import make_rig
from saddlescope.core.types import CAMERA_ROLES, GAITS

# Literature ranges (SCIENCE.md "Reference numbers")
LIT = {
    "walk": {"f": (0.85, 0.95), "v": (1.2, 1.8), "pp": (0.01, 0.05)},
    "sitting_trot": {"f": (1.3, 1.5), "v": (2.6, 3.6), "pp": (0.07, 0.16)},
    "rising_trot": {"f": (1.3, 1.5), "v": (2.6, 3.6), "pp": (0.07, 0.16)},
    "canter": {"f": (1.6, 1.7), "v": (3.4, 7.0), "pp": (0.15, 0.30)},
}
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


# --- gait model -----------------------------------------------------------------------------------
@pytest.mark.parametrize("gait", GAITS)
def test_gait_in_literature_ranges_for_several_seeds(gait):
    for seed in range(6):
        m = sample_gait(gait, np.random.default_rng(seed), camera_side=1.0)
        lit = LIT[gait]
        assert lit["f"][0] <= m.stride_hz <= lit["f"][1]
        assert lit["v"][0] <= m.speed_m_s <= lit["v"][1]
        pp = saddle_vertical_peak_to_peak(m)
        assert lit["pp"][0] <= pp <= lit["pp"][1], (gait, seed, pp)
        # dominant vertical harmonic of S: 2x stride in walk and trot, 1x in canter
        t = np.arange(256) * m.period_s / 256
        y = m.point(m.body_points_m[SADDLE_NAME], t)[:, 1]
        spec = np.abs(np.fft.rfft(y))
        assert int(np.argmax(spec[1:5])) + 1 == (1 if gait == "canter" else 2)
        # markers in a rough horizontal row 15-25 cm apart
        b = m.body_points_m
        for a, c in (("marker1", "marker2"), ("marker2", "marker3")):
            assert 0.15 <= np.linalg.norm(b[a] - b[c]) <= 0.25
        assert b[SADDLE_NAME][1] < min(b[f"marker{i}"][1] for i in (1, 2, 3))  # S above (y is down)


def test_fourier_series_derivatives_are_exact():
    rng = np.random.default_rng(0)
    a, p = rng.uniform(0, 1, 4), rng.uniform(-3, 3, 4)
    t, h = np.linspace(0, 2, 40), 1e-5
    f = lambda tt, d=0: fourier_series(tt, 1.3, a, p, derivative=d)  # noqa: E731
    np.testing.assert_allclose(f(t, 1), (f(t + h) - f(t - h)) / (2 * h), atol=1e-7)
    np.testing.assert_allclose(f(t, 2), (f(t + h, 1) - f(t - h, 1)) / (2 * h), atol=1e-6)
    with pytest.raises(InputError):
        fourier_series(t, 1.0, a, p, derivative=3)


@pytest.mark.parametrize("gait", GAITS)
def test_body_kinematics_exact(gait):
    m = sample_gait(gait, np.random.default_rng(3), camera_side=-1.0)
    t, h = np.linspace(0.1, 2.1, 30), 1e-5
    r = m.body_points_m[SADDLE_NAME]
    p = lambda tt: m.point(r, tt)  # noqa: E731
    v, a = m.point(r, t, derivative=1), m.point(r, t, derivative=2)
    np.testing.assert_allclose(v, (p(t + h) - p(t - h)) / (2 * h), atol=1e-8)
    np.testing.assert_allclose(
        a, (m.point(r, t + h, derivative=1) - m.point(r, t - h, derivative=1)) / (2 * h), atol=1e-7
    )
    omega, alpha = m.angular(t)
    np.testing.assert_allclose(alpha, (m.angular(t + h)[0] - m.angular(t - h)[0]) / (2 * h), atol=1e-7)
    # rigid-body formula a = a_O + alpha x r + omega x (omega x r) (eq. 6.38-6.39 form)
    rr = np.einsum("tij,j->ti", m.rotation(t)[0], r)
    a_rb = m.origin(t, derivative=2) + np.cross(alpha, rr) + np.cross(omega, np.cross(omega, rr))
    np.testing.assert_allclose(a, a_rb, atol=1e-12)
    # dR/dt = skew(omega) R
    R, dR, _ = m.rotation(t)
    w = omega
    skew = np.zeros((len(t), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    skew -= np.swapaxes(skew, 1, 2)
    np.testing.assert_allclose(dR, skew @ R, atol=1e-12)


def _stride_locked_share(m, name: str) -> float:
    # share of a marker's skin-motion power at the stride's harmonics, over 40 strides
    t = np.arange(0, 40 / m.stride_hz, 1 / 240)
    y = m.skin_offset(name, t)
    k = np.arange(1, 9)
    arg = np.multiply.outer(t, 2 * np.pi * m.stride_hz * k)
    basis = np.hstack([np.cos(arg), np.sin(arg)])
    fitted = basis @ np.linalg.lstsq(basis, y, rcond=None)[0]
    return float(np.sum(fitted**2) / np.sum((y - y.mean(axis=0)) ** 2))


def test_skin_models_slide_the_same_horse_differently():
    rng = lambda: np.random.default_rng(11)  # noqa: E731
    locked = sample_gait("walk", rng(), camera_side=1.0)  # the default
    noise = sample_gait("walk", rng(), camera_side=1.0, skin_model="noise")
    none = sample_gait("walk", rng(), camera_side=1.0, skin_model="none")
    for other in (noise, none):  # one seed, one horse: only the skin differs
        assert other.stride_hz == locked.stride_hz and other.speed_m_s == locked.speed_m_s
        for name, p in locked.body_points_m.items():
            np.testing.assert_array_equal(other.body_points_m[name], p)
        for ch, (a, ph) in locked.harmonics.items():
            np.testing.assert_array_equal(other.harmonics[ch][0], a)
            np.testing.assert_array_equal(other.harmonics[ch][1], ph)
    assert none.skin == {}
    t = np.linspace(0, 20, 4000)
    for name in ("marker1", "marker2", "marker3"):
        # stride-locked: most of the sliding at the stride's harmonics; noise: a few percent there
        assert _stride_locked_share(locked, name) > 0.6
        assert _stride_locked_share(noise, name) < 0.2
        rms = np.sqrt(np.mean(noise.skin_offset(name, t) ** 2, axis=0))
        assert np.all(rms[:2] > 0.0002) and np.all(rms < 0.0015)  # "small": below 1.5 mm r.m.s.
    with pytest.raises(InputError, match="skin model"):
        sample_gait("walk", rng(), camera_side=1.0, skin_model="sticky")


def test_the_triangle_layout_moves_only_the_middle_marker_of_the_same_horse():
    from saddlescope.core.kinematics.rigid_body import unobservable_axis

    rng = lambda: np.random.default_rng(5)  # noqa: E731
    thesis = sample_gait("canter", rng(), camera_side=1.0)  # the default
    triangle = sample_gait("canter", rng(), camera_side=1.0, marker_layout="triangle")
    assert triangle.stride_hz == thesis.stride_hz and triangle.skin.keys() == thesis.skin.keys()
    for name, p in thesis.body_points_m.items():
        drop = triangle.body_points_m[name] - p
        if name == "marker2":  # about 10 cm below the line of the others instead of 3-5 cm
            assert drop[0] == drop[2] == 0.0 and 0.05 < drop[1] < 0.07
        else:
            assert np.all(drop == 0.0), name
    ratio_thesis, ratio_triangle = (
        unobservable_axis(np.stack([m.body_points_m[f"marker{i}"] for i in (1, 2, 3)])[None], min_eig_ratio=0.0)[1]
        for m in (thesis, triangle))
    assert ratio_triangle > 3 * ratio_thesis  # the roll about the row is far better fixed
    with pytest.raises(InputError, match="marker layout"):
        sample_gait("walk", rng(), camera_side=1.0, marker_layout="square")


def test_the_skin_common_mode_is_the_markers_mean_sliding_and_its_derivatives():
    # what a rigid body fitted to the three markers cannot remove: their mean sliding, in the arena
    m = sample_gait("canter", np.random.default_rng(3), camera_side=1.0)
    t = np.linspace(0.0, 2.0, 2001)
    h = t[1] - t[0]
    rigid = sample_gait("canter", np.random.default_rng(3), camera_side=1.0, skin_model="none")
    mean_slide = np.mean(m.marker_positions(t)[:, :3] - rigid.marker_positions(t)[:, :3], axis=1)
    np.testing.assert_allclose(m.skin_common_mode(t), mean_slide, atol=1e-12)
    p, v, a = (m.skin_common_mode(t, derivative=d) for d in range(3))
    np.testing.assert_allclose((p[2:] - p[:-2]) / (2 * h), v[1:-1], atol=3e-4 * np.abs(v).max())
    np.testing.assert_allclose((p[2:] - 2 * p[1:-1] + p[:-2]) / h**2, a[1:-1], atol=2e-4 * np.abs(a).max())
    assert np.all(rigid.skin_common_mode(t, derivative=2) == 0.0)


def test_acceleration_harmonics_reproduce_the_exact_acceleration():
    m = sample_gait("sitting_trot", np.random.default_rng(5), camera_side=1.0)
    r = m.body_points_m[SADDLE_NAME]
    amps, phases = acceleration_harmonics(m, r, axis=1, n_harmonics=40)
    t = np.random.default_rng(1).uniform(-3, 7, 200)
    k = np.arange(1, 41)
    series = np.cos(np.multiply.outer(t, 2 * np.pi * m.stride_hz * k) + phases) @ amps
    np.testing.assert_allclose(series, m.point(r, t, derivative=2)[:, 1], atol=1e-10)


# --- truth ----------------------------------------------------------------------------------------
def test_truth_has_the_result_structure(truth):
    assert check_result_structure(truth) == []
    broken = json.loads(json.dumps(truth))
    del broken["indicators"]["vdv_y_wb"]
    broken["saddle"]["position_m"] = broken["saddle"]["position_m"][:-1]
    assert len(check_result_structure(broken)) == 2
    tr = truth["truth"]
    for key in (
        "markers_3d_mm",
        "marker_names",
        "motion_frame",
        "model",
        "saddle_acc_y_harmonics",
        "speed_kmh",
        "amplitude_y_m",
    ):
        assert key in tr
    assert truth["sync"]["motion"]["left"] == 0.0
    assert set(truth["sync"]) >= {"calibration", "plumb", "static", "motion", "freefall", "board_distance"}
    # window: two periods starting at a left frame
    assert truth["window"]["duration_s"] == pytest.approx(2 * truth["period_s"])
    assert truth["window"]["start_s"] * truth["fps"] == pytest.approx(round(truth["window"]["start_s"] * truth["fps"]))
    t = np.array(truth["saddle"]["t_s"])
    np.testing.assert_allclose(np.diff(t), 1 / truth["fps"])
    assert t[0] == pytest.approx(truth["window"]["start_s"])
    assert t[-1] < truth["window"]["start_s"] + truth["window"]["duration_s"]
    assert truth["indicators"]["stride_frequency_hz"] == pytest.approx(1 / truth["period_s"])


def test_truth_saddle_matches_markers_and_saddle_truth_at(scene, truth):
    tr = truth["truth"]
    mf = tr["motion_frame"]
    r_rm, origin = np.array(mf["R_rig_to_motion"]), np.array(mf["origin_mm"])
    np.testing.assert_allclose(r_rm @ r_rm.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r_rm), 1.0)
    np.testing.assert_allclose(r_rm[1], tr["gravity_rig"], atol=1e-12)  # motion y = gravity (down)
    names = tr["marker_names"]["motion"]
    s_idx = names.index("saddle")
    s_rig = np.array(tr["markers_3d_mm"]["motion"], dtype=float)[:, s_idx]
    t = np.array(truth["saddle"]["t_s"])
    k = np.round(t * truth["fps"]).astype(int)
    s_motion = (s_rig[k] - origin) @ r_rm.T / 1000.0
    np.testing.assert_allclose(s_motion, truth["saddle"]["position_m"], atol=1e-9)
    again = saddle_truth_at(truth, t)
    for key in ("position_m", "velocity_m_s", "acceleration_m_s2"):
        np.testing.assert_allclose(again[key], truth["saddle"][key], atol=1e-12)
    np.testing.assert_allclose(again["omega_rad_s"], truth["angular"]["omega_rad_s"], atol=1e-12)
    # origin is marker 1 at the first sample; x is the travel direction (net displacement per period)
    one = saddle_truth_at(truth, np.array([t[0], t[0] + truth["period_s"]]))
    d = one["position_m"][1] - one["position_m"][0]
    assert d[0] == pytest.approx(truth["truth"]["speed_m_s"] * truth["period_s"], rel=1e-9)
    np.testing.assert_allclose(d[1:], 0.0, atol=1e-12)
    # harmonics in truth reproduce the exact vertical acceleration at the window samples
    h = tr["saddle_acc_y_harmonics"]
    kk = np.arange(1, len(h["amplitudes_m_s2"]) + 1)
    ay = np.cos(np.multiply.outer(t, 2 * np.pi * h["f0_hz"] * kk) + h["phases_rad"]) @ np.array(h["amplitudes_m_s2"])
    np.testing.assert_allclose(ay, np.array(truth["saddle"]["acceleration_m_s2"])[:, 1], atol=1e-9)
    # amplitude_y = peak-to-peak of S's vertical displacement
    dense = saddle_truth_at(truth, t[0] + np.linspace(0, truth["period_s"], 2001))["position_m"][:, 1]
    assert np.ptp(dense) == pytest.approx(tr["amplitude_y_m"], abs=1e-6)


def test_saddle_truth_at_rejects_bad_input(truth):
    with pytest.raises(InputError):
        saddle_truth_at({"format": "x"}, np.array([0.0]))
    with pytest.raises(InputError):
        saddle_truth_at(truth, np.array([]))


def test_skin_motion_is_small_but_present(scene, truth):
    names = truth["truth"]["marker_names"]["motion"]
    m = np.array(truth["truth"]["markers_3d_mm"]["motion"], dtype=float)
    t = np.arange(m.shape[0]) / truth["fps"]
    rigid = scene.model.marker_positions(t, skin=False) @ scene.m_dir.T
    rigid_rig = scene.rig.world_to_rig_mm(rigid)
    dev = np.linalg.norm(m[:, :3] - rigid_rig[:, :3], axis=2)
    assert 0.3 < dev.max() < 8.0  # millimetres of skin motion on markers 1-3
    np.testing.assert_allclose(m[:, names.index("saddle")], rigid_rig[:, 3], atol=1e-9)  # S is rigid


# --- rig ------------------------------------------------------------------------------------------
def test_thesis_rig_matches_thesis_tables(scene):
    rig = scene.rig
    for cam in rig.cameras.values():
        assert cam.image_size == (640, 480)
        assert 710 <= cam.K[0, 0] <= 745 and 300 <= cam.K[0, 2] <= 340 and 220 <= cam.K[1, 2] <= 245
        assert -0.15 <= cam.dist[0] <= -0.11
    c = {r: cam.center_mm for r, cam in rig.cameras.items()}
    assert 220 <= np.linalg.norm(c["middle"] - c["left"]) <= 245
    assert 200 <= np.linalg.norm(c["right"] - c["middle"]) <= 245
    assert rig.fps == 30.0
    mid = scene.views["middle"].center_w
    assert abs(mid[2]) == pytest.approx(7.5, abs=0.2)  # 7.5 m from the track centre line


def test_wide_rig_and_size_override():
    s = build_scene(rig="wide", seed=2, size=(960, 540), calibration_poses=2, extras=False)
    c = {r: cam.center_mm for r, cam in s.rig.cameras.items()}
    assert np.linalg.norm(c["right"] - c["left"]) > 4000
    assert s.rig.fps == 60.0
    cam = s.rig.cameras["middle"]
    assert cam.image_size == (960, 540)
    assert cam.K[0, 0] == pytest.approx(725, abs=30)  # 1450 px at 1920 wide, halved
    w = build_scene(rig="wide", seed=2, fps=25.0, size=(640, 360), calibration_poses=2, extras=False)
    assert w.fps == 25.0


def test_bad_arguments_raise_input_errors():
    with pytest.raises(InputError, match="gait"):
        build_scene(gait="gallop")
    with pytest.raises(InputError, match="rig"):
        build_scene(rig="phone")
    with pytest.raises(InputError, match="short"):
        build_scene(gait="walk", duration_s=1.0, calibration_poses=2, extras=False)
    with pytest.raises(InputError, match="even"):
        build_scene(size=(641, 480), calibration_poses=2, extras=False)


# --- rendering vs geometry ------------------------------------------------------------------------
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


def test_calibration_clip_length():
    s = build_scene(gait="walk", seed=0, calibration_poses=90, extras=False)
    tm = s.timings["calibration"]
    assert len(s.contents["calibration"].poses) == 90
    assert tm.n_left >= 90 + 3
    centres = np.array([o for _, o in s.contents["calibration"].poses])
    # spread through the volume: about the thesis's 6.5 m x 0.7 m x 0.5 m
    assert np.ptp(centres[:, 0]) > 4.5 and np.ptp(centres[:, 1]) > 0.4 and np.ptp(centres[:, 2]) > 0.3


def test_freefall_truth_is_free_fall(scene, truth):
    ff = truth["truth"]["freefall"]
    a, b = ff["flight_left_frames"]
    assert b - a + 1 >= 21
    p = np.array(truth["truth"]["markers_3d_mm"]["freefall"], dtype=float)[a : b + 1, 0]
    g = np.array(truth["truth"]["gravity_rig"])
    along = p @ g / 1000.0
    acc = np.diff(along, 2) * truth["fps"] ** 2
    np.testing.assert_allclose(acc, 9.81, rtol=1e-9)
    assert np.ptp(along) > 0.5  # thrown from the lower edge to the upper edge of the volume


def test_board_distance_truth(truth):
    bd = truth["truth"]["board_distance"]
    assert bd["distances_mm"]["AB"] == 500 and bd["distances_mm"]["AC"] == 500
    assert bd["distances_mm"]["AD"] == pytest.approx(707.107, abs=1e-3)
    assert len(bd["poses"]) == 3
    for pose in bd["poses"]:
        pts = {k: np.array(v) for k, v in pose["points_mm"].items()}
        assert np.linalg.norm(pts["A"] - pts["B"]) == pytest.approx(500, abs=1e-9)
        assert np.linalg.norm(pts["A"] - pts["D"]) == pytest.approx(707.1068, abs=1e-3)
        a, b = pose["still_left_frames"]
        assert b - a >= 10


def test_scene_and_frames_are_deterministic():
    a = build_scene(gait="rising_trot", seed=11, calibration_poses=3, extras=False)
    b = build_scene(gait="rising_trot", seed=11, calibration_poses=3, extras=False)
    assert json.dumps(build_truth(a)) == json.dumps(build_truth(b))
    for kind, k in (("motion", 50), ("calibration", 20)):
        fa = list(render_clip_frames(a, "middle", kind, start=k, stop=k + 2))
        fb = list(render_clip_frames(b, "middle", kind, start=k, stop=k + 2))
        assert all(np.array_equal(x, y) for x, y in zip(fa, fb, strict=True))
        # a sub-range equals the same frames of a longer render
        longer = list(render_clip_frames(a, "middle", kind, start=k - 1, stop=k + 2))
        assert np.array_equal(longer[1], fa[0])
    c = build_scene(gait="rising_trot", seed=12, calibration_poses=3, extras=False)
    assert c.model.speed_m_s != a.model.speed_m_s


def test_all_gaits_build_and_give_a_two_period_window():
    for gait in GAITS:
        s = build_scene(gait=gait, seed=4, calibration_poses=2, extras=False)
        assert s.window_periods == 2
        assert s.timings["motion"].n_left / s.fps >= 3.5
        assert GAIT_RANGES[gait]["stride_hz"][0] <= s.model.stride_hz <= GAIT_RANGES[gait]["stride_hz"][1]

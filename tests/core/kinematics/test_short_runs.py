"""Crossings shorter than the window asks for (issue 27): a run just under two strides, or one cut in two,
is analysed on the whole strides it holds, not refused (core/saddle.py)."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core import saddle as S
from saddlescope.core.errors import KinematicsError
from saddlescope.core.params import PipelineParams
from saddlescope.core.types import MarkerTracks

FPS, F0 = 30.0, 1.6  # 18.75 frames a stride


def _rigid_ride(n_frames: int, lost: np.ndarray | None = None) -> tuple[MarkerTracks, MarkerTracks]:
    """Three markers of a rigid body bobbing and pitching at F0 while it travels at 4 m/s (mm), and its static shot."""
    t = np.arange(n_frames) / FPS
    model = np.array([[0.0, 0.0, 0.0], [200.0, 10.0, 0.0], [400.0, -60.0, 5.0]])
    w = 2 * np.pi * F0 * t
    origin = np.stack([4000.0 * t, 60 * np.sin(w) + 15 * np.cos(2 * w), 7000 + 10 * np.sin(w)], axis=1)
    ang = 0.05 * np.sin(w)
    R = np.zeros((n_frames, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = np.cos(ang), -np.sin(ang), np.sin(ang), np.cos(ang), 1
    xyz = np.einsum("fij,mj->fmi", R, model) + origin[:, None, :]
    if lost is not None:
        xyz[lost] = np.nan
    static = np.concatenate([model, [[150.0, -330.0, -150.0]]])[None].repeat(5, axis=0) + [0, 0, 7000]
    return MarkerTracks(("M1", "M2", "M3"), t, xyz), MarkerTracks(("M1", "M2", "M3", "S"), t[:5], static)


def _analyse(motion, static):
    kin = S.saddle_kinematics(motion, static, None, PipelineParams(), horse_idx=[0, 1, 2], saddle_idx=3,
                              gait="canter")
    return kin, S.kinematics_indicators(kin, PipelineParams())[1]


def test_a_run_just_under_two_strides_is_analysed_on_one():
    long_kin, long_ind = _analyse(*_rigid_ride(150))
    kin, ind = _analyse(*_rigid_ride(33))  # 1.1 s: 1.76 strides, refused before for two
    assert kin.period_s == pytest.approx(1 / F0, rel=0.01)
    i0, i1 = kin.window
    assert i1 - i0 == round(FPS / F0)  # one whole stride
    assert [(f.values["strides_fitted"], f.values["strides_asked"]) for f in kin.flags
            if f.code == "fit.short_crossing"] == [(1, 2)]
    # the indicators are those of the same periodic motion over two strides
    for key in ("acc_y_wb_rms", "vdv_y_wb", "vel_x_avg_kmh", "stride_frequency_hz"):
        assert ind[key] == pytest.approx(long_ind[key], rel=0.03), key


def test_a_crossing_cut_in_two_borrows_every_tracked_frame_for_its_period():
    lost = np.zeros((61, 3), dtype=bool)
    lost[26:35] = True  # 0.3 s lost in the middle: two runs of 0.87 s, each too short for a period alone
    motion, static = _rigid_ride(61, lost)
    valid = np.all(np.isfinite(motion.xyz_mm), axis=(1, 2))
    with pytest.raises(KinematicsError):  # either run alone gives no period
        S._planar_period(motion.t_s, motion.xyz_mm, valid, (0, 26), 1 / FPS, S.STRIDE_RANGE_HZ["canter"])
    kin, ind = _analyse(motion, static)
    assert kin.period_s == pytest.approx(1 / F0, rel=0.01)
    assert ind["stride_frequency_hz"] == pytest.approx(F0, rel=0.01)
    assert [(f.values["strides_fitted"], f.values["strides_asked"]) for f in kin.flags
            if f.code == "fit.short_crossing"] == [(1, 2)]


def test_less_than_one_stride_together_is_still_refused():
    lost = np.zeros((66, 3), dtype=bool)
    lost[12:20] = lost[30:38] = lost[48:56] = True  # runs of about half a stride, gaps too long to bridge
    with pytest.raises(KinematicsError):
        _analyse(*_rigid_ride(66, lost))


def _guessed_depth_at_the_ends(sound: slice, n_frames: int = 80):
    """The rigid ride with its ends' depth guessed (issue 27, seed 1014): outside ``sound`` each marker drifts
    in depth and along the track, smoothly and by its own amount (two cameras, one beyond its board's reach)."""
    from saddlescope.core.triangulation import ReachCheckedTracks

    motion, static = _rigid_ride(n_frames)
    guessed = np.ones(n_frames, dtype=bool)
    guessed[sound] = False
    # frames from the sound stretch: the lens error grows with the image radius, so towards the ends
    away = np.where(guessed, np.minimum(np.abs(np.arange(n_frames) - sound.start),
                                        np.abs(np.arange(n_frames) - (sound.stop - 1))), 0) / FPS
    xyz = motion.xyz_mm.copy()
    for m, gain in enumerate((1.0, 0.6, 0.3)):  # seed 1014: 0.1-0.8 m in depth, 10-30 mm in height
        xyz[:, m, 2] -= gain * 800.0 * away ** 2
        xyz[:, m, 0] += gain * 300.0 * away ** 2
        xyz[:, m, 1] += gain * 30.0 * away
    beyond_px = np.repeat(200.0 * away[:, None], 3, axis=1)  # farther beyond the board's reach, farther off
    return (ReachCheckedTracks(motion.names, motion.t_s, xyz, lens_extrapolation_px=beyond_px),
            MarkerTracks(motion.names, motion.t_s, xyz), static)


def test_samples_whose_depth_rests_on_a_guessed_lens_are_left_out_when_a_stride_remains():
    _, clean = _analyse(*_rigid_ride(80))
    marked, unmarked, static = _guessed_depth_at_the_ends(slice(14, 66))  # 1.73 s sound: 2.8 strides
    kin, ind = _analyse(marked, static)
    blind, _ = _analyse(unmarked, static)
    assert blind.fitted[0] < 14 and blind.fitted[1] > 66  # unmarked, the guessed ends are fitted too
    for key in ("acc_y_wb_rms", "acc_y_wk_rms", "vdv_y_wb", "vel_x_avg_kmh", "stride_frequency_hz"):
        assert ind[key] == pytest.approx(clean[key], rel=0.03), key
    assert 14 <= kin.fitted[0] and kin.fitted[1] <= 66
    assert [f.values["used_s"] for f in kin.flags if f.code == "calibration.guessed_depth"] == [pytest.approx(1.73,
                                                                                                           abs=0.005)]


def test_under_a_stride_without_a_guessed_lens_the_least_extrapolated_frames_next_to_it_complete_one():
    marked, unmarked, static = _guessed_depth_at_the_ends(slice(33, 45))  # 0.4 s sound: under a stride
    kin, _ = _analyse(marked, static)
    # 19 frames (a stride of 18.75) centred on the sound stretch: the nearest guessed frames on each side
    assert kin.fitted in ((29, 48), (30, 49))
    assert kin.fitted != _analyse(unmarked, static)[0].fitted
    assert any(f.code == "calibration.guessed_depth" and f.values["beyond_reach_px_max"] > 0 for f in kin.flags)


def test_a_run_under_a_stride_with_a_guessed_lens_is_said_in_plain_words():
    lost = np.ones((80, 3), dtype=bool)
    lost[20:60] = False  # 1.33 s tracked, of which only the middle 0.4 s is sound...
    motion, static = _rigid_ride(80, lost)
    beyond_px = np.zeros((80, 3))
    beyond_px[20:34] = beyond_px[46:60] = 50.0
    from saddlescope.core.triangulation import ReachCheckedTracks

    marked = ReachCheckedTracks(motion.names, motion.t_s, motion.xyz_mm, lens_extrapolation_px=beyond_px)
    valid = np.all(np.isfinite(motion.xyz_mm), axis=(1, 2))
    flags = []
    # ... and the run (20-60) is cut to 16 frames, under a stride (18.75): it stays, said in plain words
    run = S._run_off_guessed_lens(motion.t_s, valid & (np.arange(80) < 36), (20, 36), 1 / F0,
                                  beyond_px.max(axis=1), flags)
    assert run == (20, 36)
    assert [f.code for f in flags] == ["calibration.guessed_depth_broken"]
    kin, _ = _analyse(marked, static)  # the whole run holds two strides: analysed on the least extrapolated
    assert 20 <= kin.fitted[0] and kin.fitted[1] <= 60 and kin.fitted[1] - kin.fitted[0] < 40

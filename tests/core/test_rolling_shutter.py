"""Rolling shutters: the flash's sweep model, the readout from the row bands, each observation's instant."""

from __future__ import annotations

import numpy as np
import pytest

from saddlescope.core.errors import InputError
from saddlescope.core.rolling_shutter import (
    readout_from_bands,
    readouts_from_meta,
    row_delay_frames,
    sweep_response,
)
from saddlescope.core.sync import clip_offsets, flash_run
from saddlescope.core.triangulation.tracks import at_top_row_instants, resample_at_instants, resample_tracks
from saddlescope.core.types import ImageTracks

FPS = 30.0
READOUT = 0.025 * FPS  # a phone's 25 ms at 30 fps: three quarters of a frame
BANDS = 16


def _lamp(t: np.ndarray, on: float, ramp: float = 2.0, plateau: float = 1.5) -> np.ndarray:
    """A lamp (0..1) that ramps up from ``on`` over ``ramp`` frames, stays on, and ramps down as fast."""
    off = on + ramp + plateau
    return np.clip((t - on) / ramp, 0, 1) - np.clip((t - off) / ramp, 0, 1)


def _bands(on: float, readout: float, rng: np.random.Generator, n: int = 40) -> np.ndarray:
    """Per band of rows (n, BANDS) the brightness of frames whose top row is exposed at k, band b later."""
    k = np.arange(n, dtype=np.float64)[:, None]
    delay = (np.arange(BANDS) + 0.5) / BANDS * readout
    # each band a few rows apart: the mean of four row instants within it
    sub = np.mean([_lamp(k + delay + (j - 1.5) / 4 * readout / BANDS, on) for j in range(4)], axis=0)
    return 80.0 + 95.0 * sub + rng.normal(0, 0.1, (n, BANDS))


def test_sweep_response_is_the_ramp_without_a_readout_and_half_lit_at_minus_half_the_readout():
    s = np.linspace(-3, 3, 61)
    assert np.allclose(sweep_response(s, 2.0, 0.0), np.clip(s / 2.0 + 0.5, 0, 1))
    # the rows' mean crosses half way when the middle row does: readout / 2 before the top row
    assert sweep_response(np.array([-0.375]), 2.0, 0.75)[0] == pytest.approx(0.5, abs=1e-12)
    assert sweep_response(np.array([0.0]), 2.0, 0.75)[0] > 0.6


def test_flash_offsets_with_a_rolling_shutter_within_a_hundredth_of_a_frame():
    rng = np.random.default_rng(5)
    worst_swept, worst_global = 0.0, 0.0
    for _ in range(10):
        ons = 10 + rng.uniform(0, 3, 3)
        curves = {cam: _bands(on, READOUT, rng).mean(axis=1) for cam, on in zip(("left", "middle", "right"), ons,
                                                                                strict=True)}
        fps = dict.fromkeys(curves, FPS)
        truth = {"middle": ons[1] - ons[0], "right": ons[2] - ons[0]}
        swept = clip_offsets(curves, fps, clip="motion", readout_frames=dict.fromkeys(curves, READOUT))
        plain = clip_offsets(curves, fps, clip="motion")
        worst_swept = max(worst_swept, *(abs(swept[c] - truth[c]) for c in truth))
        worst_global = max(worst_global, *(abs(plain[c] - truth[c]) for c in truth))
    assert worst_swept < 0.01
    assert worst_global > worst_swept  # the global-shutter model misses the sweep's curvature


def test_readout_from_the_row_bands_and_none_from_a_global_shutter():
    rng = np.random.default_rng(7)
    rows = (np.arange(BANDS) + 0.5) / BANDS
    for readout_ms in (10.0, 25.0, 33.0):
        curves = _bands(11.3, readout_ms / 1000 * FPS, rng)
        start, stop = flash_run(curves.mean(axis=1), clip="motion", camera="left")
        est = readout_from_bands(curves, rows, FPS, start=start, stop=stop)
        assert est.readout_s * 1000 == pytest.approx(readout_ms, abs=0.3)
        assert est.bands == BANDS
    curves = _bands(11.3, 0.0, rng)
    start, stop = flash_run(curves.mean(axis=1), clip="motion", camera="left")
    est = readout_from_bands(curves, rows, FPS, start=start, stop=stop)
    assert est.readout_s == 0.0  # not significant: a global shutter
    assert abs(est.measured_s) < 0.5e-3


def _rolling_track(readout: float, rows: int, n: int = 60) -> tuple[ImageTracks, callable]:
    """A marker moving fast across and down the image, seen by a rolling shutter at its row's instant."""
    def at(t):
        return np.stack([100 + 25 * t + 0.4 * t ** 2, 60 + 6 * t + 20 * np.sin(0.35 * t)], axis=-1)
    k = np.arange(n, dtype=np.float64)
    t = k.copy()
    for _ in range(20):  # the instant at which the marker's row was exposed (fixed point)
        t = k + row_delay_frames(at(t)[:, 1], readout, rows)
    return ImageTracks("left", at(t)[:, None, :], np.arange(n)), at


def test_every_observation_is_placed_at_its_rows_instant():
    rows = 480
    track, truth = _rolling_track(READOUT, rows)
    wanted = np.arange(5, 50) + 0.3
    got = resample_at_instants(track, wanted, READOUT, rows)[:, 0]
    assert np.max(np.abs(got - truth(wanted))) < 0.02  # px
    plain = resample_tracks(track, wanted)[:, 0]  # the frame's instant for every row: off by the delay
    assert np.max(np.abs(plain - truth(wanted))) > 5.0
    moved = at_top_row_instants(track, READOUT, rows)
    inner = slice(3, -3)
    assert np.max(np.abs(moved.xy_px[inner, 0] - truth(np.arange(60.0))[inner])) < 0.02
    assert at_top_row_instants(track, 0.0, rows) is track


def test_readouts_from_ride_json_are_checked():
    cams = ["left", "middle", "right"]
    assert readouts_from_meta({"sync": {"method": "flash"}}, cams) is None
    assert readouts_from_meta({"sync": {"readout_ms": {"left": 25, "middle": 12.5}}}, cams) == {
        "left": 0.025, "middle": 0.0125, "right": 0.0}
    with pytest.raises(InputError, match="0-40 ms"):
        readouts_from_meta({"sync": {"readout_ms": {"left": 55}}}, cams)
    with pytest.raises(InputError, match="0-40 ms"):
        readouts_from_meta({"sync": {"readout_ms": {"left": "25"}}}, cams)
    with pytest.raises(InputError, match="does not have"):
        readouts_from_meta({"sync": {"readout_ms": {"top": 25}}}, cams)
